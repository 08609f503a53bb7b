"""Output never destroys anything: no output onto an input, FIFOs and devices written in place,
no temp file left by a signal, a program and its preview both or neither, full standard output
and impossible names reported (exit 2, no traceback)."""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main
from prs3_post.cli.options import demo_part
from prs3_post.core import output_files as output_module
from prs3_post.core.errors import InputError
from prs3_post.core.output_files import HeadLast, write_atomic, write_outputs

REPO = Path(__file__).resolve().parents[2]
WEDGE = REPO / "fixtures" / "parts" / "wedge.stl"
POSES = "tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n0,200,-680,0,0,1\n"


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def _error(path: str, message: str) -> str:
    return f"prs3-post: error: {path}: {message}\n"


# ----------------------------------------------------------------------------- -o onto an input

@pytest.fixture
def folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "part.stl").write_bytes(WEDGE.read_bytes())
    (tmp_path / "link.stl").symlink_to("part.stl")
    (tmp_path / "sub").mkdir()
    (tmp_path / "p.csv").write_text(POSES)
    (tmp_path / "bundled.stl").symlink_to(demo_part())
    return tmp_path


@pytest.mark.parametrize(("args", "message"), [
    (["part.stl", "--profile", "hole", "-o", "part.stl"],
     _error("part.stl", "is also the input PART.stl: writing --output would destroy it (choose another file)")),
    (["part.stl", "--profile", "hole", "-o", "./sub/../link.stl"],
     _error("./sub/../link.stl",
            "is also the input PART.stl: writing --output would destroy it (choose another file)")),
    (["link.stl", "--profile", "hole", "--preview", "./part.stl"],
     _error("./part.stl", "is also the input PART.stl: writing --preview would destroy it (choose another file)")),
    (["demo", "--profile", "hole", "-o", "x.png", "--preview", "./x.png"],
     _error("./x.png", "--output and --preview name the same file: one would overwrite the other")),
    (["ik", "--batch", "p.csv", "-o", "./p.csv"],
     _error("./p.csv", "is also the input --batch: writing --output would destroy it (choose another file)")),
    (["preview", "part.stl", "-o", "link.stl"],
     _error("link.stl", "is also the input PROGRAM.ngc: writing --output would destroy it (choose another file)")),
    (["demo", "--profile", "hole", "--machine", "./m.toml", "-o", "m.toml"],
     _error("m.toml", "is also the input --machine: writing --output would destroy it (choose another file)")),
    (["demo", "--profile", "hole", "-o", "bundled.stl"],
     _error("bundled.stl", "is also the input the demo part: writing --output would destroy it (choose another file)")),
])
def test_output_onto_an_input_is_refused_before_any_work(folder: Path, args: list[str], message: str) -> None:
    before = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    result = invoke(*args)
    assert (result.exit_code, result.stderr, result.stdout) == (2, message, "")
    assert {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()} == before
    assert (folder / "link.stl").is_symlink()


@pytest.mark.parametrize(("target", "input_name"), [
    ("jobs/tools.tbl", "tool_table of jobs/example.toml"),
    ("parts/../parts/twofaces.stl", "part of jobs/example.toml"),
])
def test_a_job_output_onto_a_file_the_job_names_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           target: str, input_name: str) -> None:
    """The job file names its part and tool table: -o onto either would destroy an input too."""
    monkeypatch.chdir(tmp_path)
    for folder_name in ("jobs", "parts"):
        (tmp_path / folder_name).mkdir()
    for name in ("jobs/example.toml", "jobs/tools.tbl", "parts/twofaces.stl"):
        (tmp_path / name).write_bytes((REPO / "fixtures" / name).read_bytes())
    before = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    result = invoke("job", "jobs/example.toml", "-o", target)
    message = f"is also the input {input_name}: writing --output would destroy it (choose another file)"
    assert (result.exit_code, result.stderr, result.stdout) == (2, _error(target, message), "")
    assert {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()} == before


