"""Throughput and peak memory of the CL reader, whole and streamed (a script, not a test).

    python bench/bench_cl_reader.py [--lines 1000000] [--repeat 3]

Writes a synthetic NX-style CL file (one MSYS, FEDRAT, a PAINT record every 50 moves, two thirds of
the GOTOs with i,j,k omitted) to a temporary directory and reads it (a) whole with ``read_cl`` and
(b) streamed with ``ClStream`` (chunks dropped as they come, as a streaming conversion would). As
the baseline in the same run, (c) a loop that only splits each line's values and converts them to
float (the least any text reader does). Peak memory is traced with tracemalloc per call. The
issue's end-to-end target for ``convert`` is ≥ 300,000 input moves/s on the 2-core machine and a
10-million-line input under 500 MB: the streamed reader must stay well inside both.
"""

from __future__ import annotations

import argparse
import os
import random
import tempfile

from _measure import measure

from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.readers.cl.reader import ClStream, read_cl


def write_cl(path: str, lines: int, seed: int = 0) -> int:
    """A CL file of about ``lines`` lines; returns the number of GOTOs."""
    rng = random.Random(seed)
    moves = 0
    with open(path, "w") as out:
        out.write("TOOL PATH/BENCH,TOOL,MILL\nMSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,"
                  "0.0000000,1.0000000,0.0000000\nFEDRAT/MMPM,500.0000\nRAPID\n")
        written = 4
        while written < lines - 1:
            x, y, z = rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(0, 5)
            if moves % 3 == 0:
                out.write(f"GOTO/{x:.4f},{y:.4f},{z:.4f},0.0000000,0.6000000,0.8000000\n")
            else:
                out.write(f"GOTO/{x:.4f},{y:.4f},{z:.4f}\n")
            moves += 1
            written += 1
            if moves % 50 == 0:
                out.write("PAINT/COLOR,31\n")
                written += 1
        out.write("END-OF-PATH\n")
    return moves


def baseline(path: str) -> None:
    with open(path) as stream:
        for line in stream:
            if line.startswith("GOTO/"):
                [float(v) for v in line[5:].split(",")]


def streamed(path: str) -> None:
    for _ in ClStream(path, tolerance=0.002, circle_tolerance=CIRCLE_TOL):
        pass


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.cls")
        moves = write_cl(path, args.lines)
        size = os.path.getsize(path)
        print(f"{args.lines:,} lines, {moves:,} GOTOs, {size / 1e6:.1f} MB")
        results = {
            "baseline (split + float)": measure(lambda: baseline(path), args.repeat),
            "read_cl (whole)": measure(lambda: read_cl(path, tolerance=0.002,
                                                       circle_tolerance=CIRCLE_TOL), args.repeat),
            "ClStream (chunks dropped)": measure(lambda: streamed(path), args.repeat),
        }
        base = results["baseline (split + float)"][1]
        print(f"load average {os.getloadavg()[0]:.1f}")
        for name, (seconds, cpu, peak) in results.items():
            print(f"{name:28s} {moves / seconds:10,.0f} moves/s wall {moves / cpu:10,.0f} per CPU s  "
                  f"{cpu / base:5.2f} x baseline CPU time  peak {peak / 1e6:7.1f} MB")


if __name__ == "__main__":
    main()
