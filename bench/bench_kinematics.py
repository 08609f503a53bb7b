"""Throughput and peak memory of exact IK, paper IK and FK (a script, not a test).

    python bench/bench_kinematics.py [--n 1000000] [--repeat 7]

Each kernel runs as shipped (cache-sized blocks on up to two threads) and, as the baseline in the
same run, as one whole-array pass on one thread (``block_rows = N``, ``workers = 1``), alternately,
``--repeat`` times each; the ratio of the medians is what the blocking and threading buy on this
machine. Rates are printed as the median and the range (min..max) over the runs, with the load
average before and after: on a shared machine one number means little. Peak memory is traced with
tracemalloc (NumPy reports its buffers to it) on one more call, and given per pose so that an
(N, N) temporary would show at once. Targets on the 2-core CI machine: exact IK ≥ 5 M poses/s,
FK ≥ 1 M poses/s.
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np
from _measure import load, spread, timed, traced_peak

from prs3_post.kinematics import forward, inverse
from prs3_post.kinematics.prs3.exact import inverse_exact
from prs3_post.kinematics.prs3.paper import inverse_paper
from prs3_post.machine.loading import load_machine


def workspace(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """n poses: tilt ≤ 45°, any azimuth, tip x, y ∈ [−150, 150], z ∈ [−750, −600] mm."""
    rng = np.random.default_rng(seed)
    tilt, azimuth = np.radians(rng.uniform(0, 45, n)), rng.uniform(0, 2 * np.pi, n)
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    tip = np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n), rng.uniform(-750, -600, n)])
    return tip, axis


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    geo = load_machine("patel2020").geometry
    n = args.n
    tip, axis = workspace(n)
    ik = inverse(geo, tip, axis)
    cases = [
        ("exact IK", lambda: inverse_exact(geo, tip, axis),
         lambda: inverse_exact(geo, tip, axis, block_rows=n, workers=1)),
        ("paper IK", lambda: inverse_paper(geo, tip, axis),
         lambda: inverse_paper(geo, tip, axis, block_rows=n, workers=1)),
        ("FK", lambda: forward(geo, ik.strokes, ik.stage),
         lambda: forward(geo, ik.strokes, ik.stage, block_rows=n, workers=1)),
    ]
    print(f"N = {n:,} poses, {args.repeat} runs each; before: {load()}")
    print(f"{'kernel':<10} {'M poses/s: median (min..max)':>30} {'baseline':>22} {'ratio':>6} {'peak MB':>8} "
          f"{'bytes/pose':>10}")
    for name, shipped, baseline in cases:
        shipped(), baseline()                          # warm up: page in, thread pool
        rates, base_rates = [], []
        for _ in range(args.repeat):                   # alternately, so that a load change hits both
            rates.append(n / timed(shipped)[0] / 1e6)
            base_rates.append(n / timed(baseline)[0] / 1e6)
        peak = traced_peak(shipped)
        ratio = statistics.median(rates) / statistics.median(base_rates)
        print(f"{name:<10} {spread(rates, '6.2f'):>30} {spread(base_rates, '6.2f'):>22} {ratio:6.2f} {peak / 1e6:8.1f} "
              f"{peak / n:10.0f}")
    print(f"after: {load()}")


if __name__ == "__main__":
    main()