# ----------------------------------------------------------------------------- what the target is

def test_a_fifo_is_written_into_not_replaced(tmp_path: Path) -> None:
    fifo = tmp_path / "f.ngc"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    result = invoke("demo", "--profile", "hole", "-o", str(fifo))
    reader.join(timeout=10)
    assert result.exit_code == 0
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    assert received == [invoke("demo", "--profile", "hole").stdout.encode()]
    assert [p.name for p in tmp_path.iterdir()] == ["f.ngc"]


def test_a_symbolic_link_is_written_through(tmp_path: Path) -> None:
    (tmp_path / "real.ngc").write_text("old\n")
    (tmp_path / "link.ngc").symlink_to("real.ngc")
    write_atomic(str(tmp_path / "link.ngc"), ["G0 ", b"X1\n"])
    assert (tmp_path / "link.ngc").is_symlink()
    assert (tmp_path / "real.ngc").read_text() == "G0 X1\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.ngc", "real.ngc"]


def test_a_too_long_name_is_a_clear_error(tmp_path: Path) -> None:
    name = str(tmp_path / ("a" * 300 + ".ngc"))
    result = invoke("demo", "--profile", "hole", "-o", name)
    assert (result.exit_code, result.stderr) == (2, _error(name, "cannot write the output here: File name too long"))
    assert list(tmp_path.iterdir()) == []


def test_a_long_name_that_fits_is_written(tmp_path: Path) -> None:
    """The temp file's name must not be longer than the system allows when the target's is not."""
    target = tmp_path / ("b" * 250)
    write_atomic(str(target), "x\n")
    assert [p.name for p in tmp_path.iterdir()] == [target.name]


# ----------------------------------------------------------------------------- both or neither

def test_a_failed_preview_leaves_no_program(tmp_path: Path) -> None:
    program = tmp_path / "new.ngc"
    result = invoke("demo", "--profile", "hole", "-o", str(program), "--preview", str(tmp_path / "no" / "x.png"))
    assert (result.exit_code, result.stderr) == (
        2, _error(str(tmp_path / "no" / "x.png"), "cannot write the output here: No such file or directory"))
    assert list(tmp_path.iterdir()) == []


