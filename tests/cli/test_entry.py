"""How the console script ends (issue 20 §2), each in its own process as a shell runs it:

- Ctrl-C (SIGINT): ``prs3-post: interrupted`` and exit status 130, no traceback, no temp file left;
- standard output's reader gone (``prs3-post machines | head -1``): quietly, exit status 141 (128 + SIGPIPE),
  while a program written to a file with -o is written whole;
- an optional dependency missing (matplotlib for a picture): exit status 2 and the command that installs it;
- ``--machine ''`` (and ``--dialect ''``, ``--source ''``): what a valid value is.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
WEDGE = str(REPO / "fixtures" / "parts" / "wedge.stl")
SMALL = str(REPO / "fixtures" / "verify" / "small.ngc")
CONSOLE = "from prs3_post.cli.entry import main; main()"
INTERRUPTED = "prs3-post: interrupted\n"
NO_MATPLOTLIB = "prs3-post: error: preview needs matplotlib: pip install 'prs3-post[plot]'\n"


def invoke(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="prs3-post")


def _console(*args: str, cwd: Path, prelude: str = "", **kwargs) -> subprocess.CompletedProcess[str]:
    """The console script, as ``prs3-post ARGS`` (``prelude``: Python run before it)."""
    kwargs.setdefault("stdout", subprocess.PIPE)
    return subprocess.run([sys.executable, "-c", prelude + CONSOLE, *args], cwd=cwd, stderr=subprocess.PIPE,
                          text=True, timeout=300, check=False, **kwargs)


# ----------------------------------------------------------------------------- Ctrl-C

#: The main job, with the program's write held after its first chunk: it says so on the readiness pipe
#: (fd argv[1]) and waits for a signal, so that the test interrupts it mid-file every time.
_HELD_JOB = """
import os, signal, sys
from prs3_post.cli import run

ready, write_outputs = int(sys.argv[1]), run.write_outputs

def held(chunks):
    for number, chunk in enumerate(chunks):
        yield chunk
        if number == 0:
            os.write(ready, b"w")
            while True:
                signal.pause()

def holding_write(items):
    write_outputs([(path, held(iter(data)) if not isinstance(data, (str, bytes)) else data) for path, data in items])

