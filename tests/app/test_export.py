"""`prs3-post export`: a program's tool path back in the part frame (CL and CSV), and back again.

Round trip: a golden program exported to CL and converted back (`convert`'s reader and IK) with
the setup its header records (the same machine, dialect, part origin and rotation, tool length,
tolerance) gives the same joint words on every motion line, to the output resolution (0.0001 mm;
in fact the same digits: the CL file carries 6 decimals of the tip and 9 of the axis). What differs,
and why:

* the header: the converted program's says it was converted from the CL file (``source``,
  ``tool length``, ``counts``) where the original's names the part and its operations;
* the comments (operation titles, ``hole 1/2 at ...``) and dwells (``G4``): CL has no dwell word our
  reader takes, so a dwell becomes a ``$$`` comment; comments are not motion lines;
* the G1 F words may differ in their last digit: export writes the feed in mm/min (chord × F, 4
  decimals) and convert divides it by the chord of the rounded tips again;
* a job whose tools have different lengths: convert has one tool length for every tool (CL's
  ``LOADTL`` does not give a length), so it round-trips when exported with that one length.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from prs3_post.app.convert import ConvertSettings, convert_file
from prs3_post.app.export import export_program
from prs3_post.cli.main import main
from prs3_post.core.toolpath import MoveKind
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_machine
from prs3_post.readers.program import read_program

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "golden"
AS_BUILT = REPO / "fixtures" / "machines" / "patel2020-as-built.toml"
#: The joint words' resolution, mm.
RESOLUTION = 1e-4


def _export(program: Path, out: Path, *args: str) -> None:
    result = CliRunner().invoke(main, ["export", str(program), "-o", str(out), *args])
    assert result.exit_code == 0, result.output


def _round_trip(program: Path, cl: Path, *, tool_length: float | None = None,
                machine: str | None = None) -> tuple[float, int]:
    """Convert ``cl`` back with ``program``'s setup; the largest joint-word difference and the motion lines."""
    exported = export_program(str(program), tool_length=tool_length, machine=machine)
    header = exported.header
    settings = ConvertSettings(machine=exported.machine, dialect=exported.dialect, setup=exported.setup,
                               tolerance=header.tolerance, tool_length=exported.machine.geometry.tool_length)
    back = read_program(convert_file(str(cl), settings).text, exported.dialect, path="back",
                        stage=exported.machine.stage.present, kinematics=kinematics_of(exported.machine))
    a, b = exported.program.moves, back.moves
    assert len(a) == len(b)
    assert a.kind.tolist() == b.kind.tolist()
    return float(max(np.abs(a.stage - b.stage).max(), np.abs(a.strokes - b.strokes).max())), len(a)


@pytest.mark.parametrize("name", ["wedge-square-outside.ngc", "tilt35-round.ngc", "twofaces-face6-round-fanuc.nc",
                                  "convert-mech491_APT_Variable_Axis.ngc"])
def test_a_golden_program_exported_to_cl_converts_back_to_its_joint_words(tmp_path: Path, name: str) -> None:
    cl = tmp_path / "out.cls"
    _export(GOLDEN / name, cl)
    worst, lines = _round_trip(GOLDEN / name, cl)
    assert worst <= RESOLUTION
    assert worst == 0.0                                # measured: the same digits on every line
    assert lines == {"wedge-square-outside.ngc": 121, "tilt35-round.ngc": 247, "twofaces-face6-round-fanuc.nc": 194,
                     "convert-mech491_APT_Variable_Axis.ngc": 1338}[name]


def test_a_job_of_two_tool_lengths_round_trips_with_one_tool_length(tmp_path: Path) -> None:
    program = GOLDEN / "twofaces-job-example.ngc"
    cl = tmp_path / "job.cls"
    _export(program, cl, "--tool-length", "175")
    assert _round_trip(program, cl, tool_length=175.0) == (0.0, 620)
    # with each tool's own length (172.3 and 191.25 mm) the tips differ by the length along the axis
    own = export_program(str(program))
    same = export_program(str(program), tool_length=175.0)
    first_t2 = 23                                      # rows from the M6 T2 on
    assert np.linalg.norm(own.tip[0] - same.tip[0]) == pytest.approx(175.0 - 172.3, abs=1e-9)
    assert np.linalg.norm(own.tip[first_t2] - same.tip[first_t2]) == pytest.approx(191.25 - 175.0, abs=1e-9)
    text = cl.read_text()
    assert text.count("LOADTL/") == 2 and "LOADTL/2\n" in text


def test_a_program_for_a_machine_as_built_round_trips_through_its_own_kinematics(tmp_path: Path) -> None:
    program = tmp_path / "as-built.ngc"
    result = CliRunner().invoke(main, ["demo", "--profile", "square", "--machine", str(AS_BUILT), "-o", str(program)])
    assert result.exit_code == 0, result.output
    cl = tmp_path / "as-built.cls"
    _export(program, cl)
    worst, lines = _round_trip(program, cl)
    assert worst <= RESOLUTION and lines == 20
    # the ideal machine's FK puts the same joint words elsewhere
    ideal = export_program(str(program), machine="patel2020")
    built = export_program(str(program))
    assert float(np.abs(ideal.tip - built.tip).max()) > 0.05


