"""The main job's command line: bad inputs (exact message, exit code, no output file), `faces`, `--help`.

Exit codes: 2 for a wrong input file or option, 1 for a program that would break a machine limit
or leave the workspace. Paths in messages are as the user typed them, so the tests run from the
repository root with relative paths.
"""

from __future__ import annotations

import json
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose

from prs3_post.cli.main import main
from prs3_post.cli.run import demo, run

REPO = Path(__file__).resolve().parents[2]
WEDGE = "fixtures/parts/wedge.stl"


@pytest.fixture
def at_repo(monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(REPO)
    return REPO


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def _usage(message: str, command: str = "run", part: str = " PART.stl") -> str:
    return (f"Usage: prs3-post {command} [OPTIONS]{part}\nTry 'prs3-post {command} --help' for help.\n\n"
            f"Error: {message}\n")


# (id, arguments, the whole of standard error, exit code)
BAD = [
    # the part file
    ("missing-file", ["run", "fixtures/parts/missing.stl", "--profile", "hole"],
     "prs3-post: error: fixtures/parts/missing.stl: file not found\n", 2),
    ("not-an-stl", ["run", "fixtures/bad/not_an_stl.stl", "--profile", "hole"],
     "prs3-post: error: fixtures/bad/not_an_stl.stl: not an STL file (expected ASCII 'solid ...' or binary STL): "
     "text starting with 'This is a text file, not an STL.' instead of 'solid'\n", 2),
    ("empty-mesh", ["run", "fixtures/bad/empty.stl", "--profile", "hole"],
     "prs3-post: error: fixtures/bad/empty.stl: STL has no triangles\n", 2),
    ("no-inclined-face", ["run", "fixtures/bad/cube.stl", "--profile", "hole"],
     "prs3-post: error: fixtures/bad/cube.stl: no upward-facing inclined face (1° < inclination < 89°, normal z > 0): "
     "found 6 faces: 1 horizontal up, 1 horizontal down, 4 vertical\n", 2),
    ("only-downward-face", ["run", "fixtures/bad/downward.stl", "--profile", "hole"],  # plainer since issue 7
     "prs3-post: error: fixtures/bad/downward.stl: the only inclined planar face, face 6 (45.0° from horizontal, "
     "area 707.1 mm²), faces down (normal z = -0.7071): the tool cannot reach it from above; found 7 faces: "
     "1 horizontal up, 1 horizontal down, 4 vertical, 1 inclined 45.0° facing down; if the part's -x axis "
     "(as read) points up (--up -x), face 6 (inclination 45.0°, area 707.1 mm²) is a candidate\n",
     2),
    ("wrong-units", ["run", "fixtures/bad/tiny.stl", "--profile", "hole"],
     "prs3-post: error: fixtures/bad/tiny.stl: part is only 0.1 x 0.1 x 0.325 mm (largest extent under 1 mm): "
     "if the file is in inches, use --part-units inch (2.54 x 2.54 x 8.25 mm); if it is in metres, scale it by 1000 "
     "(100 x 100 x 325 mm)\n", 2),
    ("part-is-a-folder", ["run", "fixtures/parts", "--profile", "hole"],
     _usage("Invalid value for 'PART.stl': File 'fixtures/parts' is a directory."), 2),
    # the face
    ("face-99", ["run", WEDGE, "--profile", "hole", "--face", "99"],
     "prs3-post: error: fixtures/parts/wedge.stl: face 99 does not exist (valid: 0 to 5)\n", 2),
    ("face-abc", ["run", WEDGE, "--profile", "hole", "--face", "abc"],
     _usage("Invalid value for '--face': expected auto or a face index, got 'abc'"), 2),
    ("face-facing-down", ["run", WEDGE, "--profile", "hole", "--face", "5"],
     "prs3-post: error: fixtures/parts/wedge.stl: face 5 does not face up (normal z = -1.0000, inclination 180.0°): "
     "the tool cannot reach it from above\n", 2),
    # the feature
    ("does-not-fit", ["run", WEDGE, "--profile", "square", "--size", "200"],
     "prs3-post: error: square 200.000 mm at (u 0.000, v 0.000) with tool Ø6.000: does not fit on face 4: "
     "overshoots its edge by 69.668 mm; the largest that fits at (u 0.000, v 0.000) is 93.999 mm (--size 93.999)\n",
     2),
    ("does-not-fit-demo", ["demo", "--profile", "round", "--diameter", "120"],
     "prs3-post: error: round Ø120.000 mm at (u 0.000, v 0.000) with tool Ø6.000: does not fit on face 4: "
     "overshoots its edge by 12.999 mm; the largest that fits at (u 0.000, v 0.000) is 94.001 mm (--diameter "
     "94.001)\n", 2),
    ("hole-off-the-face", ["run", WEDGE, "--profile", "hole", "--at", "0,0", "--at", "1000,0"],
     "prs3-post: error: hole 2 at (u 1000.000, v 0.000) with tool Ø6.000: does not fit on face 4: "
     "overshoots its edge by 947.098 mm; Ø6.000 fits at (u 52.901, v 0.000), the nearest place where it does "
     "(--at 52.901,0)\n", 2),
    ("tool-larger-than-inside-round", ["run", WEDGE, "--profile", "round", "--side", "inside", "--diameter", "5",
                                       "--tool-diameter", "6"],
     "prs3-post: error: --side inside: the tool Ø6.000 mm does not fit inside the round Ø5.000 mm "
     "(use a tool smaller than Ø5.000)\n", 2),
    ("tool-larger-than-inside-corner", ["run", WEDGE, "--profile", "square", "--side", "inside", "--size", "20",
                                        "--corner-radius", "1"],
     "prs3-post: error: --side inside: corner radius 1.000 mm is smaller than the tool radius 3.000 mm "
     "(use --corner-radius ≥ 3.000 or a smaller tool)\n", 2),
    ("two-centres-for-a-profile", ["run", WEDGE, "--profile", "square", "--at", "0,0", "--at", "1,1"],
     "prs3-post: error: --profile square cuts one feature: give one --at or --at-xyz (got 2)\n", 2),
    # numbers that must be > 0
    ("depth-negative", ["run", WEDGE, "--profile", "hole", "--depth", "-1"],
     "prs3-post: error: --depth must be > 0 mm (got -1)\n", 2),
    ("depth-zero", ["run", WEDGE, "--profile", "square", "--depth", "0"],
     "prs3-post: error: --depth must be > 0 mm (got 0)\n", 2),
    ("size-zero", ["run", WEDGE, "--profile", "square", "--size", "0"],
     "prs3-post: error: --size must be > 0 mm (got 0)\n", 2),
    ("size-negative", ["run", WEDGE, "--profile", "square", "--size", "-3"],
     "prs3-post: error: --size must be > 0 mm (got -3)\n", 2),
    ("diameter-zero", ["run", WEDGE, "--profile", "round", "--diameter", "0"],
     "prs3-post: error: --diameter must be > 0 mm (got 0)\n", 2),
    ("feed-zero", ["run", WEDGE, "--profile", "square", "--feed", "0"],
     "Usage: prs3-post run [OPTIONS] PART.stl\nTry 'prs3-post run --help' for help.\n\n"
     "Error: Invalid value for '--feed': 0 mm/min is out of range (allowed: 0.1 to 1e+06 mm/min)\n", 2),
    ("feed-negative", ["run", WEDGE, "--profile", "hole", "--feed", "-5"],
     "Usage: prs3-post run [OPTIONS] PART.stl\nTry 'prs3-post run --help' for help.\n\n"
     "Error: Invalid value for '--feed': -5 mm/min is out of range (allowed: 0.1 to 1e+06 mm/min)\n", 2),
    ("plunge-feed-zero", ["run", WEDGE, "--profile", "hole", "--plunge-feed", "0"],
     "Usage: prs3-post run [OPTIONS] PART.stl\nTry 'prs3-post run --help' for help.\n\n"
     "Error: Invalid value for '--plunge-feed': 0 mm/min is out of range (allowed: 0.1 to 1e+06 mm/min)\n", 2),
    ("step-down-zero", ["run", WEDGE, "--profile", "round", "--step-down", "0"],
     "prs3-post: error: --step-down must be > 0 mm (got 0)\n", 2),
    # the machine and the dialect
    ("machine-does-not-exist", ["run", WEDGE, "--profile", "hole", "--machine", "nosuch"],
     "prs3-post: error: nosuch: no such machine file or shipped name (shipped: patel2020, patel2020-head)\n", 2),
    ("dialect-does-not-exist", ["run", WEDGE, "--profile", "hole", "--dialect", "nosuch"],
     "prs3-post: error: nosuch: no such dialect file or shipped name (shipped: fanuc, linuxcnc)\n", 2),
    # reach and limits: the message names the step, the limit, the value and the margin
    ("stroke-limit", ["run", WEDGE, "--profile", "hole", "--part-origin", "0,0,0"],
     "prs3-post: error: hole 1 approach: T1 stroke -952.2064 mm is below the minimum -100.0000 mm by 852.2064 mm "
     "(5 points outside limits in all); setup: part origin at machine [0.0000, 0.0000, 0.0000] mm, rotation 0.0000 "
     "deg about z; a part origin at machine [-79.4, -190.9, -1028.4] mm puts every point inside the machine's "
     "limits: --part-origin=-79.4,-190.9,-1028.4\n", 1),
    ("stage-limit", ["run", WEDGE, "--profile", "hole", "--part-origin", "500,0,-970"],
     "prs3-post: error: hole 1 approach: stage X 582.7345 mm is above the maximum 300.0000 mm by 282.7345 mm "
     "(5 points outside limits in all); setup: part origin at machine [500.0000, 0.0000, -970.0000] mm, rotation "
     "0.0000 deg about z; a part origin at machine [-79.4, -190.9, -1028.4] mm puts every point inside the "
     "machine's limits: --part-origin=-79.4,-190.9,-1028.4\n", 1),
    ("head-without-stage", ["run", WEDGE, "--profile", "hole", "--machine", "patel2020-head"],
     "prs3-post: error: hole 1 approach: machine patel2020-head has no stage and its head alone misses the tip "
     "(-95.5279, -0.0000, -661.0557) by 19.5369 mm (x -17.2655, y -9.1429) (5 points unreachable in all); setup: "
     "part origin at machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z; no translation of "
     "the part puts every point inside the machine's limits: set by --part-origin X,Y,Z and --part-rotation DEG, "
     "or let --part-origin auto --part-rotation auto search them\n",
     1),
]


@pytest.mark.parametrize(("args", "message", "code"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_input_is_refused_and_nothing_is_written(at_repo: Path, tmp_path: Path, args: list[str], message: str,
                                                     code: int) -> None:
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    result = invoke(*args, "-o", str(out_dir / "program.ngc"))
    assert result.stderr == message
    assert result.stdout == ""
    assert result.exit_code == code
    assert list(out_dir.iterdir()) == []          # no program, no temp file


def test_bad_input_keeps_an_existing_output_file(at_repo: Path, tmp_path: Path) -> None:
    """A refused job leaves a program that is already there as it was."""
    target = tmp_path / "program.ngc"
    target.write_bytes(b"old\n")
    result = invoke("run", WEDGE, "--profile", "hole", "--part-origin", "0,0,0", "-o", str(target))
    assert result.exit_code == 1
    assert target.read_bytes() == b"old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["program.ngc"]


def test_program_goes_to_standard_output_without_o(at_repo: Path) -> None:
    result = invoke("run", WEDGE, "--profile", "hole", "--dialect", "fanuc")
    assert result.exit_code == 0
    assert result.stderr == ""
    lines = result.stdout.split("\n")
    assert lines[:2] == ["%", "O1000 (PRS3-POST)"] and lines[-2:] == ["%", ""]


# ----------------------------------------------------------------------------- faces

WEDGE_FACES = """\
face   area mm²  width mm    incl °   normal x   normal y   normal z  origin x  origin y  origin z  kind             candidate  reason
   0  32500.000    100.00   90.0000  -1.000000   0.000000   0.000000  -50.0000  200.0000  162.5000  vertical         no         vertical
   1  30000.000    100.00   90.0000   0.000000   1.000000   0.000000   -1.3889  250.0000  150.3472  vertical         no         vertical
   2  30000.000    100.00   90.0000   0.000000  -1.000000   0.000000   -1.3889  150.0000  150.3472  vertical         no         vertical
   3  27500.000    100.00   90.0000   1.000000   0.000000   0.000000   50.0000  200.0000  137.5000  vertical         no         vertical
   4  11180.340    100.00   26.5651   0.447214   0.000000   0.894427    0.0000  200.0000  300.0000  inclined up      yes        inclined up, 100.00 mm wide
   5  10000.000    100.00  180.0000   0.000000   0.000000  -1.000000    0.0000  200.0000    0.0000  horizontal down  no         faces down
auto: face 4 is the largest upward-facing inclined face (inclination 26.5651°, area 11180.3 mm²)
"""  # noqa: E501 (a golden table: its rows are as wide as the command prints them)


def test_faces_text(at_repo: Path) -> None:
    result = invoke("faces", WEDGE)
    assert (result.exit_code, result.stderr) == (0, "")
    assert result.stdout == WEDGE_FACES


def test_faces_json(at_repo: Path) -> None:
    """The same table as JSON: exact keys, indexes and order; values to 1e-9 (full float precision)."""
    result = invoke("faces", WEDGE, "--json")
    assert (result.exit_code, result.stderr) == (0, "")
    rows = json.loads(result.stdout)
    assert [list(r) for r in rows] == [["index", "area_mm2", "normal", "inclination_deg", "origin", "width_mm",
                                        "curved", "candidate", "reason"]] * 6
    assert [(r["candidate"], r["reason"]) for r in rows] == [(False, "vertical")] * 4 + [
        (True, "inclined up, 100.00 mm wide"), (False, "faces down")]
    assert_allclose([r["width_mm"] for r in rows], [100.0] * 6, rtol=0, atol=1e-9)
    assert not any(r["curved"] for r in rows)
    assert [r["index"] for r in rows] == [0, 1, 2, 3, 4, 5]
    s5 = 5.0 ** 0.5
    expected = [
        (32500.0, [-1.0, 0.0, 0.0], 90.0, [-50.0, 200.0, 162.5]),
        (30000.0, [0.0, 1.0, 0.0], 90.0, [-25.0 / 18.0, 250.0, 150.0 + 25.0 / 72.0]),
        (30000.0, [0.0, -1.0, 0.0], 90.0, [-25.0 / 18.0, 150.0, 150.0 + 25.0 / 72.0]),
        (27500.0, [1.0, 0.0, 0.0], 90.0, [50.0, 200.0, 137.5]),
        (10000.0 * s5 / 2.0, [1.0 / s5, 0.0, 2.0 / s5], 26.56505117707799, [0.0, 200.0, 300.0]),
        (10000.0, [0.0, 0.0, -1.0], 180.0, [0.0, 200.0, 0.0]),
    ]
    for row, (area, normal, inclination, origin) in zip(rows, expected, strict=False):
        assert_allclose(row["area_mm2"], area, rtol=0, atol=1e-9)
        assert_allclose(row["normal"], normal, rtol=0, atol=1e-9)
        assert_allclose(row["inclination_deg"], inclination, rtol=0, atol=1e-9)
        assert_allclose(row["origin"], origin, rtol=0, atol=1e-9)


def test_faces_of_twofaces_name_the_other_face(at_repo: Path) -> None:
    """twofaces.stl: auto takes face 5 (20°, larger); face 6 (30°) is what --face 6 means in test_job."""
    result = invoke("faces", "fixtures/parts/twofaces.stl")
    assert result.exit_code == 0
    lines = result.stdout.splitlines()
    assert lines[6].split()[:4] == ["5", "8513.422", "85.13", "20.0000"]
    assert lines[6].endswith("inclined up      yes        inclined up, 85.13 mm wide")
    assert lines[7].split()[:4] == ["6", "4618.803", "46.19", "30.0000"]
    assert lines[7].endswith("inclined up      yes        inclined up, 46.19 mm wide")
    assert lines[-1] == ("auto: face 5 is the largest upward-facing inclined face (inclination 20.0000°, "
                         "area 8513.4 mm²)")


def test_faces_bad_file(at_repo: Path) -> None:
    result = invoke("faces", "fixtures/bad/empty.stl")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == "prs3-post: error: fixtures/bad/empty.stl: STL has no triangles\n"


def test_faces_without_inclined_face_says_so(at_repo: Path) -> None:
    result = invoke("faces", "fixtures/bad/cube.stl")
    assert result.exit_code == 0
    assert result.stdout.splitlines()[-1] == (
        "auto: no upward-facing inclined face (1° < inclination < 89°, normal z > 0): found 6 faces: "
        "1 horizontal up, 1 horizontal down, 4 vertical")


# ----------------------------------------------------------------------------- --help

KEY_OPTIONS = {
    "--profile", "--face", "--at", "--at-xyz", "--part-units", "--depth", "--peck", "--dwell", "--reapproach-gap",
    "--size", "--corner-radius", "--rotation", "--diameter", "--side", "--step-down", "--direction", "--entry",
    "--ramp-angle", "--clearance", "--retract", "--tool-diameter", "--tool-number", "--feed", "--plunge-feed",
    "--spindle", "--coolant", "--machine", "--part-origin", "--dialect", "--line-numbers", "--no-line-numbers",
    "--line-start", "--line-step", "--tolerance", "-o", "--output", "--up",
}


def _option_names(command: click.Command) -> set[str]:
    return {name for p in command.params if isinstance(p, click.Option) for name in (*p.opts, *p.secondary_opts)}


@pytest.mark.parametrize("command", [run, demo], ids=["run", "demo"])
def test_help_mentions_every_option(command: click.Command) -> None:
    names = _option_names(command)
    assert KEY_OPTIONS <= names
    result = CliRunner().invoke(main, [command.name, "--help"], prog_name="prs3-post")
    assert result.exit_code == 0
    words = set(result.stdout.replace("/", " ").replace(",", " ").split())
    assert names - {"-h"} <= words, sorted(names - words)


def test_run_and_demo_take_the_same_options() -> None:
    assert _option_names(run) == _option_names(demo)
    assert [p.name for p in run.params if isinstance(p, click.Argument)] == ["part"]
    assert [p for p in demo.params if isinstance(p, click.Argument)] == []


def test_output_into_a_missing_folder_is_a_clear_error(tmp_path):
    target = tmp_path / "no" / "such" / "folder" / "demo.ngc"
    result = CliRunner().invoke(main, ["demo", "--profile", "hole", "-o", str(target)])
    assert result.exit_code == 2
    assert result.stderr == f"prs3-post: error: {target}: cannot write the output here: No such file or directory\n"
    assert list(tmp_path.iterdir()) == []


def test_output_file_gets_ordinary_permissions(tmp_path):
    import os
    import stat

    target = tmp_path / "demo.ngc"
    umask = os.umask(0o022)
    try:
        assert CliRunner().invoke(main, ["demo", "--profile", "hole", "-o", str(target)]).exit_code == 0
    finally:
        os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["demo.ngc"]        # no temp file left behind


@pytest.mark.parametrize(("args", "message"), [
    (["demo", "--profile", "hole", "--face", "²"],
     "Invalid value for '--face': expected auto or a face index, got '²'"),
    (["demo", "--profile", "hole", "--line-numbers", "--line-start", "99999", "--line-step", "1000"],
     "Invalid value for '--line-start': --line-start 99999 + --line-step 1000 passes dialect linuxcnc's largest "
     "block number 99999: every block would get the same number"),
    # issue 20 §3: --depth 1e-300 wrote a hole of depth 0 (that verified OK) while --size 1e-6 was refused for
    # its lap: one rule and one message for every length below the program's resolution
    (["demo", "--profile", "hole", "--depth", "1e-300"],
     "Invalid value for '--depth': 1e-300 mm is below the program's resolution, 0.0001 mm (dialect linuxcnc writes "
     "lengths to 4 decimals), so the program could not show it: give at least 0.0001 mm"),
    (["demo", "--profile", "square", "--size", "1e-6"],
     "Invalid value for '--size': 1e-06 mm is below the program's resolution, 0.0001 mm (dialect linuxcnc writes "
     "lengths to 4 decimals), so the program could not show it: give at least 0.0001 mm"),
    (["demo", "--profile", "hole", "--peck", "1e-300", "--dialect", "fanuc"],
     "Invalid value for '--peck': 1e-300 mm is below the program's resolution, 0.001 mm (dialect fanuc writes "
     "lengths to 3 decimals), so the program could not show it: give at least 0.001 mm (or 0: no pecking)"),
    (["demo", "--profile", "square", "--corner-radius", "5e-5"],
     "Invalid value for '--corner-radius': 5e-05 mm is below the program's resolution, 0.0001 mm (dialect linuxcnc "
     "writes lengths to 4 decimals), so the program could not show it: give at least 0.0001 mm (or 0: sharp "
     "corners)"),
])
def test_option_values_that_cannot_work_are_usage_errors(args, message):
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == f"Error: {message}"


@pytest.mark.parametrize(("args", "message"), [
    (["demo", "--profile", "hole", "--at-xyz", "18.9736,221.2132,280.5135"],
     "point (18.9736, 221.2132, 280.5135) is 8.9440 mm off the plane of face 4 (allowed: 0.0100 mm)"),
    (["demo", "--profile", "hole", "--tolerance", "0.00001"],
     "--tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm (got 1e-05)"),
    (["demo", "--profile", "hole", "--tolerance", "100"],
     "--tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm (got 100)"),
    (["demo", "--profile", "hole", "--tool-diameter", "1e-9"],
     "--tool-diameter must be from 0.01 to 500 mm (got 1e-09)"),
    (["demo", "--profile", "round", "--tool-diameter", "600"],
     "--tool-diameter must be from 0.01 to 500 mm (got 600)"),
    (["demo", "--profile", "hole", "-o", "sub/"], "sub/: is a folder or empty: give a file name"),
])
def test_bad_values_are_refused_with_their_reason(args, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, args)
    assert (result.exit_code, result.stderr) == (2, f"prs3-post: error: {message}\n")
    assert list(tmp_path.iterdir()) == []


def test_fk_json_never_writes_infinity():
    result = CliRunner().invoke(main, ["fk", "--strokes", "1e5,1e5,-1e5", "--json"])
    assert result.exit_code == 1
    assert result.stdout == "" and "do not assemble" in result.stderr


def test_verify_refuses_operation_options_without_an_stl(tmp_path):
    program = tmp_path / "sq.ngc"
    assert CliRunner().invoke(main, ["demo", "--profile", "square", "-o", str(program)]).exit_code == 0
    result = CliRunner().invoke(main, ["verify", str(program), "--depth", "9", "--size", "80", "--face", "3"])
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == (
        "Error: --face, --depth, --size: the operation options are only used with --part PART.stl")
    for option, value, message in (
        ("--tolerance", "0",
         "prs3-post: error: --tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm (got 0)"),
        ("--tolerance", "1.5",
         "prs3-post: error: --tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm (got 1.5)"),
        ("--axis-tolerance", "-1", "Error: Invalid value for '--axis-tolerance': must be a number ≥ 0 degrees, got -1"),
    ):
        result = CliRunner().invoke(main, ["verify", str(program), option, value])
        assert result.exit_code == 2 and result.stderr.splitlines()[-1] == message


def test_the_same_hole_twice_is_refused_before_writing(tmp_path: Path) -> None:
    out = tmp_path / "p.ngc"
    result = invoke("demo", "--profile", "hole", "--at", "0,0", "--at", "5,5", "--at", "0,0", "-o", str(out))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == ("prs3-post: error: hole 3 at (u 0.000, v 0.000) is hole 1 at (u 0.000, v 0.000) again "
                             "(closer than the program's resolution, 0.0001 mm): it would be drilled twice; give each "
                             "position once (--at, --at-xyz)\n")
    assert list(tmp_path.iterdir()) == []



@pytest.mark.parametrize("target", ["file", "stdout"])
def test_a_program_failing_while_it_is_written_leaves_nothing(tmp_path, monkeypatch, target):
    """The main job writes its program chunk by chunk (a few rows at a time here); a chunk that fails
    while it is formatted leaves the old file as it was and no temp file (standard output gets the
    whole text or nothing: it is formatted before any of it is written)."""
    import prs3_post.app.job as job_module
    from prs3_post.core.errors import LimitError
    from prs3_post.emit.gcode import ProgramEmitter

    monkeypatch.setattr(job_module, "EMIT_ROWS", 2)
    real = ProgramEmitter.row_pieces
    calls = []

    def failing(self, program):
        calls.append(len(program))
        if len(calls) == 3:
            raise LimitError("row 9: made to fail")
        return real(self, program)

    monkeypatch.setattr(ProgramEmitter, "row_pieces", failing)
    out = tmp_path / "old.ngc"
    out.write_text("old\n")
    args = ["demo", "--profile", "hole", "--depth", "4"] + (["-o", str(out)] if target == "file" else [])
    result = CliRunner().invoke(main, args, prog_name="prs3-post")
    assert result.exit_code == 1, result.output
    assert result.output.splitlines()[-1] == "prs3-post: error: row 9: made to fail"
    assert "G1" not in result.stdout
    assert out.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["old.ngc"]


COMMANDS = ("accuracy, calibrate, convert, demo, export, faces, fk, ik, job, linuxcnc-config, machines, preview, run, "
            "sim, sources, verify")


@pytest.mark.parametrize(("word", "hint"), [("verfy", "did you mean 'verify'? "), ("nosuchcommand", "")])
def test_a_mistyped_command_is_not_read_as_a_part(word: str, hint: str) -> None:
    result = invoke(word, "x.ngc")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == ("Usage: prs3-post [OPTIONS] COMMAND [ARGS]...\nTry 'prs3-post --help' for help.\n\n"
                             f"Error: no such command or file '{word}' ({hint}commands: {COMMANDS}; or a part file: "
                             "prs3-post PART.stl --profile ...)\n")


@pytest.mark.parametrize(("command", "arguments"), [("demo", ["--profile", "hole"]), ("convert", ["x.cls"])])
def test_a_negative_clearance_min_is_refused(tmp_path: Path, command: str, arguments: list[str]) -> None:
    out = tmp_path / "p.ngc"
    result = invoke(command, *arguments, "--clearance-min", "-1", "-o", str(out))
    assert (result.exit_code, result.stderr) == (2, _usage(
        "Invalid value for '--clearance-min': -1 mm is out of range (allowed: 0 to 1e+06 mm)", command,
        "" if command == "demo" else " INPUT..."))
    assert not out.exists()


@pytest.mark.parametrize(("lines", "message"), [
    ('[[operation]]\nprofile = "hole"\ntool = 0\n',
     "operation[1].tool: must be 1..99999 with dialect linuxcnc (its words.tool_number_max), got 0"),
    ('line_numbers = true\nline_start = 99999\nline_step = 5\n[[operation]]\nprofile = "hole"\n',
     "line_start: line_start 99999 + line_step 5 passes dialect linuxcnc's largest block number 99999: every block "
     "would get the same number"),
])
def test_a_job_files_value_is_named_by_its_key(tmp_path: Path, lines: str, message: str) -> None:
    job = tmp_path / "job.toml"
    job.write_text(f'part = "{REPO / WEDGE}"\n{lines}', encoding="utf-8")
    out = tmp_path / "p.ngc"
    result = invoke("job", str(job), "-o", str(out))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {job}: {message}\n"
    assert not out.exists()


@pytest.mark.parametrize(("args", "message"), [
    (["--profile", "square", "--diameter", "20"],
     "--profile square does not use --diameter (round only): leave it out"),
    (["--profile", "round", "--peck", "1", "--dwell", "2"],
     "--profile round does not use --peck (hole only), --dwell (hole only): leave them out"),
    (["--profile", "hole", "--step-down", "1"], "--profile hole does not use --step-down (square and round only): "
                                                "leave it out"),
])
def test_an_option_the_profile_ignores_is_refused(tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "p.ngc"
    result = invoke("demo", *args, "-o", str(out))
    assert (result.exit_code, result.stderr) == (2, _usage(message, "demo", ""))
    assert not out.exists()


def test_a_job_files_key_the_profile_ignores_is_refused(tmp_path: Path) -> None:
    job = tmp_path / "job.toml"
    job.write_text(f'part = "{REPO / WEDGE}"\n[[operation]]\nprofile = "round"\npeck = 2.0\n', encoding="utf-8")
    out = tmp_path / "p.ngc"
    result = invoke("job", str(job), "-o", str(out))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {job}: operation[1]: profile round does not use peck (hole only): "
                             "remove it\n")
    assert not out.exists()


def test_verify_against_a_part_refuses_an_option_the_profile_ignores(tmp_path: Path) -> None:
    made = invoke("demo", "--profile", "hole")
    program = tmp_path / "p.ngc"
    program.write_text("".join(line + "\n" for line in made.stdout.splitlines() if not line.startswith("(")))
    result = invoke("verify", str(program), "--part", str(REPO / WEDGE), "--profile", "hole", "--diameter", "20")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == ("Error: --profile hole does not use --diameter (round only): leave it "
                                              "out")


def test_minus_capital_v_is_the_version() -> None:
    """Issue 20: -V, as --version (and as most tools spell it)."""
    short = CliRunner().invoke(main, ["-V"])
    assert (short.exit_code, short.output) == (0, "prs3-post, version 0.1.0\n")
    assert short.output == CliRunner().invoke(main, ["--version"]).output
