"""A million-triangle part: `faces` and the main job against trimesh's own load and facets (a script, not a test).

    python bench/bench_big_mesh.py [--split 289] [--repeat 3] [--only faces|job|nocheck] [--keep DIR] [--src DIR]

The part is the demo wedge (``fixtures/parts/wedge.stl``, 12 triangles) with every triangle cut into
``split``² smaller ones on a regular grid (289: 1,002,252 triangles; each face stays one plane with
the same outline), written as a binary STL. Deterministic: the same bytes on every run.

The reference is ``trimesh.load(PART)`` followed by ``mesh.facets`` in a fresh process: what any
program built on trimesh pays to read the part and group its coplanar triangles. Each of our
commands runs in a fresh process too (``_measure.run_cli``), alternately with the reference, so that
every ratio compares two runs made in the same minutes (the machine's speed drifts on a shared
one); the script prints each pair, then the median and the range (min..max) of the CPU ratio, of
the wall ratio and of each command's peak resident memory (VmHWM):

* ``faces PART``: target within 3× the reference;
* the main job with the collision check (``run PART`` with the golden wedge-round.ngc's round):
  target within 10× the reference, peak memory under 1 GB;
* the same without the check (``--no-collision-check``), for the share the check takes.

``--src``: another checkout's ``src`` (to measure the code before a change the same way).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from _measure import REPO, ChildRun, load, run_cli, spread

WEDGE = REPO / "fixtures" / "parts" / "wedge.stl"
#: The main job's options: the golden wedge-round.ngc's round (``demo --profile round ...``).
ROUND = ["--profile", "round", "--diameter", "25", "--depth", "2", "--step-down", "1", "--tolerance", "0.01"]
COMMANDS = {
    "faces": lambda part, out: ["faces", str(part)],
    "job": lambda part, out: ["run", str(part), *ROUND, "-o", str(out)],
    "nocheck": lambda part, out: ["run", str(part), *ROUND, "--no-collision-check", "-o", str(out)],
}
TARGETS = {"faces": 3.0, "job": 10.0, "nocheck": 10.0}

#: The reference, in a child process: trimesh's load and facets, its CPU time and peak memory as run_cli's.
_REFERENCE = """import resource, sys, trimesh
mesh = trimesh.load(sys.argv[1])
print(len(mesh.faces), "triangles,", len(mesh.facets), "facets")
usage = resource.getrusage(resource.RUSAGE_SELF)
peak = int(next(ln.split()[1] for ln in open("/proc/self/status") if ln.startswith("VmHWM:")))
sys.stderr.write(f"\\nPEAK_KB {peak} CPU_S {usage.ru_utime + usage.ru_stime} FORKED_KB 0\\n")
"""


def split_triangles(triangles: np.ndarray, n: int) -> np.ndarray:
    """(T·n², 3, 3): each triangle (T, 3, 3) cut into n² on the grid of its barycentric coordinates i/n.

    A point is (i·a + j·b + k·c) / n with i + j + k = n; a point of an edge depends only on that
    edge's two corners and their weights, so the triangles on both sides of an edge get the very
    same points there, and the cut mesh stays closed."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    i, j = i[keep], j[keep]
    number = np.full((n + 1, n + 1), -1, dtype=np.int64)
    number[i, j] = np.arange(len(i))
    a_up, b_up = np.nonzero(np.add.outer(np.arange(n), np.arange(n)) < n)                 # (i, j), i + j < n
    up = np.column_stack([number[a_up, b_up], number[a_up + 1, b_up], number[a_up, b_up + 1]])
    a_dn, b_dn = np.nonzero(np.add.outer(np.arange(1, n), np.arange(n)) < n)               # (i, j), i ≥ 1
    a_dn = a_dn + 1
    down = np.column_stack([number[a_dn, b_dn], number[a_dn, b_dn + 1], number[a_dn - 1, b_dn + 1]])
    cells = np.vstack([up, down])                                                          # (n², 3) wound as abc
    weight = np.column_stack([i, j, n - i - j]).astype(np.float64)                         # (V, 3)
    points = np.einsum("vk,tkc->tvc", weight, triangles) / n                               # (T, V, 3)
    return points[:, cells].reshape(-1, 3, 3)


def write_part(folder: Path, split: int) -> tuple[Path, int]:
    """The wedge cut ``split``² times per triangle, as a binary STL in ``folder``; its path and triangles."""
    triangles = split_triangles(np.asarray(trimesh.load(WEDGE).triangles), split)
    record = np.zeros(len(triangles), dtype=[("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)),
                                             ("attributes", "<u2")])
    record["vertices"] = triangles
    path = folder / f"wedge-{len(triangles)}.stl"
    with open(path, "wb") as stream:
        stream.write(b"binary STL: the demo wedge, cut finer".ljust(80, b" "))
        stream.write(np.uint32(len(triangles)).tobytes())
        stream.write(record.tobytes())
    return path, len(triangles)


def reference(part: Path) -> ChildRun:
    """``trimesh.load`` + ``mesh.facets`` of ``part`` in a fresh process, measured as :func:`run_cli` does."""
    import os
    import subprocess
    import sys
    import time

    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _REFERENCE, str(part)], capture_output=True, text=True, check=False,
                          env=dict(os.environ))
    wall = time.perf_counter() - start
    words = next(ln.split() for ln in done.stderr.splitlines() if ln.startswith("PEAK_KB "))
    return ChildRun(wall=wall, cpu=float(words[3]), peak_mb=float(words[1]) / 1024, code=done.returncode,
                    last=done.stdout.strip()[-160:], stdout=done.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", type=int, default=289, help="each wedge triangle into SPLIT² (289: 1,002,252)")
    parser.add_argument("--repeat", type=int, default=3, help="pairs of runs per command")
    parser.add_argument("--only", choices=sorted(COMMANDS), action="append", help="this command only (repeatable)")
    parser.add_argument("--keep", type=Path, help="write the part and the programs here and keep them")
    parser.add_argument("--src", type=Path, help="run this checkout's src instead of this worktree's")
    args = parser.parse_args()
    env = {"PYTHONPATH": str(args.src.resolve())} if args.src else None
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        part, count = write_part(folder, args.split)
        print(f"{part.name}: {count:,} triangles, {part.stat().st_size / 1e6:.0f} MB; code: {args.src or REPO / 'src'}")
        print(f"before: {load()}")
        for name in args.only or ["faces", "job", "nocheck"]:
            cpu, wall, ours, theirs = [], [], [], []
            for k in range(args.repeat):
                ref = reference(part)
                run = run_cli(COMMANDS[name](part, folder / f"{part.stem}-{name}.ngc"), env=env)
                cpu.append(run.cpu / ref.cpu)
                wall.append(run.wall / ref.wall)
                ours.append(run.peak_mb)
                theirs.append(ref.peak_mb)
                failure = "" if run.code == 0 else f" ({run.last})"
                print(f"  {name} {k + 1}: {run.cpu:.2f} s CPU, {run.wall:.2f} s wall, peak RSS {run.peak_mb:.0f} MB, "
                      f"exit {run.code}{failure}; reference {ref.cpu:.2f} s CPU, {ref.wall:.2f} s wall, "
                      f"peak RSS {ref.peak_mb:.0f} MB ({ref.last}); {load()}")
            print(f"{name}: CPU {spread(cpu, '.2f')}× the reference (target ≤ {TARGETS[name]:g}×), wall "
                  f"{spread(wall, '.2f')}×; peak RSS {spread(ours, '.0f')} MB (reference {spread(theirs, '.0f')} MB)")
        print(f"after: {load()}")


if __name__ == "__main__":
    main()
