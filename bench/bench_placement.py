"""Time of automatic placement on the demo jobs (a script, not a test).

    python bench/bench_placement.py [--repeat 5]

For each demo job (the bundled wedge: hole, square, round; and the example job file, two operations
with the transition between them) the script times the whole job in this process
(:func:`prs3_post.app.job.run_operations`: STL, faces, plan, post-process, emit) three ways: with the setup
given (the one automatic placement chooses: the reference), with the part origin chosen
(``--part-origin auto``) and with the origin and the rotation chosen (``--part-rotation auto`` too).
It prints the median and the range (min..max) over ``--repeat`` runs, wall and CPU time, the CPU
ratio to the reference, and the machine's load average: on a loaded machine the ratio means more
than the seconds. Target: under 2 s (wall) for every demo job with both chosen, on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def timed(action: Callable[[], object], repeat: int) -> tuple[list[float], list[float]]:
    """Wall and CPU seconds of ``repeat`` calls."""
    walls, cpus = [], []
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        action()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return walls, cpus


def shown(values: list[float]) -> str:
    return f"{statistics.median(values):7.3f} s ({min(values):.3f}..{max(values):.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    from prs3_post.app.job import run_operations
    from prs3_post.cli.run import _job_specs, run
    from prs3_post.cli.run import job_spec as _job_spec
    from prs3_post.readers.jobfile import read_job_file

    wedge = str(REPO / "postproc" / "parts" / "patel2020-wedge.stl")
    jobs = []
    for profile in ("hole", "square", "round"):
        ctx = run.make_context("run", [wedge, "--profile", profile])
        opts = dict(ctx.params)
        jobs.append((f"wedge {profile}", (_job_spec(opts.pop("part"), opts),)))
    jobs.append(("example job (2 operations)", _job_specs(read_job_file(str(REPO / "fixtures" / "jobs" /
                                                                             "example.toml")))))
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}; {args.repeat} runs each, "
          "median (min..max)")
    for name, specs in jobs:
        for label, origin, rotation in (("origin auto", True, False), ("origin + rotation auto", True, True)):
            auto = tuple(replace(s, auto_origin=origin, auto_rotation=rotation) for s in specs)
            chosen = run_operations(auto)
            given = tuple(replace(s, setup=chosen.setup) for s in specs)
            ref_wall, ref_cpu = timed(lambda g=given: run_operations(g), args.repeat)
            wall, cpu = timed(lambda a=auto: run_operations(a), args.repeat)
            ratio = statistics.median(cpu) / statistics.median(ref_cpu)
            assert chosen.placement is not None
            print(f"{name}, {label}: {len(chosen.post.path)} rows, {chosen.placement.evaluations} rotations "
                  f"evaluated, {chosen.setup.describe()}\n"
                  f"  setup given: wall {shown(ref_wall)}, cpu {shown(ref_cpu)}\n"
                  f"  auto:        wall {shown(wall)}, cpu {shown(cpu)}, {ratio:.1f}x the given setup's cpu")
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
