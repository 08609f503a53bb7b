"""End-to-end throughput and peak memory of `prs3-post convert`, against pygcode's parse loop (a script, not a test).

    python bench/bench_convert.py [--lines 1000000] [--repeat 3] [--pygcode-lines 100000]
                                  [--only gcode|cl] [--keep DIR] [--no-bytecode]

Writes, in a temporary directory, a 3-axis program of ``--lines`` lines in a ``G68.2`` tilted work
plane (``G68.2 X10 Y20 Z0 I30 J25 K0`` then ``G53.1``: the plane 25° from the part's z; ``G1 X Y Z``
lines in it, an F every 100 moves, a comment every 50) and the equivalent APT CL file (the same
points as GOTOs in an ``MSYS/`` frame that is the tilted plane, FEDRAT and PPRINT where the program
has F and comments). Before timing, both are converted in this process at a small size and their
programs' motion lines compared: the two inputs describe the same path.

Then, ``--repeat`` times, alternately: ``prs3-post convert INPUT -o OUTDIR --jobs 1`` on each file
in a fresh process (whole process: start-up, reader, setup, exact IK, limits, emitter, atomic write)
with its modules' bytecode compiled, as an installed prs3-post has it (a cache in the temporary
directory, filled by one small conversion first: without it, where ``PYTHONDONTWRITEBYTECODE`` is
set, every run would also compile the package, about 0.3 CPU s; ``--no-bytecode`` measures that),
measuring wall time, the child's CPU time and its peak resident memory (VmHWM; with those of any
process it forks, added: see ``_measure``), and, in this
process, the reference: a loop that only parses the G-code's first ``--pygcode-lines`` lines with
``pygcode.Line`` (a sample: pygcode's rate is per line, and the whole file would take minutes).
Prints each run, then the median and range of input moves/s (wall and per CPU second), of the peak
memory and of the ratio to pygcode's loop (input lines per CPU second, both; and per second of wall
time, both), with the load average: on a loaded machine the per-CPU-second numbers are the fair
ones; on an idle one the wall-clock ratio is the throughput a user sees (the conversion of one
large file uses both cores: a reading thread and the main one).

Targets on the 2-core machine: ≥ 300,000 input moves/s end to end for one file (issue 8), ≥ 15
times the pygcode parse-only loop per CPU second in one process (issue 19, which retired the 30×
of issue 8 with the forked reading process that bought it), a 1-million-line input under 150 MB
and a 10-million-line input (``--lines 10000000 --repeat 1``) under 500 MB.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from _measure import count_lines, load, pygcode_rate, run_cli, spread

from prs3_post.part.workplane import euler_zxz_deg

#: The tilted plane: origin (part frame, mm) and Euler Z-X'-Z'' angles (degrees), as G68.2 X Y Z I J K.
PLANE_ORIGIN = (10.0, 20.0, 0.0)
PLANE_EULER_DEG = (30.0, 25.0, 0.0)
#: Puts the part (points within ±65 mm of the plane origin, tilt 25°) in the workspace of the
#: shipped machine (patel2020: tool tip near z = −680 mm, stage ±300 mm, tilt ≤ 45°).
PART_ORIGIN = "0,0,-690"
_BLOCK = 100_000


def _points(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) points in the tilted plane, mm, rounded to the 4 decimals both files are written with."""
    return np.round(np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-3, 0, n)]), 4)


def write_inputs(gcode: Path, cl: Path, lines: int, seed: int = 0) -> int:
    """Write the G-code program (about ``lines`` lines) and its CL twin; returns the G-code's motion
    records (the CL file has the same)."""
    rotation = euler_zxz_deg(*PLANE_EULER_DEG)
    axes = ",".join(f"{v:.17g}" for v in (*rotation[:, 0], *rotation[:, 1]))
    rng = np.random.default_rng(seed)
    feeds = (400, 500, 600)
    body = max(lines - 12, 1)
    moves = 0
    with open(gcode, "w", encoding="ascii") as g, open(cl, "w", encoding="ascii") as c:
        x, y, z = PLANE_ORIGIN
        i, j, k = PLANE_EULER_DEG
        g.write(f"%\nG21 G90 G94 G17\nT1 M6\nS8000 M3\nG68.2 X{x:g} Y{y:g} Z{z:g} I{i:g} J{j:g} K{k:g}\nG53.1\n"
                "G0 X0 Y0 Z5\nG1 Z0 F600\n")
        c.write(f"TOOL PATH/BENCH,TOOL,MILL\nLOADTL/1\nSPINDL/RPM,8000,CLW\nMSYS/{x:g},{y:g},{z:g},{axes}\n"
                "RAPID\nGOTO/0.0000,0.0000,5.0000,0.0000000,0.0000000,1.0000000\nFEDRAT/MMPM,600.0000\n"
                "GOTO/0.0000,0.0000,0.0000\n")
        moves += 2
        while body > 0:
            n = min(_BLOCK, body)
            points = _points(rng, n).tolist()
            feed = rng.choice(feeds, n).tolist()
            g_lines, c_lines = [], []
            for p, f in zip(points, feed, strict=True):
                moves += 1
                if moves % 100 == 0:
                    g_lines.append(f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f} F{f}")
                    c_lines.append(f"FEDRAT/MMPM,{f}.0000")
                else:
                    g_lines.append(f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f}")
                c_lines.append(f"GOTO/{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}")
                if moves % 50 == 0:
                    g_lines.append(f"(pass {moves // 50})")
                    c_lines.append(f"PPRINT/pass {moves // 50}")
            g.write("\n".join(g_lines) + "\n")
            c.write("\n".join(c_lines) + "\n")
            body -= len(g_lines)
        g.write("G0 Z5\nG69\nM5\nM30\n%\n")
        c.write(f"RAPID\nGOTO/{points[-1][0]:.4f},{points[-1][1]:.4f},5.0000\nSPINDL/OFF\nEND-OF-PATH\n")
        moves += 1
    return moves


