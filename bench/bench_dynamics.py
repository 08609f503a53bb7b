"""What feed clamping, cycle time and the collision check add to the main job (a script, not a test).

    python bench/bench_dynamics.py [--repeat 5]

In one process, alternately, ``--repeat`` times: the demo round pocket (``--step-down 0.1``, about
96,000 rows) post-processed on the shipped machine and on the same machine without ``[dynamics]``
(no clamping, no timing): the ratio of the CPU times is what clamping and timing cost, whatever the
machine's load. Then the collision check (verify's replay and the clearance of tool, holder and
nose along it) of that pocket and of a 5,000-row program (the 30° face beside a wall,
fixtures/parts/wall30.stl), against their post-processing: poses per CPU second, and the ratio of
the check's CPU time to post_process's (same process, so the load cancels).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

import numpy as np
import trimesh

from prs3_post.app.job import JobSpec, plan
from prs3_post.check.collision import check_program
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_CLEARANCE_MIN
from prs3_post.core.toolpath import Toolpath
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.face import Face
from prs3_post.part.faces import find_faces, select_face
from prs3_post.part.setup_transform import Setup
from prs3_post.part.stl import load_part
from prs3_post.post.pipeline import post_process
from prs3_post.toolpaths import Coolant, Cutting, Direction, Entry, ProfileParams, RoundShape, Side
from prs3_post.toolpaths.work import ProfileJob

REPO = Path(__file__).resolve().parents[1]


def spec(part: str, depth: float, step: float) -> JobSpec:
    machine = load_machine("patel2020")
    work = ProfileJob(RoundShape(diameter=36.0), ProfileParams(
        side=Side.ON, depth=depth, step_down=step, direction=Direction.CLIMB, entry=Entry.RAMP,
        ramp_angle=np.radians(3.0), clearance=2.0, retract=10.0))
    return JobSpec(part=part, units="mm", face=None, work=work, at_uv=np.zeros((0, 2)), at_xyz=np.zeros((0, 3)),
                   cutting=Cutting(tool_diameter=6.0, feed=300.0, plunge_feed=100.0, spindle_rpm=3000.0,
                                   coolant=Coolant.FLOOD, tool_number=1),
                   machine=machine, dialect=load_dialect("linuxcnc"), setup=Setup.resolve(machine), tolerance=0.0001)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    job = spec(str(REPO / "postproc" / "parts" / "patel2020-wedge.stl"), 10.0, 0.1)
    mesh = load_part(job.part)
    face, _ = select_face(find_faces(mesh), None, min_width=6.0)
    path = plan(job, face)
    bare = dataclasses.replace(job.machine, dynamics=None)
    with_dyn, without = [], []
    for _ in range(args.repeat):
        for machine, out in ((job.machine, with_dyn), (bare, without)):
            start = time.process_time()
            post = post_process(machine, path, job.setup, tolerance=job.tolerance, length_decimals=4,
                                angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
            out.append(time.process_time() - start)
    print(f"post_process of {len(post.program)} rows: with [dynamics] {statistics.median(with_dyn):.3f} s CPU, "
          f"without {statistics.median(without):.3f} s (median of {args.repeat}); ratio "
          f"{statistics.median(w / o for w, o in zip(with_dyn, without, strict=True)):.3f}")
    collision(job, mesh, face, path, args.repeat)
    wall = spec(str(REPO / "fixtures" / "parts" / "wall30.stl"), 1.0, 0.2)
    mesh = load_part(wall.part)
    face, _ = select_face(find_faces(mesh), None, min_width=6.0)
    collision(wall, mesh, face, plan(dataclasses.replace(wall, at_uv=np.array([[-20.0, 0.0]])), face), args.repeat)


def collision(job: JobSpec, mesh: trimesh.Trimesh, face: Face, path: Toolpath, repeat: int) -> None:
    """The collision check of ``path``'s program, alternately with its post_process, ``repeat`` times."""
    posting, checking = [], []
    for _ in range(repeat):
        start = time.process_time()
        post = post_process(job.machine, path, job.setup, tolerance=job.tolerance, length_decimals=4,
                            angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
        posting.append(time.process_time() - start)
        start = time.process_time()
        text = check_program(job.machine, post.program, job.setup, np.asarray(mesh.triangles), face, 6.0,
                             clearance_min=DEFAULT_CLEARANCE_MIN)
        checking.append(time.process_time() - start)
    rows, check = len(post.program), statistics.median(checking)
    print(f"collision check of {rows} rows ({Path(job.part).name}): {check:.3f} s CPU, {rows / check:.0f} rows/s "
          f"(median of {repeat}); check / post_process {statistics.median(checking) / statistics.median(posting):.2f}"
          f"; {text}")


if __name__ == "__main__":
    main()
