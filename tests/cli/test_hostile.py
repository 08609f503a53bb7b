"""Hostile input, round two (issue 7 §3-§5, issue 8 §2): options given twice, standard input as a
file, option values that are neither a file nor numbers. Each is refused with a message that says
what is wrong and what is valid, exit 2, and no output file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL

REPO = Path(__file__).resolve().parents[2]
WEDGE = REPO / "fixtures" / "parts" / "wedge.stl"
PROGRAM_3AXIS = "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X5\nM2\n"


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def _usage_error(result) -> str:
    """The last line of a click usage error (``Error: ...``), after checking exit 2 and no output."""
    assert (result.exit_code, result.stdout) == (2, ""), result.stderr
    return result.stderr.splitlines()[-1]


# ----------------------------------------------------------------------------- options given twice


@pytest.mark.parametrize(("args", "message"), [
    (["demo", "--profile", "hole", "--profile", "square", "-o", "d.ngc"],
     "Error: --profile given twice ('hole' and 'square'): give it once"),
    (["demo", "--profile", "hole", "-o", "a.ngc", "-o", "b.ngc"],
     "Error: -o/--output given twice ('a.ngc' and 'b.ngc'): give it once"),
    (["demo", "--profile", "hole", "-oa.ngc", "--output=b.ngc"],
     "Error: -o/--output given twice ('a.ngc' and 'b.ngc'): give it once"),
    (["run", str(WEDGE), "--profile=hole", "--depth", "3", "--depth", "4", "-o", "d.ngc"],
     "Error: --depth given twice ('3' and '4'): give it once"),
    ([str(WEDGE), "--profile", "hole", "--part-origin", "-100,-200,-970", "--part-origin=0,0,0", "-o", "d.ngc"],
     "Error: --part-origin given twice ('-100,-200,-970' and '0,0,0'): give it once"),
    (["demo", "--profile", "hole", "--collision-check", "--no-collision-check", "-o", "d.ngc"],
     "Error: --collision-check/--no-collision-check given twice ('--collision-check' and "
     "'--no-collision-check'): give it once"),
    (["convert", "in.ngc", "-d", "out", "--report", "a.json", "--report", "b.json"],
     "Error: --report given twice ('a.json' and 'b.json'): give it once"),
    (["verify", "p.ngc", "--machine", "patel2020", "--machine", "patel2020-head"],
     "Error: --machine given twice ('patel2020' and 'patel2020-head'): give it once"),
    (["faces", str(WEDGE), "--json", "--json"], "Error: --json given twice ('--json' and '--json'): give it once"),
    (["fk", "--strokes", "1,2,3", "--strokes", "4,5,6"],
     "Error: --strokes given twice ('1,2,3' and '4,5,6'): give it once"),
    (["preview", "p.ngc", "-o", "a.png", "--rapid-rate", "1", "--rapid-rate", "2"],
     "Error: --rapid-rate given twice ('1' and '2'): give it once"),
])
def test_an_option_given_twice_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                          message: str) -> None:
    """It used to be the last one, silently (``--profile hole --profile square`` cut a square)."""
    monkeypatch.chdir(tmp_path)
    assert _usage_error(invoke(*args)) == message
    assert list(tmp_path.iterdir()) == []


def test_a_repeatable_option_and_a_value_that_looks_like_an_option_are_not_repeats(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", "0,0,0,0,0,1", "--ignore", "PAINT",
                    "--ignore", "FOO", "--", "-o")              # '-o' after '--' is an input file, not an option
    assert result.exit_code == 2, result.stderr                 # an input that is not there is bad input
    lines = result.stdout.splitlines()
    assert sorted(line.split("\t")[:3] for line in lines) == [["failed", "-o", "-"], ["ok", "a.ngc", "out/a.ngc"]]
    assert [line.split("\t")[3] for line in lines if line.startswith("failed")] == ["-o: file not found"]


# ----------------------------------------------------------------------------- standard input, --work-plane


@pytest.mark.parametrize(("args", "what"), [
    (["run", "-", "--profile", "hole", "-o", "x.ngc"], "an STL file"),
    (["-", "--profile", "hole", "-o", "x.ngc"], "an STL file"),      # was: No such command '-'
    (["faces", "-"], "an STL file"),
    (["job", "-"], "a TOML file"),
])
def test_standard_input_is_refused_as_a_part_or_a_toml_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                            args: list[str], what: str) -> None:
    """It said ``-: file not found``, as if a file named '-' were missing. Standard input is read where
    one program, CL file or pose table is the input (tests/cli/test_stdio.py); a part or a TOML file is
    read alongside such an input, so it is always a file."""
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, args, prog_name="prs3-post", input="solid x\nendsolid x\n")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: <stdin>: standard input is not read as {what}: give a file " \
                            "(a file named '-' is ./-)\n"
    assert list(tmp_path.iterdir()) == []


def test_convert_reads_standard_input_and_a_file_named_dash(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``-`` was refused; it is standard input now, and ``./-`` is the file named '-'."""
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, ["convert", "-", "-o", "-", "--work-plane", "0,0,0,0,0,1"],
                                prog_name="prs3-post", input=PROGRAM_3AXIS)
    assert result.exit_code == 0, result.stderr
    assert "(source: <stdin>, format gcode, " in result.stdout.splitlines()[3]
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "-").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "./-", "-d", "out", "--work-plane", "0,0,0,0,0,1")
    assert result.exit_code == 0, result.stderr
    assert (tmp_path / "out" / "-.ngc").is_file()


