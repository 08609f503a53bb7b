"""The ik, fk and machines commands: values, CSV batch round trip, exact error messages, exit codes."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.cli.main import main
from prs3_post.kinematics import inverse

POSES = Path(__file__).resolve().parents[2] / "fixtures" / "poses" / "cases_2a_2b.csv"
TIP_2A, AXIS_2A = "-81.0264,21.2132,-679.4865", "0.447214,0,0.894427"


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def test_ik_json_case_2a():
    result = run("ik", "--tip", TIP_2A, "--axis", AXIS_2A, "--json")
    assert result.exit_code == 0, result.output
    record = json.loads(result.output)
    assert_allclose([record[k] for k in ("X", "Y", "T1", "T2", "T3")],
                    [-2.7640, 12.0703, 36.2244, 170.3886, 88.9519], atol=1e-4)
    assert_allclose([record["theta1_deg"], record["theta3_deg"], record["cond"]], [60.5347, 64.2154, 2.0034], atol=1e-4)
    assert record["ok"] is True and record["violations"] == []


def test_ik_paper_model_json():
    record = json.loads(run("ik", "--tip", TIP_2A, "--axis", AXIS_2A, "--model", "paper", "--json").output)
    assert_allclose([record["T1"], record["T2"], record["T3"]], [41.0978, 172.9648, 84.7195], atol=5e-4)
    assert [record["X"], record["Y"]] == [0.0, 0.0]


def test_ik_text_report_and_limit_exit_code():
    result = run("ik", "--tip", TIP_2A, "--axis", "0.9,0,0.3")
    assert result.exit_code == 1
    assert result.output.splitlines()[-2:] == [
        "LIMIT T2 stroke: 422.0763 mm (margin -22.0763 mm)",
        "LIMIT tilt: 71.5651 deg (margin -26.5651 deg)",
    ]


def test_ik_batch_round_trip(tmp_path):
    out = tmp_path / "out.csv"
    result = run("ik", "--batch", str(POSES), "-o", str(out))
    assert result.exit_code == 1                        # the third pose breaks limits
    assert result.output == ("prs3-post: 1 of 3 poses unreachable or outside limits (lines 5); "
                             "see the ok column\n")
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert list(rows[0]) == ["tip_x", "tip_y", "tip_z", "axis_x", "axis_y", "axis_z", "X", "Y", "T1", "T2", "T3",
                             "theta1_deg", "theta2_deg", "theta3_deg", "cond", "ok"]
    assert [r["ok"] for r in rows] == ["true", "true", "false"]
    # 9 decimals (1 nm): the strokes read back reproduce the tips through FK to 1e-9 mm
    for row in rows[:2]:
        fk = json.loads(run("fk", "--strokes", f"{row['T1']},{row['T2']},{row['T3']}",
                            "--xy", f"{row['X']},{row['Y']}", "--json").output)
        assert_allclose([fk["tip_x"], fk["tip_y"], fk["tip_z"]],
                        [float(row["tip_x"]), float(row["tip_y"]), float(row["tip_z"])], atol=1e-9)
    assert_allclose(float(rows[1]["X"]), -8.3211, atol=1e-4)


@pytest.mark.parametrize(("content", "message"), [
    ("x,y,z\n1,2,3\n", "{p}:1: expected the header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z, got 'x,y,z'"),
    ("", "{p}:1: expected the header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z, got an empty file"),
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0\n",
     "{p}:2: expected 6 values (tip_x,tip_y,tip_z,axis_x,axis_y,axis_z), got 5"),
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0,1\n1,2,abc,0,0,1\n", "{p}:3: not a number: 'abc'"),
    # values beyond what --tip and --axis allow, NaN and infinity: the line, the column and the range
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0,1\n\n1e308,2,3,0,0,1\n",
     "{p}:4: tip_x = 1e+308 mm is out of range (allowed: within ±1e+06 mm)"),
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0,1\n1,2,-2000000,0,0,1\n",
     "{p}:3: tip_z = -2e+06 mm is out of range (allowed: within ±1e+06 mm)"),
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0,1\n1,2,3,0,nan,1\n",
     "{p}:3: axis_y = nan is out of range (allowed: within ±1e+06)"),
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0,1\n1,2,3,0,0,-inf\n",
     "{p}:3: axis_z = -inf is out of range (allowed: within ±1e+06)"),
    ("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n1,2,3,0,0,1\n\n1,2,3,0,0,0\n1,2,3,0,0,-1\n",
     "{p}: line 4: the axis has zero length; line 5: the axis points away from the spindle (axis z must be > 0)"),
])
def test_ik_batch_bad_input(tmp_path, content, message):
    path, out = tmp_path / "poses.csv", tmp_path / "out.csv"
    path.write_text(content)
    result = run("ik", "--batch", str(path), "-o", str(out))
    assert result.exit_code == 2
    assert result.output == f"prs3-post: error: {message.format(p=path)}\n"
    assert not out.exists() and list(tmp_path.iterdir()) == [path]


def test_ik_missing_batch_file(tmp_path):
    result = run("ik", "--batch", str(tmp_path / "none.csv"))
    assert (result.exit_code, result.output) == (2, f"prs3-post: error: {tmp_path / 'none.csv'}: file not found\n")


def test_ik_bad_option_values():
    result = run("ik", "--tip", "1,2", "--axis", AXIS_2A)
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == (
        "Error: Invalid value for '--tip': expected 3 plain decimal numbers X,Y,Z, got '1,2'"
    )
    result = run("ik", "--tip", TIP_2A, "--axis", "0,0,-1")
    assert (result.exit_code, result.output) == (
        2, "prs3-post: error: pose 0: the axis points away from the spindle (axis z must be > 0)\n")


def test_ik_head_machine_reports_the_missing_xy():
    result = run("ik", "--tip", TIP_2A, "--axis", AXIS_2A, "--model", "head", "--machine", "patel2020-head")
    assert result.exit_code == 1
    assert result.output == (
        "prs3-post: error: machine patel2020-head has no stage and its head alone misses this tip by 12.3827 mm "
        "(x -2.7640, y 12.0703): the tilt's parasitic shift must be matched by the part setup, "
        "or use a machine with an XY stage\n"
    )


def test_fk_text_and_json():
    result = run("fk", "--strokes", "36.2243753,170.3884539,88.9518701", "--xy", "-2.7640208,12.0703266")
    assert result.exit_code == 0
    assert result.output.splitlines()[:2] == [
        "tip   -81.0264 21.2132 -679.4865 mm",
        "axis  0.447214 0.000000 0.894427   tilt 26.5651 deg",
    ]
    record = json.loads(run("fk", "--strokes", "36.2243753,170.3884539,88.9518701", "--json").output)
    assert record["converged"] is True and record["iterations"] <= 6
    assert_allclose(record["tilt_deg"], np.degrees(np.arctan(0.5)), atol=1e-6)


def test_fk_checks_the_machines_limits():
    """fk --strokes -1000,-1000,-1000 printed a tip 395 mm above the base with exit 0: a setting the lead
    screws cannot take. It is checked as ik checks a pose: every violated limit with its margin, exit 1."""
    inside = run("fk", "--strokes", "36.2243753,170.3884539,88.9518701", "--xy", "-2.7640208,12.0703266")
    assert (inside.exit_code, inside.output.splitlines()[-1]) == (0, "ok: within every limit")
    outside = run("fk", "--strokes", "-1000,-1000,-1000")
    assert outside.exit_code == 1
    assert outside.output.splitlines()[-3:] == [f"LIMIT T{i} stroke: -1000.0000 mm (margin -900.0000 mm)"
                                                for i in (1, 2, 3)]
    record = json.loads(run("fk", "--strokes", "36.2243753,170.3884539,88.9518701", "--xy", "500,12", "--json").output)
    assert (record["ok"], record["violations"]) == (False, [{"limit": "stage X", "value": 500.0, "margin": -200.0,
                                                             "unit": "mm"}])


def test_fk_at_the_stroke_limits_is_within_them():
    """fk --strokes 400,400,400 (the maximum) reported "LIMIT T1 stroke: 400.0000 mm (margin 0.0000 mm)" and
    exit 1: its IK round trip gives 400.00000000000006 mm. A stroke visibly beyond the limit still fails."""
    at = run("fk", "--strokes", "400,400,400")
    assert (at.exit_code, at.output.splitlines()[-1]) == (0, "ok: within every limit")
    beyond = run("fk", "--strokes", "400.0001,400,400")
    assert beyond.exit_code == 1
    assert beyond.output.splitlines()[-1].startswith("LIMIT T1 stroke: 400.0001 mm (margin -0.0001 mm)")


def test_fk_does_not_assemble():
    result = run("fk", "--strokes", "0,0,2000")
    assert result.exit_code == 1
    assert result.output.startswith(
        "prs3-post: error: strokes 0, 0, 2000 mm do not assemble the head of patel2020 (no rigid platform pose")


def test_machines_list():
    result = run("machines")
    assert result.exit_code == 0
    assert [line.split()[0] for line in result.output.splitlines()] == ["patel2020", "patel2020-head"]


def test_pose_reader_fast_and_careful_paths_agree(tmp_path):
    from prs3_post.readers.poses import read_poses

    header = "tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n"
    clean, quoted = tmp_path / "clean.csv", tmp_path / "quoted.csv"
    clean.write_text(header + "1.5,2,-680,0,0,1\n\n-3,4e1,-690.25,0.1,0,1\n")
    quoted.write_text(header + '"1.5",2,-680,0,0,1\n\n-3,4e1,-690.25,0.1,0,"1"\n')   # csv quoting: careful path
    fast, careful = read_poses(str(clean)), read_poses(str(quoted))
    for a, b in ((fast.tip, careful.tip), (fast.axis, careful.axis)):
        assert_allclose(a, b, atol=0.0)
    assert fast.line.tolist() == careful.line.tolist() == [2, 4]
    commented = tmp_path / "commented.csv"
    commented.write_text(header + "#1,2,3,0,0,1\n")
    with pytest.raises(Exception) as caught:
        read_poses(str(commented))
    assert str(caught.value) == f"{commented}:2: not a number: '#1'"


@pytest.mark.parametrize("body", [
    "1.5,2,-680,0,0,1\n-3,4e1,-690.25,0.1,0,1\n",            # plain: numpy reads the bytes
    "1.5,2,-680,0,0,1\n-3,4e1,-690.25,0.1,0,1",               # no newline at the end
    "1.5, 2,-680,0,0,1\n  \n-3,4e1,-690.25,0.1,0,1\n",        # spaces, a line of spaces (blank)
    "1.5,2,-680,0,0,1\r\n-3,4e1,-690.25,0.1,0,1\r\n",        # CRLF
    "1.5,2,-680,0,0,1\n\t\n-3,4e1,-690.25,0.1,0,1\n",        # a tab line (blank)
])
def test_pose_reader_counts_lines_alike_whatever_path_reads_them(tmp_path, body):
    """The plain-bytes reader and the line readers give the same values and the same line numbers."""
    from prs3_post.readers.poses import read_poses

    path = tmp_path / "poses.csv"
    path.write_bytes(("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n" + body).encode("ascii"))
    table = read_poses(str(path))
    assert table.tip.tolist() == [[1.5, 2.0, -680.0], [-3.0, 40.0, -690.25]]
    assert table.axis.tolist() == [[0.0, 0.0, 1.0], [0.1, 0.0, 1.0]]
    blank = 1 if ("  \n" in body or "\t" in body) else 0
    assert table.line.tolist() == [2, 3 + blank]


def _pose_file(tmp_path: Path, rows: int, *, bad_line: int | None = None) -> Path:
    rng = np.random.default_rng(7)
    tilt, azimuth = np.radians(rng.uniform(0, 60, rows)), rng.uniform(0, 2 * np.pi, rows)   # some beyond limits
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    tip = np.column_stack([rng.uniform(-150, 150, (rows, 2)), rng.uniform(-750, -600, rows)])
    lines = ["tip_x,tip_y,tip_z,axis_x,axis_y,axis_z"]
    lines += [",".join(map(repr, r)) for r in np.hstack([tip, axis]).tolist()]
    lines.insert(5, "")                                              # a blank line: numbering goes on
    if bad_line is not None:
        lines[bad_line - 1] = "1,2,3,0,0"
    path = tmp_path / "poses.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_ik_batch_streams_in_chunks(tmp_path):
    """Chunks of 3 lines give the bytes of one chunk; every value is its 9-decimal text."""
    from prs3_post.app.ik_batch import IKBatch
    from prs3_post.machine.loading import load_machine
    from prs3_post.readers.poses import read_poses

    path, machine = _pose_file(tmp_path, 40), load_machine("patel2020")
    small, large = IKBatch(machine, str(path), chunk_lines=3), IKBatch(machine, str(path))
    text = b"".join(small.chunks())
    assert text == b"".join(large.chunks())
    assert small.summary() == large.summary() is not None and small.poses == 40
    table = read_poses(str(path))
    unit = table.axis / np.linalg.norm(table.axis, axis=1)[:, None]
    ik = inverse(machine.geometry, table.tip, unit)
    values = np.column_stack([table.tip, unit, ik.stage, ik.strokes, np.degrees(ik.link_angle), ik.condition])
    rows = text.decode().splitlines()[1:]
    expected = [",".join("nan" if np.isnan(v) else f"{v:.9f}".replace("-0.000000000", "0.000000000") for v in row)
                for row in values.tolist()]
    assert [r.rsplit(",", 1)[0] for r in rows] == expected
    assert small.outside_lines == [int(table.line[i]) for i in np.flatnonzero(
        [r.endswith("false") for r in rows])][:10]


def test_ik_batch_bad_line_in_a_later_chunk_writes_nothing(tmp_path):
    from prs3_post.app.ik_batch import IKBatch
    from prs3_post.core.errors import InputError
    from prs3_post.core.output_files import write_atomic
    from prs3_post.machine.loading import load_machine

    path = _pose_file(tmp_path, 40, bad_line=31)
    out = tmp_path / "out.csv"
    with pytest.raises(InputError) as caught:
        write_atomic(str(out), IKBatch(load_machine("patel2020"), str(path), chunk_lines=4).chunks())
    assert str(caught.value) == f"{path}:31: expected 6 values (tip_x,tip_y,tip_z,axis_x,axis_y,axis_z), got 5"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.csv"]


def test_ik_batch_reads_a_csv_saved_with_a_byte_order_mark(tmp_path):
    """Spreadsheets save UTF-8 CSV with a BOM before the header: it is not part of the header."""
    plain, marked = tmp_path / "plain.csv", tmp_path / "marked.csv"
    plain.write_text(POSES.read_text())
    marked.write_bytes(b"\xef\xbb\xbf" + POSES.read_bytes())
    expected = run("ik", "--batch", str(plain))
    assert expected.exit_code == 1 and run("ik", "--batch", str(marked)).output == expected.output


def test_ik_batch_formats_ahead_on_a_thread_and_keeps_the_bytes_and_the_errors(tmp_path):
    """A chunk's lines are formatted on a second thread while the next chunk is solved: the output is the
    same bytes whatever the chunk size, and a bad line in a later chunk still fails the whole batch."""
    from prs3_post.app.ik_batch import IKBatch
    from prs3_post.core.errors import InputError
    from prs3_post.machine.loading import load_machine

    rng = np.random.default_rng(3)
    rows = ["tip_x,tip_y,tip_z,axis_x,axis_y,axis_z"]
    for _ in range(50):
        tilt, azimuth = rng.uniform(0, 0.5), rng.uniform(0, 2 * np.pi)
        axis = (np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt))
        rows.append(",".join(repr(float(v)) for v in (*rng.uniform(-100, 100, 2), rng.uniform(-720, -640), *axis)))
    table = tmp_path / "poses.csv"
    table.write_text("\n".join(rows) + "\n")
    machine = load_machine("patel2020")
    outputs = {size: b"".join(IKBatch(machine, str(table), chunk_lines=size).chunks()) for size in (1, 7, 65536)}
    assert outputs[1] == outputs[7] == outputs[65536]
    assert outputs[1].count(b"\n") == 51
    rows[40] = "1,2,3,0,0,0"                                    # line 41: a zero axis, in the sixth chunk of 7
    table.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"poses\.csv.*41"):
        b"".join(IKBatch(machine, str(table), chunk_lines=7).chunks())
