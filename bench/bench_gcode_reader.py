"""Throughput and peak memory of the 3+2 G-code reader, against pygcode's parse loop (a script, not a test).

    python bench/bench_gcode_reader.py [--lines 1000000] [--repeat 3] [--pygcode-lines 100000]

Writes a synthetic 3-axis program in a G68.2 tilted plane (``G1 X.. Y.. Z..`` lines, an F every
100 moves, a comment every 50) to a temporary directory and reads it (a) whole with ``read_gcode``
and (b) streamed with ``GcodeStream`` (chunks dropped as they come, as a streaming conversion
would). The reference in the same run, (c), is a loop that only parses the program's first
``--pygcode-lines`` lines with ``pygcode.Line`` (its rate is per line, so a shorter run measures
it fairly). The three run alternately ``--repeat`` times; the script prints the median and the
range of each rate, wall clock and per CPU second (the fairer one on a loaded machine), and of the
ratio to pygcode's loop per CPU second. Peak memory is traced with tracemalloc in one more call.
The issue's end-to-end targets for ``convert``: ≥ 300,000 input moves/s for one file on the
2-core machine, ≥ 30 times pygcode's parse-only loop, a 10-million-line input under 500 MB; the
reader alone must be well inside them.
"""

from __future__ import annotations

import argparse
import os
import random
import tempfile

from _measure import load, pygcode_rate, spread, timed, traced_peak

from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.readers.gcode.reader import GcodeStream, read_gcode


def write_program(path: str, lines: int, seed: int = 0) -> int:
    """A 3+2 program of about ``lines`` lines; returns the number of moves."""
    rng = random.Random(seed)
    moves = 0
    with open(path, "w") as out:
        out.write("%\nG21 G90 G94 G17\nT1 M6\nS8000 M3\nG0 X0 Y0 Z50\nG68.2 X10 Y20 Z0 I30 J25 K0\nG53.1\n"
                  "G0 X0 Y0 Z5\nG1 Z0 F600\n")
        written = 9
        while written < lines - 3:
            x, y, z = rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-3, 0)
            feed = f" F{rng.choice((400, 500, 600))}" if moves % 100 == 0 else ""
            out.write(f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f}{feed}\n")
            moves += 1
            written += 1
            if moves % 50 == 0:
                out.write(f"(pass {moves // 50})\n")
                written += 1
        out.write("G69\nM30\n%\n")
    return moves + 3


def streamed(path: str) -> None:
    for _ in GcodeStream(path, tolerance=0.002, circle_tolerance=CIRCLE_TOL):
        pass


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--pygcode-lines", type=int, default=100_000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.ngc")
        moves = write_program(path, args.lines)
        size = os.path.getsize(path)
        print(f"{args.lines:,} lines, {moves:,} moves, {size / 1e6:.1f} MB; {load()}")
        reference_lines = min(args.pygcode_lines, args.lines)
        calls = (("read_gcode (whole)", lambda: read_gcode(path, tolerance=0.002, circle_tolerance=CIRCLE_TOL)),
                 ("GcodeStream (chunks dropped)", lambda: streamed(path)))
        reference: list[tuple[float, float]] = []                       # lines/s wall, per CPU s
        rates: dict[str, list[tuple[float, float]]] = {name: [] for name, _ in calls}
        for _ in range(args.repeat):                                    # alternately: the same load for each
            reference.append(pygcode_rate(path, reference_lines))
            for name, call in calls:
                wall, cpu = timed(call)
                rates[name].append((moves / wall, moves / cpu))
        print(f"{'pygcode.Line (parse only)':28s} lines/s wall {spread([r[0] for r in reference], ',.0f')}, "
              f"per CPU s {spread([r[1] for r in reference], ',.0f')} (first {reference_lines:,} lines)")
        for name, call in calls:
            walls, cpus = [r[0] for r in rates[name]], [r[1] for r in rates[name]]
            ratio = [args.lines / moves * c / ref[1] for c, ref in zip(cpus, reference, strict=True)]
            print(f"{name:28s} moves/s wall {spread(walls, ',.0f')}, per CPU s {spread(cpus, ',.0f')}; "
                  f"lines per CPU s / pygcode's: {spread(ratio, '.1f')}x; peak {traced_peak(call) / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