@pytest.mark.parametrize(("args", "message"), [
    (["a.ngc", "-d", "-"], "Error: Invalid value for '-d' / '--output-dir': '-' is no folder: convert writes one "
                           "program per input into DIR, standard output cannot take them (a folder named '-' is ./-)"),
    (["a.ngc", "b.ngc", "-o", "-"], "Error: -o FILE writes the program of one input, and 2 files are given: convert "
                                    "them into a folder with -d DIR"),
    (["a.ngc", "-o", "-", "--report", "-"],
     "prs3-post: error: standard output: --output and --report both write to it: give one of them a file"),
])
def test_convert_refuses_two_things_on_standard_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       args: list[str], message: str) -> None:
    """'-o -' made a folder named '-' (exit 0); now it is one program on standard output, and only one."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    (tmp_path / "b.ngc").write_text(PROGRAM_3AXIS)
    assert _usage_error(invoke("convert", *args, "--work-plane", "0,0,0,0,0,1")) == message
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc", "b.ngc"]


@pytest.mark.parametrize("text", ["nan", "1,2,3,0,0,nan", "inf,0,0,0,0,1", "0x1p3,0,0,0,0,1", "nowhere.stl:2"])
def test_a_work_plane_that_is_neither_numbers_nor_a_file_says_what_is_valid(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    """`--work-plane nan` said only ``nan: file not found``."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", text)
    assert _usage_error(result) == (f"Error: Invalid value for '--work-plane': {text}: file not found, and not 6 or 9 "
                                    "plain decimal numbers: a work plane is PART.stl[:FACE] or "
                                    "OX,OY,OZ,NX,NY,NZ[,XX,XY,XZ] (mm)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc"]


