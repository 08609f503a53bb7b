"""prs3-post verify and the program reader: replay through FK, limits between points, deviations, bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.app.job import run_job
from prs3_post.check.verify import Intended, replay, verify_program
from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE, NOMINAL_RAPID_RATE
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.core.errors import InputError
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.kinematics import forward
from prs3_post.kinematics.replay import EPSILON_FRACTION, PROBE_INTERVALS
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.program import load_program, read_program

REPO = Path(__file__).resolve().parents[2]
VERIFY = REPO / "fixtures" / "verify"
WEDGE = REPO / "postproc" / "parts" / "patel2020-wedge.stl"
DIALECT_8 = VERIFY / "linuxcnc-8dec.toml"
MACHINE = load_machine("patel2020")


def run(*args: str):
    return CliRunner().invoke(main, [str(a) for a in args])


def square_program(tmp_path: Path, *extra: str) -> Path:
    """The demo square in the 8-decimal dialect (its rounding moves the tip by < 1e-8 mm)."""
    out = tmp_path / "square.ngc"
    result = run("demo", "--profile", "square", "--dialect", DIALECT_8, "-o", out, *extra)
    assert result.exit_code == 0, result.output
    return out


def verify_json(*args: str):
    result = run("verify", *args, "--json")
    return result.exit_code, json.loads(result.stdout)


# ----------------------------------------------------------------------------- reader


def test_reader_reads_back_what_the_emitter_wrote():
    """Every row, F word and event of a job's program comes back from its text (4 decimals)."""
    from prs3_post.cli.run import job_spec as _job_spec

    opts = dict(profile="hole", face_choice="auto", at_uv=(), at_xyz=(), units="mm", depth=5.0, peck=2.0,
                reapproach_gap=0.5, dwell=0.5, size=30.0, corner_radius=0.0, rotation=0.0, diameter=30.0,
                side="on", step_down=1.0, direction="climb", entry="ramp", ramp_angle=3.0, clearance=2.0,
                retract=10.0, tool_diameter=6.0, tool_number=3, feed=300.0, plunge_feed=100.0, spindle=2500.0,
                coolant="mist", machine_name="patel2020", part_origin=None, dialect_name="fanuc", tolerance=0.002)
    spec = _job_spec(str(WEDGE), opts)
    result = run_job(spec)
    read = read_program(result.text, spec.dialect, path="hole.nc")
    moves, made = read.moves, result.post.program
    assert moves.kind.tolist() == made.kind.tolist()
    assert_allclose(moves.strokes, np.round(made.strokes, 3), atol=1e-12)
    assert_allclose(moves.stage, np.round(made.stage, 3), atol=1e-12)
    assert_allclose(moves.inverse_time, np.round(made.inverse_time, 4), atol=1e-12)
    assert [(e.before, e.kind, e.value) for e in moves.events] == [
        (e.before, e.kind, e.value) for e in made.events if e.kind is not EventKind.COMMENT
    ]
    lines = result.text.split("\n")
    assert all(lines[n - 1].startswith("N") and "(" not in lines[n - 1] for n in moves.source.tolist())
    assert read.end_line == len(lines) - 2                 # M30, then the closing %


