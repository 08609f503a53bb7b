"""Throughput and peak memory of exact IK, paper IK and FK (a script, not a test).

    python bench/bench_kinematics.py [--n 1000000] [--repeat 3]

Each kernel runs as shipped (cache-sized blocks on up to two threads) and, as the baseline in the
same run, as one whole-array pass on one thread (``block_rows = N``, ``workers = 1``); the ratio
is what the blocking and threading buy on this machine. Peak memory is traced with tracemalloc
(NumPy reports its buffers to it) per call, and given per pose so that an (N, N) temporary would
show at once. Targets on the 2-core CI machine: exact IK ≥ 5 M poses/s, FK ≥ 1 M poses/s.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

import numpy as np

from prs3_post.config import load_machine
from prs3_post.kinematics import IKModel, forward, inverse
from prs3_post.kinematics.exact import inverse_exact


def workspace(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """n poses: tilt ≤ 45°, any azimuth, tip x, y ∈ [−150, 150], z ∈ [−750, −600] mm."""
    rng = np.random.default_rng(seed)
    tilt, azimuth = np.radians(rng.uniform(0, 45, n)), rng.uniform(0, 2 * np.pi, n)
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    tip = np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n), rng.uniform(-750, -600, n)])
    return tip, axis


def measure(call, repeat: int) -> tuple[float, int]:
    """Best wall time of ``repeat`` calls (s) and the peak traced memory of one call (bytes)."""
    call()                                             # warm up: page in, thread pool
    best = min(_timed(call) for _ in range(repeat))
    tracemalloc.start()
    call()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return best, peak


def _timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    geo = load_machine("patel2020").geometry
    n = args.n
    tip, axis = workspace(n)
    ik = inverse(geo, tip, axis)
    cases = [
        ("exact IK", lambda: inverse_exact(geo, tip, axis), lambda: inverse_exact(geo, tip, axis, block_rows=n, workers=1)),
        ("paper IK", lambda: inverse(geo, tip, axis, model=IKModel.PAPER), None),
        ("FK", lambda: forward(geo, ik.strokes, ik.stage),
         lambda: forward(geo, ik.strokes, ik.stage, block_rows=n, workers=1)),
    ]
    print(f"N = {n:,} poses, best of {args.repeat}")
    print(f"{'kernel':<10} {'M poses/s':>10} {'baseline':>10} {'ratio':>7} {'peak MB':>9} {'bytes/pose':>11}")
    for name, shipped, baseline in cases:
        seconds, peak = measure(shipped, args.repeat)
        rate = n / seconds / 1e6
        if baseline is not None:
            base_rate = n / measure(baseline, 1)[0] / 1e6
            base_text, ratio_text = f"{base_rate:10.2f}", f"{rate / base_rate:7.2f}"
        else:
            base_text, ratio_text = f"{'-':>10}", f"{'-':>7}"
        print(f"{name:<10} {rate:10.2f} {base_text} {ratio_text} {peak / 1e6:9.1f} {peak / n:11.0f}")


if __name__ == "__main__":
    main()
