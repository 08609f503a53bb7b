"""Throughput and peak memory of the main job and of `ik --batch` at a million rows (a script, not a test).

    python bench/bench_main.py [--repeat 5] [--poses 1000000] [--only main|ik] [--keep DIR]

Each command runs in a fresh process ``--repeat`` times (whole process: start-up included), and
the script prints each run, then the median and the range (min..max) over the runs, with the
machine's load average before and after (the numbers mean little on a loaded machine):

* main job: ``prs3-post demo --profile round --diameter 36 --depth 10 --step-down 0.01
  --tolerance 0.0001`` — 1,000 passes of a 3,000-segment circle, about 950,000 lines; lines/s of
  the written program. Target ≥ 250,000 lines/s within 300 MB.
* ``prs3-post ik --batch`` on ``--poses`` random workspace poses (tilt ≤ 45°, written with full
  precision, 120 MB for a million): rows/s. Target ≥ 500,000 rows/s within 300 MB at any size.

Peak memory is the child's own peak resident set (VmHWM), its CPU time user + system from its own
``getrusage`` (``_measure.run_cli``): the rates per CPU second are the fairer ones on a loaded machine.

Because a loaded machine slows everything, the formatting is also measured against its old way in
the same process, alternately (``--rows`` rows): the emitter's motion lines against one
``format_word`` call per word (what the old emitter spent 86 % of its time on), and the batch
CSV's lines against ``repr`` per number (the old CSV's 85 %). Those ratios hold whatever the load.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from _measure import count_lines, load, run_cli, spread

MAIN_JOB = ["demo", "--profile", "round", "--diameter", "36", "--depth", "10", "--step-down", "0.01",
            "--tolerance", "0.0001"]


def write_poses(path: Path, n: int, seed: int = 0) -> None:
    """``n`` poses: tilt ≤ 45°, any azimuth, tip x, y ∈ [−150, 150], z ∈ [−750, −600] mm, 17 digits."""
    rng = np.random.default_rng(seed)
    with open(path, "w", encoding="ascii") as stream:
        stream.write("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n")
        for lo in range(0, n, 100_000):
            m = min(n, lo + 100_000) - lo
            tilt, azimuth = np.radians(rng.uniform(0, 45, m)), rng.uniform(0, 2 * np.pi, m)
            axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
            tip = np.column_stack([rng.uniform(-150, 150, (m, 2)), rng.uniform(-750, -600, m)])
            np.savetxt(stream, np.hstack([tip, axis]), fmt="%.17g", delimiter=",")


def bench(name: str, args: list[str], out: Path, count_rows, repeat: int, target_rate: float, unit: str) -> None:
    """Run ``args`` ``repeat`` times; rows per second from ``count_rows(out)``; print each run and the spread."""
    rates, cpu_rates, peaks = [], [], []
    for _ in range(repeat):
        out.unlink(missing_ok=True)
        run = run_cli([*args, "-o", str(out)])
        wall, cpu, rss = run.wall, run.cpu, run.peak_mb
        rows = count_rows(out) if out.exists() else 0
        rates.append(rows / wall)
        cpu_rates.append(rows / cpu)
        peaks.append(rss)
        print(f"  {name}: {wall:.2f} s wall, {cpu:.2f} s CPU, {rows:,} {unit}, {rows / wall:,.0f} {unit}/s, "
              f"{rows / cpu:,.0f} per CPU s, peak RSS {rss:.0f} MB, exit {run.code}: {run.last}")
    print(f"{name} {unit}/s (wall): {spread(rates, ',.0f')}; per CPU second: {spread(cpu_rates, ',.0f')}  "
          f"(target ≥ {target_rate:,.0f})")
    print(f"{name} peak RSS MB: {spread(peaks, '.0f')}  (target < 300)")


def formatting_ratios(rows: int, repeat: int) -> None:
    """Bulk formatting against the old one-number-at-a-time way, in this process, alternately."""
    from prs3_post.core.numbers import ChoiceColumn, format_word, render_rows, scale_column
    from prs3_post.core.toolpath import JointProgram
    from prs3_post.emit.gcode import ProgramEmitter
    from prs3_post.machine.loading import load_dialect

    rng = np.random.default_rng(1)
    program = JointProgram(kind=np.ones(rows, dtype=np.int64), stage=rng.uniform(-300, 300, (rows, 2)),
                           strokes=rng.uniform(-100, 400, (rows, 3)), inverse_time=rng.uniform(1, 100, rows),
                           source=np.zeros(rows, dtype=np.int64))
    dialect = load_dialect("linuxcnc")
    table = rng.uniform(-700, 700, (rows, 15))

    def emitter() -> None:
        ProgramEmitter(dialect).rows(program)

    def words() -> None:
        for values in (*program.stage.T, *program.strokes.T):
            [format_word("X", v, 4) for v in values.tolist()]
        [format_word("F", v, 4) for v in program.inverse_time.tolist()]

    def csv_bulk() -> None:
        columns = [(b"", scale_column(table[:, j], 9)) for j in range(15)]
        columns.append(ChoiceColumn(np.ones(rows, dtype=np.int64), (b"false", b"true")))
        render_rows(columns, np.ones((rows, 16), dtype=bool), separator=b",")

    def csv_repr() -> None:
        "\n".join(",".join(map(repr, row)) + ",true" for row in table.tolist())

    for name, new, old in (("program lines (emitter vs format_word)", emitter, words),
                           ("CSV lines (render_rows vs repr)", csv_bulk, csv_repr)):
        ratios, rates = [], []
        for _ in range(repeat):
            start = time.process_time()
            new()
            middle = time.process_time()
            old()
            end = time.process_time()
            rates.append(rows / (middle - start))
            ratios.append((end - middle) / (middle - start))
        print(f"{name}: {spread(rates, ',.0f')} rows per CPU second, {spread(ratios, '.1f')}× the old way")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--only", choices=["main", "ik", "formatting"])
    parser.add_argument("--rows", type=int, default=200_000, help="rows of the formatting comparison")
    parser.add_argument("--keep", type=Path, help="write the inputs and outputs here and keep them")
    args = parser.parse_args()
    print(f"before: {load()}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        if args.only in (None, "main"):
            print(f"main job: prs3-post {' '.join(MAIN_JOB)}")
            bench("main job", MAIN_JOB, folder / "main.ngc", count_lines, args.repeat, 250_000, "lines")
        if args.only in (None, "ik"):
            poses = folder / "poses.csv"
            write_poses(poses, args.poses)
            print(f"ik --batch: {args.poses:,} poses, {poses.stat().st_size / 1e6:.0f} MB")
            bench("ik --batch", ["ik", "--batch", str(poses)], folder / "ik.csv", lambda p: count_lines(p) - 1,
                  args.repeat, 500_000, "rows")
    if args.only in (None, "formatting"):
        formatting_ratios(args.rows, args.repeat)
    print(f"after: {load()}")


if __name__ == "__main__":
    main()