def test_a_counter_clockwise_spindle_and_an_optional_stop_are_m4_and_m1_and_read_back(tmp_path, rs274_check):
    """CAM input marks them (SPINDL/...,CCLW and OPSTOP here; M4 and M1 in 3+2 G-code): the program says
    M4 and M1 (not M3 and M0: the spindle would turn the wrong way), LinuxCNC runs it, and verify's
    reader gives the same events back."""
    from prs3_post.emit.gcode import emit_program
    from prs3_post.post.pipeline import post_process
    from prs3_post.readers.cl.reader import parse_cl

    cl = ("LOADTL/1\nSPINDL/RPM,1200,CCLW\nFEDRAT/100,MMPM\nRAPID\nGOTO/0,0,10\nGOTO/0,0,0\nOPSTOP\n"
          "GOTO/5,0,0\nSTOP\nSPINDL/OFF\nFINI\n")
    path = parse_cl(cl, path="t.cls", tolerance=0.002, circle_tolerance=CIRCLE_TOL).toolpath
    dialect, setup = load_dialect("linuxcnc"), Setup.resolve(MACHINE)
    made = post_process(MACHINE, path, setup, length_decimals=dialect.decimals.length,
                        tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE).program
    text = emit_program(made, dialect)
    assert text == (
        "(axes: X Y = stage X Y mm, U V W = actuator strokes T1 T2 T3 mm)\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\n"
        "G61\n"
        "(tool 1)\n"
        "T1 M6\n"
        "S1200 M4\n"
        "G0 X-100.0000 Y-200.0000 U355.5270 V355.5270 W355.5270\n"
        "G93\n"
        "G1 U365.5270 V365.5270 W365.5270 F10.0000\n"
        "M1\n"
        "G1 X-95.0000 Y-200.0000 U365.5270 V365.5270 W365.5270 F20.0000\n"
        "M0\n"
        "M5\n"
        "G94\n"
        "M2\n"
    )
    out = tmp_path / "ccw.ngc"
    out.write_text(text)
    code, report = rs274_check(out)
    assert code == 0, report
    read = load_program(str(out), dialect)
    events = [(e.before, e.kind, e.value) for e in read.moves.events]
    assert events == [(0, EventKind.TOOL_CHANGE, 1.0), (0, EventKind.SPINDLE_ON_CCW, 1200.0),
                      (2, EventKind.OPTIONAL_STOP, 0.0), (3, EventKind.STOP, 0.0), (3, EventKind.SPINDLE_OFF, 0.0)]
    assert events == [(e.before, e.kind, e.value) for e in made.events if e.kind is not EventKind.COMMENT]
    assert verify_program(MACHINE, read.moves, setup=setup,
                          tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                          length_decimals=4, feed_decimals=4).ok
    assert run("verify", out).exit_code == 0


def test_reader_keeps_modal_state_and_line_numbers():
    text = "%\nO1000 (T)\nN10 G0 X1 Y2 U3 V4 W5\n(c)\nN20 G93\nN30 G1 U3.5 F2.\nN40 V4.5 F.5\nN50 G0 X0\nN60 M30\n%\n"
    read = read_program(text, load_dialect("fanuc"), path="t.nc")
    m = read.moves
    assert m.kind.tolist() == [MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED, MoveKind.RAPID]
    assert m.source.tolist() == [3, 6, 7, 8]
    assert_allclose(np.column_stack([m.stage, m.strokes]),
                    [[1, 2, 3, 4, 5], [1, 2, 3.5, 4, 5], [1, 2, 3.5, 4.5, 5], [0, 2, 3.5, 4.5, 5]], atol=0)
    assert m.inverse_time.tolist() == [0.0, 2.0, 0.5, 0.0]
    assert read.end_line == 9


@pytest.mark.parametrize(("name", "message"), [
    ("z_word.ngc", "{p}:12: word 'Z' is not an axis of dialect linuxcnc (axes: X Y U V W)"),
    ("truncated.ngc", "{p}: the program never ends: no M2 or M30 in its 12 lines (truncated file?)"),
    ("not_gcode.ngc", "{p}:1: not G-code: cannot read 'This is not a G-code program.' as words "
                      "(a letter and a number each, e.g. G1 X-1.5)"),
    ("binary.ngc", "{p}: not a G-code program: binary data (byte 0x1a at offset 6)"),
    ("g2_arc.ngc", "{p}:12: G2 is not a code prs3-post programs use "
                   "(allowed: G0 G1 G4 G17 G21 G40 G49 G54 G61 G64 G80 G90 G93 G94)"),
    ("g1_without_f.ngc", "{p}:12: G1 without F under G93 (inverse time needs an F word on every G1)"),
    ("f_zero.ngc", "{p}:11: F0.0000: the feed must be > 0 (LinuxCNC raises F0 to 0.1 /min)"),
    ("open_comment.ngc", "{p}:12: comment opened with '(' at column 59 is not closed with ')'"),
])
def test_verify_bad_program_files(name, message):
    path = VERIFY / "bad" / name
    result = run("verify", path)
    assert (result.exit_code, result.output) == (2, f"prs3-post: error: {message.format(p=path)}\n")


