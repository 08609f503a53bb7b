"""5-axis G-code in: the source conventions (proven against a CL source), the reader's TCP, machine and
clamp blocks, round trips in every shipped convention, the corpus programs, exact refusals."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.core.errors import ConfigError, InputError
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.machine.cam_conventions import Rotary
from prs3_post.machine.loading import load_machine, load_source
from prs3_post.part.setup_transform import Setup
from prs3_post.post.pipeline import post_process
from prs3_post.readers.cl.reader import read_cl
from prs3_post.readers.fivex.reader import FivexFile, parse_fivex, read_fivex

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus"
HAAS = CORPUS / "gcode" / "mech491_PostProcessed_Variable_Axis_haas_umc750.nc"
HAAS_CL = CORPUS / "cl" / "mech491_APT_Variable_Axis.cls"
TOL = 0.002
INCH = 25.4
corpus = pytest.mark.skipif(not CORPUS.is_dir(), reason="../shared/corpus is not there")


def _parse(text: str, source: str, **kwargs: object) -> FivexFile:
    return parse_fivex(text, load_source(source), path="t.ngc", tolerance=TOL,  # type: ignore[arg-type]
                       **({"circle_tolerance": CIRCLE_TOL} | kwargs))


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1)))


# ----------------------------------------------------------------------------- the golden pair


@corpus
def test_haas_program_lands_on_its_cl_source() -> None:
    """The Haas UMC-750 program read with haas-umc750 gives the tips and tool axes of the CL file it was
    posted from (MSYS applied: its origin (3, 3, 0) in is the program's G54), within the program's
    rounding: 0.0001 in on X Y Z, 0.001° on B C."""
    gcode = read_fivex(str(HAAS), load_source("haas-umc750"), tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    cl = read_cl(str(HAAS_CL), tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert gcode.gcode.units == "inch" and cl.units == "inch"
    assert len(gcode.toolpath) == len(cl.toolpath) == 348
    msys_origin = np.array([3.0, 3.0, 0.0]) * INCH
    assert_allclose(gcode.toolpath.tip, cl.toolpath.tip - msys_origin, atol=0.0001 * INCH + 1e-9, rtol=0)
    assert _angle_deg(gcode.toolpath.axis, cl.toolpath.axis).max() < 0.001
    assert gcode.toolpath.kind.tolist() == cl.toolpath.kind.tolist()
    assert_allclose(gcode.toolpath.feed, cl.toolpath.feed, atol=1e-9, rtol=0)     # F10. IPM, G94: tip feed


@corpus
@pytest.mark.parametrize("signs", [(1, -1), (-1, 1), (1, 1)])
def test_haas_other_turning_directions_miss_the_cl_axes(signs: tuple[int, int]) -> None:
    """The convention is proven, not assumed: B or C turning the other way misses the CL axes by degrees."""
    haas = load_source("haas-umc750")
    turned = dataclasses.replace(haas, tables=tuple(dataclasses.replace(r, sign=s)
                                                    for r, s in zip(haas.tables, signs, strict=True)))
    gcode = read_fivex(str(HAAS), turned, tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    cl = read_cl(str(HAAS_CL), tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert _angle_deg(gcode.toolpath.axis, cl.toolpath.axis).max() > 10.0


@corpus
def test_haas_program_accounting() -> None:
    """Every line accounted for: machine-coordinate blocks, clamps, G255, the trailing listing line."""
    read = read_fivex(str(HAAS), load_source("haas-umc750"), tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    c, g = read.counts, read.gcode.counts
    assert (c.tcp_on, c.tcp_off, c.tcp_moves, c.prepositions) == (1, 1, 348, 1)
    assert c.machine_blocks == (("G28", 4), ("G53", 3))
    assert c.clamps == (("M10", 1), ("M11", 1), ("M12", 1), ("M13", 1))
    assert c.inert == (("G255", 1),)
    assert (c.trailing_lines, c.trailing_first) == (1, 391)
    assert g.lines == 391 and g.records == 373 and g.moves == 348
    assert g.lines == g.records + g.comment_lines + g.blank_lines + dict(g.skipped)["%"] + c.trailing_lines
    comments = [e.text for e in read.toolpath.events if e.kind is EventKind.COMMENT]
    assert comments.count("G91 G28 B0.0 C0.0: home (G28) of the source machine, not converted") == 2
    assert comments.count("G53 G00 Z0.0: machine coordinates (G53) of the source machine, not converted") == 3
    assert "M11: axis clamp, not converted" in comments and "G255: no effect on this machine, not converted" in comments


# ----------------------------------------------------------------------------- round trips


def _words_haas(axis: np.ndarray, flip: bool) -> dict[str, float]:
    # tool axis (sin B cos C, sin B sin C, cos B): B, C from the axis (flip: −B, C + 180)
    b, c = math.degrees(math.acos(axis[2])), math.degrees(math.atan2(axis[1], axis[0]))
    return {"B": -b, "C": c + 180.0} if flip else {"B": b, "C": c}


def _words_xyzac(axis: np.ndarray, flip: bool) -> dict[str, float]:
    # LinuxCNC xyzac-trt: (sin C sin A, cos C sin A, cos A)
    a, c = math.degrees(math.acos(axis[2])), math.degrees(math.atan2(axis[0], axis[1]))
    return {"A": -a, "C": c + 180.0} if flip else {"A": a, "C": c}


def _words_head_ab(axis: np.ndarray, flip: bool) -> dict[str, float]:
    # head A (about X) carrying head B (about Y): (sin B, −sin A cos B, cos A cos B)
    b, a = math.degrees(math.asin(axis[0])), math.degrees(math.atan2(-axis[1], axis[2]))
    return {"A": a + 180.0, "B": 180.0 - b} if flip else {"A": a, "B": b}


_INVERSES = {"haas-umc750": _words_haas, "xyzac-trt": _words_xyzac, "head-ab": _words_head_ab}
_TCP = {"haas-umc750": "G234 H1", "xyzac-trt": "M428", "head-ab": "G43.4 H1", "vector": "G43.5 H1"}


def _orientations(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(count, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    return v / np.linalg.norm(v, axis=1)[:, None]


@pytest.mark.parametrize("name", ["haas-umc750", "xyzac-trt", "head-ab", "vector"])
def test_round_trip_every_shipped_convention(name: str) -> None:
    """orientation → rotary words (closed forms derived by hand, with either sign and wound by whole
    turns) → the reader → the same axis, to 1e-9."""
    axes = _orientations(60, seed=len(name))
    rng = np.random.default_rng(7)
    lines = ["G21 G90 G94", _TCP[name]]
    for i, axis in enumerate(axes):
        if name == "vector":
            words = dict(zip("IJK", axis * rng.uniform(0.2, 5.0), strict=True))
        else:
            words = _INVERSES[name](axis, flip=bool(i % 2))
            words = {k: v + 360.0 * int(rng.integers(-2, 3)) for k, v in words.items()}
        text = " ".join(f"{k}{v:.12f}" for k, v in words.items())
        lines.append(f"G1 X{i} Y{-i} Z{10 + i} {text} F500" if i else f"G0 X0 Y0 Z10 {text}")
    read = _parse("\n".join(lines) + "\nM2\n", name)
    assert_allclose(read.toolpath.axis, axes, atol=1e-9, rtol=0)
    assert read.counts.tcp_moves == 60


def test_c_wraps_around_on_the_short_great_circle() -> None:
    """C 359° → 1° is a 2° turn: the linearized path keeps the axis between the two (never the long way)."""
    text = "G21 G90\nG234 H1\nG0 X0 Y0 Z5 B20 C359\nG1 X10 C1 F600\nG1 X20 C-359\nM30\n"
    read = _parse(text, "haas-umc750")
    azimuth = np.degrees(np.arctan2(read.toolpath.axis[:, 1], read.toolpath.axis[:, 0]))
    assert_allclose(azimuth, [-1.0, 1.0, 1.0], atol=1e-9)
    machine = load_machine("patel2020")
    result = post_process(machine, read.toolpath, Setup((0.0, 0.0, -900.0)),
                          tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    between = np.degrees(np.arctan2(result.path.axis[:, 1], result.path.axis[:, 0]))
    assert np.all(np.abs(between) <= 1.0 + 1e-9)
    assert len(result.path) < 20


def test_inverse_time_feeds_keep_each_move_time() -> None:
    """G93: each input move takes 1/F minutes in the program too, however it was subdivided."""
    text = ("G21 G90\nM428\nG0 X0 Y0 Z10 A0 C0\nG93\nG1 X20 Y5 Z8 A20 C30 F12.5\nG1 X25 Y-5 A-15 C-40 F40\n"
            "G1 X30 F80\nG94\nM429\nM2\n")
    read = _parse(text, "xyzac-trt")
    # without [dynamics]: the reorientations at these feeds need faster strokes than the machine's (clamped)
    machine = dataclasses.replace(load_machine("patel2020"), dynamics=None)
    result = post_process(machine, read.toolpath, Setup((0.0, 0.0, -900.0)),
                          tolerance=DEFAULT_TOLERANCE, angle_tolerance=DEFAULT_ANGLE_TOLERANCE)
    program = result.program
    for line, f in ((5, 12.5), (6, 40.0), (7, 80.0)):
        rows = program.source == line
        assert rows.sum() >= 1
        assert_allclose(np.sum(1.0 / program.inverse_time[rows]), 1.0 / f, rtol=1e-9)


def test_arc_under_tcp_keeps_the_orientation() -> None:
    read = _parse("G21 G90\nG43.4 H1\nG0 X0 Y0 Z5 A10 B0\nG2 X10 Y0 I5 J0 F300\nM2\n", "head-ab")
    assert read.gcode.counts.arcs == 1 and len(read.toolpath) > 2
    assert_allclose(read.toolpath.axis, np.tile([0.0, -math.sin(math.radians(10)), math.cos(math.radians(10))],
                                                (len(read.toolpath), 1)), atol=1e-12)


def test_linear_moves_outside_tcp_at_rotary_zero_are_three_axis() -> None:
    read = _parse("G21 G90\nG0 B0 C0\nG0 X0 Y0 Z5\nG1 Z0 F100\nM30\n", "haas-umc750")
    assert read.toolpath.tip.tolist() == [[0.0, 0.0, 5.0], [0.0, 0.0, 0.0]]
    assert read.toolpath.axis.tolist() == [[0.0, 0.0, 1.0]] * 2
    assert read.counts.prepositions == 1 and read.counts.tcp_moves == 0


def test_tcp_codes_can_be_overridden() -> None:
    text = "G21 G90\nM128\nG0 X0 Y0 Z5 B10 C0\nM129\nM30\n"
    with pytest.raises(InputError) as error:
        _parse(text, "haas-umc750")
    assert str(error.value) == (
        "t.ngc:2: code M128 is not read by the 5-axis G-code reader (source haas-umc750) (codes read: G0 G1 G2 G3 G4 "
        "G17 G18 G19 G20 G21 G40 G43 G49 G54 G80 G90 G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 M9 M30; "
        "G234 G255 G28 G49 G53 M10 M11 M12 M13)")
    read = _parse(text, "haas-umc750", tcp_on=("M128",), tcp_off=("M129",))
    assert read.tcp_on == ("M128",) and read.counts.tcp_on == 1 and read.counts.tcp_off == 1
    with pytest.raises(ConfigError, match=r"tcp.on: G1 is read as itself \(motion group\), it cannot switch TCP"):
        _parse(text, "haas-umc750", tcp_on=("G1",))


# ----------------------------------------------------------------------------- the corpus


@corpus
@pytest.mark.parametrize(("name", "rows", "beyond"), [("linuxcnc_boat-xyzac.ngc", 1883, 894),
                                                      ("linuxcnc_impeller-7bl-xyzac.ngc", 4492, 3653)])
def test_linuxcnc_demos_read_and_tilt_beyond_45_degrees(name: str, rows: int, beyond: int) -> None:
    """Both demos are TCP throughout (M428 on line 2): they read completely; then the tilt limit
    (45°) refuses them at their first line beyond it, which is the line and value the pipeline names."""
    read = read_fivex(str(CORPUS / "gcode" / name), load_source("xyzac-trt"), tolerance=TOL,
                      circle_tolerance=CIRCLE_TOL)
    assert len(read.toolpath) == rows and read.counts.tcp_on == 1 and read.counts.tcp_off == 1
    tilt = np.degrees(np.arccos(np.clip(read.toolpath.axis[:, 2], -1.0, 1.0)))
    assert int((tilt > 45.0).sum()) == beyond


@corpus
def test_linuxcnc_expressions_are_refused_with_their_line() -> None:
    path = str(CORPUS / "gcode" / "linuxcnc_xyzab-tdr-demo.ngc")
    with pytest.raises(InputError) as error:
        read_fivex(path, load_source("xyzac-trt"), tolerance=TOL, circle_tolerance=CIRCLE_TOL)
    assert str(error.value) == (
        f"{path}:10: LinuxCNC expression or parameter in 'g10 l20 p0 x-[#<_hal[xyzab_tdr_kins.x-ro...': its values "
        "exist only in LinuxCNC's interpreter at run time (HAL pins, parameters), so the program cannot be converted; "
        "write it in plain numbers")


# ----------------------------------------------------------------------------- refusals

_OUTSIDE = ("outside TCP (G234 not on): without TCP the source machine's X Y Z are not the tool tip in the part "
            "frame, and where a rotary move takes the tip depends on the source machine's pivot geometry, which the "
            "source file does not give; it cannot be converted")
_IN_PLACE = ("a feed move that turns the tool about a fixed tip (a reorientation in place): it has no tip path, and "
             "this machine's program times every move by its tip path (G93), so its time cannot be kept; give the "
             "tip a move, or turn at rapid (G0)")


@pytest.mark.parametrize(("source", "text", "message"), [
    ("haas-umc750", "G20 G90\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nG0 X1 A10\n",
     "t.ngc:4: rotary word 'A10': source haas-umc750 has no A axis (its rotary words are B C)"),
    ("vector", "G21 G90\nG43.5 H1\nG0 X0 Y0 Z10 A1\n",
     "t.ngc:3: rotary word 'A1': source vector has no A axis (the orientation is the tool vector I J K)"),
    ("vector", "G21 G90\nG43.5 H1\nG0 X0 Y0 Z10 I0 J0 K0\n",
     "t.ngc:3: zero-length tool vector I0 J0 K0: the tool axis has no direction"),
    ("vector", "G21 G90\nG43.5 H1\nG0 X0 Y0 Z10 I0 J0\n", "t.ngc:3: a tool vector needs all of I J K on its line"),
    ("vector", "G21 G90\nG43.5 H1\nG0 X0 Y0 Z10 I0 J0 K1\nG2 X1 Y1 I1 J0 K0 F100\n",
     "t.ngc:4: G2 in a vector source: I J K are the tool vector here, not an arc's centre (a vector program has no "
     "arcs)"),
    ("haas-umc750", "G20 G90\nG0 B0 C0\nG0 X0 Y0 Z1\nG0 B10\n", f"t.ngc:4: rotary motion (B10) {_OUTSIDE}"),
    ("haas-umc750", "G20 G90\nG0 B0 C0\nG0 X0 Y0 Z1\nG234 H1\nG0 X1 B5\nG49\nG1 X2 C5 F10\n",
     f"t.ngc:7: rotary motion (C5) {_OUTSIDE}"),
    ("haas-umc750", "G20 G90\nG0 B10 C0\nG0 X0 Y0 Z1\n",
     f"t.ngc:3: a linear move with the rotaries at B10 C0 (not at their zero) {_OUTSIDE}"),
    ("haas-umc750", "G20 G90\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nG21\n",
     "t.ngc:4: inconsistent units: G21 (mm) after moves in inch; a program's length unit must not change after its "
     "first move"),
    ("haas-umc750", "G20 G90\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nG1 B10 F10\n", f"t.ngc:4: {_IN_PLACE}"),
    ("haas-umc750", "G20 G90\nG234 H1\nG0 X0 Y0 Z1\n",
     "t.ngc:3: a move before the tool orientation is known: give B C on it or before it"),
    ("haas-umc750", "G20 G90\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nG53 G0 Z0 M5\n",
     "t.ngc:4: M5 on the G53 line: a machine-coordinate block is not converted, so it may hold only G0/G1, G90/G91 "
     "and axis words (put the rest on its own line)"),
    ("haas-umc750", "G20 G90\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nG53 G0 Z0\nG1 X1 Y1 Z1 F10\n",
     "t.ngc:5: G1 after the machine-coordinate block of line 4: the source machine moved in its own coordinates, so "
     "the tool's position is not known here; the next move must be a rapid (G0)"),
    ("xyzac-trt", "G21 G90\nM428\nG0 X0 Y0 Z1 A0 C0\nG81 X1 Y1 Z-1 R1 F100\n",
     "t.ngc:4: code G81 is not read by the 5-axis G-code reader (source xyzac-trt) (codes read: G0 G1 G2 G3 G4 G17 "
     "G18 G19 G20 G21 G40 G43 G49 G54 G80 G90 G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 M9 M30; G28 "
     "G53 M428 M429)"),
])
def test_bad_input_exact_message(source: str, text: str, message: str) -> None:
    with pytest.raises(InputError) as error:
        _parse(text, source)
    assert str(error.value) == message


def test_text_after_the_closing_percent_is_reported_not_read() -> None:
    read = _parse("%\nG21\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nM30\n%\nTool Path Listing has 6 lines. (\n\nmore [#1]\n",
                  "haas-umc750")
    assert (read.counts.trailing_lines, read.counts.trailing_first) == (2, 7)


# ----------------------------------------------------------------------------- source files


def test_sources_command_lists_the_shipped_conventions() -> None:
    result = CliRunner().invoke(main, ["sources"])
    assert result.exit_code == 0
    assert result.output == (
        "haas-umc750    B C    G234 G49     Haas UMC-750 trunnion: table B (about Y) carrying table C (about Z), "
        "TCP G234/G49\n"
        "head-ab        A B    G43.4 G49    head-head: head A (about X) carrying head B (about Y), TCP G43.4/G49\n"
        "vector         I J K  G43.5 G49    tool vectors I J K on the motion blocks (tip to spindle), TCP G43.5/G49\n"
        "xyzac-trt      A C    M428 M429    LinuxCNC xyzac-trt: table A (about X) carrying table C (about Z), TCP "
        "M428/M429\n")


def test_shipped_sources_load_as_documented() -> None:
    haas = load_source("haas-umc750")
    assert haas.tables == (Rotary("B", True, (0.0, 1.0, 0.0), -1), Rotary("C", True, (0.0, 0.0, 1.0), -1))
    assert haas.source == "sources/haas-umc750.toml" and haas.clamps == ("M10", "M11", "M12", "M13")
    assert load_source("head-ab").heads[0] == Rotary("A", False, (1.0, 0.0, 0.0), 1)
    assert load_source("vector").vector_words == ("I", "J", "K")


@pytest.mark.parametrize(("change", "message"), [
    (("\nsign = -1", "\nsign = 2", 1), "table[0].sign: must be 1 or -1, got 2"),
    (("zero_deg = 0.0", "zero_deg = 0.0\nspeed = 3", 1), "table[0].speed: unknown key"),
    (('word = "C"', 'word = "B"', 1), "table: rotary word B appears twice in the chain"),
    (('on = ["G234"]', 'on = ["G234x"]', 1), "tcp.on[0]: expected a G or M code such as G43.4, got 'G234x'"),
    (("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 2.0, 0.0]", 1),
     "table[0].axis: must be a unit vector, got [0.0, 2.0, 0.0] (length 2)"),
    (('off = ["G49"]', 'off = ["G234"]', 1), "tcp.off: G234 is also in tcp.on"),
    # a word that is no rotary letter was reported as "table[0].axis: unknown key" (the keys after it unread)
    (('word = "B"', 'word = "X"', 1), "table[0].word: must be A, B or C, got 'X'"),
    # inert and clamp codes are dropped from their blocks: G1 made every cut a rapid, M30 hid the program's end
    (('inert = ["G255"]', 'inert = ["G255", "G1", "M30"]', 1), "codes.inert[1]: G1 is a motion code, it cannot be "
     "inert (inert and clamp codes must change nothing in a conversion: no motion code G0-G3, G73, G80-G89, no feed "
     "mode G93-G95, no program end M2, M30)"),
    (('clamps = ["M10", "M11", "M12", "M13"]', 'clamps = ["M10", "M30"]', 1), "codes.clamps[1]: M30 is a program "
     "end, it cannot be a clamp (inert and clamp codes must change nothing in a conversion: no motion code G0-G3, "
     "G73, G80-G89, no feed mode G93-G95, no program end M2, M30)"),
    (('inert = ["G255"]', 'inert = ["G85"]', 1), "codes.inert[0]: G85 is a motion code, it cannot be inert (inert "
     "and clamp codes must change nothing in a conversion: no motion code G0-G3, G73, G80-G89, no feed mode "
     "G93-G95, no program end M2, M30)"),
    (('inert = ["G255"]', 'inert = ["G93"]', 1), "codes.inert[0]: G93 is a feed mode, it cannot be inert (inert "
     "and clamp codes must change nothing in a conversion: no motion code G0-G3, G73, G80-G89, no feed mode "
     "G93-G95, no program end M2, M30)"),
], ids=["sign", "unknown-key", "word-twice", "tcp-code", "axis", "tcp-both", "word", "inert-g1", "clamp-m30",
        "inert-cycle", "inert-feed-mode"])
def test_bad_source_files(tmp_path: Path, change: tuple[str, str, int], message: str) -> None:
    text = (REPO / "postproc" / "sources" / "haas-umc750.toml").read_text()
    old, new, count = change
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new, count))
    with pytest.raises(ConfigError) as error:
        load_source(str(path))
    assert str(error.value) == f"{path}: {message}"


def test_feed_rows_are_tip_feeds_under_g94() -> None:
    read = _parse("G20 G90 G94\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nG1 X1 B5 F10\nM30\n", "haas-umc750")
    assert read.toolpath.kind.tolist() == [int(MoveKind.RAPID), int(MoveKind.FEED)]
    assert read.toolpath.feed.tolist() == [0.0, 254.0]


# ----------------------------------------------------------------------------- through convert

#: The CL conversion's part origin in tests/test_convert.py, shifted by the CL file's MSYS origin
#: (3, 3, 0) in: the Haas program's G54 is the MSYS frame, so both put the part at one place.
_CL_ORIGIN = (-44.0, -81.3, -786.7)
_HAAS_ORIGIN = (-44.0 + 3 * INCH, -81.3 + 3 * INCH, -786.7)


def _convert_settings(origin: tuple[float, float, float], source: str, **kwargs: object) -> object:
    from prs3_post.app.convert import ConvertSettings
    from prs3_post.machine.loading import load_dialect

    machine = load_machine("patel2020")
    return ConvertSettings(machine=machine, dialect=load_dialect("linuxcnc"), setup=Setup(origin),
                           source=load_source(source), **kwargs)  # type: ignore[arg-type]


@corpus
def test_converted_haas_program_replays_onto_the_cl_points(tmp_path: Path, rs274_check) -> None:
    """FK of the converted Haas program lands on the CL file's points and axes (MSYS and the same placement
    applied) within the Haas program's rounding (0.0001 in, 0.001°) plus the output's; LinuxCNC accepts it."""
    from prs3_post.app.convert import convert_file
    from prs3_post.kinematics import forward
    from prs3_post.post.pipeline import place_toolpath
    from prs3_post.readers.program import read_program

    settings = _convert_settings(_HAAS_ORIGIN, "haas-umc750")
    conversion = convert_file(str(HAAS), settings)  # type: ignore[arg-type]
    program = read_program(conversion.text, settings.dialect, path="haas.ngc")  # type: ignore[attr-defined]
    fk = forward(settings.machine.geometry, program.moves.strokes, program.moves.stage)  # type: ignore[attr-defined]
    assert fk.converged.all() and len(fk.tip) == conversion.report.emitted_moves == 1338
    lines = read_fivex(str(HAAS), load_source("haas-umc750"), tolerance=TOL,
                       circle_tolerance=CIRCLE_TOL).toolpath.source
    last = np.array([np.flatnonzero(conversion.path.source == line)[-1] for line in lines])   # each input move's end
    cl = place_toolpath(read_cl(str(HAAS_CL), tolerance=TOL, circle_tolerance=CIRCLE_TOL).toolpath, Setup(_CL_ORIGIN))
    rounding = 2e-4                                   # 4 decimals on 5 joint words (as tests/test_convert.py)
    assert_allclose(fk.tip[last], cl.tip, atol=0.0001 * INCH + rounding, rtol=0)
    assert _angle_deg(fk.axis[last], cl.axis).max() < 0.001 + 1e-3
    assert conversion.report.skipped[-2:] == (("rotary positioning outside TCP (sets the next orientation)", 1),
                                              ("text after the closing % (from line 391)", 1))
    out = tmp_path / "haas.ngc"
    out.write_text(conversion.text)
    code, text = rs274_check(out)
    assert code == 0, text


@corpus
@pytest.mark.parametrize(("name", "message"), [
    ("linuxcnc_boat-xyzac.ngc", "663: the program's tool axis tilts 46.0620 deg from the part's z, beyond this "
     "machine's maximum tilt 45.0000 deg; 894 of 1883 rows (47.5%) tilt beyond it, and a setup turns the part about "
     "z only, so no setup brings them within it (the CAM program must tilt the tool less)"),
    ("linuxcnc_impeller-7bl-xyzac.ngc", "8: the program's tool axis tilts 71.8410 deg from the part's z, beyond this "
     "machine's maximum tilt 45.0000 deg; 3653 of 4492 rows (81.3%) tilt beyond it, and a setup turns the part about "
     "z only, so no setup brings them within it (the CAM program must tilt the tool less)"),
    ("linuxcnc_xyzab-tdr-demo.ngc", "10: LinuxCNC expression or parameter in 'g10 l20 p0 x-[#<_hal[xyzab_tdr_kins."
     "x-ro...': its values exist only in LinuxCNC's interpreter at run time (HAL pins, parameters), so the program "
     "cannot be converted; write it in plain numbers"),
])
def test_linuxcnc_demos_fail_for_their_reason(name: str, message: str, tmp_path: Path) -> None:
    path = CORPUS / "gcode" / name
    result = CliRunner().invoke(main, ["convert", str(path), "-d", str(tmp_path), "--jobs", "1",
                                       "--source", "xyzac-trt", "--part-origin", "0,0,-900"])
    assert result.exit_code == (2 if "expression" in message else 1)   # bad input 2, a limit 1
    assert result.stdout == f"failed\t{path}\t-\t{path}:{message}\n"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "message"), [
    (["--source", "nope"], "prs3-post: error: nope: no such source file or shipped name (shipped: haas-umc750, "
                           "head-ab, vector, xyzac-trt)"),
    (["--source", "haas-umc750", "--tcp-on", "G43.4;"], "Error: Invalid value for '--tcp-on': expected G or M codes "
                                                       "separated by commas (e.g. G43.4,M428), got 'G43.4;'"),
])
def test_convert_bad_source_options(args: list[str], message: str, tmp_path: Path) -> None:
    program = tmp_path / "in.nc"
    program.write_text("G21\nG234 H1\nG0 X0 Y0 Z1 B0 C0\nM30\n")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(program), "-d", str(out), "--jobs", "1", *args])
    assert result.exit_code == 2
    assert message in result.output.splitlines()
    assert not out.exists() or list(out.iterdir()) == []


@pytest.mark.parametrize(("inert", "message"), [
    ('["G255", "G1", "M30"]', "codes.inert[1]: G1 is a motion code, it cannot be inert (inert and clamp codes must "
     "change nothing in a conversion: no motion code G0-G3, G73, G80-G89, no feed mode G93-G95, no program end M2, "
     "M30)"),
    ('["G90"]', "codes.inert: G90 is read as itself (distance group), it cannot be inert"),
    ('["M6"]', "codes.inert: M6 is read as itself (tool change group), it cannot be inert"),
], ids=["motion", "distance", "tool-change"])
def test_convert_refuses_a_source_whose_inert_codes_are_read(inert: str, message: str, tmp_path: Path) -> None:
    """A copy of haas-umc750.toml with inert = ["G255", "G1", "M30"] turned every cut into a rapid: the Haas
    program came out with 348 G0 and 1 G1 instead of 3 G0 and 1336 G1, exit 0, and verify said OK."""
    source = tmp_path / "haas.toml"
    source.write_text((REPO / "postproc" / "sources" / "haas-umc750.toml").read_text().replace(
        'inert = ["G255"]', f"inert = {inert}"))
    program = tmp_path / "in.nc"
    program.write_text("G21 G90\nG234 H1\nG0 X0 Y0 Z5 B0 C0\nG1 X10 F300\nG1 X20\nG49\nM30\n")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(program), "-d", str(out), "--jobs", "1", "--source",
                                       str(source), "--part-origin", "0,0,-900"])
    assert result.exit_code == 2, result.output
    assert result.stderr == f"prs3-post: error: {source}: {message}\n"
    assert not out.exists() or list(out.iterdir()) == []


def test_convert_with_tcp_codes_given(tmp_path: Path) -> None:
    program = tmp_path / "in.nc"
    program.write_text("G21 G90\nM128\nG0 X0 Y0 Z5 B10 C0\nG1 X10 B12 C5 F300\nM129\nM30\n")
    out = tmp_path / "out"
    args = ["convert", str(program), "-d", str(out), "--jobs", "1", "--source", "haas-umc750", "--part-origin",
            "0,0,-900"]
    refused = CliRunner().invoke(main, args)
    assert refused.exit_code == 2 and list(out.iterdir()) == []
    result = CliRunner().invoke(main, [*args, "--tcp-on", "M128", "--tcp-off", "m129"])
    assert result.exit_code == 0, result.output
    assert [p.name for p in out.iterdir()] == ["in.ngc"]


@corpus
def test_verify_against_the_haas_source(tmp_path: Path) -> None:
    """The header records the source convention and TCP codes, so that verify --against reads the input as
    the conversion did."""
    args = ["convert", str(HAAS), "-d", str(tmp_path), "--jobs", "1", "--source", "haas-umc750",
            "--part-origin=" + ",".join(f"{v:g}" for v in _HAAS_ORIGIN)]
    assert CliRunner().invoke(main, args).exit_code == 0
    out = tmp_path / (HAAS.stem + ".ngc")
    assert out.read_text().splitlines()[4] == "(five axis: haas-umc750, tcp on G234, off G49)"
    verified = CliRunner().invoke(main, ["verify", str(out), "--against", str(HAAS)])
    assert verified.exit_code == 0, verified.output
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance"


@pytest.mark.parametrize("name", ["haas-umc750", "xyzac-trt", "head-ab", "vector"])
def test_synthesized_program_converts_and_replays(name: str, tmp_path: Path, rs274_check) -> None:
    """A 5-axis program in each shipped convention (tilts up to 30°, G93 and G94 moves) converts; FK of the
    program lands on the tips and axes the reader gave; LinuxCNC's interpreter accepts the output."""
    from prs3_post.app.convert import convert_file
    from prs3_post.kinematics import forward
    from prs3_post.post.pipeline import place_toolpath
    from prs3_post.readers.program import read_program

    rng = np.random.default_rng(11)
    tilt = np.radians(rng.uniform(0.0, 30.0, 24))
    azimuth = rng.uniform(-math.pi, math.pi, 24)
    axes = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    lines = ["%", "G21 G90 G94", _TCP[name]]
    for i, axis in enumerate(axes):
        words = (dict(zip("IJK", axis, strict=True)) if name == "vector"
                 else _INVERSES[name](axis, flip=bool(i % 3 == 1)))
        text = " ".join(f"{k}{v:.6f}" for k, v in words.items())
        x, y, z = 3.0 * math.cos(i / 4.0), 3.0 * math.sin(i / 4.0), 2.0 - 0.05 * i
        if i == 0:
            lines.append(f"G0 X{x:.4f} Y{y:.4f} Z10 {text}")
        elif i == 12:
            lines.append("G93")
        lines.append(f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f} {text} F{(40.0 if i >= 12 else 300.0):g}")
    lines += ["G94", "G0 Z10", "M30", "%"]
    program_path = tmp_path / f"{name}.nc"
    program_path.write_text("\n".join(lines) + "\n")
    settings = _convert_settings((0.0, 0.0, -780.0), name)
    conversion = convert_file(str(program_path), settings)  # type: ignore[arg-type]
    program = read_program(conversion.text, settings.dialect, path="out.ngc")  # type: ignore[attr-defined]
    fk = forward(settings.machine.geometry, program.moves.strokes, program.moves.stage)  # type: ignore[attr-defined]
    assert fk.converged.all()
    read = place_toolpath(parse_fivex(program_path.read_text(), load_source(name), path="in", tolerance=TOL,
                                      circle_tolerance=CIRCLE_TOL).toolpath,
                          Setup((0.0, 0.0, -780.0)))
    last = np.array([np.flatnonzero(conversion.path.source == line)[-1] for line in read.source])
    assert_allclose(fk.tip[last], read.tip, atol=2e-4, rtol=0)
    assert _angle_deg(fk.axis[last], read.axis).max() < 1e-3
    out = tmp_path / "out.ngc"
    out.write_text(conversion.text)
    code, text = rs274_check(out)
    assert code == 0, text
