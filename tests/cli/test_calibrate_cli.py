"""The calibrate, calibrate plan and accuracy commands on the simulated machine of fixtures/calibration
(scripts/make_calibration_fixtures.py): outputs, reports, exit codes, and nothing written on an error."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.cli.main import main
from prs3_post.machine.loading import load_machine

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "calibration"
MEASURED, VALIDATE = str(FIXTURES / "measured.csv"), str(FIXTURES / "validate.csv")


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def test_plan_writes_the_poses_and_reports_the_expected_uncertainty(tmp_path):
    out, report = tmp_path / "poses.csv", tmp_path / "plan.json"
    result = run("calibrate", "plan", "--poses", "40", "--noise-mm", "0.005", "--no-axes", "-o", str(out),
                 "--report", str(report))
    assert result.exit_code == 0, result.output
    assert result.output.splitlines()[0] == ("40 poses chosen from 3000 inside every limit of patel2020 (D-optimal; "
                                             f"log det {json.loads(report.read_text())['log_det']:.1f}), measuring "
                                             "the tip.")
    lines = out.read_text().splitlines()
    assert lines[0] == "t1,t2,t3,x,y,px,py,pz" and len(lines) == 41
    record = json.loads(report.read_text())
    assert record["poses"] == 40 and record["axes_measured"] is False and record["criterion"].startswith("D-optimal")
    assert {row["name"] for row in record["held"]} >= {"tool_axis.x", "tool_axis.y", "leg1.rail_point.along_rail"}
    assert all(row["std"] < row["expected_error"] for row in record["expected_std"])


def test_plan_with_two_tools_writes_their_lengths(tmp_path):
    out = tmp_path / "poses.csv"
    result = run("calibrate", "plan", "--poses", "40", "--tool-lengths", "175,225", "-o", str(out))
    assert result.exit_code == 0, result.output
    lines = out.read_text().splitlines()
    assert lines[0] == "t1,t2,t3,x,y,px,py,pz,ax,ay,az,tool_length_mm"
    assert {line.rsplit(",", 1)[1] for line in lines[1:]} == {"175.0000", "225.0000"}


def test_calibrate_writes_the_machine_file_the_report_and_the_picture(tmp_path):
    out, report, picture = tmp_path / "calibrated.toml", tmp_path / "calibration.json", tmp_path / "residuals.png"
    result = run("calibrate", MEASURED, "--noise-mm", "0.005", "--validate", VALIDATE, "-o", str(out), "--report",
                 str(report), "--preview", str(picture))
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0] == f"Calibrated patel2020 from 60 measured poses of {MEASURED} (tips and axes):"
    assert lines[1] == "  before    tip RMS 1.1587 mm, worst 2.8786 mm (line 24); axis RMS 0.4117 deg"
    assert lines[2] == "  after     tip RMS 0.0075 mm, worst 0.0150 mm (line 10); axis RMS 0.0038 deg"
    record = json.loads(report.read_text())
    assert record["rows"] == 60 and record["noise_mm"]["assumed"] == 0.005
    assert record["noise_mm"]["estimated"] == pytest.approx(0.004246, abs=2e-6)
    assert record["before"]["tip_rms_mm"] == pytest.approx(1.158717, abs=2e-6)
    assert record["after"]["tip_rms_mm"] == pytest.approx(0.007452, abs=2e-6)
    assert record["holdout"]["after"]["tip_rms_mm"] < 0.015 and record["validation"]["after"]["tip_rms_mm"] < 0.015
    assert len(record["parameters"]) == 32 and len(record["held"]) == 9
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = out.read_text()
    assert text.startswith("# Machine patel2020 as calibrated by prs3-post calibrate (machine file: "
                           "machines/patel2020.toml).\n# Identified from ")
    machine = load_machine(str(out))
    assert machine.kinematics == "3-prs-general" and len(machine.calibration.parameters) == 32


def test_calibrate_to_standard_output_prints_the_summary_on_standard_error(tmp_path):
    result = CliRunner().invoke(main, ["calibrate", MEASURED, "--noise-mm", "0.005", "-o", "-"])
    assert result.exit_code == 0, result.stderr
    assert result.stdout.startswith("# Machine patel2020 as calibrated") and "[[legs]]" in result.stdout
    assert result.stderr.startswith("Calibrated patel2020 from 60 measured poses")


@pytest.mark.parametrize(("text", "message"), [
    ("t1,t2,t3,px,py,pz\n1,2,3,4,5\n", "{path}:2: expected 6 values (t1,t2,t3,px,py,pz), got 5"),
    ("t1,t2,t3,px,py,pz\n1,2,3,4,5,6\n", "{path}: 1 measured poses are fewer than the 30 parameters that tips can "
                                         "identify: measure at least 30 poses (prs3-post calibrate plan --poses N "
                                         "makes a plan)"),
])
def test_a_bad_file_exits_2_and_writes_nothing(tmp_path, text, message):
    path, out = tmp_path / "bad.csv", tmp_path / "calibrated.toml"
    path.write_text(text)
    result = run("calibrate", str(path), "-o", str(out))
    assert result.exit_code == 2
    assert result.output == f"prs3-post: error: {message.format(path=path)}\n"
    assert not out.exists()


def test_calibrate_help_names_both_uses():
    result = run("calibrate", "--help")
    assert result.exit_code == 0
    assert "prs3-post calibrate plan --machine M --poses N -o poses.csv" in result.output
    assert "prs3-post calibrate MEASUREMENTS.csv --machine M -o calibrated.toml" in result.output


def test_accuracy_of_the_nominal_and_the_calibrated_machine(tmp_path):
    nominal = run("accuracy")
    assert nominal.exit_code == 0, nominal.output
    lines = nominal.output.splitlines()
    assert lines[0] == ("Tool accuracy of patel2020 at machine -100.000, -200.000, -754.473 mm (1 sigma, first order): "
                        "parameters from each parameter's expected error (the machine is not calibrated); actuators "
                        "set to 0.0010 mm.")
    assert lines[2].split()[0] == "0.0" and float(lines[2].split()[1]) > 0.5          # about a millimetre
    out = tmp_path / "calibrated.toml"
    assert run("calibrate", MEASURED, "--noise-mm", "0.005", "-o", str(out)).exit_code == 0
    result = run("accuracy", "--machine", str(out), "--json", "--preview", str(tmp_path / "map.png"))
    assert result.exit_code == 0, result.output
    record = json.loads(result.output)
    assert record["source"] == "the machine file's calibration"
    tips = [v for row in record["tip_mm"] for v in row if v is not None]
    assert max(tips) < 0.01 and min(tips) > 0.0
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"


def test_fit_frame_finds_the_instruments_frame(tmp_path):
    """The measured tips and axes in a tracker's frame (turned 20° about z, tilted 1°, 2 m away):
    refused as they are, calibrated with --fit-frame to the same residuals."""
    lines = Path(MEASURED).read_text().splitlines()
    turn = np.radians(20.0)
    tilt = np.radians(1.0)
    rz = np.array([[np.cos(turn), -np.sin(turn), 0], [np.sin(turn), np.cos(turn), 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    rotation, shift = rx @ rz, np.array([2000.0, -500.0, 1200.0])
    rows = []
    for line in lines[1:]:
        v = np.array([float(c) for c in line.split(",")])
        tip, axis = rotation @ v[5:8] + shift, rotation @ v[8:11]
        rows.append(",".join([*line.split(",")[:5], *(f"{x:.4f}" for x in tip), *(f"{x:.7f}" for x in axis)]))
    path = tmp_path / "tracker.csv"
    path.write_text("\n".join([lines[0], *rows]) + "\n")
    refused = run("calibrate", str(path), "-o", str(tmp_path / "no.toml"))
    assert refused.exit_code == 2 and "--fit-frame identifies the measurement frame" in refused.output
    report = tmp_path / "frame.json"
    result = run("calibrate", str(path), "--fit-frame", "--noise-mm", "0.005", "-o", str(tmp_path / "c.toml"),
                 "--report", str(report))
    assert result.exit_code == 0, result.output
    record = json.loads(report.read_text())
    assert record["fit_frame"] is True and record["after"]["tip_rms_mm"] < 0.009
    assert_allclose(record["frame"]["rotation"], rotation, atol=5e-3)
    assert_allclose(record["frame"]["translation_mm"], shift, atol=10.0)
