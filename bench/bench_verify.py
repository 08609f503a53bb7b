"""Throughput and peak memory of `prs3-post verify` on a long program (a script, not a test).

    python bench/bench_verify.py [--lines 1000000] [--repeat 3] [--pygcode-lines 50000] [--keep DIR]

Generates a program of the emitter's shape in a temporary directory (the header and footer of the
golden wedge-round.ngc around ``--lines`` G1 lines: laps of a circle on the stage at the golden's
tool axis, stepping down by equal strokes, and every tenth lap a slow sweep of the tool axis), then
runs ``prs3-post verify`` on it in a fresh process ``--repeat`` times, measuring wall time (lines/s),
CPU time and the peak resident memory of that process (its VmHWM). In the same run, the reference:
a loop that only parses the same file's first ``--pygcode-lines`` lines with ``pygcode.Line``
(lines/s; it is far too slow for the whole file). Prints the median and the range over the
repeats, with the machine's load average: on a loaded machine the wall-clock rates fall with the
load, the rates per CPU second much less.

Targets (issue 7): ≥ 200,000 lines/s on a 1,000,000-line program, peak memory < 300 MB, and
≥ 10× (aim 20×) the pygcode loop.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
from _measure import REPO, pygcode_rate, run_cli, spread

from prs3_post.core.numbers import fixed_column
from prs3_post.kinematics import forward
from prs3_post.machine.loading import load_machine

GOLDEN = REPO / "fixtures" / "golden" / "wedge-round.ngc"


def _words(letter: str, values: np.ndarray) -> list[str]:
    """Fixed 4-decimal words of a column, no ``-0.0000`` (the emitter's formatter)."""
    return [letter + text for text in fixed_column(values, 4)]


def make_program(path: Path, lines: int) -> int:
    """Write a program with about ``lines`` lines; returns its line count."""
    golden = GOLDEN.read_text().split("\n")
    first_g1 = next(i for i, ln in enumerate(golden) if ln.startswith("G1 "))
    head = golden[:first_g1]
    tail = golden[next(i for i, ln in enumerate(golden) if ln == "M9") - 2:]
    pose = {}                                                         # where the G0s before G93 leave the head
    for line in golden[:first_g1]:
        if line.startswith("G0 "):
            pose.update((w[0], float(w[1:])) for w in line.split()[1:])
    start = np.array([pose[letter] for letter in "XYUVW"])
    n = max(lines - len(head) - len(tail), 10)
    per_lap = 200
    t = np.arange(1, n + 1)
    angle = 2 * np.pi * t / per_lap
    lap = t // per_lap
    joints = np.zeros((n, 5))
    joints[:, 0] = start[0] + 10.0 * (np.cos(angle) - 1.0)
    joints[:, 1] = start[1] + 10.0 * np.sin(angle)
    joints[:, 2:] = start[2:] + (0.002 * t / per_lap)[:, None]                         # step down: equal strokes
    sweep = (lap % 10) == 9                                                           # every tenth lap: tilt sweep
    joints[sweep, 2] += 0.5 * np.sin(angle[sweep] / 2) ** 2
    joints = np.round(joints, 4)
    machine = load_machine("patel2020")
    fk = forward(machine.geometry, joints[:, 2:], joints[:, :2])
    previous = np.vstack([start, joints[:-1]])
    fk_prev = forward(machine.geometry, previous[:, 2:], previous[:, :2])
    chord = np.linalg.norm(fk.tip - fk_prev.tip, axis=1)
    step = np.abs(joints - previous)                                   # each axis's move, mm
    minutes = np.maximum.reduce([chord / 300.0,                         # 300 mm/min at the tip, and each axis
                                 step[:, :2].max(axis=1) / 9000.0,      # at 90 % of its top speed (stage
                                 step[:, 2:].max(axis=1) / 4500.0,      # 10000, strokes 5000 mm/min), so the
                                 np.full(len(chord), 1e-9)])             # program verifies clean
    feed = np.round(1.0 / minutes, 4)
    columns = [_words(letter, joints[:, i]) for i, letter in enumerate("XYUVW")] + [_words("F", feed)]
    body = []
    last = [""] * 5
    for row in zip(*columns, strict=True):
        words = ["G1"] + [w for i, w in enumerate(row[:5]) if w != last[i]] + [row[5]]
        last = list(row[:5])
        body.append(" ".join(words))
    text = "\n".join(head + body + tail)
    path.write_text(text if text.endswith("\n") else text + "\n")
    return len(head) + len(body) + len(tail) - (1 if text.endswith("\n") else 0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--pygcode-lines", type=int, default=50_000)
    parser.add_argument("--keep", type=Path, help="write the program here and keep it")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        program = folder / "bench.ngc"
        count = make_program(program, args.lines)
        size = program.stat().st_size / 1e6
        print(f"program: {count} lines, {size:.1f} MB; load average {os.getloadavg()[0]:.2f}; "
              f"{os.cpu_count()} cores")
        walls, cpus, peaks, refs, ref_cpus = [], [], [], [], []
        for _ in range(args.repeat):
            run = run_cli(["verify", str(program)])
            walls.append(run.wall)
            cpus.append(run.cpu)
            peaks.append(run.peak_mb)
            ref, ref_cpu = pygcode_rate(program, min(args.pygcode_lines, count))
            refs.append(ref)
            ref_cpus.append(ref_cpu)
            print(f"  verify: {run.wall:.2f} s wall, {run.cpu:.2f} s CPU, peak RSS {run.peak_mb:.0f} MB, "
                  f"exit {run.code}: {run.last} "
                  f"(load average {os.getloadavg()[0]:.2f})")
        rates = [count / w for w in walls]
        cpu_rates = [count / c for c in cpus]
        print(f"verify lines/s (wall): {spread(rates, ',.0f')}  (target ≥ 200,000)")
        print(f"verify lines per CPU second: {spread(cpu_rates, ',.0f')}")
        print(f"verify peak RSS MB: {spread(peaks, '.0f')}  (target < 300)")
        print(f"pygcode.Line loop lines/s (wall): {spread(refs, ',.0f')}; per CPU second: {spread(ref_cpus, ',.0f')}")
        print(f"verify / pygcode (wall): {spread([r / p for r, p in zip(rates, refs, strict=True)], '.1f')}×; "
              f"(CPU): {spread([r / p for r, p in zip(cpu_rates, ref_cpus, strict=True)], '.1f')}×  "
              "(target ≥ 10×, aim 20×)")


if __name__ == "__main__":
    main()