def test_verify_unknown_dialect():
    result = run("verify", VERIFY / "small.ngc", "--dialect", "nope")
    assert (result.exit_code, result.output) == (
        2, "prs3-post: error: nope: no such dialect file or shipped name (shipped: fanuc, linuxcnc)\n")


@pytest.mark.parametrize(("text", "message"), [
    ("", "not a G-code program: the file is empty"),
    ("\ufeffG0 X1 Y1 U1 V1 W1\nM2\n", "starts with a UTF-8 byte-order mark, which LinuxCNC rejects ('Bad character')"),
    ("(only a comment)\n", "not a G-code program: no code, only comments and blank lines"),
    ("G0 X1 Y1 U1 V1\nM2\n", "1: the first move must set every axis (X Y U V W); missing: W (actuator T3)"),
    ("G0 X1 Y1 U1 V1 W1 X2\nM2\n", "1: word 'X' appears twice (X1 and X2)"),
    ("G0 G1 X1 Y1 U1 V1 W1\nM2\n", "1: G0 and G1 are in the same modal group (motion): one per line"),
    ("X1 Y1 U1 V1 W1\nM2\n", "1: axis words without a motion mode (G0 or G1)"),
    ("G0 X1 Y1 U1 V1 W1 N5\nM2\n", "1: the block number N5 must be the first word of the line"),
    ("G0 X1 Y1 U1 V1 W1 Q2\nM2\n", "1: word 'Q' is not used in prs3-post programs (words read: G M N F S T P "
                                   "and the axes X Y U V W)"),
    ("G0 X1 Y1 U1 V1 W1\nG1 U2 F3\nM2\n", "2: G1 under G94 (units per minute): prs3-post programs feed in G93 "
                                         "inverse time, where F = 1 / minutes of the move"),
    ("G0 X1 Y1 U1 V1 W1 F3\nM2\n", "1: F word on a line without a G1 move (prs3-post programs carry F only on "
                                   "G1 lines)"),
    ("M3\nM2\n", "1: M3 (spindle on) without a spindle speed S > 0"),
    ("S0 M4\nM2\n", "1: M4 (spindle on, counter-clockwise) without a spindle speed S > 0"),
    ("M3 M4\nM2\n", "1: M3 and M4 are in the same modal group (spindle): one per line"),
    ("M0 M1\nM2\n", "1: M0 and M1 are in the same modal group (stop): one per line"),
    ("G0 X1 Y1 U1 V1 W1\nM2\nG0 X2\n", "3: code after the program end (line 2): 'G0 X2' (LinuxCNC never reads it)"),
    ("G0 X1 Y1 U1 V1 W1\nM2\n%\nG0\n", "4: text after the closing '%': 'G0' (LinuxCNC never reads it)"),
    ("G0 X1e-5 Y1 U1 V1 W1\nM2\n", "1: word 'E' is not used in prs3-post programs (words read: G M N F S T P "
                                      "and the axes X Y U V W)"),
    ("G4 P-1\nM2\n", "1: G4 (dwell) needs a P word ≥ 0 (seconds)"),
    ("G0 X1 Y1 U1 V1 W1 P2\nM2\n", "1: word 'P' (P2) needs G4 (dwell) or G64 on the same line"),
])
def test_reader_rejects_with_exact_messages(tmp_path, text, message):
    path = tmp_path / "p.ngc"
    path.write_bytes(text.encode("utf-8"))
    with pytest.raises(InputError) as caught:
        load_program(str(path), load_dialect("linuxcnc"))
    sep = "" if message[0].isdigit() else " "
    assert str(caught.value) == f"{path}:{sep}{message}"


@pytest.mark.parametrize(("ending", "length", "message"), [
    ("\r\n", 252, "2: the line is 252 characters, dialect linuxcnc allows 251 with a CRLF line ending "
                  "(LinuxCNC counts the CR; 252 with LF)"),
    ("\r\n", 251, None),
    ("\n", 252, None),
    ("\n", 253, "2: the line is 253 characters, dialect linuxcnc allows 252"),
])
def test_reader_line_length_counts_the_cr_of_crlf(tmp_path, ending, length, message):
    """LinuxCNC counts a CRLF line's CR towards its 252 characters, as the emitter does (one less)."""
    comment = "(" + "c" * (length - 2) + ")"
    path = tmp_path / "p.ngc"
    path.write_bytes(ending.join(["G0 X1 Y1 U1 V1 W1", comment, "M2", ""]).encode("ascii"))
    if message is None:
        read = load_program(str(path), load_dialect("linuxcnc"))
        assert (read.lines[1], read.end_line) == (comment, 3)
    else:
        with pytest.raises(InputError) as caught:
            load_program(str(path), load_dialect("linuxcnc"))
        assert str(caught.value) == f"{path}:{message}"


