"""The G-code emitter and its dialects.

Programs are compared whole (golden strings in this file), and every program a test emits is also
checked by :func:`_emit`: each line within the dialect's length, each line parsed by pygcode with
no word left over, F on every feed move under G93, and LinuxCNC's own interpreter (``rs274-check``,
``RS274_CHECK`` overrides its path) accepting it. When LinuxCNC is not installed the interpreter
runs are left out and ``test_rs274_check_available`` is skipped with the reason; with the
environment variable ``CI`` set it fails instead.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pygcode
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.core.errors import ConfigError, LimitError
from prs3_post.core.numbers import format_word
from prs3_post.core.toolpath import Event, EventKind, JointProgram, MoveKind
from prs3_post.emit import gcode
from prs3_post.emit.gcode import ProgramEmitter, emit_program, sanitize_comment
from prs3_post.machine.loading import Dialect, load_dialect

REPO = Path(__file__).resolve().parents[2]
BAD_DIALECTS = sorted((REPO / "fixtures" / "bad" / "dialects").glob("*.toml"))
#: LinuxCNC's interpreter wrapper (scripts/rs274-check); RS274_CHECK overrides where it lives.
RS274_CHECK = Path(os.environ.get("RS274_CHECK", REPO / "scripts" / "rs274-check"))

R, F = MoveKind.RAPID, MoveKind.FEED


# ----------------------------------------------------------------------------- helpers


def _program(kind, stage, strokes, inverse_time, source=None, events=(), labels=()) -> JointProgram:
    n = len(kind)
    return JointProgram(
        kind=np.array(kind, dtype=np.int64),
        stage=np.array(stage, dtype=np.float64).reshape(n, 2),
        strokes=np.array(strokes, dtype=np.float64).reshape(n, 3),
        inverse_time=np.array(inverse_time, dtype=np.float64),
        source=np.arange(n) if source is None else np.array(source),
        events=tuple(events),
        source_labels=tuple(labels),
    )


def _drill() -> JointProgram:
    """One hole: tool change, spindle, mist, rapid, feed, a zero-length feed, dwell, retract."""
    return _program(
        kind=[R, R, F, F, R],
        stage=[[-2.7639, 12.0703]] * 4 + [[0.0, 0.0]],
        strokes=[
            [30.0, 160.0, 80.0],
            [38.0978, 169.9648, 81.7195],
            [41.0978, 172.9648, 84.7195],
            [41.0978, 172.9648, 84.71951],  # same text with 4 decimals, not with 3
            [30.0, 160.0, 80.0],
        ],
        inverse_time=[0.0, 0.0, 100.0, 12.5, 0.0],
        source=[0, 1, 2, 2, 3],
        labels=("hole 1 clear", "hole 1 approach", "hole 1 feed", "hole 1 retract"),
        events=(
            Event(0, EventKind.TOOL_CHANGE, 1, "6 mm drill (HSS)"),
            Event(0, EventKind.SPINDLE_ON, 3000),
            Event(0, EventKind.COOLANT_ON, 0, "mist"),
            Event(2, EventKind.COMMENT, 0, "hole 1\nat 26.6°"),
            Event(4, EventKind.DWELL, 0.5),
            Event(5, EventKind.SPINDLE_OFF),
            Event(5, EventKind.COOLANT_OFF),
        ),
    )


HEADER = (("tool", "T1 6 mm drill"), ("machine", "patel2020"), ("part", "wedge.stl"), ("units", "mm"))


def _unavailable(reason: str) -> None:
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI is set, so this is a failure, not a skip)")
    pytest.skip(reason)


def _run_rs274(path: Path, axes: str, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(RS274_CHECK), "-a", axes, *extra, str(path)],
        capture_output=True,
        text=True,
        timeout=300,
    )


@functools.cache
def _rs274_missing() -> str:
    """Why LinuxCNC's interpreter cannot run here ("" when it can): asked once, of the checker itself."""
    if not RS274_CHECK.is_file():
        return f"rs274-check not found at {RS274_CHECK} (set RS274_CHECK)"
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / "probe.ngc"
        probe.write_text("M2\n", encoding="ascii")
        result = _run_rs274(probe, "XYZ")
    if result.returncode == 2 and "gcode module is missing" in result.stderr:
        return "LinuxCNC is not installed (apt-get install --no-install-recommends linuxcnc-uspace)"
    assert result.returncode == 0, result.stderr
    return ""


def _rs274(path: Path, axes: str, *extra: str) -> subprocess.CompletedProcess[str]:
    """Run LinuxCNC's interpreter on ``path``; skip (fail under CI) when LinuxCNC is missing."""
    if _rs274_missing():
        _unavailable(_rs274_missing())
    return _run_rs274(path, axes, *extra)


def test_rs274_check_available() -> None:
    """Reports once why the interpreter checks in the other tests did not run (fails under CI)."""
    if _rs274_missing():
        _unavailable(_rs274_missing())


def _axes(dialect: Dialect) -> str:
    a = dialect.axes
    return "".join(sorted({a.x, a.y, a.t1, a.t2, a.t3}))