def test_a_work_plane_face_that_does_not_face_up_is_an_option_error(tmp_path: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", f"{WEDGE}:5")
    assert _usage_error(result).startswith("Error: Invalid value for '--work-plane': face 5 does not face up")


# ----------------------------------------------------------------------------- a header is input


def _demo_program(tmp_path: Path) -> list[str]:
    result = invoke("demo", "--profile", "hole", "-o", str(tmp_path / "h.ngc"))
    assert result.exit_code == 0, result.stderr
    return (tmp_path / "h.ngc").read_text().splitlines()


@pytest.mark.parametrize(("machine", "problem"), [
    ("/dev/zero", "'/dev/zero') cannot be loaded here (is not a regular file: give a machine TOML file or a shipped "
                  "name (shipped: patel2020, patel2020-head)"),
    ("a" * 3000, f"'{'a' * 39}…') cannot be loaded here (cannot read the file: File name too long"),
])
def test_a_header_machine_is_checked_as_a_given_one_and_shown_short(tmp_path: Path, machine: str,
                                                                    problem: str) -> None:
    """A 3000-character machine name in a header was an OSError traceback (name too long)."""
    lines = _demo_program(tmp_path)
    assert lines[1].startswith("(machine: patel2020 ")
    lines[1] = f"(machine: {machine} [x])"
    program = tmp_path / "m.ngc"
    program.write_text("\n".join(lines) + "\n")
    result = invoke("verify", str(program))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {program}:2: header: the machine it names ({problem}; a header's "
                             "machine is read as a given one is): give the machine explicitly\n")


def test_a_machine_name_too_long_for_the_system_is_a_config_error() -> None:
    result = invoke("fk", "--strokes", "0,0,0", "--machine", "b" * 3000)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {'b' * 3000}: cannot read the file: File name too long\n"


# ----------------------------------------------------------------------------- feeds


@pytest.mark.parametrize(("args", "message"), [
    (["demo", "--profile", "square", "--feed", "0.0000001"],
     "Invalid value for '--feed': 1e-07 mm/min is out of range (allowed: 0.1 to 1e+06 mm/min)"),
    (["demo", "--profile", "hole", "--plunge-feed", "0.05"],
     "Invalid value for '--plunge-feed': 0.05 mm/min is out of range (allowed: 0.1 to 1e+06 mm/min)"),
    (["demo", "--profile", "hole", "--feed", "2e6"],          # the range named was -1e+06 to 1e+06
     "Invalid value for '--feed': 2e+06 mm/min is out of range (allowed: 0.1 to 1e+06 mm/min)"),
    (["demo", "--profile", "hole", "--spindle", "2e6"],
     "Invalid value for '--spindle': 2e+06 rpm is out of range (allowed: 1 to 1e+06 rpm)"),
    (["demo", "--profile", "hole", "--spindle", "1e-9"],     # was exit 1: "spindle_on event before row ..."
     "Invalid value for '--spindle': 1e-09 rpm is out of range (allowed: 1 to 1e+06 rpm)"),
])
def test_a_feed_too_slow_to_mean_anything_is_bad_input(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       args: list[str], message: str) -> None:
    """--feed 0.0000001 was a limit error (exit 1) about an inverse-time F printing as 0 (the same feed in a
    G-code input too: see fixtures/bad/gcode/feed_too_slow*.ngc, fixtures/bad/cl/feed_*too_slow.cls)."""
    monkeypatch.chdir(tmp_path)
    result = invoke(*args, "-o", "x.ngc")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == f"Error: {message}"
    assert list(tmp_path.iterdir()) == []


def test_a_job_file_feed_too_slow_names_its_key(tmp_path: Path) -> None:
    job = tmp_path / "j.toml"
    job.write_text(f'part = "{WEDGE}"\n[[operation]]\nprofile = "hole"\nplunge_feed = 0.001\n')
    result = invoke("job", str(job), "-o", str(tmp_path / "j.ngc"))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {job}: operation[1].plunge_feed: 0.001 mm/min is out of range " \
                            "(allowed: 0.1 to 1e+06 mm/min)\n"
    assert not (tmp_path / "j.ngc").exists()


def test_a_job_file_spindle_speed_that_prints_as_zero_names_its_key(tmp_path: Path) -> None:
    """spindle = 1e-9 was a limit error (exit 1) about an event before row 2, with a part-origin suggestion."""
    job = tmp_path / "j.toml"
    job.write_text(f'part = "{WEDGE}"\n[[operation]]\nprofile = "hole"\nspindle = 1e-9\n')
    result = invoke("job", str(job), "-o", str(tmp_path / "j.ngc"))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {job}: operation[1].spindle: 1e-09 rpm is out of range " \
                            "(allowed: 1 to 1e+06 rpm)\n"
    assert not (tmp_path / "j.ngc").exists()


# ----------------------------------------------------------------------------- short lines


CL_SOURCE = Path("/work/shared/corpus/cl/mech491_APT_SimpleMillPlane.cls")


def _short_dialect(tmp_path: Path, length: int, ending: str = "\\n") -> Path:
    text = (REPO / "postproc" / "dialects" / "linuxcnc.toml").read_text(encoding="utf-8")
    text = text.replace("max_line_length = 252", f"max_line_length = {length}", 1)
    text = text.replace('line_ending = "\\n"', f'line_ending = "{ending}"', 1)
    path = tmp_path / f"short{length}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("ending", ["\\n", "\\r\\n"], ids=["lf", "crlf"])
def test_a_header_wrapped_at_the_shortest_line_reads_back(tmp_path: Path, ending: str) -> None:
    """A 60-character line limit split the part's SHA-256 over two lines: verify could not read its own
    program back. At the shortest limit allowed (80) every fixed field keeps its words whole."""
    from prs3_post.core.input_files import file_sha256
    from prs3_post.emit.header_read import read_header

    dialect = _short_dialect(tmp_path, 80, ending)
    program = tmp_path / "p.ngc"
    made = invoke("demo", "--profile", "square", "--dialect", str(dialect), "-o", str(program))
    assert made.exit_code == 0, made.stderr
    lines = program.read_bytes().decode().split("\r\n" if ending == "\\r\\n" else "\n")
    assert max(len(line) for line in lines) <= (79 if ending == "\\r\\n" else 80)
    assert any(line.startswith("(  ") for line in lines)           # the header did wrap
    header = read_header(str(program))
    assert header is not None and header.part_sha256 == file_sha256(str(REPO / "postproc" / "parts" /
                                                                         "patel2020-wedge.stl"))
    checked = invoke("verify", str(program))
    assert (checked.exit_code, checked.stdout.splitlines()[-1]) == (0, "OK: within every limit and tolerance")


@pytest.mark.skipif(not CL_SOURCE.is_file(), reason="the shared corpus is not here")
def test_a_converted_program_with_short_lines_verifies_against_its_input(tmp_path: Path) -> None:
    dialect = _short_dialect(tmp_path, 80)
    made = invoke("convert", str(CL_SOURCE), "-d", str(tmp_path / "out"), "--part-origin", "0,-17.2,-856",
                  "--dialect", str(dialect))
    assert made.exit_code == 0, made.stdout + made.stderr
    program = tmp_path / "out" / "mech491_APT_SimpleMillPlane.ngc"
    assert max(len(line) for line in program.read_text().splitlines()) <= 80
    checked = invoke("verify", str(program), "--against", str(CL_SOURCE))
    assert (checked.exit_code, checked.stdout.splitlines()[-1]) == (0, "OK: within every limit and tolerance")


# ----------------------------------------------------------------------------- a converted program's counts


@pytest.fixture(scope="module")
def converted(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    if not CL_SOURCE.is_file():
        pytest.skip("the shared corpus is not here")
    out = tmp_path_factory.mktemp("converted")
    made = invoke("convert", str(CL_SOURCE), "-d", str(out), "--part-origin", "0,-17.2,-856")
    assert made.exit_code == 0, made.stdout + made.stderr
    return (out / "mech491_APT_SimpleMillPlane.ngc").read_text().splitlines()


def _edited(tmp_path: Path, lines: list[str], old: str, new: str | None) -> tuple[Path, int]:
    """The program with the first line starting with ``old`` replaced (or removed: None); the counts' line."""
    at = next(i for i, line in enumerate(lines) if line.startswith(old))
    edited = [*lines[:at], *([] if new is None else [lines[at].replace(old, new, 1)]), *lines[at + 1:]]
    path = tmp_path / "edited.ngc"
    path.write_text("\n".join(edited) + "\n")
    return path, next(i for i, line in enumerate(lines) if line.startswith("(counts: ")) + 1


@pytest.mark.parametrize("against", [True, False], ids=["against", "alone"])
def test_a_converted_program_whose_body_lost_a_line_fails_on_its_counts(tmp_path: Path, converted: list[str],
                                                                       against: bool) -> None:
    """A G1 line deleted (M2 still there): verify --against blamed the options; verify alone said OK."""
    path, line = _edited(tmp_path, converted, "G1 X-272.3120", None)
    result = invoke("verify", str(path), *(["--against", str(CL_SOURCE)] if against else []))
    assert (result.exit_code, result.stdout) == (1, "")
    assert result.stderr == (f"prs3-post: error: {path}:{line}: header: counts: 103 program moves, but the program "
                             "has 102 motion lines (G0/G1): its body was cut short or edited after it was written\n")


@pytest.mark.parametrize(("old", "new", "entry", "again"), [
    ("(counts: 82 records", "(counts: 81 records", "81 records", "82"),
    ("(counts: 82 records, 33 moves", "(counts: 82 records, 34 moves", "34 moves", "33"),
    ("(counts: 82 records, 33 moves, 2 arcs to 70 rows", "(counts: 82 records, 33 moves, 2 arcs to 71 rows",
     "71 arc rows", "70"),
    ("(counts: 82 records, 33 moves, 2 arcs to 70 rows, 0 cycle holes to 0 rows, 1 comments",
     "(counts: 82 records, 33 moves, 2 arcs to 70 rows, 0 cycle holes to 0 rows, 2 comments", "2 comments", "1"),
])
def test_a_converted_program_whose_counts_were_edited_fails_against_its_input(
        tmp_path: Path, converted: list[str], old: str, new: str, entry: str, again: str) -> None:
    path, line = _edited(tmp_path, converted, old, new)
    result = invoke("verify", str(path), "--against", str(CL_SOURCE))
    assert (result.exit_code, result.stdout) == (1, "")
    assert result.stderr == (f"prs3-post: error: {path}:{line}: header: counts: {entry}, but "
                             f"mech491_APT_SimpleMillPlane.cls converted again gives {again}: the header was edited, "
                             "or the program was made from another input or by another version\n")


# ----------------------------------------------------------------------------- numbers that are not plain


POSES_HEADER = "tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n"


@pytest.mark.parametrize("cell", ["1_0", "\uff11", "\u0661"])
def test_a_pose_table_number_is_a_plain_decimal(tmp_path: Path, cell: str) -> None:
    """float() took '1_0' as 10 and a full-width '１' as 1 (numpy's parser refused them, the careful reader
    after it did not)."""
    poses = tmp_path / "p.csv"
    poses.write_text(f"{POSES_HEADER}{cell},200,-680,0,0,1\n", encoding="utf-8")
    result = invoke("ik", "--batch", str(poses))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {poses}:2: not a number: '{cell}'\n"


def test_a_pose_table_with_spaces_and_crlf_still_reads(tmp_path: Path) -> None:
    poses = tmp_path / "p.csv"
    poses.write_bytes(f"{POSES_HEADER}0, 200,-680 ,0,0,1\r\n".encode())
    result = invoke("ik", "--batch", str(poses))
    assert result.exit_code == 0, result.stderr
    assert result.stdout.splitlines()[1].startswith("0.000000000,200.000000000,-680.000000000,")


@pytest.mark.parametrize("cell", ["\uff11", "\u0661"])
def test_a_cl_number_is_made_of_ascii_digits(tmp_path: Path, cell: str) -> None:
    """GOTO/１,２,-1 was converted as GOTO/1,2,-1 (the record reader's \\d took any digit)."""
    source = tmp_path / "u.cls"
    source.write_text(f"UNITS/MM\nFEDRAT/MMPM,100\nRAPID\nGOTO/0,0,5\nGOTO/{cell},2,-1\nFINI\n", encoding="utf-8")
    result = invoke("convert", str(source), "-d", str(tmp_path / "out"), "--part-origin=0,0,-850")
    assert result.exit_code == 2
    assert result.stdout == (f"failed\t{source}\t-\t{source}:5: GOTO/ value 1: '{cell}' is not a number (expected a "
                             "decimal like -12.5, .5 or 1.5E+02)\n")
    assert list((tmp_path / "out").iterdir()) == []


def test_a_text_file_that_is_not_an_stl_is_shown_as_written(tmp_path: Path) -> None:
    part = tmp_path / "u.stl"
    part.write_text("ｓｏｌｉｄ x\n", encoding="utf-8")
    result = invoke("faces", str(part))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {part}: not an STL file (expected ASCII 'solid ...' or binary STL): "
                             "text starting with 'ｓｏｌｉｄ x' instead of 'solid'\n")


def test_a_work_plane_stl_is_read_with_up_and_part_units(tmp_path: Path) -> None:
    """--work-plane PART.stl was always read as mm and z up: a Y-up part had no face that faced up."""
    import trimesh

    wedge = trimesh.load(str(WEDGE))
    y_up = wedge.copy()
    y_up.vertices = np.column_stack([wedge.vertices[:, 0], wedge.vertices[:, 2], -wedge.vertices[:, 1]])
    y_up.export(str(tmp_path / "wedge_yup.stl"))
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    headers = []
    for plane, extra in ((f"{WEDGE}:4", []), (f"{tmp_path / 'wedge_yup.stl'}:4", ["--up", "y"])):
        out = tmp_path / f"out{len(headers)}"
        result = invoke("convert", str(tmp_path / "a.ngc"), "-d", str(out), "--work-plane", plane, *extra)
        assert result.exit_code == 0, result.stdout + result.stderr
        headers.append(next(line for line in (out / "a.ngc").read_text().splitlines()
                            if line.startswith("(work plane: ")))
    assert headers[1] == headers[0]


# ----------------------------------------------------------------------------- job files


LONG = "z" * 5000


@pytest.mark.parametrize(("body", "message"), [
    ("setup.part_origin = [1e300, 0, 0]\n[[operation]]\nprofile = \"hole\"\n",
     "setup.part_origin: part origin: each of x, y, z must be a finite number within ±100000 mm, got [1e+300, 0, 0]"),
    ("setup.part_rotation_deg = 1e300\n[[operation]]\nprofile = \"hole\"\n",
     "setup.part_rotation_deg: part rotation: must be a finite number within ±3600 degrees, got 1e+300"),
    (f"[[operation]]\nprofile = \"{LONG}\"\n",
     f"operation[1].profile: expected one of hole, square, round, got '{'z' * 39}…'"),
    ("[[operation]]\nprofile = \"HOLE\"\npeck = 2.0\n",      # was: profile HOLE does not use peck (hole only)
     "operation[1].profile: expected one of hole, square, round, got 'HOLE'"),
    ("[[operation]]\nprofile = 7\ndiameter = 20.0\n",
     "operation[1].profile: expected one of hole, square, round, got 7"),
    ("[[operation]]\nprofile = \"hole\"\nat = []\n",         # was: one hole at the face origin, as without 'at'
     "operation[1].at: expected a list of points like [[1.0, 2.0]], got []"),
    ("[[operation]]\nprofile = \"hole\"\nat_xyz = []\n",
     "operation[1].at_xyz: expected a list of points like [[1.0, 2.0, 3.0]], got []"),
    ("[[operation]]\nprofile = \"hole\"\nat_xyz = [1.0, 2.0, 3.0]\n",
     "operation[1].at_xyz: expected a list of points like [[1.0, 2.0, 3.0]], got [1.0, 2.0, 3.0]"),
    (f"[[operation]]\nprofile = \"hole\"\ndepth = \"{LONG}\"\n",
     f"operation[1].depth: expected a number, got '{'z' * 39}…'"),
    (f"[[operation]]\nprofile = \"hole\"\n{LONG} = 1\n",
     f"operation[1].{'z' * 39}…: unknown key (an operation has "),
    (f"{LONG} = 1\n[[operation]]\nprofile = \"hole\"\n", f"{'z' * 39}…: unknown key (a job file has "),
])
def test_a_job_file_error_names_its_key_and_shows_values_short(tmp_path: Path, body: str, message: str) -> None:
    """The setup's errors named operation[1] and '--part-origin'; a 5000-character value or key was printed
    in full."""
    job = tmp_path / "j.toml"
    job.write_text(f'part = "{WEDGE}"\n{body}')
    result = invoke("job", str(job), "-o", str(tmp_path / "j.ngc"))
    assert (result.exit_code, result.stdout) == (2, "")
    line = result.stderr.removesuffix("\n")
    assert "\n" not in line and len(line) < 500
    expected = f"prs3-post: error: {job}: {message}"
    assert line.startswith(expected) if message.endswith("has ") else line == expected
    assert not (tmp_path / "j.ngc").exists()


def test_a_long_tcp_code_list_is_shown_short(tmp_path: Path) -> None:
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", str(tmp_path / "a.ngc"), "-d", str(tmp_path / "out"), "--source", "vector",
                    "--tcp-on", "G" * 5000)
    assert _usage_error(result) == ("Error: Invalid value for '--tcp-on': expected G or M codes separated by commas "
                                    f"(e.g. G43.4,M428), got '{'G' * 39}…'")