def test_reader_refuses_stage_words_without_a_stage():
    with pytest.raises(InputError) as caught:
        read_program("G0 X1 U1 V1 W1\nM2\n", load_dialect("linuxcnc"), path="h.ngc", stage=False)
    assert str(caught.value) == ("h.ngc:1: word 'X' is the stage X axis of dialect linuxcnc, and the machine has "
                                 "no stage (axes: U V W)")
    read = read_program("G0 U1 V1 W1\nM2\n", load_dialect("linuxcnc"), path="h.ngc", stage=False)
    assert read.moves.stage.tolist() == [[0.0, 0.0]]


# ----------------------------------------------------------------------------- verify


def test_unaltered_program_passes_against_its_part(tmp_path):
    program = square_program(tmp_path)
    code, report = verify_json(program, "--dialect", DIALECT_8, "--part", WEDGE, "--profile", "square")
    assert (code, report["ok"], report["problems"], report["warnings"]) == (0, True, [], [])
    assert report["against"]["tip_max_mm"] < 1e-7 and report["against"]["axis_max_deg"] < 1e-6
    assert [g["feed_mm_per_min"] for g in report["feeds"]["groups"]] == pytest.approx([100.0, 300.0], abs=1e-6)
    assert report["sampling_bound_mm"] <= report["sampling"]["epsilon_mm"]
    # the JSON path is the FK tip in part coordinates: the first G1 ends on the wedge's face z = 300 - x/2
    ends = [i for i, f in enumerate(report["path"]["fraction"]) if f == 1.0]
    tips = np.array(report["path"]["tip_part"])[ends]
    assert len(ends) == report["moves"] and report["path"]["kind"][ends[2]] == "feed"
    assert_allclose(tips[2, 2] + tips[2, 0] / 2, 300.0, atol=1e-6)
    result = run("verify", program, "--dialect", DIALECT_8)
    assert result.exit_code == 0
    assert result.output.splitlines()[-1] == "OK: within every limit and tolerance"


def test_one_actuator_altered_by_10_um_is_flagged_at_its_line(tmp_path):
    """V (T2) on one G1 line + 0.01 mm: the tip moves by FK(altered) − FK(original), and verify says so."""
    program = square_program(tmp_path)
    lines = program.read_text().split("\n")
    dialect = load_dialect(str(DIALECT_8))
    original = load_program(str(program), dialect)
    kind = original.moves.kind
    row = next(r for r in range(3, len(kind) - 1)               # a G1 between two G1s, with a V word
               if (kind[r - 1:r + 2] == MoveKind.FEED).all() and " V" in lines[original.moves.source[r] - 1])
    number = int(original.moves.source[row])
    words = lines[number - 1].split()
    at = next(i for i, w in enumerate(words) if w.startswith("V"))
    words[at] = f"V{float(words[at][1:]) + 0.01:.8f}"
    lines[number - 1] = " ".join(words)
    altered_path = tmp_path / "altered.ngc"
    altered_path.write_text("\n".join(lines))
    altered = load_program(str(altered_path), dialect)

    joints = [np.column_stack([p.moves.stage, p.moves.strokes])[row] for p in (original, altered)]
    assert_allclose(joints[1] - joints[0], [0, 0, 0, 0.01, 0], atol=1e-9)
    fk = forward(MACHINE.geometry, np.array([j[2:] for j in joints]), np.array([j[:2] for j in joints]))
    expected = fk.tip[1] - fk.tip[0]                    # the alteration through the Jacobian
    assert np.linalg.norm(expected) > 0.004             # well above the 0.002 mm tolerance

    code, report = verify_json(altered_path, "--dialect", DIALECT_8, "--part", WEDGE, "--profile", "square")
    assert code == 1 and report["ok"] is False
    against = report["against"]
    assert against["tip_max_line"] == number and against["tip_max_at"] == 1.0
    assert_allclose(against["tip_max_vector_mm"], expected, atol=1e-6)
    assert_allclose(against["tip_max_mm"], np.linalg.norm(expected), atol=1e-6)
    next_line = int(original.moves.source[row + 1])
    assert [(p["line"], p["kind"]) for p in report["problems"] if p["kind"] == "deviation"] == [
        (number, "deviation"), (next_line, "deviation")]
    assert report["problems"][0]["line"] == number
    # the unaltered program passes with the same options
    assert run("verify", program, "--dialect", DIALECT_8, "--part", WEDGE, "--profile", "square").exit_code == 0


