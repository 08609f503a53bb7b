"""No tracebacks: inputs that once crashed the tool are refused with a clear message (exit 2, no
output file): files that are not UTF-8, not regular or too large; degenerate or enormous parts;
numbers that no machine means (1e308, nan, 1_0)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
WEDGE = REPO / "fixtures" / "parts" / "wedge.stl"
DEMO_ARGS = ["demo", "--profile", "hole"]


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def _ascii_stl(path: Path, vertices: list[tuple[float, float, float]], faces: list[tuple[int, int, int]]) -> Path:
    lines = ["solid t"]
    for face in faces:
        lines += ["facet normal 0 0 0", "outer loop", *(f"vertex {' '.join(map(repr, vertices[i]))}" for i in face),
                  "endloop", "endfacet"]
    path.write_text("\n".join([*lines, "endsolid t", ""]))
    return path


# A closed tetrahedron whose four vertices lie on one line: every triangle has zero area.
FLAT = ([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0), (3.0, 0.0, 0.0)],
        [(0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)])
# The same tetrahedron, not flat, with one vertex at 1e155 mm.
HUGE = ([(0.0, 0.0, 0.0), (1e155, 0.0, 0.0), (0.0, 10.0, 0.0), (0.0, 0.0, 10.0)],
        [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])


# ----------------------------------------------------------------------------- files


@pytest.mark.parametrize("kind", ["machine", "dialect"])
def test_a_toml_file_that_is_not_utf8_is_a_config_error(tmp_path: Path, kind: str) -> None:
    source = REPO / "postproc" / f"{kind}s" / ("patel2020.toml" if kind == "machine" else "linuxcnc.toml")
    text = source.read_text(encoding="utf-8")
    latin1 = tmp_path / f"{kind}.toml"
    latin1.write_bytes(("# copied by José\n" + text).encode("latin-1", errors="replace"))
    out = tmp_path / "out.ngc"
    result = invoke(*DEMO_ARGS, f"--{kind}", str(latin1), "-o", str(out))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {latin1}:1: not UTF-8 text (byte 0xe9): save the file as UTF-8\n"
    assert not out.exists()


def test_a_device_is_not_read() -> None:
    result = invoke("faces", "/dev/zero")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == "prs3-post: error: /dev/zero: is a character device, not a regular file: give an STL file\n"


@pytest.mark.parametrize("command", [["faces"], ["verify"], ["ik", "--batch"]], ids=["faces", "verify", "ik"])
def test_a_fifo_is_refused_instead_of_waited_on(tmp_path: Path, command: list[str]) -> None:
    fifo = tmp_path / "input"
    os.mkfifo(fifo)
    done = subprocess.run([sys.executable, "-c", "from prs3_post.cli.main import main; main()", *command, str(fifo)],
                          capture_output=True, text=True, timeout=60, check=False)
    what = {"faces": "an STL file", "verify": "a G-code program", "ik": "a CSV file"}[command[0]]
    assert (done.returncode, done.stdout) == (2, "")
    assert done.stderr == f"prs3-post: error: {fifo}: is a FIFO (named pipe), not a regular file: give {what}\n"


def test_an_input_over_its_size_limit_is_refused(tmp_path: Path) -> None:
    big = tmp_path / "big.stl"
    with big.open("wb") as stream:                   # sparse: takes no room on the disk
        stream.truncate(500_000_001)
    result = invoke("faces", str(big))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {big}: is 500 MB, more than the 500 MB limit for an STL file\n"


# ----------------------------------------------------------------------------- parts


@pytest.mark.parametrize("command", [["faces"], ["faces", "--json"], ["run", "--profile", "hole"]],
                         ids=["faces", "json", "run"])
def test_a_part_of_zero_area_triangles_is_refused(tmp_path: Path, command: list[str]) -> None:
    """It used to give one face with a NaN normal: NaN rows in `faces`, a ValueError with --json."""
    flat = _ascii_stl(tmp_path / "flat.stl", *FLAT)
    result = invoke(command[0], str(flat), *command[1:], "-o" if command[0] == "run" else "--part-units",
                    str(tmp_path / "out.ngc") if command[0] == "run" else "mm")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {flat}: STL has no triangle with an area (all are flat slivers): "
                             "it encloses no solid\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["flat.stl"]


def test_zero_area_triangles_make_no_face() -> None:
    """find_faces on such a mesh (not through the reader): no face, rather than one with a NaN normal."""
    import trimesh

    from prs3_post.part.faces import find_faces

    mesh = trimesh.Trimesh(vertices=FLAT[0], faces=FLAT[1], process=False)
    assert find_faces(mesh) == ()


@pytest.mark.parametrize("command", [["faces"], ["run", "--profile", "hole"]], ids=["faces", "run"])
def test_a_part_with_enormous_coordinates_is_refused(tmp_path: Path, command: list[str]) -> None:
    huge = _ascii_stl(tmp_path / "huge.stl", *HUGE)
    result = invoke(command[0], str(huge), *command[1:])
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {huge}: coordinates reach 1e+155 mm: beyond ±1e+06 mm, the largest "
                             "part this tool handles (is the STL in the right units?)\n")


# ----------------------------------------------------------------------------- numbers

TOO_LONG = "1" + "0" * 300


@pytest.mark.parametrize(("args", "message"), [
    ([*DEMO_ARGS, "--at", "1_0,0"], "Invalid value for '--at': expected 2 plain decimal numbers U,V, got '1_0,0'"),
    ([*DEMO_ARGS, "--at", "1e308,0"],
     "Invalid value for '--at': U = 1e+308 mm is out of range (allowed: within ±1e+06 mm)"),
    ([*DEMO_ARGS, "--at", f"{TOO_LONG},0"],
     "Invalid value for '--at': U = 1e+300 mm is out of range (allowed: within ±1e+06 mm)"),
    ([*DEMO_ARGS, "--rotation", "1e308"],
     "Invalid value for '--rotation': 1e+308 degrees is out of range (allowed: -3600 to 3600 degrees)"),
    ([*DEMO_ARGS, "--depth", "1_0"],
     "Invalid value for '--depth': expected a plain decimal number (like 12.5 or -0.25), got '1_0'"),
    ([*DEMO_ARGS, "--feed", "inf"],
     "Invalid value for '--feed': expected a plain decimal number (like 12.5 or -0.25), got 'inf'"),
    ([*DEMO_ARGS, "--size", TOO_LONG + "x"],
     "Invalid value for '--size': expected a plain decimal number (like 12.5 or -0.25), "
     f"got '{TOO_LONG[:39]}…'"),
    ([*DEMO_ARGS, "--part-rotation", "٣"],
     "Invalid value for '--part-rotation': expected a plain decimal number (like 12.5 or -0.25), got '٣'"),
    (["preview", "p.ngc", "-o", "p.png", "--part-origin=1e308,0,0"],
     "Invalid value for '--part-origin': X = 1e+308 mm is out of range (allowed: within ±1e+06 mm)"),
    (["preview", "p.ngc", "-o", "p.png", "--rapid-rate", "nan"],
     "Invalid value for '--rapid-rate': expected a plain decimal number (like 12.5 or -0.25), got 'nan'"),
    (["preview", "p.ngc", "-o", "p.png", "--rapid-rate", "0"],
     "Invalid value for '--rapid-rate': 0 mm/min is out of range (allowed: > 0 and ≤ 1e+06 mm/min)"),
    (["ik", "--tip", "0,200,-680", "--axis", "0,0,1e400"],
     "Invalid value for '--axis': K = inf is out of range (allowed: within ±1e+06)"),
    ([*DEMO_ARGS, "--tool-number", "1_0"],
     "Invalid value for '--tool-number': expected a whole number (like 12), got '1_0'"),
    ([*DEMO_ARGS, "--tool-number", TOO_LONG],
     "Invalid value for '--tool-number': 1e+300 is out of range (allowed: at most 30 digits)"),
    ([*DEMO_ARGS, "--line-numbers", "--line-step", "5000"],
     "Invalid value for '--line-step': 5000 is out of range (allowed: 1 to 1000)"),
    (["fk", "--strokes", " 1,2,3"], "Invalid value for '--strokes': expected 3 plain decimal numbers T1,T2,T3, "
                                    "got ' 1,2,3'"),
])
def test_numbers_are_plain_decimals_of_meaningful_size(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       args: list[str], message: str) -> None:
    monkeypatch.chdir(tmp_path)
    result = invoke(*args)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == f"Error: {message}"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", ["12.5", "-0.25", ".5", "5.", "+3", "1e-3", "2E+1"])
def test_plain_decimals_are_accepted(value: str) -> None:
    result = invoke("demo", "--profile", "square", "--rotation", value, "--ramp-angle", "2.5")
    assert result.exit_code == 0, result.stderr


def test_every_program_reader_refuses_a_fifo(tmp_path: Path) -> None:
    """The streaming reader, the header reader and the source hash open files through open_input too."""
    from prs3_post.core.errors import InputError
    from prs3_post.core.input_files import file_sha256
    from prs3_post.emit.header_read import read_header
    from prs3_post.machine.loading import load_dialect
    from prs3_post.readers.program import ProgramStream

    fifo = tmp_path / "prog.ngc"
    os.mkfifo(fifo)
    message = f"{fifo}: is a FIFO (named pipe), not a regular file: give "
    for read, what in ((lambda: list(ProgramStream(str(fifo), load_dialect("linuxcnc"))), "a G-code program"),
                       (lambda: read_header(str(fifo)), "a G-code program"),
                       (lambda: file_sha256(str(fifo)), "a file")):
        with pytest.raises(InputError) as caught:
            read()
        assert str(caught.value) == message + what


@pytest.mark.parametrize("command", ["verify", "preview"])
def test_a_program_value_no_machine_means_is_refused(tmp_path: Path, command: str) -> None:
    """verify used to print it in full: 150-digit stage positions, margins and times."""
    program = invoke(*DEMO_ARGS).stdout.splitlines()
    line = next(i for i, text in enumerate(program) if text.startswith("G0 X"))
    program[line] = "G0 X" + "9" * 150 + ".0" + program[line][program[line].index(" Y"):]
    path = tmp_path / "big.ngc"
    path.write_text("\n".join(program) + "\n")
    result = invoke(command, str(path), *(["-o", str(tmp_path / "big.png")] if command == "preview" else []))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {path}:{line + 1}: X 1e+150 mm is out of range "
                             "(allowed: within ±1e+06 mm)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.ngc"]


_BELOW = "mm is below the program's resolution, 0.0001 mm (dialect linuxcnc writes lengths to 4 decimals), so the " \
         "program could not show it: give at least 0.0001 mm"


@pytest.mark.parametrize(("args", "message"), [
    # below the resolution (issue 20 §3): refused as every such length is, before any pass is counted
    (["demo", "--profile", "square", "--step-down", "1e-320"],
     f"Error: Invalid value for '--step-down': 9.99989e-321 {_BELOW}"),
    (["demo", "--profile", "hole", "--peck", "1e-320", "--reapproach-gap", "0"],
     f"Error: Invalid value for '--peck': 9.99989e-321 {_BELOW} (or 0: no pecking)"),
    (["demo", "--profile", "square", "--step-down", "0.0001"],
     "prs3-post: error: --depth 2 mm in --step-down 0.0001 mm steps would take 20000 passes (at most 10000): use "
     "a larger --step-down"),
])
def test_a_subnormal_step_is_refused(tmp_path: Path, args: list[str], message: str) -> None:
    """Found by the fuzz test: depth / 1e-320 is infinite, and counting its passes was an OverflowError."""
    result = invoke(*args, "-o", str(tmp_path / "out.ngc"))
    assert (result.exit_code, result.stderr.splitlines()[-1]) == (2, message)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("value", "shown"), [("1e300", "'1e300'"), ("1" + "0" * 400, "'1" + "0" * 39 + "...'")])
def test_a_huge_cl_coordinate_is_bad_input_shown_in_a_few_digits(tmp_path: Path, value: str, shown: str) -> None:
    """A CL point at 1e300 mm was a stage limit failure (exit 1), 400 digits a 'NaN or infinite' one: both are
    input errors at the line, the value shown as written and cut to 40 characters."""
    cl = tmp_path / "far.cls"
    cl.write_text(f"UNITS/MM\nFEDRAT/MMPM,100\nRAPID\nGOTO/{value},0,0\nFINI\n")    # RAPID: a feed cannot come first
    result = invoke("convert", str(cl), "-d", str(tmp_path / "out"), "--part-origin", "0,0,-680")
    assert result.exit_code == 2
    problem = "is out of range (allowed: within ±1e+06 mm; is the file in the right units?)" if len(value) < 300 \
        else "is too large to be a finite number"
    assert result.stdout == f"failed\t{cl}\t-\t{cl}:4: GOTO/ value 1: {shown} {problem}\n"
    assert "Traceback" not in result.output and list((tmp_path / "out").iterdir()) == []


@pytest.mark.parametrize("number", ["1_0", "\u0661", "1,5", "\uff11"])
def test_an_stl_number_is_a_plain_decimal(tmp_path: Path, number: str) -> None:
    """float() reads '1_0' as 10 and '١' as 1: an STL coordinate so written was read as that number. The value is
    shown as written (it was shown as the Latin-1 reading of its UTF-8 bytes, lowered: '١' as 'ù¡', '１' as 'ï¼')."""
    part = _ascii_stl(tmp_path / "part.stl", *HUGE)
    text = part.read_text(encoding="utf-8").replace("vertex 0.0 10.0 0.0", f"vertex 0.0 {number} 0.0", 1)
    part.write_text(text, encoding="utf-8")
    line = text.splitlines().index(f"vertex 0.0 {number} 0.0") + 1
    result = invoke("faces", str(part))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {part}:{line}: '{number}' is not a plain decimal number "
                             "(like -12.5 or 1.25e+01)\n")
