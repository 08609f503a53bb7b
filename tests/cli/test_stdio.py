"""``-`` as a file name (issue 20 §2): standard input where one program, CL file or pose table is the
input (`convert -`, `verify -`, `preview -`, `ik --batch -`), standard output where one program or
report is the output (`convert ONE -o -`, `convert --report -`). Messages name standard input
``<stdin>``, with its line numbers; what cannot be read is refused with exit 2 and nothing written."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
CAM = REPO / "fixtures" / "gcode" / "g68-peck-arc.ngc"
CAM_ORIGIN = "--part-origin=-60.9,-10.9,-745"
GOLDEN = REPO / "fixtures" / "golden" / "convert-g68-peck-arc.ngc"
PROGRAM_3AXIS = "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X5\nM2\n"
PLANE = ("--work-plane", "0,0,0,0,0,1")
POSES = "tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n-81.0264,21.2132,-679.4865,0.447214,0,0.894427\n"


def invoke(*args: str, stdin: str | bytes | None = None):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post", input=stdin)


def run_process(*args: str, stdin: bytes | None = None, closed_stdin: bool = False,
                cwd: Path | None = None) -> subprocess.CompletedProcess[bytes]:
    """The CLI in its own process (standard input really closed, or bytes on it)."""
    return subprocess.run([sys.executable, "-c", "from prs3_post.cli.main import main; main()", *args],
                          input=None if closed_stdin else stdin or b"", capture_output=True, cwd=cwd, check=False,
                          preexec_fn=(lambda: os.close(0)) if closed_stdin else None)


def _error(done: subprocess.CompletedProcess[bytes]) -> str:
    """The error a command reported: ``prs3-post: error: ...``, or a conversion's per-file line."""
    first = done.stderr.decode().splitlines()[0]
    return first.removeprefix("prs3-post: error: ").removeprefix("failed\t<stdin>\t-\t")


@pytest.fixture
def program(tmp_path: Path) -> Path:
    """The demo's square, a program with a prs3-post header."""
    out = tmp_path / "sq.ngc"
    result = invoke("demo", "--profile", "square", "-o", str(out))
    assert result.exit_code == 0, result.stderr
    return out


# ----------------------------------------------------------------------------- standard input


def test_verify_reads_standard_input_as_it_reads_the_file(program: Path) -> None:
    from_file = invoke("verify", str(program), "--json")
    from_stdin = invoke("verify", "-", "--json", stdin=program.read_text())
    assert (from_file.exit_code, from_stdin.exit_code) == (0, 0), from_stdin.stderr
    a, b = json.loads(from_file.stdout), json.loads(from_stdin.stdout)
    assert (a["program"], b["program"]) == (str(program), "<stdin>")
    del a["program"], b["program"]
    assert a == b
    text = invoke("verify", "-", stdin=program.read_text())
    assert text.stdout.startswith("<stdin>: 20 moves (16 G1, 4 G0), dialect linuxcnc, machine patel2020\n")


def test_a_bad_line_on_standard_input_is_named_by_its_line(program: Path) -> None:
    lines = program.read_text().splitlines(keepends=True)
    lines[25] = "G1 X1 Q3\n"
    result = invoke("verify", "-", stdin="".join(lines))
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == ("prs3-post: error: <stdin>:26: word 'Q' is not used in prs3-post programs (words read: "
                             "G M N F S T P and the axes X Y U V W)\n")


def test_ik_batch_reads_standard_input(tmp_path: Path) -> None:
    table = tmp_path / "poses.csv"
    table.write_text(POSES)
    from_file = invoke("ik", "--batch", str(table))
    from_stdin = invoke("ik", "--batch", "-", stdin=POSES)
    assert (from_file.exit_code, from_stdin.exit_code) == (0, 0), from_stdin.stderr
    assert from_stdin.stdout == from_file.stdout
    assert from_stdin.stdout.splitlines()[1].split(",")[8:11] == ["36.224369832", "170.388568482", "88.951896690"]
    written = tmp_path / "strokes.csv"
    result = invoke("ik", "--batch", "-", "-o", str(written), stdin=POSES)
    assert (result.exit_code, result.stdout) == (0, "")
    assert written.read_text() == from_file.stdout


def test_convert_reads_standard_input_into_standard_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    from_file = invoke("convert", str(CAM), "-o", "-", CAM_ORIGIN)
    from_stdin = invoke("convert", "-", "-o", "-", CAM_ORIGIN, stdin=CAM.read_text())
    assert (from_file.exit_code, from_stdin.exit_code) == (0, 0), from_stdin.stderr
    assert list(tmp_path.iterdir()) == []
    assert from_file.stdout == GOLDEN.read_text()
    a, b = from_file.stdout.splitlines(), from_stdin.stdout.splitlines()
    assert a[3].startswith("(source: g68-peck-arc.ngc, format gcode, ")
    assert b[3] == a[3].replace("g68-peck-arc.ngc", "<stdin>")
    assert a[:3] + a[4:] == b[:3] + b[4:]
    assert from_stdin.stderr.startswith("ok\t<stdin>\t-\t")     # the per-file line: not among the program