def test_limit_crossed_between_two_points_inside_the_joint_interpolation():
    """A G0 whose end points are inside every limit but whose joint-space interpolation is not.

    A stroke cannot do this: the controller moves every stroke linearly between its end values
    (T(t) = (1 − t) T_a + t T_b), so a stroke between two in-range values stays in range; the same
    holds for the stage. Link angles, the tool's tilt and the condition number are nonlinear in the
    joints, so they can leave their range mid-move. Here the tool turns from 44° tilt toward azimuth
    0° to 44° toward 60° (tip at −80, 0, −680 mm); on the joint-space line it passes near azimuth 30°,
    where the head is weakest, and tilts to 46.26° (> 45°) halfway.
    """
    path = VERIFY / "tilt_midmove.ngc"
    result = run("verify", path)
    assert result.exit_code == 1
    assert result.output.splitlines()[-2:] == [
        "FAIL: 1 problem",
        "  line 6: tilt 46.2642 deg is above the maximum 45.0000 deg by 1.2642 deg at 50.0 % of the move",
    ]
    _code, report = verify_json(path)
    limits = {c["limit"]: c for c in report["limits"]}
    # the end points are within limits (margins from FK of the programmed values alone)
    program = load_program(str(path), load_dialect("linuxcnc"))
    ends = forward(MACHINE.geometry, program.moves.strokes, program.moves.stage)
    assert_allclose(np.degrees(np.arccos(ends.axis[:, 2])), [44.0, 44.0], atol=1e-5)
    # a dense reference of the move: the reported worst tilt is its maximum
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    joints = np.column_stack([program.moves.stage, program.moves.strokes])
    dense = forward(MACHINE.geometry, ((1 - t) * joints[0] + t * joints[1])[:, 2:],
                    ((1 - t) * joints[0] + t * joints[1])[:, :2])
    tilt = np.degrees(np.arccos(dense.axis[:, 2]))
    n = report["moves_detail"][1]["intervals"]
    between = np.abs(np.diff(tilt, 2)).max() / (1 / 20000) ** 2 * (1 / n) ** 2 / 8   # h²/8 · max|tilt''|
    assert 0 <= tilt.max() - limits["tilt"]["value"] <= between
    assert limits["tilt"]["line"] == 6 and abs(limits["tilt"]["at"] - 0.5) <= 1 / n
    # strokes are linear in the move: their closest approach is at an end point
    assert all(limits[f"T{i} stroke"]["at"] == 1.0 for i in (1, 2, 3))
    assert report["sampling_bound_mm"] <= report["sampling"]["epsilon_mm"]


def test_paper_case_2a_2b_actuations_against_the_intended_poses():
    """The paper's T for cases 2a/2b on a rigid head: the tool is 2.27° and 4.89° off the face normal."""
    program, poses = VERIFY / "paper_2a_2b.ngc", VERIFY / "paper_2a_2b.csv"
    code, report = verify_json(program, "--against", poses)
    assert code == 1
    detail = report["moves_detail"]
    assert [d["line"] for d in detail] == [5, 7]
    assert_allclose([d["axis_deviation_deg"] for d in detail], [2.2725, 4.8889], atol=5e-5)
    assert_allclose([d["axis_deviation_deg"] for d in detail], [2.27, 4.89], atol=5e-3)   # DESIGN.md
    fk = forward(MACHINE.geometry, np.array([[41.0978, 172.9648, 84.7195], [26.2745, 172.2674, 94.9981]]))
    intended = np.array([[-81.0264, 21.2132, -679.4865], [-86.5836, 0.0, -676.7079]])
    assert_allclose([d["tip_deviation_mm"] for d in detail], fk.tip - intended, atol=1e-9)
    assert (report["against"]["axis_max_line"], report["against"]["tip_max_line"]) == (7, 5)
    text = run("verify", program, "--against", poses).output.splitlines()
    assert "  line 5: the tool axis is 2.2725° from the intended axis at the end point (allowed 0.01°)" in text
    assert "  line 7: the tool axis is 4.8889° from the intended axis at the end point (allowed 0.01°)" in text