def test_a_failed_rename_undoes_the_ones_before(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    first, second = tmp_path / "a.ngc", tmp_path / "b.png"
    first.write_text("old\n")
    real_replace = os.replace

    def replace(src, dst):
        if Path(dst) == second:
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    monkeypatch.setattr(output_module.os, "replace", replace)
    with pytest.raises(InputError) as caught:
        write_outputs([(str(first), "new\n"), (str(second), b"png")])
    assert str(caught.value) == f"{second}: cannot write the output: No space left on device"
    assert first.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc"]


# ----------------------------------------------------------------------------- signals and streams

_SIGNAL_SCRIPT = """
import os, signal, sys
from prs3_post.core.output_files import write_atomic
def chunks():
    yield "first half\\n"
    os.kill(os.getpid(), signal.{name})
    yield "second half\\n"
try:
    write_atomic(sys.argv[1], chunks())
except KeyboardInterrupt:
    print("interrupted")
"""


@pytest.mark.parametrize(("name", "returncode", "stdout"), [
    ("SIGTERM", -signal.SIGTERM, ""), ("SIGINT", 0, "interrupted\n"), ("SIGHUP", -signal.SIGHUP, ""),
])
def test_a_signal_during_a_write_leaves_no_temp_file(tmp_path: Path, name: str, returncode: int, stdout: str) -> None:
    target = tmp_path / "prog.ngc"
    target.write_text("old\n")
    done = subprocess.run([sys.executable, "-c", _SIGNAL_SCRIPT.format(name=name), str(target)],
                          capture_output=True, text=True, timeout=60, check=False)
    assert (done.returncode, done.stdout) == (returncode, stdout), done.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["prog.ngc"]
    assert target.read_text() == "old\n"


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize("args", [["demo", "--profile", "hole"], ["faces", str(WEDGE)], ["--help"], ["--version"],
                                  ["convert", "--help"]], ids=["demo", "faces", "help", "version", "convert-help"])
def test_full_standard_output_is_a_clear_error(args: list[str]) -> None:
    """Also the help and the version, which click printed itself: an OSError traceback before."""
    with open("/dev/full", "w") as full:
        done = subprocess.run([sys.executable, "-c", "from prs3_post.cli.main import main; main()", *args],
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=60, check=False)
    assert (done.returncode, done.stderr) == (
        2, "prs3-post: error: standard output: cannot write: No space left on device\n")


_CONSOLE_SCRIPT = "from prs3_post.cli.entry import main; main()"
_CLOSED = "prs3-post: error: standard output: cannot write: it is closed (redirect it to a file or to /dev/null)\n"


def _with_stdout_closed(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """The console script run as ``prs3-post ARGS >&-`` (DEVNULL is an open standard output, not a closed one)."""
    return subprocess.run([sys.executable, "-c", _CONSOLE_SCRIPT, *args], cwd=cwd, stdout=None,
                          stderr=subprocess.PIPE, text=True, timeout=120, check=False,
                          preexec_fn=lambda: os.close(1))


@pytest.mark.parametrize("args", [
    ["machines"], ["demo", "--profile", "hole"], ["faces", str(WEDGE)], ["fk", "--strokes", "300,300,300"],
    ["verify", "prog.ngc"], ["ik", "--batch", "poses.csv"], ["--version"]],
    ids=["machines", "demo", "faces", "fk", "verify", "ik-batch", "version"])
def test_closed_standard_output_is_a_clear_error(args: list[str], tmp_path: Path) -> None:
    """``prs3-post machines >&-``: Python's standard output is None, and every command ended in
    "AttributeError: 'NoneType' object has no attribute 'flush'" (a traceback, exit 1)."""
    (tmp_path / "poses.csv").write_text(POSES)
    assert invoke("demo", "--profile", "hole", "-o", str(tmp_path / "prog.ngc")).exit_code == 0
    done = _with_stdout_closed(*args, cwd=tmp_path)
    assert (done.returncode, done.stderr) == (2, _CLOSED)


def test_closed_standard_output_still_writes_complete_files(tmp_path: Path) -> None:
    """Files named by -o are written in full as with an open standard output: the program and the IK table
    (nothing for standard output: exit 0), convert's programs (its summary line for standard output: exit 2,
    as with a full one). Before, each ended in an AttributeError traceback."""
    (tmp_path / "poses.csv").write_text(POSES)
    (tmp_path / "part.cls").write_text("FEDRAT/100\nRAPID\nGOTO/0,0,100\nGOTO/0,0,0\nGOTO/10,0,0\n")
    open_dir, closed_dir = tmp_path / "open", tmp_path / "closed"
    runs = [(["demo", "--profile", "hole", "-o", "{}/prog.ngc"], 0, ""),
            (["ik", "--batch", str(tmp_path / "poses.csv"), "-o", "{}/strokes.csv"], 0, ""),
            (["convert", str(tmp_path / "part.cls"), "-d", "{}/programs", "--jobs", "1"], 2, _CLOSED)]
    for args, code, stderr in runs:
        for where in (open_dir, closed_dir):
            where.mkdir(exist_ok=True)
        assert invoke(*[a.format(open_dir) for a in args]).exit_code == 0
        done = _with_stdout_closed(*[a.format(closed_dir) for a in args], cwd=tmp_path)
        assert done.returncode == code, done.stderr
        if code:
            assert done.stderr == stderr
    written = sorted(str(p.relative_to(closed_dir)) for p in closed_dir.rglob("*") if p.is_file())
    assert written == ["prog.ngc", "programs/part.ngc", "strokes.csv"]
    for name in written:
        assert (closed_dir / name).read_bytes() == (open_dir / name).read_bytes(), name


_INTERRUPTED_IMPORT = """
import sys
class Interrupt:                       # Ctrl-C while the CLI's modules (numpy, click, ...) load
    def find_spec(self, name, path=None, target=None):
        if name == "prs3_post.cli.main":
            raise KeyboardInterrupt
sys.meta_path.insert(0, Interrupt())
from prs3_post.cli.entry import main
main()
"""


def test_ctrl_c_while_the_cli_loads_is_reported_as_later() -> None:
    """The console script runs prs3_post.cli.entry:main: Ctrl-C in the first half second (the imports) was a
    KeyboardInterrupt traceback; it is 'prs3-post: interrupted' and exit 130, as at any later moment (issue 20:
    click's 'Aborted!' and exit 1 were a limit violation's status)."""
    done = subprocess.run([sys.executable, "-c", _INTERRUPTED_IMPORT, "machines"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert (done.returncode, done.stdout, done.stderr) == (130, "", "prs3-post: interrupted\n")
    scripts = (REPO / "pyproject.toml").read_text().split("[project.scripts]\n")[1].splitlines()[0]
    assert scripts == 'prs3-post = "prs3_post.cli.entry:main"'


# ----------------------------------------------------------------------------- a head made last

def _head_last(made: list[str]) -> HeadLast:
    def body():
        for piece in ("G0 X1\n", b"G1 X2\n"):
            made.append("body")
            yield piece

    def head() -> str:
        made.append("head")
        return "(counts: 2 lines)\n"

    return HeadLast(body=body(), head=head)


def test_a_head_made_last_is_written_first(tmp_path: Path) -> None:
    made: list[str] = []
    target = tmp_path / "p.ngc"
    write_atomic(str(target), _head_last(made))
    assert made == ["body", "body", "head"]
    assert target.read_text() == "(counts: 2 lines)\nG0 X1\nG1 X2\n"
    assert [p.name for p in tmp_path.iterdir()] == ["p.ngc"]       # the spooled body left no file


def test_a_head_made_last_goes_first_into_a_fifo(tmp_path: Path) -> None:
    fifo = tmp_path / "f.ngc"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    write_atomic(str(fifo), _head_last([]))
    reader.join(timeout=10)
    assert received == [b"(counts: 2 lines)\nG0 X1\nG1 X2\n"]
    assert stat.S_ISFIFO(fifo.lstat().st_mode)


def test_a_body_that_fails_leaves_nothing_and_makes_no_head(tmp_path: Path) -> None:
    made: list[str] = []

    def body():
        yield "G0 X1\n"
        raise InputError("bad line", path="in.cls", line=3)

    target = tmp_path / "p.ngc"
    target.write_text("old\n")
    with pytest.raises(InputError, match=r"in\.cls:3: bad line"):
        write_atomic(str(target), HeadLast(body=body(), head=lambda: made.append("head") or ""))
    assert made == []
    assert [p.name for p in tmp_path.iterdir()] == ["p.ngc"]
    assert target.read_text() == "old\n"


def test_chunks_for_standard_output_are_written_once_all_are_made(capfdbinary: pytest.CaptureFixture[bytes]) -> None:
    """A table streamed to standard output (ik --batch) whose third chunk fails wrote its first two;
    now nothing is written, as for a file."""
    def chunks():
        yield "a,b\n"
        yield b"1,2\n"
        raise InputError("not a number: 'x'", path="-", line=3)

    with pytest.raises(InputError, match=r"^<stdin>:3: not a number: 'x'$"):
        output_module.write_stdout(chunks())
    assert capfdbinary.readouterr().out == b""
    output_module.write_stdout(iter(["a,b\n", b"1,2\n"]))
    assert capfdbinary.readouterr().out == b"a,b\n1,2\n"