def _check_lines(text: str, dialect: Dialect) -> None:
    """Length, pygcode parse with no leftover word, and F on every feed move while G93 is on."""
    ending = dialect.line_ending
    assert text.endswith(ending)
    lines = text[: -len(ending)].split(ending)
    limit = dialect.max_line_length - (len(ending) - 1)
    style = dialect.comments
    motion, inverse_time = None, False
    axis_letters = {dialect.axes.x, dialect.axes.y, dialect.axes.t1, dialect.axes.t2, dialect.axes.t3}
    for number, line in enumerate(lines, 1):
        assert len(line) <= limit, f"line {number} is {len(line)} characters: {line}"
        assert "\r" not in line and "\n" not in line
        assert all(" " <= c <= "~" for c in line), f"line {number}: {line!r}"
        if line == "%":
            continue
        parsed = pygcode.Line(line)
        # pygcode leaves a word it cannot place in modal_params: only axis words and F of a modal
        # motion line (no G0/G1 on it, the motion mode of an earlier line applies) may be there.
        leftover = {str(w)[0] for w in parsed.block.modal_params}
        allowed = axis_letters | {"F"} if dialect.modal_motion and motion is not None else set()
        assert leftover <= allowed, f"line {number}: words pygcode could not place: {line}"
        code = line.split(style.open, 1)[0].strip()
        if line.startswith(style.open):
            assert code == "" and line.endswith(style.close) and line.count(style.close) == 1, line
            assert len(parsed.block.words) == 0
            continue
        tokens = code.split()
        assert len(parsed.block.words) == len(tokens), f"line {number}: {line}"
        letters = {t[0] for t in tokens}
        if "G93" in tokens:
            inverse_time = True
        if "G94" in tokens:
            inverse_time = False
        for token in tokens:
            if token in ("G0", "G1"):
                motion = token
        if motion == "G1" and (("G1" in tokens) or letters & axis_letters):
            assert inverse_time, f"line {number}: a feed move outside G93: {line}"
            assert sum(t.startswith("F") for t in tokens) == 1, f"line {number}: F missing: {line}"
        if motion == "G0" or "G0" in tokens:
            assert "F" not in letters, f"line {number}: F on a rapid: {line}"


def _emit(program: JointProgram, dialect: Dialect, tmp_path: Path, **kwargs) -> str:
    """Emit, then check the text (see :func:`_check_lines`) and run LinuxCNC's interpreter on it.

    Without LinuxCNC the interpreter run is left out here (so that the golden comparisons still
    run) and :func:`test_rs274_check_available` reports it, as a skip or, under CI, a failure.
    """
    text = emit_program(program, dialect, **kwargs)
    assert emit_program(program, dialect, **kwargs) == text  # deterministic
    _check_lines(text, dialect)
    if not _rs274_missing():
        path = tmp_path / f"{dialect.name}.ngc"
        path.write_bytes(text.encode("ascii"))
        result = _run_rs274(path, _axes(dialect))
        assert result.returncode == 0, result.stderr
    return text


@pytest.fixture(scope="module")
def linuxcnc() -> Dialect:
    return load_dialect("linuxcnc")


@pytest.fixture(scope="module")
def fanuc() -> Dialect:
    return load_dialect("fanuc")


# ----------------------------------------------------------------------------- numbers


@pytest.mark.parametrize(
    ("letter", "value", "decimals", "expected"),
    [
        ("X", -0.00004, 4, "X0.0000"),  # never -0.0000
        ("X", -0.0, 4, "X0.0000"),
        ("X", 1e-5, 4, "X0.0000"),  # never 1e-05 (LinuxCNC reads an E word)
        ("X", -1e-5, 4, "X0.0000"),
        ("X", -0.00005, 4, "X-0.0001"),  # binary -5.00000000000000024e-05: rounds away
        ("X", 12.34565, 4, "X12.3456"),  # binary 12.3456499999...: rounds down
        ("X", 12.34575, 4, "X12.3458"),  # binary 12.3457500000...1: rounds up
        ("U", 1e20, 4, "U100000000000000000000.0000"),
        ("V", -123.456789, 8, "V-123.45678900"),
        ("S", 2999.5, 0, "S3000"),
        ("P", -0.4, 0, "P0"),
        ("F", 2.0, 0, "F2"),
    ],
)
def test_format_word(letter: str, value: float, decimals: int, expected: str) -> None:
    assert format_word(letter, value, decimals) == expected


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
def test_format_word_refuses_non_finite(value: float) -> None:
    with pytest.raises(ValueError) as info:
        format_word("X", value, 4)
    assert str(info.value) == f"X: {value!r} is not a finite number"


# ----------------------------------------------------------------------------- dialect files