def test_sampling_rule_refines_curved_moves_and_keeps_straight_ones():
    program = load_program(str(VERIFY / "tilt_midmove.ngc"), load_dialect("linuxcnc")).moves
    rep = replay(MACHINE, program, tolerance=0.002)
    assert rep.intervals[0] == 1 and rep.intervals[1] > 100
    assert rep.bound[1] <= 0.002 * EPSILON_FRACTION
    square = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc")).moves
    # the square's moves keep the tool axis (equal stroke changes, up to the rounding): the head
    # translates, the tip path is straight and the link angles constant: end points only, within ε
    flat = replay(MACHINE, square, tolerance=0.002)
    assert flat.intervals.tolist() == [1] * len(square)
    assert np.all(flat.bound <= 0.002 * EPSILON_FRACTION) and flat.bound[1:].max() > 0.0
    probed = replay(MACHINE, square, tolerance=0.002, translations=False)
    assert probed.intervals.tolist() == [1] + [PROBE_INTERVALS] * (len(square) - 1)
    assert_allclose(probed.tip[probed.end], flat.tip, atol=1e-9)
    # the closest approach to every limit is the same (strokes and stage are linear: at the ends)
    assert_allclose(np.nanmin(probed.limits.margin, axis=0), np.nanmin(flat.limits.margin, axis=0), atol=1e-9)
    # N = 1 works: one sample, no move
    one = replay(MACHINE, type(square)(kind=square.kind[:1], stage=square.stage[:1], strokes=square.strokes[:1],
                                         inverse_time=square.inverse_time[:1], source=square.source[:1]),
                                         tolerance=DEFAULT_TOLERANCE)
    assert (one.tip.shape, one.intervals.tolist(), one.bound.tolist()) == ((1, 3), [1], [0.0])


def test_feed_checks_with_and_without_the_part(tmp_path):
    program = square_program(tmp_path)
    lines = program.read_text().split("\n")
    code, report = verify_json(program, "--dialect", DIALECT_8)
    number, f_word = next((d["line"], d["F"]) for d in report["moves_detail"]
                          if d["kind"] == "feed" and abs(d["implied_feed_mm_per_min"] - 300.0) < 1e-3)
    words = lines[number - 1].split()
    words[-1] = f"F{1.01 * f_word:.8f}"                            # 1 % faster
    lines[number - 1] = " ".join(words)
    edited = tmp_path / "edited.ngc"
    edited.write_text("\n".join(lines))
    code, report = verify_json(edited, "--dialect", DIALECT_8)
    assert (code, report["problems"]) == (0, [])                  # a warning, not a failure
    assert [w["line"] for w in report["warnings"]] == [number]
    assert report["warnings"][0]["message"].startswith(f"line {number}: implied tip feed 303.000 mm/min matches "
                                                       "no other G1 (feeds: 100.0 ×4, 300.0 ×11)")
    code, report = verify_json(edited, "--dialect", DIALECT_8, "--part", WEDGE, "--profile", "square")
    assert code == 1
    assert [(p["line"], p["kind"]) for p in report["problems"]] == [(number, "feed")]
    assert report["problems"][0]["message"].startswith(f"line {number}: implied tip feed 303.000 mm/min")


def test_verify_fanuc_program_against_its_part(tmp_path):
    out = tmp_path / "round.nc"
    assert run("demo", "--profile", "round", "--dialect", "fanuc", "-o", out).exit_code == 0
    result = run("verify", out, "--dialect", "fanuc", "--part", WEDGE, "--profile", "round")
    assert result.exit_code == 0, result.output
    # 3 decimals: the deviation is the rounding, and it is allowed for
    _code, report = verify_json(out, "--dialect", "fanuc", "--part", WEDGE, "--profile", "round")
    assert 1e-4 < report["against"]["tip_max_mm"] < 0.002 + max(d["rounding_mm"] for d in report["moves_detail"])