def test_convert_of_standard_input_needs_one_output_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a.ngc").write_text(PROGRAM_3AXIS)
    into_folder = invoke("convert", "-", "-d", "out", *PLANE, stdin=PROGRAM_3AXIS)
    assert (into_folder.exit_code, into_folder.stdout) == (2, "")
    assert into_folder.stderr == ("prs3-post: error: <stdin>: standard input has no file name to name its program "
                                  "after: convert it alone, into one file or standard output (-o -)\n")
    with_others = invoke("convert", "-", "a.ngc", "-d", "out", *PLANE, stdin=PROGRAM_3AXIS)
    assert (with_others.exit_code, with_others.stdout) == (2, "")
    assert with_others.stderr == ("prs3-post: error: <stdin>: standard input is one input: convert it alone (with "
                                  "-o FILE or -o -), the other files in another command\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc"]
    into_file = invoke("convert", "-", "-o", "b.ngc", *PLANE, stdin=PROGRAM_3AXIS)
    assert into_file.exit_code == 0, into_file.stderr
    assert "(source: <stdin>, format gcode, " in (tmp_path / "b.ngc").read_text().splitlines()[3]


@pytest.mark.parametrize(("args", "message"), [
    (["verify", "-", "--against", "-"], "<stdin>: given for PROGRAM.ngc and --against: standard input is one "
                                        "input; give the other a file"),
    (["convert", "-", "-", "-o", "-", *PLANE], "<stdin>: given 2 times for INPUT...: standard input is one input; "
                                               "give it once"),
    (["preview", "-", "--part", "-", "-o", "x.png"], "<stdin>: given for PROGRAM.ngc and --part: standard input is "
                                                     "one input; give the other a file"),
])
def test_standard_input_given_twice_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str],
                                               message: str) -> None:
    monkeypatch.chdir(tmp_path)
    result = invoke(*args, stdin=PROGRAM_3AXIS)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == f"prs3-post: error: {message}\n"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "empty"), [
    (["verify", "-"], "<stdin>: not a G-code program: the file is empty"),
    (["convert", "-", "-o", "-", *PLANE], "<stdin>: the file is empty (0 bytes): nothing to convert"),
    (["ik", "--batch", "-"], "<stdin>:1: expected the header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z, got an empty "
                             "file"),
])
def test_closed_and_empty_standard_input_are_bad_input(tmp_path: Path, args: list[str], empty: str) -> None:
    closed = run_process(*args, closed_stdin=True, cwd=tmp_path)
    assert (closed.returncode, closed.stdout) == (2, b"")
    assert _error(closed) == "<stdin>: cannot read: it is closed (give a file, or redirect standard input from one)"
    nothing = run_process(*args, stdin=b"", cwd=tmp_path)
    assert (nothing.returncode, nothing.stdout) == (2, b"")
    assert _error(nothing) == empty
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "message"), [
    (["verify", "-"], "<stdin>: not a G-code program: binary data (byte 0x1a at offset 6)"),
    (["convert", "-", "-o", "-", *PLANE], "<stdin>: not a G-code program: binary data (byte 0x1a at offset 5)"),
    (["ik", "--batch", "-"], "<stdin>: not UTF-8 text"),
])
def test_binary_standard_input_is_bad_input(tmp_path: Path, args: list[str], message: str) -> None:
    png = b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 8
    done = run_process(*args, stdin=png, cwd=tmp_path)
    assert (done.returncode, done.stdout) == (2, b"")
    assert _error(done).startswith(message)
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- standard output


def test_convert_report_to_standard_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The JSON report alone on standard output; the per-file lines go to standard error."""
    monkeypatch.chdir(tmp_path)
    result = invoke("convert", str(CAM), "-d", "out", CAM_ORIGIN, "--report", "-")
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["summary"]["converted"] == 1
    assert report["files"][0]["output"] == "out/g68-peck-arc.ngc"
    assert (tmp_path / "out" / "g68-peck-arc.ngc").read_text() == GOLDEN.read_text()
    assert result.stderr.startswith(f"ok\t{CAM}\tout/g68-peck-arc.ngc\t")


def test_convert_to_standard_output_writes_nothing_of_a_failing_file(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A limit failure found at the end of the file: nothing of the program reaches standard output."""
    monkeypatch.chdir(tmp_path)
    far = PROGRAM_3AXIS.replace("G1 X5", "G1 X5\nG1 X900")
    result = invoke("convert", "-", "-o", "-", *PLANE, stdin=far)
    assert result.exit_code == 1
    assert result.stdout == ""
    assert result.stderr.startswith("failed\t<stdin>\t-\t<stdin>:5: ")