def same_path(folder: Path) -> int:
    """Convert small twins in this process; the number of motion lines, after checking that the G-code
    and the CL programs have the same ones (SystemExit if not)."""
    from prs3_post.app.convert import ConvertSettings, convert_file
    from prs3_post.machine.loading import load_dialect, load_machine
    from prs3_post.part.setup_transform import Setup

    gcode, cl = folder / "small.ngc", folder / "small.cls"
    write_inputs(gcode, cl, 2_000)
    origin = tuple(float(v) for v in PART_ORIGIN.split(","))
    settings = ConvertSettings(machine=load_machine("patel2020"), dialect=load_dialect("linuxcnc"),
                               setup=Setup(origin))      # type: ignore[arg-type]  # three numbers
    programs = [[ln for ln in convert_file(str(p), settings).text.splitlines() if ln.startswith(("G0 ", "G1 "))]
                for p in (gcode, cl)]
    if programs[0] != programs[1] or not programs[0]:
        raise SystemExit("the G-code and the CL twin do not convert to the same motion lines")
    return len(programs[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--pygcode-lines", type=int, default=100_000)
    parser.add_argument("--only", choices=["gcode", "cl"], help="convert only this input")
    parser.add_argument("--keep", type=Path, help="write the inputs and programs here and keep them")
    parser.add_argument("--no-bytecode", action="store_true",
                        help="run the children as the environment says (compiling each time where it forbids bytecode)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"G-code and CL twins convert to the same {same_path(folder):,} motion lines (2,000-line check)")
        inputs = {"gcode": folder / "bench.ngc", "cl": folder / "bench.cls"}
        moves = write_inputs(inputs["gcode"], inputs["cl"], args.lines)
        lines = {name: count_lines(path) for name, path in inputs.items()}
        for name, path in inputs.items():
            print(f"{name}: {lines[name]:,} lines, {moves:,} moves, {path.stat().st_size / 1e6:.0f} MB")
        print(f"convert --part-origin={PART_ORIGIN} --jobs 1 (linuxcnc); before: {load()}")
        # the children's bytecode: cached in the folder, as an installed package has it (compiled once, here)
        child_env = None if args.no_bytecode else {"PYTHONDONTWRITEBYTECODE": "",
                                                   "PYTHONPYCACHEPREFIX": str(folder / "bytecode")}
        warm = run_cli(["convert", str(folder / "small.ngc"), "-d", str(folder / "out-warm"),
                        f"--part-origin={PART_ORIGIN}", "--jobs", "1", "--force"], env=child_env)
        if warm.code != 0:
            raise SystemExit(f"the warm-up conversion failed (exit {warm.code}): {warm.last}")
        print("children run with " + ("the environment's bytecode setting" if args.no_bytecode else
                                      f"compiled bytecode (cached in {folder / 'bytecode'})"))
        names = [args.only] if args.only else list(inputs)
        runs: dict[str, list] = {name: [] for name in names}
        reference: list[tuple[float, float]] = []
        sample = min(args.pygcode_lines, lines["gcode"])
        for _ in range(args.repeat):                     # alternately: each under the same load
            reference.append(pygcode_rate(inputs["gcode"], sample))
            for name in names:
                out, report = folder / f"out-{name}", folder / f"report-{name}.json"
                run = run_cli(["convert", str(inputs[name]), "-d", str(out), f"--part-origin={PART_ORIGIN}",
                               "--jobs", "1", "--force", "--report", str(report)], env=child_env)
                record = json.loads(report.read_text())["files"][0]["report"] if report.exists() else None
                converted = record["input_moves"] if record and run.code == 0 else 0
                if converted != moves:
                    raise SystemExit(f"{name}: convert exit {run.code}, {converted} of {moves} moves: {run.last}")
                runs[name].append(run)
                print(f"  {name}: {run.wall:.2f} s wall, {run.cpu:.2f} s CPU, {moves / run.wall:,.0f} moves/s, "
                      f"{moves / run.cpu:,.0f} per CPU s, peak {run.peak_mb:.0f} MB; pygcode "
                      f"{reference[-1][1]:,.0f} lines per CPU s; {load()}")
        print(f"pygcode.Line loop (parse only, first {sample:,} lines): lines/s wall "
              f"{spread([r[0] for r in reference], ',.0f')}; per CPU s {spread([r[1] for r in reference], ',.0f')}")
        for name in names:
            done = runs[name]
            ratio = [lines[name] / r.cpu / ref[1] for r, ref in zip(done, reference, strict=True)]
            ratio_wall = [lines[name] / r.wall / ref[0] for r, ref in zip(done, reference, strict=True)]
            print(f"convert {name}: input moves/s wall {spread([moves / r.wall for r in done], ',.0f')}; "
                  f"per CPU s {spread([moves / r.cpu for r in done], ',.0f')} (target ≥ 300,000)")
            print(f"convert {name}: peak {spread([r.peak_mb for r in done], '.0f')} MB (target < 500 at 10M lines); "
                  f"input lines per CPU s / pygcode's: {spread(ratio, '.1f')}× (target ≥ 15×), per s of wall "
                  f"time: {spread(ratio_wall, '.1f')}×")
        print(f"after: {load()}")


if __name__ == "__main__":
    main()