def test_a_report_onto_a_loop_of_symbolic_links_is_a_clear_error(tmp_path: Path,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Path.resolve() raised RuntimeError('Symlink loop'): a traceback; and OUTDIR was made before the report
    was found unwritable."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    (tmp_path / "loop1").symlink_to("loop2")
    (tmp_path / "loop2").symlink_to("loop1")
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", "0,0,0,0,0,1", "--report", "loop1")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == "prs3-post: error: loop1: cannot write the output here: Too many levels of symbolic links\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc", "loop1", "loop2"]


@pytest.mark.parametrize("command", ["verify", "preview"])
def test_a_cl_file_given_as_a_program_says_to_convert_it(tmp_path: Path, command: str) -> None:
    """It said "not G-code: cannot read 'TOOL PATH/...' as words"."""
    source = tmp_path / "cam.cls"
    source.write_text("TOOL PATH/FACING,TOOL,MILL\nUNITS/MM\nFEDRAT/MMPM,100\nGOTO/0,0,5\nFINI\n")
    result = invoke(command, str(source), *(["-o", str(tmp_path / "p.png")] if command == "preview" else []))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {source}: an APT CL file (CAM output), not a program for this "
                             f"machine: convert it first (prs3-post convert {source} -o PROGRAM.ngc), then give the "
                             f"program, with --against {source} to compare them\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.cls"]