def test_the_cl_file_has_the_records_cam_viewers_read(tmp_path: Path) -> None:
    cl = tmp_path / "sq.cls"
    _export(GOLDEN / "wedge-square-outside.ngc", cl)
    records = [line for line in cl.read_text().splitlines() if not line.startswith("$$")]
    assert records[:7] == ["UNITS/MM", "MULTAX", "LOADTL/1", "SPINDL/RPM,3000.0,CLW", "COOLNT/FLOOD", "RAPID",
                           "GOTO/20.571808,199.999977,300.894474,0.447213666,-0.000000002,0.894427156"]
    assert records[-3:] == ["COOLNT/OFF", "SPINDL/OFF", "FINI"]
    assert sum(r.startswith("GOTO/") for r in records) == 121
    assert "FEDRAT/MMPM,99.9982" in records


def test_the_csv_has_one_row_per_motion_line_with_the_fk_of_its_joint_words(tmp_path: Path) -> None:
    program = GOLDEN / "wedge-square-outside.ngc"
    result = CliRunner().invoke(main, ["export", str(program), "--format", "csv", "-o", "-"])
    assert result.exit_code == 0, result.output
    rows = result.stdout.splitlines()
    assert rows[0] == "line,x,y,z,i,j,k,feed_mm_min,time_s"
    assert len(rows) == 1 + 121
    first = rows[1].split(",")
    # line 23: G0 X-1.1658 Y-9.1429 U25.8434 V160.0075 W78.5709 → fk, then the setup's inverse
    fk = CliRunner().invoke(main, ["fk", "--strokes", "25.8434,160.0075,78.5709", "--xy", "-1.1658,-9.1429", "--json"])
    import json

    pose = json.loads(fk.stdout)
    origin = np.array([-100.0, -200.0, -970.0])              # the header's setup, rotation 0
    tip = np.array([pose["tip_x"], pose["tip_y"], pose["tip_z"]]) - origin
    assert first[0] == "23"
    assert [float(v) for v in first[1:4]] == pytest.approx(tip.tolist(), abs=5e-7)
    assert [float(v) for v in first[4:7]] == pytest.approx([pose["axis_x"], pose["axis_y"], pose["axis_z"]], abs=5e-10)
    assert first[1:4] == ["20.571808", "199.999977", "300.894474"]
    assert first[7:] == ["", "0.0000"]                        # a G0: no feed; the program's start
    third = rows[3].split(",")
    assert third[0] == "26" and third[7] == "99.9982"         # G1 of the 100 mm/min plunge (F rounded)
    exported = export_program(str(program))
    feed = exported.program.moves.kind == MoveKind.FEED
    chord = np.linalg.norm(np.diff(exported.tip, axis=0), axis=1)
    assert np.allclose(exported.feed[1:][feed[1:]], (chord * exported.program.moves.inverse_time[1:])[feed[1:]])
    assert math.isclose(float(rows[-1].split(",")[8]), exported.duration.sum(), abs_tol=5e-5)


def test_a_program_without_a_header_is_refused_with_its_line(tmp_path: Path) -> None:
    program = tmp_path / "bare.ngc"
    program.write_text("G0 X1 Y2 U30 V30 W30\nM2\n")
    out = tmp_path / "bare.cls"
    result = CliRunner().invoke(main, ["export", str(program), "-o", str(out)])
    assert result.exit_code == 2
    assert result.stderr == (f"prs3-post: error: {program}:1: no prs3-post header (the '(program: prs3-post ...)' "
                             "comments at its top): export needs the machine, setup and tool length the program was "
                             "made for; export a program made by prs3-post (run, job or convert)\n")
    assert not out.exists()


def test_an_unreadable_line_is_refused_with_its_line_and_nothing_is_written(tmp_path: Path) -> None:
    lines = (GOLDEN / "wedge-square-outside.ngc").read_text().splitlines(keepends=True)
    lines[25] = "G1 X1 Q7\n"                          # line 26
    program = tmp_path / "bad.ngc"
    program.write_text("".join(lines))
    out = tmp_path / "bad.csv"
    result = CliRunner().invoke(main, ["export", str(program), "-o", str(out)])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"prs3-post: error: {program}:26: ")
    assert not out.exists() and not list(tmp_path.glob(".*tmp"))


def test_the_output_may_not_be_the_program(tmp_path: Path) -> None:
    program = tmp_path / "p.ngc"
    program.write_bytes((GOLDEN / "wedge-square-outside.ngc").read_bytes())
    result = CliRunner().invoke(main, ["export", str(program), "-o", str(program)])
    assert result.exit_code == 2
    assert "is also the input PROGRAM.ngc" in result.stderr
    assert program.read_bytes() == (GOLDEN / "wedge-square-outside.ngc").read_bytes()


def test_the_setup_given_replaces_the_headers(tmp_path: Path) -> None:
    program = str(GOLDEN / "wedge-square-outside.ngc")
    recorded = export_program(program)
    moved = export_program(program, origin=(-90.0, -200.0, -970.0), rotation_deg=90.0)
    # p_part = Rz(-90°)(p_machine - origin): the x the header's setup gives, less 10, becomes -y
    assert moved.tip[0, 1] == pytest.approx(-(recorded.tip[0, 0] - 10.0), abs=1e-9)
    assert moved.tip[0, 0] == pytest.approx(recorded.tip[0, 1], abs=1e-9)
    assert load_machine("patel2020").geometry.tool_length == recorded.machine.geometry.tool_length
