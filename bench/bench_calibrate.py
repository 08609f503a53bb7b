"""Calibration: whole-process wall and CPU time of ``calibrate`` on 80 measured poses (a script, not a test).

    python bench/bench_calibrate.py [--repeat 5] [--poses 80]

Makes ``--poses`` measurements of the simulated machine of ``fixtures/calibration`` (the poses
``calibrate plan`` chooses, 5 µm of noise: ``scripts/make_calibration_fixtures.py``), then runs,
each ``--repeat`` times in a fresh process (``_measure.run_cli``), ``calibrate`` on them with the
5-fold hold-out, and ``calibrate plan`` for as many poses; prints each one's median and range of
wall and CPU time and its peak memory, with the load average before and after. Target (issue 22):
calibrating 80 poses in under 10 s on the 2-core machine.
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
from pathlib import Path

import numpy as np
from _measure import REPO, load, run_cli, spread

from prs3_post.app.calibrate import plan_calibration
from prs3_post.kinematics.calibration.parameters import error_model
from prs3_post.machine.loading import load_machine


def _fixtures_script():
    """scripts/make_calibration_fixtures.py (its simulation: ``NOISE``, ``measurements``)."""
    spec = importlib.util.spec_from_file_location("make_calibration_fixtures",
                                                  REPO / "scripts" / "make_calibration_fixtures.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--poses", type=int, default=80)
    args = parser.parse_args()
    fixtures = _fixtures_script()
    noise = fixtures.NOISE
    machine = load_machine("patel2020")
    model = error_model(machine.geometry)
    true = np.random.default_rng(2022).uniform(-1.0, 1.0, len(model.parameters))
    plan = plan_calibration(machine, args.poses, noise=noise)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        measured = folder / "measured.csv"
        measured.write_text(fixtures.measurements(model, true, plan.strokes, plan.stage, 1), encoding="utf-8")
        env = {"PYTHONDONTWRITEBYTECODE": "", "PYTHONPYCACHEPREFIX": str(folder / "pyc")}
        commands = {
            f"calibrate ({args.poses} poses)": ["calibrate", str(measured), "--noise-mm", str(noise), "-o",
                                               str(folder / "calibrated.toml")],
            f"calibrate plan ({args.poses} poses)": ["calibrate", "plan", "--poses", str(args.poses), "-o",
                                                    str(folder / "poses.csv")],
        }
        for command in commands.values():                   # the byte code cache, and a check that each works
            run = run_cli(command, env)
            assert run.code == 0, run.last
        print(f"before: {load()}")
        for name, command in commands.items():
            runs = [run_cli(command, env) for _ in range(args.repeat)]
            print(f"{name}: wall {spread([r.wall for r in runs], '.2f')} s; "
                  f"CPU {spread([r.cpu for r in runs], '.2f')} s; peak {spread([r.peak_mb for r in runs], '.0f')} MB")
        print(f"after: {load()}")


if __name__ == "__main__":
    main()