@pytest.mark.parametrize("command", ["verify", "preview"])
def test_a_five_axis_cam_program_given_as_a_program_says_to_convert_it_with_a_source(tmp_path: Path,
                                                                                   command: str) -> None:
    """It said "cam.ngc:2: not G-code: cannot read 'M428 ;TCP:xyzac' as words" (the corpus's LinuxCNC xyzac
    programs), or named the first A/B/C word as an unknown axis: the next step is convert with --source."""
    source = tmp_path / "cam.ngc"
    source.write_text("%\nM428 ;TCP:xyzac\nG21 G90\nG0 X0 Y0 Z10 A0 C0\nG1 Z0 A10 F100\nM2\n%\n")
    result = invoke(command, str(source), *(["-o", str(tmp_path / "p.png")] if command == "preview" else []))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {source}: 5-axis CAM output (it turns rotary axes: A, B or C words), "
                             "not a program for this machine: convert it first with the source machine it was written "
                             f"for (prs3-post convert {source} --source NAME -o PROGRAM.ngc; prs3-post sources lists "
                             f"them), then give the program, with --against {source} to compare them\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.ngc"]


@pytest.mark.parametrize(("text", "line", "column"), [
    ("G21 G90\rG0 X0\rM2\r", 1, 8),                       # CR-only line ends: one long line
    ("G21 G90\nG0 X0 Y0 U0 V100\r W0\nM2\n", 2, 17),
])
def test_a_cr_inside_a_line_is_named(tmp_path: Path, text: str, line: int, column: int) -> None:
    """It said "cannot read 'G21 G90G0 X0M2' as words" (the CR invisible), or that a CR-only file's one
    line is too long "with a CRLF line ending"."""
    program = tmp_path / "cr.ngc"
    program.write_bytes(text.encode())
    result = invoke("verify", str(program))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {program}:{line}: a CR character at column {column}, inside the "
                             "line: LinuxCNC reads LF or CRLF line ends (a file with CR-only line ends: save it with "
                             "LF)\n")


