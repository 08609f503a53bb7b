"""Write the calibration fixtures: a simulated machine as built and its measurements.

``fixtures/calibration/as-built.toml`` is the shipped patel2020 machine with every parameter of the
head off by a random amount within its expected error (rail points ±0.5 mm, rail directions and
revolute axes ±0.1°, link lengths ±0.2 mm, platform joints ±0.3 mm, encoder zeros ±0.5 mm, the tool
±0.3 mm and ±0.1°): the machine a calibration should find. ``measured.csv`` holds its tips and axes at
the 60 poses ``prs3-post calibrate plan --machine patel2020 --poses 60 --noise-mm 0.005`` chooses,
each coordinate with 5 µm of noise (an axis as two points 100 mm apart); ``validate.csv`` the same
at 30 other poses inside every limit. Run from the repository: ``python scripts/make_calibration_fixtures.py``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from prs3_post.app.calibrate import limit_report, plan_calibration
from prs3_post.kinematics.calibration.parameters import Observations, error_model
from prs3_post.kinematics.calibration.residuals import predict
from prs3_post.machine.loading import load_machine
from prs3_post.machine.writing import machine_toml

OUT = Path(__file__).resolve().parents[1] / "fixtures" / "calibration"
NOISE = 0.005


def measurements(model, true, strokes, stage, seed: int) -> str:
    """The simulated machine's tips and axes at ``strokes``, with NOISE, as a measurement CSV."""
    rng = np.random.default_rng(seed)
    n = len(strokes)
    length = np.full(n, model.nominal.tool_length)
    truth = predict(model, true, Observations(strokes=strokes, stage=stage, tool_length=length, tip=np.zeros((n, 3)),
                                              axis=np.zeros((n, 3)), has_axis=True))
    tip = truth.tip + rng.normal(0.0, NOISE, (n, 3))
    axis = truth.axis + rng.normal(0.0, NOISE / 100.0, (n, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    lines = ["t1,t2,t3,x,y,px,py,pz,ax,ay,az"]
    lines += [",".join([*(f"{v:.4f}" for v in (*strokes[i], *stage[i])), *(f"{v:.4f}" for v in tip[i]),
                        *(f"{v:.7f}" for v in axis[i])]) for i in range(n)]
    return "\n".join(lines) + "\n"


def main() -> None:
    machine = load_machine("patel2020")
    model = error_model(machine.geometry)
    true = np.random.default_rng(2022).uniform(-1.0, 1.0, len(model.parameters))
    OUT.mkdir(parents=True, exist_ok=True)
    built = replace(machine, geometry=model.head(true), kinematics="3-prs-general",
                    description="Patel 2020 head as built (simulated: each part off within its expected error)")
    (OUT / "as-built.toml").write_text(machine_toml(built, comment=[
        "A simulated machine as built: patel2020 with every parameter of the head off by a random amount",
        "within its expected error (scripts/make_calibration_fixtures.py). measured.csv and validate.csv",
        "are its tips and axes with 5 um of noise; `prs3-post calibrate` should find this machine."]), encoding="utf-8")
    plan = plan_calibration(machine, 60, noise=NOISE)
    (OUT / "measured.csv").write_text(measurements(model, true, plan.strokes, plan.stage, 1), encoding="utf-8")
    rng = np.random.default_rng(3)
    strokes = rng.uniform(*machine.limits.stroke, (300, 3))
    report, placed = limit_report(machine, strokes, np.zeros((300, 2)))
    other = strokes[report.ok & placed][:30]
    (OUT / "validate.csv").write_text(measurements(model, true, other, np.zeros((30, 2)), 2), encoding="utf-8")


if __name__ == "__main__":
    main()
