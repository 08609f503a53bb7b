"""The collision check on fine meshes: the main job and `verify --against` (a script, not a test).

    python bench/bench_collision.py [--parts wedge:6,wall30:7] [--keep DIR] [--src DIR]

Each part is a fixture cut finer with trimesh's ``subdivide()`` (every triangle into four, ``N``
times: the wedge 6 times is 49,152 triangles, wall30 7 times 327,680), written as a binary STL. On
each, in fresh processes: the main job (the wedge: the golden wedge-round.ngc's round; wall30: a
hole 8.1 mm from the face's origin, whose holder comes 8.6 mm from the wall, so that minima are
measured, not only bounded) and ``verify PROGRAM --against PART.stl --json``. Prints each run's
wall time, CPU time and peak resident memory (VmHWM) with the load average, and the collision
entry of the header, and the clearances verify reports. ``--src``: another checkout's ``src`` (to
measure the code before a change the same way).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import trimesh
from _measure import REPO, load, run_cli

PARTS = REPO / "fixtures" / "parts"
#: The main job's options per part.
JOBS = {
    "wedge": ["--profile", "round", "--diameter", "25", "--depth", "2", "--step-down", "1", "--tolerance", "0.01"],
    "wall30": ["--profile", "hole", "--at", "8.1,0"],
}


def make_part(name: str, times: int, folder: Path) -> tuple[Path, int]:
    """``fixtures/parts/NAME.stl`` subdivided ``times`` times, written to ``folder``; its path and triangles."""
    mesh = trimesh.load(PARTS / f"{name}.stl")
    for _ in range(times):
        mesh = mesh.subdivide()
    path = folder / f"{name}-{len(mesh.faces)}.stl"
    mesh.export(path)
    return path, len(mesh.faces)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="wedge:6,wall30:7", help="NAME:TIMES,... (fixtures/parts/NAME.stl)")
    parser.add_argument("--keep", type=Path, help="write the parts and programs here and keep them")
    parser.add_argument("--src", type=Path, help="run this checkout's src instead of this worktree's")
    args = parser.parse_args()
    env = {"PYTHONPATH": str(args.src.resolve())} if args.src else None
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"code: {args.src or REPO / 'src'}; {load()}")
        for item in args.parts.split(","):
            name, times = item.split(":")
            part, triangles = make_part(name, int(times), folder)
            program = folder / f"{part.stem}.ngc"
            print(f"{part.name}: {triangles:,} triangles")
            job = run_cli(["run", str(part), *JOBS[name], "-o", str(program)], env=env)
            entry = next((ln for ln in program.read_text().splitlines() if ln.startswith("(collision:")), "") \
                if program.exists() else ""
            print(f"  main job: {job.wall:.1f} s wall, {job.cpu:.1f} s CPU, peak RSS {job.peak_mb:.0f} MB, "
                  f"exit {job.code} ({load()})")
            print(f"    {entry}")
            if not program.exists():
                continue
            verify = run_cli(["verify", str(program), "--against", str(part), "--json"], env=env)
            (folder / f"{part.stem}.json").write_text(verify.stdout)
            print(f"  verify --against: {verify.wall:.1f} s wall, {verify.cpu:.1f} s CPU, peak RSS "
                  f"{verify.peak_mb:.0f} MB, exit {verify.code} ({load()})")
            print(f"    {clearance_words(verify.stdout)}")


def clearance_words(stdout: str) -> str:
    """Each body's clearance in ``verify --json``'s report: ``tool over 11.000 mm (line 33), ...``."""
    try:
        bodies = json.loads(stdout)["clearance"]["bodies"]
    except (json.JSONDecodeError, KeyError, TypeError):
        return f"no clearance in the report: {stdout[-200:]!r}"
    return ", ".join(f"{b['body']} {'' if b['exact'] else 'over '}{b['distance_mm']:.3f} mm (line {b['line']})"
                     for b in bodies)


if __name__ == "__main__":
    main()