run.write_outputs = holding_write
sys.argv[1:] = sys.argv[2:]
"""


def _wait_ready(ready_read: int, process: subprocess.Popen[bytes]) -> None:
    if not select.select([ready_read], [], [], 300)[0]:
        process.kill()
        pytest.fail("the command neither wrote nor ended in 300 s")
    assert os.read(ready_read, 1) == b"w", "it ended before writing: " + process.communicate()[1].decode()


def test_ctrl_c_while_writing_a_program_is_exit_130_and_leaves_nothing(tmp_path: Path) -> None:
    ready_read, ready_write = os.pipe()
    try:
        process = subprocess.Popen(
            [sys.executable, "-c", _HELD_JOB + CONSOLE, str(ready_write), "demo", "--profile", "round",
             "--step-down", "0.1", "-o", "prog.ngc"],
            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, pass_fds=(ready_write,))
        os.close(ready_write)
        _wait_ready(ready_read, process)
    finally:
        os.close(ready_read)
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]    # what the signal must clean up
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert (process.returncode, out, err) == (130, b"", INTERRUPTED.encode())
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_the_command_runs_is_exit_130(tmp_path: Path) -> None:
    """KeyboardInterrupt anywhere in a command (here: as the part is read) is the same one line."""
    prelude = ("import prs3_post.app.listings as listings\n"
               "def interrupted(*args, **kwargs):\n    raise KeyboardInterrupt\n"
               "listings.faces_text = interrupted\n")
    done = _console("faces", WEDGE, cwd=tmp_path, prelude=prelude)
    assert (done.returncode, done.stdout, done.stderr) == (130, "", INTERRUPTED)


# ----------------------------------------------------------------------------- standard output's reader gone


def _reader_gone(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``prs3-post ARGS | head -0``, made certain: the pipe's reading end is closed before the command starts."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return _console(*args, cwd=cwd, stdout=write_end)
    finally:
        os.close(write_end)


@pytest.mark.parametrize("args", [
    ["machines"], ["sources"], ["demo", "--profile", "hole"], ["faces", WEDGE], ["fk", "--strokes", "300,300,300"],
    ["verify", SMALL], ["--help"], ["--version"], ["convert", "--help"]],
    ids=["machines", "sources", "demo", "faces", "fk", "verify", "help", "version", "convert-help"])
def test_a_reader_that_went_away_ends_the_command_quietly_with_141(args: list[str], tmp_path: Path) -> None:
    done = _reader_gone(*args, cwd=tmp_path)
    assert (done.returncode, done.stderr) == (141, "")


def test_a_program_written_to_a_file_is_whole_when_standard_outputs_reader_went_away(tmp_path: Path) -> None:
    assert invoke("demo", "--profile", "square", "-o", tmp_path / "plain.ngc").exit_code == 0
    done = _reader_gone("demo", "--profile", "square", "-o", "piped.ngc", cwd=tmp_path)
    assert done.returncode == 0
    assert done.stderr.startswith("prs3-post: wrote piped.ngc: 49 lines, 20 moves; ")
    assert (tmp_path / "piped.ngc").read_text() == (tmp_path / "plain.ngc").read_text()


# ----------------------------------------------------------------------------- matplotlib missing

#: matplotlib cannot be imported (as where it is not installed).
_NO_MATPLOTLIB = "import sys\nsys.modules['matplotlib'] = None\nsys.modules['mpl_toolkits'] = None\n"


@pytest.mark.parametrize("args", [["preview", SMALL, "-o", "p.png"],
                                  ["demo", "--profile", "square", "-o", "p.ngc", "--preview", "p.png"]],
                         ids=["preview", "demo-preview"])
def test_a_picture_without_matplotlib_is_exit_2_with_the_install_command(args: list[str], tmp_path: Path) -> None:
    done = _console(*args, cwd=tmp_path, prelude=_NO_MATPLOTLIB)
    assert (done.returncode, done.stdout, done.stderr) == (2, "", NO_MATPLOTLIB)
    assert list(tmp_path.iterdir()) == []                 # neither the picture nor the program
    plain = _console("demo", "--profile", "square", "-o", "p.ngc", cwd=tmp_path, prelude=_NO_MATPLOTLIB)
    assert plain.returncode == 0, plain.stderr           # without a picture, matplotlib is not needed


# ----------------------------------------------------------------------------- an empty name


def _empty(kind: str, flag: str) -> str:
    names = {"machine": "patel2020, patel2020-head", "dialect": "fanuc, linuxcnc",
             "source": "haas-umc750, head-ab, vector, xyzac-trt"}[kind]
    return (f"Error: Invalid value for '{flag}': empty name (valid: a shipped {kind} name: {names}; or the path of a "
            f"{kind} TOML file)")


@pytest.mark.parametrize(("args", "kind", "flag"), [
    (["fk", "--strokes", "300,300,300", "--machine", ""], "machine", "--machine"),
    (["ik", "--tip", "0,0,-680", "--axis", "0,0,1", "--machine", ""], "machine", "--machine"),
    (["demo", "--profile", "hole", "--machine", ""], "machine", "--machine"),
    (["demo", "--profile", "hole", "--dialect", ""], "dialect", "--dialect"),
    (["verify", SMALL, "--machine", ""], "machine", "--machine"),
    (["preview", SMALL, "-o", "x.png", "--dialect", ""], "dialect", "--dialect"),
    (["convert", "x.cls", "-d", "out", "--machine", ""], "machine", "--machine"),
    (["convert", "x.cls", "-d", "out", "--source", ""], "source", "--source"),
], ids=["fk", "ik", "demo", "demo-dialect", "verify", "preview-dialect", "convert", "convert-source"])
def test_an_empty_machine_or_dialect_name_says_what_is_valid(args: list[str], kind: str, flag: str) -> None:
    result = invoke(*args)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == _empty(kind, flag)


def test_a_blank_machine_name_is_named_blank() -> None:
    result = invoke("fk", "--strokes", "300,300,300", "--machine", "  ")
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == _empty("machine", "--machine").replace("empty name", "blank name")


def test_an_empty_machine_in_a_job_file_names_its_key(tmp_path: Path) -> None:
    job = tmp_path / "job.toml"
    job.write_text((REPO / "fixtures" / "jobs" / "example.toml").read_text()
                   .replace('"../parts/twofaces.stl"', repr(str(REPO / "fixtures" / "parts" / "twofaces.stl")))
                   .replace('"tools.tbl"', repr(str(REPO / "fixtures" / "jobs" / "tools.tbl")))
                   .replace('up = "z"\n', 'up = "z"\nmachine = ""\n'))
    result = invoke("job", job, "-o", tmp_path / "x.ngc")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == (f"prs3-post: error: {job}: machine: empty name (valid: a shipped machine name: "
                             "patel2020, patel2020-head; or the path of a machine TOML file)\n")


def test_the_help_lists_every_exit_status() -> None:
    text = invoke("--help").stdout
    statuses = text.split("Exit status (every command):\n")[1].split("\n\n")[0].splitlines()
    assert [line.split()[0] for line in statuses] == ["0", "1", "2", "130", "141"]
    assert "  prs3-post verify part.ngc --part part.stl\n" in text