def test_shipped_dialects(linuxcnc: Dialect, fanuc: Dialect) -> None:
    assert (linuxcnc.name, linuxcnc.source) == ("linuxcnc", "dialects/linuxcnc.toml")
    assert dataclasses.astuple(linuxcnc.axes) == ("X", "Y", "U", "V", "W")
    assert dataclasses.astuple(linuxcnc.decimals) == (4, 4, 0, 3)
    assert dataclasses.astuple(linuxcnc.line_numbers) == (False, "N", 10, 10, 99999)
    assert (linuxcnc.percent, linuxcnc.program_number, linuxcnc.end_code) == (False, 0, "M2")
    assert linuxcnc.safe_start == ("G17 G21 G40 G49 G54 G80 G90 G94", "G61")
    assert (linuxcnc.modal_motion, linuxcnc.dwell_unit, linuxcnc.line_ending) == (False, "s", "\n")
    assert (fanuc.name, fanuc.source) == ("fanuc", "dialects/fanuc.toml")
    assert dataclasses.astuple(fanuc.decimals) == (3, 4, 0, 0)
    assert dataclasses.astuple(fanuc.line_numbers) == (True, "N", 10, 10, 99999)
    assert (fanuc.percent, fanuc.program_number, fanuc.program_name, fanuc.end_code) == (
        True, 1000, "PRS3-POST", "M30"
    )
    assert (fanuc.comments.uppercase, fanuc.modal_motion, fanuc.dwell_unit) == (True, True, "ms")


def test_bad_dialect_files_exist() -> None:
    assert len(BAD_DIALECTS) >= 30


@pytest.mark.parametrize("path", BAD_DIALECTS, ids=[p.stem for p in BAD_DIALECTS])
def test_bad_dialect(path: Path) -> None:
    first = path.read_text(encoding="utf-8").splitlines()[0]
    assert first.startswith("# expect: ")
    expected = first.removeprefix("# expect: ")
    with pytest.raises(ConfigError) as info:
        load_dialect(str(path))
    assert info.value.args[0] == expected
    assert str(info.value) == f"{path}: {expected}"


def test_unknown_dialect_name() -> None:
    with pytest.raises(ConfigError) as info:
        load_dialect("nonesuch")
    assert str(info.value) == "nonesuch: no such dialect file or shipped name (shipped: fanuc, linuxcnc)"


# ----------------------------------------------------------------------------- whole programs

LINUXCNC_DRILL = """\
(tool: T1 6 mm drill)
(machine: patel2020)
(part: wedge.stl)
(units: mm)
(axes: X Y = stage X Y mm, U V W = actuator strokes T1 T2 T3 mm)
(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)
G17 G21 G40 G49 G54 G80 G90 G94
G61
(6 mm drill [HSS])
T1 M6
S3000 M3
M7
G0 X-2.7639 Y12.0703 U30.0000 V160.0000 W80.0000
G0 U38.0978 V169.9648 W81.7195
(hole 1 at 26.6 deg)
G93
G1 U41.0978 V172.9648 W84.7195 F100.0000
G1 F12.5000
G4 P0.500
G0 X0.0000 Y0.0000 U30.0000 V160.0000 W80.0000
M5
M9
G94
M2
"""

FANUC_DRILL = """\
%
O1000 (PRS3-POST)
(TOOL: T1 6 MM DRILL)
(MACHINE: PATEL2020)
(PART: WEDGE.STL)
(UNITS: MM)
(AXES: X Y = STAGE X Y MM, U V W = ACTUATOR STROKES T1 T2 T3 MM)
(MOTION: JOINT SPACE, G1 FEED IN G93 INVERSE TIME, F = 1 / MOVE TIME IN MIN)
N10 G17 G21 G40 G49 G54 G80 G90 G94
N20 G61
(6 MM DRILL [HSS])
N30 T1 M6
N40 S3000 M3
N50 M7
N60 G0 X-2.764 Y12.070 U30.000 V160.000 W80.000
N70 U38.098 V169.965 W81.719
(HOLE 1 AT 26.6 DEG)
N80 G93
N90 G1 U41.098 V172.965 W84.719 F100.0000
N100 W84.720 F12.5000
N110 G4 P500
N120 G0 X0.000 Y0.000 U30.000 V160.000 W80.000
N130 M5
N140 M9
N150 G94
N160 M30
%
"""


def test_linuxcnc_program(linuxcnc: Dialect, tmp_path: Path) -> None:
    assert _emit(_drill(), linuxcnc, tmp_path, header=HEADER) == LINUXCNC_DRILL


def test_fanuc_program(fanuc: Dialect, tmp_path: Path) -> None:
    # Modal G0/G1, N numbers, 3 decimals (84.7195 -> 84.719 but 84.71951 -> 84.720), dwell in ms.
    assert _emit(_drill(), fanuc, tmp_path, header=HEADER) == FANUC_DRILL


def test_empty_program(linuxcnc: Dialect, tmp_path: Path) -> None:
    empty = _program([], [], [], [])
    assert _emit(empty, linuxcnc, tmp_path) == (
        "(axes: X Y = stage X Y mm, U V W = actuator strokes T1 T2 T3 mm)\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\n"
        "G61\n"
        "M2\n"
    )


