"""Never write a program the controller rejects (issue 7 section 4).

* Tool numbers are bounded by the dialect (``words.tool_number_max``); LinuxCNC reads T2147483648
  and above as "Negative tool id", and the float of a tool-change event garbles far larger ones.
* Every G1 moves at least one axis by at least one output unit: points and depth passes closer
  than what the output can show are merged, so there is no G1 without an axis word, no duplicate
  lap, no 1e-5 mm plunge printed as a sideways move; and every G1's F still gives the requested tip feed.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from prs3_post.app.job import JobResult, run_job
from prs3_post.check.verify import Intended, verify_program
from prs3_post.cli.main import main
from prs3_post.cli.options import demo_part, error_text
from prs3_post.cli.run import demo
from prs3_post.cli.run import job_spec as _job_spec
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE
from prs3_post.core.errors import ConfigError, FeatureError, Prs3Error
from prs3_post.core.numbers import format_word
from prs3_post.core.toolpath import MoveKind
from prs3_post.machine.controller_rules import block_problem
from prs3_post.machine.loading import Dialect, load_dialect, load_machine
from prs3_post.post.visible_moves import visible_moves
from prs3_post.readers.program import read_program
from prs3_post.toolpaths.common import pass_depths

REPO = Path(__file__).resolve().parents[2]


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


# ----------------------------------------------------------------------------- tool numbers


def _dialect_with_tool_max(tmp_path: Path, top: int) -> Path:
    text = (REPO / "postproc" / "dialects" / "linuxcnc.toml").read_text(encoding="utf-8")
    assert text.count("tool_number_max = 99999\n") == 1
    path = tmp_path / "small-tools.toml"
    path.write_text(text.replace("tool_number_max = 99999\n", f"tool_number_max = {top}\n"), encoding="utf-8")
    return path


@pytest.mark.parametrize(("extra", "message"), [
    ([], "must be 1..99999 with dialect linuxcnc (its words.tool_number_max), got 100000000000000000000"),
    (["--dialect", "fanuc"], "must be 1..99999 with dialect fanuc (its words.tool_number_max), "
                             "got 100000000000000000000"),
])
def test_a_tool_number_beyond_the_dialect_is_a_usage_error(tmp_path, extra, message):
    out = tmp_path / "p.ngc"
    result = invoke("demo", "--profile", "hole", "--tool-number", "100000000000000000000", *extra, "-o", str(out))
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == f"Error: Invalid value for '--tool-number': {message}"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("number", ["0", "-3", "100000"])
def test_both_bounds_of_the_tool_number_say_the_same(tmp_path, number):
    out = tmp_path / "p.ngc"
    result = invoke("demo", "--profile", "hole", "--tool-number", number, "-o", str(out))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == ("Error: Invalid value for '--tool-number': must be 1..99999 with dialect "
                                              f"linuxcnc (its words.tool_number_max), got {number}")
    assert list(tmp_path.iterdir()) == []


def test_the_dialect_sets_the_largest_tool_number(tmp_path):
    dialect = _dialect_with_tool_max(tmp_path, 9)
    out = tmp_path / "p.ngc"
    refused = invoke("demo", "--profile", "hole", "--tool-number", "10", "--dialect", str(dialect), "-o", str(out))
    assert (refused.exit_code, refused.stderr.splitlines()[-1]) == (
        2, "Error: Invalid value for '--tool-number': must be 1..9 with dialect small-tools (its "
           "words.tool_number_max), got 10")
    assert not out.exists()
    accepted = invoke("demo", "--profile", "hole", "--tool-number", "9", "--dialect", str(dialect), "-o", str(out))
    assert accepted.exit_code == 0, accepted.stderr
    assert [line for line in out.read_text().splitlines() if line.endswith("M6")] == ["T9 M6"]


def test_the_largest_tool_number_passes_linuxcnc(tmp_path, rs274_check):
    out = tmp_path / "p.ngc"
    assert invoke("demo", "--profile", "hole", "--tool-number", "99999", "-o", str(out)).exit_code == 0
    assert [line for line in out.read_text().splitlines() if line.endswith("M6")] == ["T99999 M6"]
    table = tmp_path / "tools.tbl"
    table.write_text("T99999 P1 D6 ;\n", encoding="ascii")
    code, report = rs274_check(out, "--tool-table", str(table))
    assert code == 0, report


# ----------------------------------------------------------------------------- every G1 moves


def _g1_lines_that_move_nothing(text: str, dialect: Dialect) -> list[str]:
    """The G1 blocks whose axis words all repeat the axes' last values (or that have none).

    Tracks the modal G0/G1 (Fanuc-style dialects write it only where it changes) and the last
    value written for each axis letter; comments and block numbers are left out.
    """
    ax = dialect.axes
    letters = {ax.x, ax.y, ax.t1, ax.t2, ax.t3}
    last: dict[str, float] = {}
    mode = ""
    idle = []
    for line in text.splitlines():
        words = [w for w in re.sub(r"\([^)]*\)", " ", line).split() if not w.startswith("N")]
        mode = next((w for w in reversed(words) if w in ("G0", "G1")), mode)
        axes = {w[0]: float(w[1:]) for w in words if w[0] in letters}
        motion = bool(axes) or "G0" in words or "G1" in words
        if motion and mode == "G1" and all(last.get(letter) == value for letter, value in axes.items()):
            idle.append(line)
        last.update(axes)
    return idle


def test_the_idle_g1_finder_finds_them() -> None:
    dialect = load_dialect("fanuc")
    text = "N10 G0 X1.000 U2.000\nN20 G1 U2.001 F3.0\nN30 U2.001 F4.0\nN40 G1 F5.0\nN50 G0 X1.000\nN60 W1.000 F1\n"
    assert _g1_lines_that_move_nothing(text, dialect) == ["N30 U2.001 F4.0", "N40 G1 F5.0"]


def _job(args: list[str]) -> tuple[JobResult, Dialect]:
    """Run the main job on the demo part with these options, in process (as `prs3-post demo` does)."""
    opts = demo.make_context("demo", [*args]).params
    spec = _job_spec(str(demo_part()), opts)
    return run_job(spec), spec.dialect


def _feed_problems(result: JobResult, dialect: Dialect, machine_name: str = "patel2020") -> list[str]:
    """What `verify --against` says about the feeds: each G1's implied tip feed (the chord between
    its printed end points × F) against the feed the job asked for, within what the rounding allows."""
    program = read_program(result.text, dialect, path="<program>")
    path = result.post.path
    intended = Intended(tip=path.tip, axis=path.axis, feed=np.where(path.kind == MoveKind.FEED, path.feed, np.nan),
                        kind=path.kind, label="job")
    report = verify_program(load_machine(machine_name), program.moves, setup=result.setup, intended=intended,
                            length_decimals=dialect.decimals.length, feed_decimals=dialect.decimals.inverse_time,
                            tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE)
    return [p.message for p in (*report.problems, *report.warnings) if p.kind == "feed"]


#: Found by an independent sweep of random jobs: each wrote a G1 that moves nothing the program shows.
REPROS = {
    "round-ramp-vertex": ["--profile", "round", "--diameter", "30", "--depth", "1", "--step-down", "1",
                          "--ramp-angle", "2.9308158971662404"],
    "square-duplicate-lap": ["--profile", "square", "--depth", "2.00001", "--step-down", "1", "--entry", "plunge"],
    "hole-sideways-plunge": ["--profile", "hole", "--depth", "2.00001", "--peck", "1", "--reapproach-gap", "0"],
}


@pytest.mark.parametrize("args", REPROS.values(), ids=REPROS.keys())
def test_sub_resolution_moves_are_merged(tmp_path, rs274_check, args):
    result, dialect = _job(args)
    assert _g1_lines_that_move_nothing(result.text, dialect) == []
    assert _feed_problems(result, dialect) == []
    out = tmp_path / "p.ngc"
    out.write_text(result.text, encoding="ascii")
    code, report = rs274_check(out)
    assert code == 0, report


def test_a_depth_pass_closer_than_the_resolution_merges_into_the_last() -> None:
    square, _ = _job(REPROS["square-duplicate-lap"])
    passes = [e.text for e in square.path_part.events if e.text.startswith("square pass")]
    assert passes == ["square pass 1/2 at depth 1.000 mm", "square pass 2/2 at depth 2.000 mm"]
    hole, _ = _job(REPROS["hole-sideways-plunge"])
    assert hole.path_part.source_labels[1:-1] == (
        "hole 1 peck 1 feed", "hole 1 peck 1 clear", "hole 1 peck 2 reapproach", "hole 1 peck 2 feed")


def test_the_pipeline_drops_rows_that_print_no_move() -> None:
    # A clearance below the resolution: the feed down to the face would print no word at all. A request
    # refuses it (issue 20 §3: one rule for every length below the resolution); the library's pipeline,
    # given one, drops the rows it cannot show.
    with pytest.raises(click.BadParameter, match="below the program's resolution"):
        _job(["--profile", "round", "--clearance", "0.00003", "--retract", "0.00003"])
    opts = demo.make_context("demo", ["--profile", "round"]).params
    spec = _job_spec(str(demo_part()), opts)
    work = dataclasses.replace(spec.work, params=dataclasses.replace(spec.work.params, clearance=0.00003,
                                                                     retract=0.00003))
    result, dialect = run_job(dataclasses.replace(spec, work=work)), spec.dialect
    labels = [result.post.path.describe(r) for r in range(len(result.post.path))]
    assert labels[:3] == ["round approach", "round pass 1/2 ramp", "round pass 1/2 ramp"]
    assert _g1_lines_that_move_nothing(result.text, dialect) == []


def _tiny_or(low: float, high: float) -> st.SearchStrategy[float]:
    """Values in [low, high], and ones just past a whole multiple (the slivers a sweep finds)."""
    return st.one_of(st.floats(low, high), st.integers(1, 4).map(lambda k: k + 1e-5), st.just(1e-3))


@st.composite
def _job_args(draw: st.DrawFn) -> list[str]:
    """Random valid main-job options for the demo part (sizes that fit its face)."""
    profile = draw(st.sampled_from(["hole", "square", "round"]))
    clearance = draw(st.one_of(st.floats(1e-3, 5.0), st.just(1e-3)))   # from the resolution (fanuc's: 0.001)
    retract = clearance + draw(st.one_of(st.just(0.0), st.floats(0.0, 10.0)))
    args = ["--profile", profile, "--depth", repr(draw(_tiny_or(1e-3, 6.0))),
            "--clearance", repr(clearance), "--retract", repr(retract),
            "--feed", repr(draw(st.floats(1.0, 5000.0))), "--plunge-feed", repr(draw(st.floats(1.0, 2000.0))),
            "--dialect", draw(st.sampled_from(["linuxcnc", "fanuc"]))]
    if profile == "hole":
        peck = draw(st.one_of(st.just(0.0), st.floats(0.5, 3.0), st.just(1.0)))
        gap = draw(st.one_of(st.just(0.0), st.floats(1e-3, 0.999 * peck))) if peck else 0.5
        return [*args, "--peck", repr(peck), "--reapproach-gap", repr(gap)]
    args += ["--step-down", repr(draw(st.one_of(st.floats(0.3, 3.0), st.just(1.0)))),
             "--entry", draw(st.sampled_from(["ramp", "plunge"])), "--ramp-angle", repr(draw(st.floats(0.5, 30.0))),
             "--direction", draw(st.sampled_from(["climb", "conventional"])),
             "--side", draw(st.sampled_from(["on", "outside"]))]
    if profile == "square":
        size = draw(st.floats(8.0, 40.0))
        corner = draw(st.one_of(st.just(0.0), st.just(1e-3), st.floats(1e-3, size / 2)))
        return [*args, "--size", repr(size), "--corner-radius", repr(corner),
                "--rotation", repr(draw(st.floats(-90, 90)))]
    return [*args, "--diameter", repr(draw(st.floats(1e-3, 40.0)))]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(args=_job_args())
@example(args=REPROS["round-ramp-vertex"])
@example(args=["--profile", "round", "--clearance", "0.001", "--retract", "0.001", "--dialect", "fanuc"])
def test_every_g1_moves_a_word_and_keeps_its_feed(args: list[str]) -> None:
    try:
        result, dialect = _job(args)
    except Prs3Error:                   # refused (a tool too large for the round, ...): nothing written
        return
    assert _g1_lines_that_move_nothing(result.text, dialect) == []
    assert _feed_problems(result, dialect) == []


def _words_oracle(joints: np.ndarray, decimals: int) -> list[bool]:
    """Every row formatted and compared with the last kept one, in a plain loop."""
    keep, last = [True], [format_word("", v, decimals) for v in joints[0]]
    for row in joints[1:]:
        words = [format_word("", v, decimals) for v in row]
        keep.append(words != last)
        last = words
    return keep


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(st.one_of(st.tuples(st.floats(-3e-4, 3e-4), st.floats(-3e-4, 3e-4), st.booleans()),
                                st.tuples(st.floats(-3e-5, 3e-5), st.floats(-3e-5, 3e-5), st.just(False))),
                      max_size=40),
       decimals=st.sampled_from([3, 4]))
def test_visible_moves_keeps_exactly_the_rows_that_print_a_move(steps, decimals):
    walk = np.cumsum(np.array([(0.0, 0.0, False), *steps], dtype=np.float64), axis=0)
    joints = np.column_stack([walk[:, 0], 2.0 * walk[:, 1] - walk[:, 0], np.full(len(walk), 7.0)])
    assert visible_moves(joints, decimals).tolist() == _words_oracle(joints, decimals)
    # with the tips: first the rows whose tip is within half a unit of the last kept one's (a run of
    # short steps with one axis), then, of the others, those that print no move
    tip = np.column_stack([walk[:, 0], walk[:, 1], np.zeros(len(walk))])
    axis = np.column_stack([np.zeros(len(walk)), 1e-3 * walk[:, 2], np.ones(len(walk))])   # turns where True
    near, away, last = 0.5 * 10.0 ** -decimals, [True], 0
    for row in range(1, len(walk)):
        short = np.linalg.norm(tip[row] - tip[row - 1]) < near and (axis[row] == axis[row - 1]).all()
        away.append(not (short and np.linalg.norm(tip[row] - tip[last]) < near))
        last = row if away[-1] else last
    expected = np.array(away)
    expected[np.flatnonzero(away)] = _words_oracle(joints[np.array(away)], decimals)
    assert visible_moves(joints, decimals, tip=tip, axis=axis).tolist() == expected.tolist()


def test_a_row_after_a_dropped_one_is_compared_with_the_last_kept_row():
    # Row 1 is dropped (its tip moved 0.00004 mm) though its word rounds up; row 2 steps more than one
    # unit from row 1, yet prints what row 0 printed: it must go too, or it would be a G1 moving nothing.
    joints = np.array([[0.0], [0.00006], [-0.000045]])
    tip = np.array([[0.0, 0, 0], [0.00004, 0, 0], [0.0001, 0, 0]])
    keep = visible_moves(joints, 4, tip=tip, axis=np.tile([0.0, 0, 1], (3, 1)))
    assert keep.tolist() == [True, False, False]


def test_a_step_finer_than_the_resolution_is_refused():
    with pytest.raises(FeatureError) as caught:
        pass_depths(0.5, 5e-5)
    assert error_text(caught.value) == "--step-down must be ≥ 0.0001 mm, the resolution of the program (got 5e-05)"
    with pytest.raises(FeatureError) as caught:
        pass_depths(3.0, 0.0005, resolution=0.001, key="peck")
    assert error_text(caught.value) == "--peck must be ≥ 0.001 mm, the resolution of the program (got 0.0005)"
    assert pass_depths(3e-5, 5e-5).tolist() == [3e-5]             # one pass: the step does not matter


def test_contour_points_closer_than_the_resolution_merge():
    # Corners of radius 0.00001 mm: each corner arc is one step the program cannot show (a request refuses
    # the radius, issue 20 §3; the library, given it, merges the points).
    opts = demo.make_context("demo", ["--profile", "square", "--depth", "1"]).params
    spec = _job_spec(str(demo_part()), opts)
    work = dataclasses.replace(spec.work, shape=dataclasses.replace(spec.work.shape, corner_radius=0.00001))
    result, dialect = run_job(dataclasses.replace(spec, work=work)), spec.dialect
    lap = [r for r in range(len(result.path_part)) if result.path_part.describe(r) == "square pass 1/1 lap"]
    assert len(lap) == 4 + 1 + 1        # a point per corner (not 2), the contour's start, back to the ramp's end
    assert _g1_lines_that_move_nothing(result.text, dialect) == []


# ----------------------------------------------------------------------------- dialect blocks

#: Blocks the loader accepts, one of each kind a safe start, preamble or postamble may need.
GOOD_BLOCKS = ["G17 G21 G40 G49 G54 G80 G90 G94", "G61", "G43 H1 (tool length)", "G43.2 H2", "G92.1", "G4 P0.5",
               "T1", "M61 Q1", "S1000 M3", "G96 S100 D3000", "G97", "M19 R90 Q1", "M5 M9", "M48", "M50 P1",
               "M62 P0", "M67 E0.5 Q0", "M66 P0 L0 Q1", "F100", "(MSG, tool 1 in)", "G59.3", "G93", "G95", "M1",
               "M70", "M100 P1 Q2", "G61.1", "G90.1", "G98", "G8"]
#: Blocks LinuxCNC itself rejects, with what the loader says (after ``blocks.preamble[0]: ``).
LINUXCNC_REJECTS = {
    "G12": "G12 is not an RS-274/NGC G code LinuxCNC knows",
    "M7 M8": "M7 and M8 are in the same modal group (coolant): one per block",
    "G17 G18": "G17 and G18 are in the same modal group (plane): one per block",
    "M1 M3 M8 M48 M5": "M3 and M5 are in the same modal group (spindle): one per block",
    "M0 M3 M6 M8 M48": "has more than 4 M codes (LinuxCNC: too many M codes on a line)",
    "H1": "H1: H needs a code that uses it on the same block (G43, G43.2)",
    "G4": "G4 needs P on the same block",
    "S-100 M3": "S-100: S must not be negative",
    "S1 S2": "has two S words (LinuxCNC takes one per block)",
    "T1.5": "T1.5: T must be a whole number",
    "G0 Z100": "G0 moves the machine (a dialect block must not: the program's moves carry their own checks)",
    "M2": "M2 ends the program (program.end_code does, after the postamble)",
    "(unclosed": "comment opened with '(' at column 1 is not closed with ')'",
    "M5 (a (b))": "comment at column 4 contains another '(' (LinuxCNC rejects nested comments)",
}


def _dialect_with(tmp_path: Path, key: str, blocks: list[str]) -> Path:
    text = (REPO / "postproc" / "dialects" / "linuxcnc.toml").read_text(encoding="utf-8")
    line = next(ln for ln in text.splitlines() if ln.startswith(f"{key} = "))
    path = tmp_path / f"{key}.toml"
    path.write_text(text.replace(line, f"{key} = {json.dumps(blocks)}"), encoding="utf-8")
    return path


@pytest.mark.parametrize("name", ["linuxcnc", "fanuc"])
def test_shipped_dialect_blocks_pass_the_check(name):
    dialect = load_dialect(name)
    for block in (*dialect.safe_start, *dialect.preamble, *dialect.postamble):
        assert block_problem(block, (dialect.comments.open, dialect.comments.close), tool_number_max=99999) is None


def test_accepted_blocks_run_on_linuxcnc(tmp_path, rs274_check):
    """Every kind of block the loader takes, in the preamble and the postamble of a real job."""
    dialect = _dialect_with(tmp_path, "preamble", GOOD_BLOCKS)
    dialect.write_text(dialect.read_text().replace("postamble = []", f"postamble = {json.dumps(GOOD_BLOCKS)}"))
    out = tmp_path / "p.ngc"
    result = invoke("demo", "--profile", "hole", "--dialect", str(dialect), "-o", str(out))
    assert result.exit_code == 0, result.stderr
    lines = out.read_text().splitlines()
    assert lines.count("G43 H1 (tool length)") == 2
    code, report = rs274_check(out)
    assert code == 0, report


def test_blocks_linuxcnc_rejects_are_refused_when_the_dialect_loads(tmp_path, rs274_check):
    programs = []
    for i, (block, message) in enumerate(LINUXCNC_REJECTS.items()):
        with pytest.raises(ConfigError) as caught:
            load_dialect(str(_dialect_with(tmp_path, "preamble", [block])))
        assert caught.value.args[0] == f"blocks.preamble[0]: {message}, got {block!r}"
        programs.append(tmp_path / f"{i}.ngc")
        programs[-1].write_text(f"G17 G21 G40 G49 G54 G80 G90 G94\nG61\n{block}\nG0 X0 Y0 U0 V0 W0\nM2\n")
    code, report = rs274_check(*programs)
    assert code == 1
    rejected = {int(line.split(".ngc:")[0].rsplit("/", 1)[1]) for line in report.splitlines() if ".ngc:" in line
                and ": OK" not in line}
    assert rejected == set(range(len(programs))), report


def test_a_contour_the_program_cannot_show_is_refused():
    with pytest.raises(FeatureError) as caught:
        _job(["--profile", "round", "--diameter", "0.001", "--dialect", "fanuc"])
    assert str(caught.value) == (
        "round Ø0.001 mm at (u 0.000, v 0.000) with tool Ø6.000: the tool centre goes 0.0028 mm around, too little "
        "for the program's resolution of 0.001 mm (a larger shape, or a hole?)")
    result, dialect = _job(["--profile", "round", "--diameter", "0.001"])      # 4 decimals show it
    assert _g1_lines_that_move_nothing(result.text, dialect) == []
