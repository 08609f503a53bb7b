"""Job files: several operations, faces and tools in one program (``prs3-post job``), tool lengths from a
tool table, the transitions between operations, and their headers read back."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import compare_golden
from numpy.testing import assert_allclose

from prs3_post.app.job import JobResult, run_operations, specs_from_header
from prs3_post.app.job_transitions import post_transition
from prs3_post.cli.main import main
from prs3_post.core.errors import InputError
from prs3_post.core.toolpath import EventKind, MoveKind, Toolpath
from prs3_post.emit.header_read import header_comments, parse_header
from prs3_post.kinematics import IKModel, forward, inverse
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.readers.jobfile import read_job_file
from prs3_post.readers.program import read_program

REPO = Path(__file__).resolve().parents[2]
JOBS = REPO / "fixtures" / "jobs"
EXAMPLE = JOBS / "example.toml"
TWOFACES = REPO / "fixtures" / "parts" / "twofaces.stl"
GOLDEN = REPO / "fixtures" / "golden" / "twofaces-job-example.ngc"
MACHINE = load_machine("patel2020")


def run_cli(*args: str) -> object:
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, JobResult]:
    """The example job through the CLI (the program file) and through the library (the rows)."""
    out = tmp_path_factory.mktemp("job") / "example.ngc"
    result = run_cli("job", str(EXAMPLE), "-o", str(out))
    assert result.exit_code == 0, result.output
    from prs3_post.cli.run import _job_specs

    return out, run_operations(_job_specs(read_job_file(str(EXAMPLE))))


def test_example_job_golden(example, update_golden) -> None:
    out, result = example
    text = out.read_text(encoding="utf-8")
    assert text == result.text
    compare_golden(text, GOLDEN, update_golden)


def test_example_header_states_the_tools_and_the_lengths_the_ik_used(example) -> None:
    out, result = example
    lines = out.read_text(encoding="utf-8").splitlines()
    assert lines[5] == ("(tools: T1 diameter 6.000 mm, length 52.300 mm, IK length 172.300 mm and T2 diameter "
                        "8.000 mm, length 71.250 mm, IK length 191.250 mm)")
    assert [o.tool_length for o in result.operations] == [120.0 + 52.3, 120.0 + 71.25]
    assert [o.label for o in result.operations] == ["operation 1 (hole on face 5)", "operation 2 (round on face 6)"]


def test_every_row_replays_onto_its_operation_path_with_its_own_tool_length(example) -> None:
    """FK of the program as written (4 decimals), each row with the tool length its operation's IK used,
    puts the tip on the intended row (machine frame) within the output rounding; the machine's own
    tool length would put it off by the difference of lengths."""
    out, result = example
    moves = read_program(out.read_text(encoding="utf-8"), load_dialect("linuxcnc"), path=str(out)).moves
    path = result.post.path
    assert len(moves) == len(path) == len(result.tool_length)
    tip = np.zeros((len(moves), 3))
    for length in np.unique(result.tool_length):
        rows = result.tool_length == length
        geometry = MACHINE.geometry.with_tool(length - MACHINE.geometry.gauge_offset)
        fk = forward(geometry, moves.strokes[rows], moves.stage[rows])
        assert fk.converged.all()
        tip[rows] = fk.tip
    error = np.linalg.norm(tip - path.tip, axis=1)
    assert error.max() < 3e-4                          # 4 decimals on 5 joints (measured: about 1e-4 mm)
    plain = forward(MACHINE.geometry, moves.strokes, moves.stage)
    off = np.linalg.norm(plain.tip - path.tip, axis=1)
    assert_allclose(off, np.abs(result.tool_length - 175.0), atol=3e-4)
    # every feed row of each operation is on that operation's own planned path (part frame → machine)
    for operation in result.operations:
        planned = result.setup.points_to_machine(operation.path_part.tip[operation.path_part.kind == MoveKind.FEED])
        labels = np.array(path.source_labels)[path.source]
        mine = np.char.startswith(labels.astype(str), operation.label) & (path.kind == MoveKind.FEED)
        gap = np.min(np.linalg.norm(tip[mine][:, None, :] - planned[None, :, :], axis=2), axis=1)
        assert len(planned) and gap.max() < 3e-4


def test_tool_changes_with_spindle_and_coolant_stopped_around_them(example) -> None:
    _, result = example
    program = result.post.program
    kinds = [(e.kind, e.value) for e in program.events if e.kind is not EventKind.COMMENT]
    assert kinds == [
        (EventKind.TOOL_CHANGE, 1.0), (EventKind.SPINDLE_ON, 3000.0), (EventKind.COOLANT_ON, 0.0),
        (EventKind.COOLANT_OFF, 0.0), (EventKind.SPINDLE_OFF, 0.0),
        (EventKind.TOOL_CHANGE, 2.0), (EventKind.SPINDLE_ON, 3000.0), (EventKind.COOLANT_ON, 0.0),
        (EventKind.COOLANT_OFF, 0.0), (EventKind.SPINDLE_OFF, 0.0),
    ]
    change = next(e.before for e in program.events if e.kind is EventKind.TOOL_CHANGE and e.value == 2.0)
    path = result.post.path
    # the tool changes up at the safe height: above the part's top plus the retract, with the new tool too
    top = result.setup.points_to_machine(result.triangles.reshape(-1, 3))[:, 2].max()
    assert path.describe(change - 1) == "operation 1 (hole on face 5), lift to the safe height"
    assert path.describe(change) == "operation 2 (round on face 6), turn the tool axis at the safe height"
    new_tip = path.tip[change - 1] - (191.25 - 172.3) * path.axis[change - 1]
    assert_allclose(new_tip[2], top + 10.0, atol=1e-9)
    # the turn: tip fixed, axis from face 5's normal to face 6's, every row checked, then over face 6
    turn = np.flatnonzero(path.source == path.source[change])
    assert_allclose(path.tip[turn[:-1]], np.tile(new_tip, (len(turn) - 1, 1)), atol=1e-9)
    assert_allclose(path.axis[turn[-1]], result.operations[1].face.normal, atol=1e-12)
    assert_allclose(path.axis[turn[-1]], [0.5, 0.0, math.sqrt(3) / 2], atol=1e-6)   # the STL's float32
    assert result.post.limits.ok.all()


def test_direct_reorientation_would_cross_the_tilt_limit_the_retract_first_one_does_not() -> None:
    """Two poses at 44.5° and 43.8° tilt, 120 mm apart in height: the controller's straight joint-space
    move between them tilts the tool 46.07° on the way (past the 45° limit); lifting first, turning
    at the safe height (subdivided) and going over stays within 44.52°."""
    def axis(tilt: float, azimuth: float) -> np.ndarray:
        t, p = math.radians(tilt), math.radians(azimuth)
        return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])

    a = (np.array([0.0, 0.0, -564.1836868421426]), axis(44.51122998, 49.668226))
    b = (np.array([0.0, 0.0, -684.777794707293]), axis(43.77814429, 355.01680029))

    def row(pose: tuple[np.ndarray, np.ndarray]) -> Toolpath:
        return Toolpath(kind=[MoveKind.RAPID], tip=pose[0][None], axis=pose[1][None], feed=[0.0], source=[0],
                        source_labels=("x",))

    def worst_tilt(joints: np.ndarray) -> float:
        s = np.linspace(0.0, 1.0, 201)[:, None, None]
        mixed = ((1.0 - s) * joints[None, :-1] + s * joints[None, 1:]).reshape(-1, 5)
        fk = forward(MACHINE.geometry, mixed[:, 2:], mixed[:, :2])
        assert fk.converged.all()
        return float(np.degrees(np.arccos(fk.axis[:, 2])).max())

    ends = inverse(MACHINE.geometry, np.array([a[0], b[0]]), np.array([a[1], b[1]]), model=IKModel.EXACT)
    direct = np.column_stack([ends.stage, ends.strokes])
    assert worst_tilt(direct) == pytest.approx(46.0760, abs=1e-3)
    lifted, turned = post_transition(MACHINE, row(a), row(b), (175.0, 175.0), -540.0, labels=("lift", "turn"))
    assert lifted is not None
    joints = np.vstack([direct[:1], *(np.column_stack([p.ik.stage, p.ik.strokes]) for p in (lifted, turned)),
                        direct[1:]])
    assert worst_tilt(joints) == pytest.approx(44.5112, abs=1e-3)
    assert turned.limits.ok.all() and lifted.limits.ok.all()


def test_header_read_back_rebuilds_the_same_program(example) -> None:
    out, _ = example
    text = out.read_text(encoding="utf-8")
    header = parse_header(header_comments(text), path=str(out))
    assert header is not None and len(header.operations) == 2
    assert [t.number for t in header.tools] == [1, 2] and [t.ik_length for t in header.tools] == [172.3, 191.25]
    specs = specs_from_header(header, str(TWOFACES), MACHINE, load_dialect("linuxcnc"))
    assert run_operations(specs).text == text


def test_verify_against_the_part_rebuilds_the_job_from_the_header(example) -> None:
    out, _ = example
    result = run_cli("verify", str(out), "--part", str(TWOFACES), "--json")
    assert result.exit_code == 0, result.output
    import json

    report = json.loads(result.stdout)
    assert report["against"]["label"] == "twofaces.stl (hole+round)"
    assert report["against"]["tip_max_mm"] < 3e-4


def test_every_job_output_passes_linuxcnc(example, rs274_check, tmp_path: Path) -> None:
    out, _ = example
    same_tool = tmp_path / "same.toml"
    same_tool.write_text(EXAMPLE.read_text(encoding="utf-8").replace("tool = 2 ", "tool = 1 ")
                         .replace('"../parts/twofaces.stl"', f'"{TWOFACES}"')
                         .replace('"tools.tbl"', f'"{JOBS / "tools.tbl"}"')
                         .replace("diameter = 20.0", "diameter = 24.0"),
                         encoding="utf-8")
    second = tmp_path / "same.ngc"
    made = run_cli("job", str(same_tool), "-o", str(second))
    assert made.exit_code == 0, made.output
    text = second.read_text(encoding="utf-8")
    assert text.count(" M6") == 1                   # the same tool: no second tool change
    code, output = rs274_check(out, second)
    assert code == 0, output


@pytest.mark.parametrize(("edit", "message"), [
    (("tool = 2 ", "tool = 3 "), "{tbl}: tool T3 is not in the tool table (it has T1, T2, T7)"),
    (("diameter = 20.0", "diameter = 20.0\ntool_diameter = 6.0"),
     "{tbl}:4: T2 has diameter 8.000 mm in the tool table, but the operation's tool diameter is 6.000 mm"),
    (("step_down = 1.0", "step_dwon = 1.0"),
     "{job}: operation[2].step_dwon: unknown key (an operation has profile, face, at, at_xyz, depth, peck, "
     "reapproach_gap, dwell, size, corner_radius, rotation, diameter, side, step_down, direction, entry, "
     "ramp_angle, clearance, retract, tool, tool_diameter, feed, plunge_feed, spindle, coolant)"),
    (("part_rotation_deg = 0.0", "part_rotation_deg = 0.0\nflip = true"),
     "{job}: setup.flip: unknown key (the setup has part_origin, part_rotation_deg)"),
    (("up = \"z\"", "up = \"z\"\nspeed = 3"),
     "{job}: speed: unknown key (a job file has part, units, up, machine, dialect, tool_table, tolerance, "
     "line_numbers, line_start, line_step, setup, operation)"),
    (("part_origin = [-100.0, -200.0, -970.0]", 'part_origin = "automatic"'),
     '{job}: setup.part_origin: expected [x, y, z] in mm or "auto", got \'automatic\''),
    (("depth = 6.0", "depth = \"6\""), "{job}: operation[1].depth: expected a number, got '6'"),
    (("feed = 400.0", "feed = -1.0"), "{job}: operation[2].feed: -1 mm/min is out of range (allowed: 0.1 to "
                                      "1e+06 mm/min)"),
    (("feed = 400.0", "feed = 1e9"), "{job}: operation[2].feed: 1e+09 mm/min is out of range (allowed: 0.1 to "
                                     "1e+06 mm/min)"),

    # planning errors: the file and the key, not the option (they were '--profile round ... --at' without a file)
    (("feed = 400.0", "feed = 400.0\nat = [[0.0, 0.0], [1.0, 1.0]]"),
     "{job}: operation[2].at: profile round cuts one feature: give one at or at_xyz (got 2)"),
    (("[[5.0, 5.0], [-5.0, -5.0]]", "[[5.0, 5.0], [5.0, 5.0]]"),
     "{job}: operation[1].at: hole 2 at (u 5.000, v 5.000) is hole 1 at (u 5.000, v 5.000) again (closer than the "
     "program's resolution, 0.0001 mm): it would be drilled twice; give each position once (at, at_xyz)"),
    (('up = "z"', 'up = "z"\ntolerance = 100.0'),
     "{job}: tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm (got 100)"),
    (("peck = 2.0", "peck = 2.0\ntool_diameter = 1e-9"),
     "{job}: operation[1]: tool_diameter must be from 0.01 to 500 mm (got 1e-09)"),
    (("diameter = 20.0", 'diameter = 7.0\nside = "inside"'),
     "{job}: operation[2].side: side inside: the tool Ø8.000 mm does not fit inside the round Ø7.000 mm (use a tool "
     "smaller than Ø7.000)"),
])
def test_bad_job_files(tmp_path: Path, edit: tuple[str, str], message: str) -> None:
    job = tmp_path / "job.toml"
    text = EXAMPLE.read_text(encoding="utf-8").replace('"../parts/twofaces.stl"', f'"{TWOFACES}"')
    text = text.replace('"tools.tbl"', f'"{JOBS / "tools.tbl"}"')
    assert edit[0] in text
    job.write_text(text.replace(edit[0], edit[1], 1), encoding="utf-8")
    out = tmp_path / "out.ngc"
    result = run_cli("job", str(job), "-o", str(out))
    assert result.stderr == "prs3-post: error: " + message.format(job=job, tbl=JOBS / "tools.tbl") + "\n"
    assert result.exit_code == 2 and not out.exists()


def test_main_job_with_a_tool_table_uses_the_tool_length(tmp_path: Path) -> None:
    out = tmp_path / "hole.ngc"
    result = run_cli("run", str(TWOFACES), "--profile", "hole", "--at", "5,5", "--tool-number", "2",
                     "--tool-diameter", "8", "--tool-table", str(JOBS / "tools.tbl"), "-o", str(out))
    assert result.exit_code == 0, result.output
    text = out.read_text(encoding="utf-8")
    assert "(tools: T2 diameter 8.000 mm, length 71.250 mm, IK length 191.250 mm)" in text.splitlines()
    verified = run_cli("verify", str(out), "--part", str(TWOFACES))
    assert verified.exit_code == 0, verified.output
    wrong = run_cli("run", str(TWOFACES), "--profile", "hole", "--tool-number", "2", "--tool-table",
                    str(JOBS / "tools.tbl"), "-o", str(tmp_path / "x.ngc"))
    assert wrong.exit_code == 2
    assert wrong.stderr == (f"prs3-post: error: {JOBS / 'tools.tbl'}:4: T2 has diameter 8.000 mm in the tool table, "
                            "but the operation's tool diameter is 6.000 mm\n")


def test_job_file_reader_resolves_paths_against_the_file() -> None:
    job = read_job_file(str(EXAMPLE))
    assert job.part == str(JOBS / "../parts/twofaces.stl")
    assert job.settings == {"units": "mm", "up": "z", "tool_table": str(JOBS / "tools.tbl")}
    assert (job.part_origin, job.part_rotation_deg) == ((-100.0, -200.0, -970.0), 0.0)
    assert [o["profile"] for o in job.operations] == ["hole", "round"]
    with pytest.raises(InputError):
        read_job_file(str(JOBS / "tools.tbl"))


@pytest.mark.parametrize("post_rows", [None, 2])
def test_a_limit_error_names_the_operation_and_a_placement_for_it_alone(tmp_path: Path, monkeypatch,
                                                                         post_rows: int | None) -> None:
    # posted 2 rows at a time, the pieces posted are gone when the error comes: the operation is planned again
    import prs3_post.app.job as job_module

    if post_rows is not None:
        monkeypatch.setattr(job_module, "POST_ROWS", post_rows)
    job = tmp_path / "job.toml"
    text = EXAMPLE.read_text(encoding="utf-8").replace('"../parts/twofaces.stl"', f'"{TWOFACES}"')
    job.write_text(text.replace('"tools.tbl"', f'"{JOBS / "tools.tbl"}"').replace("feed = 400.0", "feed = 400.0\n"
                                                                                   "retract = 300.0"), encoding="utf-8")
    out = tmp_path / "out.ngc"
    result = run_cli("job", str(job), "-o", str(out))
    assert (result.exit_code, out.exists()) == (1, False)
    assert result.stderr == (
        "prs3-post: error: operation 2 (round on face 6), round approach: T1 stroke -230.7257 mm is below the "
        "minimum -100.0000 mm by 130.7257 mm (2 points outside limits in all); setup: part origin at machine "
        "[-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z; a part origin at machine "
        "[-210.1, -188.4, -1149.4] mm puts this operation (alone) inside the machine's limits\n")


def test_one_tool_number_is_one_tool(tmp_path: Path) -> None:
    job = tmp_path / "job.toml"
    text = EXAMPLE.read_text(encoding="utf-8").replace('"../parts/twofaces.stl"', f'"{TWOFACES}"')
    text = text.replace('tool_table = "tools.tbl"\n', "").replace("tool = 2 ", "tool = 1 ")
    job.write_text(text.replace("diameter = 20.0", "diameter = 20.0\ntool_diameter = 8.0"), encoding="utf-8")
    result = run_cli("job", str(job), "-o", str(tmp_path / "out.ngc"))
    assert (result.exit_code, result.stderr) == (2, f"prs3-post: error: {job}: operation[2].tool_diameter: operation 2 "
                                                    "uses T1 with diameter 8.000 mm, operation 1 with 6.000 mm: one "
                                                    "tool number is one tool\n")


def test_a_header_whose_tool_lengths_the_machine_no_longer_gives_is_refused(example) -> None:
    out, _ = example
    text = out.read_text(encoding="utf-8").replace("IK length 172.300 mm", "IK length 175.000 mm")
    header = parse_header(header_comments(text), path="prog.ngc")
    with pytest.raises(InputError) as caught:
        specs_from_header(header, str(TWOFACES), MACHINE, load_dialect("linuxcnc"))
    assert str(caught.value) == ("prog.ngc:6: header: tools: T1's IK length 175.000 mm is not machine patel2020's "
                                 "gauge offset 120.000 mm + its length 52.300 mm: the machine file has changed since "
                                 "the program was made")


def test_verify_replays_each_row_with_the_tool_in_the_spindle(example) -> None:
    """The header's tool lengths make the replay put each tip where its tool's tip is: against the job's
    own path within the rounding; with the machine's tool length for every row, off by the length
    difference of the longer tool (16.25 mm)."""
    from prs3_post.app.verify import intended_from_job, open_program, tool_lengths_of, verify_loaded

    out, _ = example
    context = open_program(str(out))
    specs = specs_from_header(context.header, str(TWOFACES), context.machine, context.dialect)
    intended = intended_from_job(specs)
    assert tool_lengths_of(context.header) == {1: 172.3, 2: 191.25}
    right = verify_loaded(context.program, context.machine, context.setup, context.dialect, tolerance=0.002,
                          intended=intended, tool_lengths=tool_lengths_of(context.header))
    wrong = verify_loaded(context.program, context.machine, context.setup, context.dialect, tolerance=0.002,
                          intended=intended)
    def tip_max(report) -> float:
        return float(np.nanmax(np.linalg.norm(report.against.tip_deviation, axis=1)))

    assert right.ok and tip_max(right) < 3e-4
    assert not wrong.ok and tip_max(wrong) == pytest.approx(191.25 - 175.0, abs=3e-4)


@pytest.mark.parametrize(("old", "new", "message"), [
    ("(operations: 2)", "(operations: 3)", "p.ngc:7: header: operations: 3 operations, but no 'operation 3 face', "
     "'operation 3', 'operation 3 parameters', 'operation 3 tool' entry"),
    ("(operations: 2)", "(operations: 0)", "p.ngc:7: header: operations: expected 'N', the number of operations "
     "(1 to 9999), got '0'"),
    ("IK length 191.250 mm)", "IK length x mm)", "p.ngc:6: header: tools: expected 'TN diameter D mm[, length L mm], "
     "IK length TL mm' for each tool (joined by 'and'), got 'T2 diameter 8.000 mm, length 71.250 mm, IK length x mm'"),
    ("(tools: ", "(toolz: ", "p.ngc:19: header: no 'tools' entry (a prs3-post header has program, machine, dialect, "
     "part, setup, tools, operations, tolerance, units)"),
    ("(operation 2 tool: T2", "(operation 2 tool: X2", "p.ngc:15: header: operation 2 tool: expected 'TN diameter "
     ".. mm, feed .. mm/min, ...', got 'X2 diameter 8.000 mm, feed 400.0 mm/min, plunge 100.0 mm/min, spindle 3000 "
     "rpm, coolant flood'"),
])
def test_a_bad_job_header_names_its_line_and_entry(old: str, new: str, message: str) -> None:
    text = GOLDEN.read_text(encoding="utf-8")
    assert old in text
    with pytest.raises(InputError) as caught:
        parse_header(header_comments(text.replace(old, new)), path="p.ngc")
    assert str(caught.value) == message


def test_the_moves_between_operations_count_in_the_header_of_the_operation_whose_tool_makes_them(tmp_path, monkeypatch):
    # the example's lift and turn clear the part by more than the 11 mm horizon (each body over it, as the
    # golden says); here each transition check reports its holder 3 mm and its nose 4 mm from the part
    # (rows 1 and 2 of its program), as if something stood there: the lift is operation 1's (its tool),
    # the turn and the way down operation 2's, and each operation's entry is its bodies' minima over both
    import prs3_post.app.job as job_module
    from prs3_post.check.collision import ProgramClearance

    checked = job_module._check_transition
    seen = []

    def nearer(*args, **kwargs):
        found = checked(*args, **kwargs)
        seen.extend(owner for owner, _ in found)
        return [(owner, ProgramClearance(distance=np.array([c.distance[0], 3.0 + owner, 4.0 + owner]),
                                         exact=np.array([c.exact[0], True, True]), row=np.array([c.row[0], 1, 2]),
                                         point=c.point)) for owner, c in found]

    monkeypatch.setattr(job_module, "_check_transition", nearer)
    out = tmp_path / "job.ngc"
    result = run_cli("job", str(EXAMPLE), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert seen == [0, 1]                              # the lift (operation 1's tool), the turn and the way down
    lines = out.read_text(encoding="utf-8").split("\n")
    at = next(k for k, line in enumerate(lines) if line.startswith("(collision: "))
    wrapped = [lines[at]] + [line for line in lines[at + 1:at + 3] if line.startswith("(  ")]
    assert " ".join(line.strip("()").strip() for line in wrapped) == (
        "collision: operation 1: clear of the part by at least 1.000 mm: tool over 11.000 mm, holder 3.000 mm, "
        "spindle nose 4.000 mm, operation 2: clear of the part by at least 1.000 mm: tool 9.274 mm, holder 4.000 mm, "
        "spindle nose 5.000 mm")
    header = parse_header(header_comments("\n".join(lines)), path=str(out))
    assert [(op.collision_check, op.clearance_min) for op in header.operations] == [(True, 1.0), (True, 1.0)]


def test_a_tool_tables_diameter_out_of_range_names_the_table_line(tmp_path: Path) -> None:
    """'T1 P1 D0' was reported as 'job.toml: operation[1]: tool_diameter must be from 0.01 to 500 mm (got 0)', a key
    the job file does not have."""
    table = tmp_path / "tools.tbl"
    table.write_text((JOBS / "tools.tbl").read_text(encoding="utf-8").replace("T1 P1 D6.000", "T1 P1 D0"),
                     encoding="utf-8")
    job = tmp_path / "job.toml"
    text = EXAMPLE.read_text(encoding="utf-8").replace('"../parts/twofaces.stl"', f'"{TWOFACES}"')
    job.write_text(text.replace('"tools.tbl"', f'"{table}"'), encoding="utf-8")
    result = run_cli("job", str(job), "-o", str(tmp_path / "out.ngc"))
    assert (result.exit_code, result.stderr) == (2, f"prs3-post: error: {table}:3: T1 has diameter 0 mm in the tool "
                                                    "table: a job takes a diameter from 0.01 to 500 mm (or give "
                                                    "tool_diameter in the operation)\n")
    assert not (tmp_path / "out.ngc").exists()