@pytest.mark.parametrize(("args", "code", "message"), [
    (("--against", "{v}/x.apt"), 2, "prs3-post: error: {v}/x.apt: --against takes POSES.csv (one pose per motion "
     "line) or the CAM file a program was converted from (its header names it); the part the program was made "
     "from is --part PART.stl\n"),
    (("--against", "{v}/paper_2a_2b.csv"), 2, "prs3-post: error: {v}/paper_2a_2b.csv: 2 poses for the 5 motion "
     "lines of {v}/small.ngc: give one pose per G0/G1 line, in order\n"),
    (("--part", str(WEDGE), "--profile", "square"), 1, "prs3-post: error: the program has 5 moves, "
     "patel2020-wedge.stl (square) has 20: they do not describe the same path (check the options it was made "
     "with)\n"),
])
def test_verify_against_errors(args, code, message):
    result = run("verify", VERIFY / "small.ngc", *(a.format(v=VERIFY) for a in args))
    assert (result.exit_code, result.output) == (code, message.format(v=VERIFY))


def test_verify_against_part_needs_the_operation():
    result = run("verify", VERIFY / "small.ngc", "--part", WEDGE)
    assert result.exit_code == 2
    assert result.output.splitlines()[-1] == ("Error: --part PART.stl needs --profile and the other operation "
                                              "options the program was made with (it has no prs3-post header that "
                                              "records them)")


def test_verify_help_has_an_example():
    text = run("verify", "--help").output
    assert "  prs3-post verify sq.ngc --part postproc/parts/patel2020-wedge.stl --json" in text
    assert "for a program made by `prs3-post convert` its CAM input" in " ".join(text.split())


def test_verify_program_library_call_reports_rounding():
    program = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc")).moves
    report = verify_program(MACHINE, program, setup=Setup.resolve(MACHINE),
                            tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                            length_decimals=4, feed_decimals=4)
    assert report.ok
    # half a unit of 4 decimals on X, Y and the three strokes moves the tip by less than 5 × 5e-5 mm
    assert np.all((report.rounding > 5e-5) & (report.rounding < 2.5e-4))
    assert math.isclose(report.tolerance, 0.002)


def test_good_fixtures_pass_linuxcnc(rs274_check):
    """The hand-written fixture programs are programs LinuxCNC accepts (only the bad ones are bad)."""
    code, out = rs274_check(VERIFY / "small.ngc", VERIFY / "paper_2a_2b.ngc", VERIFY / "tilt_midmove.ngc")
    assert code == 0, out


def test_g64_blending_is_read_and_warned_about(tmp_path):
    path = tmp_path / "blend.ngc"
    lines = (VERIFY / "small.ngc").read_text().split("\n")
    lines[3] = "G64 P0.01"                               # instead of G61
    path.write_text("\n".join(lines))
    code, report = verify_json(path)
    assert (code, report["warnings"]) == (0, [{
        "line": 4, "kind": "blending", "message": "line 4: G64 path blending: the control may round corners in "
        "joint space (a curve at the tip); the replay assumes exact stops (G61)"}])