def test_fk_refuses_a_stage_position_on_a_machine_without_a_stage() -> None:
    """fk --xy 1,2 on patel2020-head moved the tip by (1, 2) mm: a stage that is not there."""
    result = invoke("fk", "--strokes", "100,100,100", "--xy", "1,2", "--machine", "patel2020-head")
    assert _usage_error(result) == ("Error: Invalid value for '--xy': machine patel2020-head has no stage "
                                    "(stage.present = false): the tip is where the head puts it; leave --xy out")
    alone = invoke("fk", "--strokes", "100,100,100", "--machine", "patel2020-head")
    assert (alone.exit_code, alone.stdout.splitlines()[0]) == (0, "tip   0.0000 0.0000 -704.4730 mm")


def test_an_automatic_part_origin_beyond_the_setups_range_is_a_limit_failure(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """With a 1 km tool the best origin is a kilometre down: it failed as bad input (exit 2) with the setup's check
    of a value the user never gave ('part origin: each of x, y, z must be ... within ±100000 mm')."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", "0,0,0,0,0,1", "--tool-length", "1e6",
                    "--part-origin", "auto", "--jobs", "1")
    assert result.exit_code == 1, result.stderr
    reason = result.stdout.split("\t")[3]
    assert reason.startswith("a.ngc: no part origin puts every point inside the machine's limits: the best one is "
                             "at machine [") and reason.endswith(
        "] mm, beyond the ±100000 mm a part origin may be from the machine's origin (is the tool length right?)\n")
    assert not (tmp_path / "out" / "a.ngc").exists()


@pytest.mark.parametrize(("option", "value"), [("--tool-diameter", "6"), ("--clearance-min", "3")])
def test_convert_refuses_the_parts_check_options_without_a_part(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                option: str, value: str) -> None:
    """They were taken and ignored (exit 0, the header saying 'collision: not checked (no part given)'): the user
    who gave a tool's diameter or a clearance believed the program checked."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", "0,0,0,0,0,1", option, value)
    assert _usage_error(result) == (f"Error: {option} is used only with --part PART.stl (the check against the "
                                    "part): give the part, or leave it out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc"]


@pytest.mark.parametrize("option", ["--tcp-on", "--tcp-off"])
def test_convert_refuses_tcp_codes_without_a_source(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    option: str) -> None:
    """--tcp-on G43.4 on a 3+2 program was taken and ignored (exit 0): only a 5-axis --source reads TCP codes."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", "0,0,0,0,0,1", option, "G43.4")
    assert _usage_error(result) == (f"Error: {option} is used only with --source (a 5-axis program's TCP codes): "
                                    "give the source machine, or leave it out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc"]


@pytest.mark.parametrize("word", ["", " "])
def test_convert_refuses_an_empty_word_to_ignore(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, word: str) -> None:
    """'--ignore ""' was taken (a word no record has) and the file converted as without it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    result = invoke("convert", "a.ngc", "-d", "out", "--work-plane", "0,0,0,0,0,1", "--ignore", word)
    assert _usage_error(result) == (f"Error: Invalid value for '--ignore': {word!r}: give a CL major word, "
                                    "like PAINT")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc"]


# ----------------------------------------------------------------------------- line ends and a byte-order mark

_CL = ("$$ line ends\nUNITS/MM\nFEDRAT/MMPM,100\nRAPID\nGOTO/0,0,5\nGOTO/0,0,-1\nGOTO/5,0,-1,$\n0,0,1\n"
       "CIRCLE/5,5,-1,0,0,1,5\nGOTO/10,5,-1\nFINI\n")


def _ascii_wedge() -> str:
    import trimesh

    return trimesh.exchange.stl.export_stl_ascii(trimesh.load(str(WEDGE), file_type="stl", force="mesh"))


@pytest.mark.parametrize("form", ["crlf", "cr", "one-line", "bom", "bom-cr"])
def test_an_ascii_stl_reads_alike_with_any_line_ends_and_a_bom(tmp_path: Path, form: str) -> None:
    """CR-only line ends (or the whole file on one line) said "'solid' has no matching 'endsolid'"; a UTF-8
    byte-order mark said "text starting with '\\ufeffsolid ...'" (the mark invisible)."""
    from prs3_post.part.stl import load_part

    text = _ascii_wedge()
    made = {"crlf": text.replace("\n", "\r\n"), "cr": text.replace("\n", "\r"), "one-line": text.replace("\n", " "),
            "bom": "\ufeff" + text, "bom-cr": "\ufeff" + text.replace("\n", "\r")}[form]
    (tmp_path / "lf.stl").write_bytes(text.encode())
    (tmp_path / "other.stl").write_bytes(made.encode())
    expected = load_part(str(tmp_path / "lf.stl"))
    read = load_part(str(tmp_path / "other.stl"))
    np.testing.assert_array_equal(read.vertices, expected.vertices)
    np.testing.assert_array_equal(read.faces, expected.faces)
    result = invoke("faces", str(tmp_path / "other.stl"))
    assert (result.exit_code, result.stdout) == (0, invoke("faces", str(tmp_path / "lf.stl")).stdout)


@pytest.mark.parametrize("ending", ["\r", "\r\n"])
def test_an_ascii_stl_error_names_its_line_with_any_line_ends(tmp_path: Path, ending: str) -> None:
    part = tmp_path / "bad.stl"
    part.write_bytes("\ufeffsolid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertx 1 0 0\nvertex 0 1 0\n"
                     "endloop\nendfacet\nendsolid t\n".replace("\n", ending).encode())
    result = invoke("faces", str(part))
    assert (result.exit_code, result.stderr) == (2, f"prs3-post: error: {part}:5: expected 'vertex', found 'vertx'\n")


@pytest.mark.parametrize("ending", ["\r", "\r\n"])
def test_a_cl_file_reads_alike_with_any_line_ends(tmp_path: Path, ending: str) -> None:
    """A CL file with CR-only line ends said "no moves in the file" (it was one line)."""
    from prs3_post.readers.cl.reader import read_cl

    (tmp_path / "lf.cls").write_bytes(_CL.encode())
    (tmp_path / "other.cls").write_bytes(("\ufeff" + _CL.replace("\n", ending)).encode())
    expected = read_cl(str(tmp_path / "lf.cls"), tolerance=0.01, circle_tolerance=CIRCLE_TOL).toolpath
    read = read_cl(str(tmp_path / "other.cls"), tolerance=0.01, circle_tolerance=CIRCLE_TOL).toolpath
    assert len(expected) > 4
    for column in ("kind", "tip", "axis", "feed", "source"):
        np.testing.assert_array_equal(getattr(read, column), getattr(expected, column))
    out = tmp_path / "out"
    result = invoke("convert", str(tmp_path / "other.cls"), "-d", str(out), "--part-origin=0,0,-850", "--jobs", "1")
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("ending", ["\r", "\r\n"])
def test_a_cl_error_names_its_line_with_any_line_ends(tmp_path: Path, ending: str) -> None:
    source = tmp_path / "bad.cls"
    source.write_bytes(_CL.replace("GOTO/10,5,-1", "GOTO/10,5").replace("\n", ending).encode())
    result = invoke("convert", str(source), "-d", str(tmp_path / "out"), "--part-origin=0,0,-850", "--jobs", "1")
    assert result.exit_code == 2
    assert result.stdout.split("\t")[3].startswith(f"{source}:10: "), result.stdout


@pytest.mark.parametrize("ending", ["\r", "\r\n"])
def test_a_pose_table_reads_alike_with_any_line_ends(tmp_path: Path, ending: str) -> None:
    """A table with CR-only line ends (a spreadsheet's "CSV (Macintosh)") was read as its header alone:
    ik --batch wrote no pose and exited 0."""
    table = f"{POSES_HEADER}0,200,-680,0,0,1\n5,200,-680,0,0,1\n\n0,210,-680,0,0,1\n"
    (tmp_path / "lf.csv").write_text(table)
    (tmp_path / "other.csv").write_bytes(table.replace("\n", ending).encode())
    expected = invoke("ik", "--batch", str(tmp_path / "lf.csv"))
    assert (expected.exit_code, len(expected.stdout.splitlines())) == (0, 4)
    result = invoke("ik", "--batch", str(tmp_path / "other.csv"))
    assert (result.exit_code, result.stdout) == (0, expected.stdout)
    (tmp_path / "bad.csv").write_bytes(table.replace("5,200", "x,200").replace("\n", ending).encode())
    result = invoke("ik", "--batch", str(tmp_path / "bad.csv"))
    assert (result.exit_code, result.stderr) == (2, f"prs3-post: error: {tmp_path / 'bad.csv'}:3: not a number: 'x'\n")


@pytest.mark.parametrize("ending", ["\r", "\r\n"])
def test_a_cam_gcode_program_reads_alike_with_any_line_ends(tmp_path: Path, ending: str) -> None:
    """convert of a CAM program with CR-only line ends said "cannot read 'G0 X0 Y0 Z5<CR>G1 Z-1 ...' as words",
    its CRs printed raw into the message (a terminal overwrote the line with them)."""
    from prs3_post.readers.gcode.reader import read_gcode

    program = "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\n\nG1 X5\nG2 X10 Y0 I2.5 J0\nM2\n"
    (tmp_path / "lf.ngc").write_text(program)
    (tmp_path / "other.nc").write_bytes(program.replace("\n", ending).encode())
    expected = read_gcode(str(tmp_path / "lf.ngc"), tolerance=0.01, circle_tolerance=CIRCLE_TOL).toolpath
    read = read_gcode(str(tmp_path / "other.nc"), tolerance=0.01, circle_tolerance=CIRCLE_TOL).toolpath
    assert len(expected) > 4
    for column in ("kind", "tip", "axis", "feed", "source"):
        np.testing.assert_array_equal(getattr(read, column), getattr(expected, column))
    result = invoke("convert", str(tmp_path / "other.nc"), "-d", str(tmp_path / "out"), "--part-origin=0,0,-850",
                    "--jobs", "1")
    assert result.exit_code == 0, result.output
    (tmp_path / "bad.nc").write_bytes(program.replace("X5", "X5 Q").replace("\n", ending).encode())
    result = invoke("convert", str(tmp_path / "bad.nc"), "-d", str(tmp_path / "out2"), "--part-origin=0,0,-850",
                    "--jobs", "1")
    assert result.exit_code == 2
    assert result.stdout.split("\t")[3].startswith(f"{tmp_path / 'bad.nc'}:5: "), result.stdout
    assert "\r" not in result.output