def test_words_omitted_on_formatted_text(linuxcnc: Dialect, tmp_path: Path) -> None:
    # Row 1: X 1.00004 prints as X1.0000 (changed), Y -0.00004 as Y0.0000 (unchanged), T1 10.00001
    # as U10.0000 (unchanged). Row 2: every float differs from row 1 but only W's text does.
    program = _program(
        kind=[R, F, F, F],
        stage=[[0, 0], [1.00004, -0.00004], [0.99996, 0.00004], [0.99994, 0]],
        strokes=[[10, 20, 30], [10.00001, 20, 30], [10, 19.99996, 30.00005], [10, 20, 30]],
        inverse_time=[0, 5, 5, 5],
    )
    assert _emit(program, linuxcnc, tmp_path) == (
        "(axes: X Y = stage X Y mm, U V W = actuator strokes T1 T2 T3 mm)\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\n"
        "G61\n"
        "G0 X0.0000 Y0.0000 U10.0000 V20.0000 W30.0000\n"
        "G93\n"
        "G1 X1.0000 F5.0000\n"
        "G1 W30.0001 F5.0000\n"
        "G1 X0.9999 W30.0000 F5.0000\n"
        "G94\n"
        "M2\n"
    )


def test_f_on_every_feed_move(linuxcnc: Dialect, fanuc: Dialect, tmp_path: Path) -> None:
    # Same inverse time on every row, and rows whose words do not change: F is still on every G1.
    n = 7
    program = _program(
        kind=[R] + [F] * n,
        stage=[[0, 0]] * (n + 1),
        strokes=[[10, 20, 30]] + [[10, 20, 30 + (i // 2)] for i in range(n)],
        inverse_time=[0] + [7.25] * n,
    )
    for dialect in (linuxcnc, fanuc):
        text = _emit(program, dialect, tmp_path)
        motion = [line for line in text.splitlines() if "F" in line.split("(")[0]]
        assert len(motion) == n
        assert all(line.split()[-1] == "F7.2500" for line in motion)


def test_no_stage_modal_numbering_and_stop(linuxcnc: Dialect, tmp_path: Path) -> None:
    # A pure head: X/Y never written. Modal G0/G1, numbering switched on from the caller with
    # its own start/step, wrapping after N130 back to that start. After M0 every word again.
    dialect = dataclasses.replace(
        linuxcnc, modal_motion=True, line_numbers=dataclasses.replace(linuxcnc.line_numbers, wrap_after=130)
    )
    program = _program(
        kind=[R, F, F, R, R, F],
        stage=[[0, 0]] * 6,
        strokes=[[1, 2, 3], [1, 2, 4], [1, 2, 5], [1, 2, 3], [1, 2, 3], [1, 2, 4]],
        inverse_time=[0, 2, 2, 0, 0, 0.5],
        events=(
            Event(4, EventKind.STOP),
            Event(4, EventKind.COMMENT, 0, "turn the part (face B) now)\n(then press cycle start"),
        ),
    )
    text = _emit(
        program, dialect, tmp_path, stage=False, line_numbers=True, line_start=100, line_step=5,
        header=(("machine", "patel2020-head"),),
    )
    assert text == (
        "(machine: patel2020-head)\n"
        "(axes: U V W = actuator strokes T1 T2 T3 mm, no stage)\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\n"
        "N100 G17 G21 G40 G49 G54 G80 G90 G94\n"
        "N105 G61\n"
        "N110 G0 U1.0000 V2.0000 W3.0000\n"
        "N115 G93\n"
        "N120 G1 W4.0000 F2.0000\n"
        "N125 W5.0000 F2.0000\n"
        "N130 G0 W3.0000\n"
        "N100 M0\n"
        "(turn the part [face B] now] [then press cycle start)\n"
        "N105 G0 U1.0000 V2.0000 W3.0000\n"
        "N110 G1 W4.0000 F0.5000\n"
        "N115 G94\n"
        "N120 M2\n"
    )


def test_line_numbers_off_override(fanuc: Dialect, tmp_path: Path) -> None:
    program = _program([R], [[1, 2]], [[3, 4, 5]], [0])
    assert _emit(program, fanuc, tmp_path, line_numbers=False) == (
        "%\n"
        "O1000 (PRS3-POST)\n"
        "(AXES: X Y = STAGE X Y MM, U V W = ACTUATOR STROKES T1 T2 T3 MM)\n"
        "(MOTION: JOINT SPACE, G1 FEED IN G93 INVERSE TIME, F = 1 / MOVE TIME IN MIN)\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\n"
        "G61\n"
        "G0 X1.000 Y2.000 U3.000 V4.000 W5.000\n"
        "M30\n"
        "%\n"
    )


def test_custom_letters_blocks_and_crlf(linuxcnc: Dialect, tmp_path: Path) -> None:
    dialect = dataclasses.replace(
        linuxcnc,
        axes=dataclasses.replace(linuxcnc.axes, t1="A", t2="B", t3="C"),
        line_ending="\r\n",
        preamble=("G43 H1",),
        postamble=("G0 X0 Y0",),
        end_code="M30",
        percent=True,
    )
    program = _program([R, F], [[0, 0], [0, 1]], [[1, 2, 3], [1, 2, 3]], [0, 60])
    assert _emit(program, dialect, tmp_path) == (
        "%\r\n"
        "(axes: X Y = stage X Y mm, A B C = actuator strokes T1 T2 T3 mm)\r\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\r\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\r\n"
        "G61\r\n"
        "G43 H1\r\n"
        "G0 X0.0000 Y0.0000 A1.0000 B2.0000 C3.0000\r\n"
        "G93\r\n"
        "G1 Y1.0000 F60.0000\r\n"
        "G94\r\n"
        "G0 X0 Y0\r\n"
        "M30\r\n"
        "%\r\n"
    )


def test_interpreter_sees_the_joint_values(linuxcnc: Dialect, tmp_path: Path) -> None:
    """LinuxCNC's canonical calls carry the programmed end points and feed in G93 on every G1."""
    program = _drill()
    path = tmp_path / "drill.ngc"
    path.write_text(emit_program(program, linuxcnc), encoding="ascii")
    result = _rs274(path, "XYUVW", "--canon", "-")
    assert result.returncode == 0, result.stderr
    moves = []
    for line in result.stdout.splitlines():
        _, call, *fields = line.split()
        if call in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            words = dict(f.split("=") for f in fields)
            moves.append((call, [float(words[a]) for a in "XYUVW"], words.get("MODE")))
    assert [(call, mode) for call, _, mode in moves] == [
        ("STRAIGHT_TRAVERSE", None), ("STRAIGHT_TRAVERSE", None),
        ("STRAIGHT_FEED", "G93"), ("STRAIGHT_FEED", "G93"), ("STRAIGHT_TRAVERSE", None),
    ]
    joints = np.hstack([program.stage, program.strokes])
    assert_allclose(np.array([m[1] for m in moves]), joints, rtol=0, atol=5e-5)


# ----------------------------------------------------------------------------- comments


def test_sanitize_comment(linuxcnc: Dialect, fanuc: Dialect) -> None:
    text = "a) (b\nc\td\r\x7f\x85é° 5% µm ±1"
    # \r, DEL and the C1 control \x85 are controls (space); é is not ASCII (?); ° µ ± are mapped.
    assert sanitize_comment(text, linuxcnc.comments) == "a] [b c d   ? deg 5% um +/-1"
    assert sanitize_comment(text, fanuc.comments) == "A] [B C D   ? DEG 5 PCT UM +/-1"


def test_comment_cannot_close_early(linuxcnc: Dialect, tmp_path: Path) -> None:
    # Without sanitizing, ") G0 X500" would end the comment and move X.
    program = _program(
        [R], [[0, 0]], [[1, 2, 3]], [0],
        events=(Event(1, EventKind.COMMENT, 0, "done) G0 X500 (\nM30"),),
    )
    assert _emit(program, linuxcnc, tmp_path, header=(("part", "a)b(c.stl"),)) == (
        "(part: a]b[c.stl)\n"
        "(axes: X Y = stage X Y mm, U V W = actuator strokes T1 T2 T3 mm)\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\n"
        "G61\n"
        "G0 X0.0000 Y0.0000 U1.0000 V2.0000 W3.0000\n"
        "(done] G0 X500 [ M30)\n"
        "M2\n"
    )


def test_long_comments_are_split(linuxcnc: Dialect, tmp_path: Path) -> None:
    words = "depth=5 " * 40  # 320 characters with spaces
    name = "x" * 300 + ".stl"  # no space to break at
    program = _program([R], [[0, 0]], [[1, 2, 3]], [0])
    text = _emit(program, linuxcnc, tmp_path, header=(("parameters", words.strip()), ("part", name)))
    # 250 characters of text fit between "(" and ")"; continuation lines are indented by two spaces.
    assert text == (
        "(parameters: " + "depth=5 " * 28 + "depth=5)\n"
        "(  " + "depth=5 " * 10 + "depth=5)\n"
        "(part: " + "x" * 244 + ")\n"
        "(  " + "x" * 56 + ".stl)\n"
        "(axes: X Y = stage X Y mm, U V W = actuator strokes T1 T2 T3 mm)\n"
        "(motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min)\n"
        "G17 G21 G40 G49 G54 G80 G90 G94\n"
        "G61\n"
        "G0 X0.0000 Y0.0000 U1.0000 V2.0000 W3.0000\n"
        "M2\n"
    )
    assert max(len(line) for line in text.splitlines()) == 252


def test_long_comment_crlf_fits_251(linuxcnc: Dialect, tmp_path: Path) -> None:
    dialect = dataclasses.replace(linuxcnc, line_ending="\r\n")
    program = _program([], [], [], [], events=(Event(0, EventKind.COMMENT, 0, "y" * 260),))
    text = _emit(program, dialect, tmp_path)
    lines = text.split("\r\n")
    assert lines[2:] == [
        "G17 G21 G40 G49 G54 G80 G90 G94", "G61", "(" + "y" * 249 + ")", "(  " + "y" * 11 + ")", "M2", ""
    ]


# ----------------------------------------------------------------------------- errors


def _error(program: JointProgram, dialect: Dialect, kind: type[Exception] = LimitError, **kwargs) -> str:
    with pytest.raises(kind) as info:
        emit_program(program, dialect, **kwargs)
    return str(info.value)


LABELS = ("hole 1 approach", "hole 1 feed")


def test_inverse_time_that_prints_as_zero(linuxcnc: Dialect) -> None:
    program = _program([R, F], [[0, 0]] * 2, [[1, 2, 3], [1, 2, 4]], [0, 0.00004], [0, 1], labels=LABELS)
    assert _error(program, linuxcnc) == (
        "row 1 from hole 1 feed: inverse-time feed 4e-05 /min formats to F0.0000 with "
        "decimals.inverse_time = 4 (the move would take 25000 min); "
        "LinuxCNC would raise F0 to 0.1 and run the move at another feed"
    )


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_inverse_time_not_positive(linuxcnc: Dialect, value: float) -> None:
    program = _program([R, F], [[0, 0]] * 2, [[1, 2, 3], [1, 2, 4]], [0, value], [7, 9])
    assert _error(program, linuxcnc) == (
        f"row 1 from line 9: inverse-time feed must be a finite number > 0 /min, got {value!r}"
    )


def test_rapid_ignores_inverse_time(linuxcnc: Dialect, tmp_path: Path) -> None:
    program = _program([R], [[0, 0]], [[1, 2, 3]], [float("nan")])
    assert _emit(program, linuxcnc, tmp_path).splitlines()[-2] == "G0 X0.0000 Y0.0000 U1.0000 V2.0000 W3.0000"


def test_huge_finite_values_are_not_taken_for_non_finite(linuxcnc: Dialect) -> None:
    """The finiteness check sums each array first: a sum that overflows (two values of 1.5e308) is
    not an error, the values are written (as Python formats them)."""
    dialect = replace(linuxcnc, max_line_length=400)
    program = _program([R, F], [[1.5e308, 0], [1.5e308, 1]], [[1, 2, 3]] * 2, [0, 2.0])
    motion = [line for line in emit_program(program, dialect).splitlines() if line.startswith(("G0 ", "G1 "))]
    assert motion == [f"G0 X{1.5e308:.4f} Y0.0000 U1.0000 V2.0000 W3.0000", "G1 Y1.0000 F2.0000"]


def test_non_finite_axis(linuxcnc: Dialect) -> None:
    program = _program([R, F], [[0, 0]] * 2, [[1, 2, 3], [1, np.nan, 4]], [0, 1], [0, 1], labels=LABELS)
    assert _error(program, linuxcnc) == "row 1 from hole 1 feed: actuator stroke T2 (V) is nan, not a finite number"
    program = _program([R], [[np.inf, 0]], [[1, 2, 3]], [0], [4])
    assert _error(program, linuxcnc) == "row 0 from line 4: stage X (X) is inf, not a finite number"


def test_stage_on_a_machine_without_one(linuxcnc: Dialect) -> None:
    program = _program([R, R], [[0, -0.00004], [0, 0.2]], [[1, 2, 3]] * 2, [0, 0], [0, 1], labels=LABELS)
    assert _error(program, linuxcnc, stage=False) == (
        "row 1 from hole 1 feed: stage Y is 0.2000 mm on a machine without a stage"
    )


def test_line_too_long(linuxcnc: Dialect) -> None:
    # A value no limit check would pass, but the emitter must still never write an over-long block.
    program = _program([R], [[1e250, 0]], [[1, 2, 3]], [0], [3])
    digits = f"{1e250:.4f}"  # 250 digits (1e250 is 9.99...e249 in binary), the point and 4 decimals
    assert len(digits) == 255
    assert _error(program, linuxcnc) == (
        "row 0 from line 3: the block is 291 characters, the dialect allows 252: G0 X" + digits[:56] + "..."
    )


SPINDLE = "spindle speed must be > 0 rpm once printed with decimals.spindle = 0, got"
TOOL = "tool number must be a whole number 0..99999 (words.tool_number_max), got"


@pytest.mark.parametrize(
    ("event", "message"),
    [
        (Event(0, EventKind.SPINDLE_ON, -100), f"spindle_on event before row 0 from hole 1 approach: {SPINDLE} -100.0"),
        (Event(0, EventKind.SPINDLE_ON, 0.4), f"spindle_on event before row 0 from hole 1 approach: {SPINDLE} 0.4"),
        (Event(1, EventKind.SPINDLE_ON, np.nan), f"spindle_on event before row 1 from hole 1 feed: {SPINDLE} nan"),
        (Event(2, EventKind.TOOL_CHANGE, 1.5), f"tool_change event after the last row: {TOOL} 1.5"),
        (Event(2, EventKind.TOOL_CHANGE, -1), f"tool_change event after the last row: {TOOL} -1.0"),
        (Event(2, EventKind.TOOL_CHANGE, 100000), f"tool_change event after the last row: {TOOL} 100000.0"),
        (Event(2, EventKind.TOOL_CHANGE, 1e20), f"tool_change event after the last row: {TOOL} 1e+20"),
        (
            Event(1, EventKind.DWELL, -0.5),
            "dwell event before row 1 from hole 1 feed: dwell must be a finite number ≥ 0 s, got -0.5",
        ),
    ],
)
def test_bad_event_values(linuxcnc: Dialect, event: Event, message: str) -> None:
    program = _program([R, F], [[0, 0]] * 2, [[1, 2, 3], [1, 2, 4]], [0, 1], [0, 1], [event], LABELS)
    assert _error(program, linuxcnc) == message


def test_caller_mistakes(linuxcnc: Dialect) -> None:
    program = _program([R], [[0, 0]], [[1, 2, 3]], [0], events=[Event(2, EventKind.STOP)])
    assert _error(program, linuxcnc, ValueError) == "stop event: before = 2 is outside 0..1"
    program = _program([2], [[0, 0]], [[1, 2, 3]], [0])
    assert _error(program, linuxcnc, ValueError) == "row 0: kind 2 is not a MoveKind"
    program = _program([R], [[0, 0]], [[1, 2, 3]], [0])
    assert _error(program, linuxcnc, ValueError, line_start=100000) == "line_start must be 0..99999, got 100000"
    assert _error(program, linuxcnc, ValueError, line_step=0) == "line_step must be ≥ 1, got 0"


def test_comments_the_controller_would_act_on_stay_plain_comments(tmp_path):
    """LinuxCNC pops up (MSG, ...) and acts on DEBUG, PRINT, LOG...; text from outside must not do that."""
    import subprocess

    dialect = load_dialect("linuxcnc")
    long_text = "x" * 246 + " msg, split onto the next line"        # wraps right before "msg,"
    program = JointProgram(
        kind=np.array([MoveKind.RAPID]), stage=np.zeros((1, 2)), strokes=np.zeros((1, 3)),
        inverse_time=np.zeros(1), source=np.zeros(1, dtype=np.int64),
        events=(Event(0, EventKind.COMMENT, text=" MSG, stop here"), Event(0, EventKind.COMMENT, text=long_text),
                Event(1, EventKind.COMMENT, text="debug,#<x>")),
    )
    text = emit_program(program, dialect)
    comments = [line for line in text.splitlines() if line.startswith("(")]
    assert "( MSG. stop here)" in comments and "(debug.#<x>)" in comments
    assert "(  msg. split onto the next line)" in comments      # the continuation line is guarded too
    assert all(len(line) <= 252 for line in text.splitlines())
    if _rs274_missing():
        _unavailable(_rs274_missing())
    path = tmp_path / "comments.ngc"
    path.write_text(text)
    canon = subprocess.run([sys.executable, str(RS274_CHECK), "-a", "XYUVW", "--canon", "-", str(path)],
                           capture_output=True, text=True, check=False)
    assert canon.returncode == 0, canon.stdout + canon.stderr
    assert "MESSAGE" not in canon.stdout


# ----------------------------------------------------------------------------- chunks and the column formatter


def _chunks(program: JointProgram, size: int) -> list[JointProgram]:
    """``program`` cut into chunks of ``size`` rows; an event goes with the row it comes before
    (events after the last row with the last chunk)."""
    n = len(program)
    out = []
    for lo in range(0, max(n, 1), size):
        hi = min(n, lo + size)
        last = hi == n
        out.append(JointProgram(
            kind=program.kind[lo:hi], stage=program.stage[lo:hi], strokes=program.strokes[lo:hi],
            inverse_time=program.inverse_time[lo:hi], source=program.source[lo:hi],
            events=tuple(replace(e, before=e.before - lo) for e in program.events
                         if lo <= e.before < hi or (last and e.before == n)),
            source_labels=program.source_labels,
        ))
    return out


def _random_program(seed: int, n: int = 200) -> JointProgram:
    """Rows that repeat values (so that words are left out), change kind, stop and change tools."""
    rng = np.random.default_rng(seed)
    kind = rng.integers(0, 2, n)
    values = np.round(rng.uniform(-300, 300, (n, 5)), rng.integers(2, 6))
    values[rng.random((n, 5)) < 0.4] = 0.0
    repeat = rng.random(n) < 0.3
    for row in np.flatnonzero(repeat[1:]) + 1:
        values[row] = values[row - 1]
    events = [Event(int(b), EventKind(k), 2.0, "x") for b, k in zip(
        rng.integers(0, n + 1, 12), rng.choice(["stop", "tool_change", "comment", "dwell", "coolant_off"], 12),
        strict=True)]
    return _program(kind, values[:, :2], values[:, 2:], rng.uniform(0.5, 50.0, n), events=events)


@pytest.mark.parametrize("size", [1, 2, 7, 10_000])
@pytest.mark.parametrize("dialect_name", ["linuxcnc", "fanuc"])
def test_emitter_in_chunks_is_byte_identical(size: int, dialect_name: str) -> None:
    dialect = load_dialect(dialect_name)
    for program, stage in [(_drill(), True), (_random_program(1), True), (_random_program(2), True),
                           (_program([R, F, F], [[0, 0]] * 3, [[1, 2, 3], [1, 2, 3], [1, 2, 4]], [0, 1, 1]), False)]:
        whole = emit_program(program, dialect, header=HEADER, stage=stage, line_numbers=True, line_start=99990)
        emitter = ProgramEmitter(dialect, stage=stage, line_numbers=True, line_start=99990)
        pieces = [emitter.begin(HEADER), *(emitter.rows(chunk) for chunk in _chunks(program, size)), emitter.end()]
        assert "".join(pieces) == whole


def test_emitter_blocks_within_a_chunk(monkeypatch, linuxcnc: Dialect) -> None:
    """Long chunks are formatted CHUNK_ROWS rows at a time: the text is the same."""
    program = _random_program(3, 500)
    whole = emit_program(program, linuxcnc)
    monkeypatch.setattr(gcode, "CHUNK_ROWS", 3)
    assert emit_program(program, linuxcnc) == whole


def _reference_motion(program: JointProgram, dialect: Dialect, numbered: bool) -> list[str]:
    """The motion lines, one row at a time with format_word (a program without events)."""
    ax = dialect.axes
    columns = [[format_word(letter, v, dialect.decimals.length) for v in values.tolist()]
               for letter, values in [(ax.x, program.stage[:, 0]), (ax.y, program.stage[:, 1]),
                                      (ax.t1, program.strokes[:, 0]), (ax.t2, program.strokes[:, 1]),
                                      (ax.t3, program.strokes[:, 2])]]
    lines, last, last_kind, number, g93 = [], [None] * 5, None, dialect.line_numbers.start, False
    for row, kind in enumerate(program.kind.tolist()):
        parts = []
        if kind == MoveKind.FEED and not g93:
            lines.append("G93")
            g93 = True
        words = [column[row] for j, column in enumerate(columns) if column[row] != last[j]]
        last = [column[row] for column in columns]
        if not dialect.modal_motion or kind != last_kind or not words:
            parts.append("G1" if kind == MoveKind.FEED else "G0")
        parts += words
        if kind == MoveKind.FEED:
            parts.append(format_word("F", float(program.inverse_time[row]), dialect.decimals.inverse_time))
        last_kind = kind
        lines.append(" ".join(parts))
    if numbered:
        for i, line in enumerate(lines):
            lines[i] = f"N{number} {line}"
            number = number + dialect.line_numbers.step
    return lines


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), decimals=st.integers(1, 6), modal=st.booleans(), numbered=st.booleans())
def test_motion_lines_match_a_row_by_row_reference(seed: int, decimals: int, modal: bool, numbered: bool) -> None:
    base = load_dialect("linuxcnc")
    dialect = replace(base, decimals=replace(base.decimals, length=decimals), modal_motion=modal)
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 60))
    # values on and near the rounding ties of the chosen decimals, repeated often
    ties = (rng.integers(-10**6, 10**6, (n, 5)) + 0.5) / 10**decimals
    values = np.where(rng.random((n, 5)) < 0.5, ties, np.round(rng.uniform(-400, 400, (n, 5)), decimals + 1))
    values[rng.random((n, 5)) < 0.3] = -0.0
    program = _program(rng.integers(0, 2, n), values[:, :2], values[:, 2:], rng.uniform(0.01, 99.0, n))
    emitter = ProgramEmitter(dialect, line_numbers=numbered)
    got = emitter.rows(program).splitlines()
    assert got == _reference_motion(program, dialect, numbered)


# ----------------------------------------------------------------------------- long comments


@settings(max_examples=1000, deadline=None)
@given(text=st.text(alphabet="ab -", max_size=400), width=st.integers(min_value=1, max_value=40))
def test_comment_wrapping_is_textwraps(text: str, width: int) -> None:
    """The wrapping of long comments cuts a long word in one pass: the same lines as textwrap.wrap."""
    import textwrap

    expected = textwrap.wrap(text, width=width, subsequent_indent=gcode._CONTINUATION, break_on_hyphens=False)
    assert gcode.wrap_comment(text, width) == expected


def test_a_comment_of_megabytes_is_wrapped_in_linear_time() -> None:
    """textwrap cuts one line off a word longer than a line per pass and copies the rest: a 20 MB CAM comment (one
    word) took some 20 s, 50 MB minutes (convert looked hung)."""
    import time

    word = "x" * 20_000_000
    start = time.process_time()
    lines = gcode.wrap_comment(word, 250)
    assert time.process_time() - start < 5.0
    assert (len(lines), lines[0], lines[1]) == (-(-(20_000_000 - 250) // 248) + 1, "x" * 250, "  " + "x" * 248)
    assert "".join(line.lstrip(" ") for line in lines) == word