def test_text_report_against_line_comes_from_the_summary_not_the_json_record(monkeypatch):
    """The text report's against line needs the maxima and means only: it never builds the JSON record
    (every sample as lists, and the summary again)."""
    import prs3_post.app.verify_report as fmt

    moves = load_program(str(VERIFY / "small.ngc"), load_dialect("linuxcnc")).moves
    fk = forward(MACHINE.geometry, moves.strokes, moves.stage)
    tip, axis = fk.tip.copy(), fk.axis.copy()
    tip[2] += [0.01, 0.0, 0.0]                          # line 11's end point, 10 µm off in x
    axis[3] = (axis[3] + [0.001, 0.0, 0.0]) / np.linalg.norm(axis[3] + [0.001, 0.0, 0.0])   # line 12's axis
    intended = Intended(tip=tip, axis=axis, feed=np.full(len(tip), np.nan), kind=np.full(len(tip), -1),
                        label="shifted.csv")
    report = verify_program(MACHINE, moves, setup=Setup.resolve(MACHINE), intended=intended,
                            tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                            length_decimals=4, feed_decimals=4)
    record = fmt.report_record(report, path="small.ngc", dialect="linuxcnc", rapid_rate=NOMINAL_RAPID_RATE)
    assert fmt.against_summary(report) == record["against"]
    turned = math.degrees(math.acos(np.clip(fk.axis[3] @ axis[3], -1.0, 1.0)))   # clip: rounding past 1
    assert_allclose([record["against"]["tip_max_mm"], record["against"]["axis_max_deg"]], [0.01, turned], atol=1e-9)
    summaries = []

    def counted(*args, **kwargs):
        summaries.append(1)
        return fmt_row_times(*args, **kwargs)

    def refused(*args, **kwargs):
        raise AssertionError("report_text built the whole JSON record")

    fmt_row_times = fmt.row_times
    monkeypatch.setattr(fmt, "row_times", counted)
    monkeypatch.setattr(fmt, "report_record", refused)
    text = fmt.report_text(report, path="small.ngc", dialect="linuxcnc", rapid_rate=NOMINAL_RAPID_RATE).splitlines()
    assert len(summaries) == 1                          # the headline's summary, once
    assert [ln for ln in text if ln.startswith("  against")] == [
        "  against shifted.csv: tip max 0.010000 mm at line 11 (mean 0.004211), axis max 0.0512° at line 12 "
        "(mean 0.0121°)"]


def test_no_straightness_problem_where_the_head_does_not_assemble(tmp_path):
    """W600 on a G1 of the demo square: the head does not assemble there, so the line's problems are that,
    the stroke limit and the stroke speed (the jump to W600 in the move's time); no 'leaves the straight line
    by nan mm' besides (nor on the next move, which starts there)."""
    out = tmp_path / "square.ngc"
    assert run("demo", "--profile", "square", "-o", out).exit_code == 0
    lines = out.read_text().split("\n")
    number = next(n for n, ln in enumerate(lines, start=1) if ln.startswith("G1 ") and " W" in ln)
    lines[number - 1] = " ".join("W600" if w.startswith("W") else w for w in lines[number - 1].split())
    assert lines[number - 1] == "G1 X-8.3212 U33.4461 V167.6102 W600 F50.0000"
    out.write_text("\n".join(lines))
    code, report = verify_json(out)
    assert (code, report["problems"]) == (1, [
        {"line": 26, "kind": "reach", "message": "line 26: the head does not assemble at 25.0 % of the move "
                                                 "(strokes 32.1044, 166.2685, 213.2885 mm)"},
        {"line": 26, "kind": "limit", "message": "line 26: T3 stroke 600.0000 mm is above the maximum 400.0000 mm "
                                                 "by 200.0000 mm at the end point"},
        {"line": 26, "kind": "speed", "message": "line 26: the feed drives stroke T3 at 25780.8 mm/min, 5.16 x its top "
                                                 "speed 5000.0 mm/min"},
        {"line": 28, "kind": "reach", "message": "line 28: the head does not assemble at 12.5 % of the move "
                                                 "(strokes 33.5340, 167.6981, 535.8596 mm)"},
        {"line": 28, "kind": "limit", "message": "line 28: T3 stroke 535.8596 mm is above the maximum 400.0000 mm "
                                                 "by 135.8596 mm at 12.5 % of the move"},
    ])
    assert number == 26


@pytest.mark.parametrize("as_json", [False, True], ids=["streamed", "json"])
def test_a_converted_program_is_not_warned_about_its_cam_feeds(as_json):
    """A CAM program uses the feeds it likes (here F200 for the milling, F100 once for its G81 hole): verify warned
    'line 85: implied tip feed 100.000 mm/min matches no other G1 ...: a hand-edited F or point?' of a program
    converted and never edited. The warning is for the main job's programs (a feed and a plunge feed each)."""
    program = REPO / "fixtures" / "golden" / "convert-wedge-face-3axis.ngc"
    result = run("verify", program, *(["--json"] if as_json else []))
    assert result.exit_code == 0, result.output
    if as_json:
        assert json.loads(result.output)["warnings"] == []
    else:
        assert "warning" not in result.output and result.output.splitlines()[-1] == "OK: within every limit and " \
                                                                                     "tolerance"
