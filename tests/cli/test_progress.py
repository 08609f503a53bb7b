"""Progress on long work (issue 20 §2): one bar that measures bytes read or rows replayed, drawn on
standard error only when it is a terminal. The commands run in their own process with standard error
on a pseudo-terminal (:func:`pty.openpty`) to see the bar, and on a pipe to see that nothing is drawn."""

from __future__ import annotations

import io
import os
import pty
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from prs3_post.cli.progress import ProgressBar

PLANE = ("--work-plane", "0,0,0,0,0,1")
#: A 3-axis program of some 2.4 MB: more than two of the readers' 1 MB pieces, so the bar has steps.
LINES = 90_000


def _program(folder: Path) -> Path:
    body = "".join(f"G1 X{(i % 400) / 100:.3f} Y{(i % 300) / 100:.3f} Z-1.000\n" for i in range(LINES))
    path = folder / "long.ngc"
    path.write_text(f"G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\n{body}M2\n")
    return path


def _cli(args: list[str], cwd: Path, *, terminal: bool) -> tuple[int, str, str]:
    """Exit status, standard output and standard error (a pseudo-terminal's bytes, or a pipe's)."""
    command = [sys.executable, "-c", "from prs3_post.cli.main import main; main()", *args]
    if not terminal:
        done = subprocess.run(command, cwd=cwd, capture_output=True, text=True, check=False)
        return done.returncode, done.stdout, done.stderr
    main, child = pty.openpty()
    with tempfile.TemporaryFile() as stdout:         # (a pipe read after the terminal could fill and block)
        process = subprocess.Popen(command, cwd=cwd, stdin=subprocess.DEVNULL, stdout=stdout, stderr=child)
        os.close(child)
        seen = b""
        while True:
            try:
                piece = os.read(main, 65536)
            except OSError:                              # the child's end closed (Linux: EIO)
                break
            if not piece:
                break
            seen += piece
        os.close(main)
        code = process.wait()
        stdout.seek(0)
        return code, stdout.read().decode(), seen.decode()


def _percents(stderr: str, label: str) -> list[int]:
    return [int(p) for p in re.findall(rf"\r?{label} \[[#.]{{30}}\] +(\d+)%", stderr)]


def test_convert_draws_one_bar_by_bytes_from_0_to_100(tmp_path: Path) -> None:
    source = _program(tmp_path)
    code, out, err = _cli(["convert", str(source), "-d", "out", *PLANE, "--jobs", "1"], tmp_path, terminal=True)
    assert code == 0, err
    shown = _percents(err, "converting")
    assert shown[0] == 0 and shown[-1] == 100
    assert shown == sorted(set(shown))                  # one bar, moving forward only
    assert any(0 < p < 100 for p in shown)              # steps between: not 0 % then at once 100 %
    assert err.count("converting [") == len(shown)
    assert (tmp_path / "out" / "long.ngc").is_file()
    assert out == ""                                    # on a terminal the bar replaces the per-file lines


def test_nothing_is_drawn_when_standard_error_is_not_a_terminal(tmp_path: Path) -> None:
    source = _program(tmp_path)
    code, out, err = _cli(["convert", str(source), "-d", "out", *PLANE, "--jobs", "1"], tmp_path, terminal=False)
    assert code == 0, err
    assert "[" not in err and "%" not in err and "\r" not in err
    assert out.startswith(f"ok\t{source}\tout/long.ngc\t{LINES + 2} moves")
    code, out, err = _cli(["verify", "out/long.ngc"], tmp_path, terminal=False)
    assert code == 0, err
    assert (err, "\r" in out) == ("", False)


def test_verify_and_preview_show_progress(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    source = _program(tmp_path)
    assert _cli(["convert", str(source), "-d", "out", *PLANE, "--jobs", "1"], tmp_path, terminal=False)[0] == 0
    code, out, err = _cli(["verify", "out/long.ngc"], tmp_path, terminal=True)
    assert code == 0, err
    assert out.endswith("OK: within every limit and tolerance\n")
    shown = _percents(err, "verifying")
    assert shown[-1] == 100 and shown == sorted(set(shown)) and any(0 < p < 100 for p in shown)
    code, out, err = _cli(["verify", "out/long.ngc", "--json"], tmp_path, terminal=True)   # read whole, then replayed
    assert code == 0, err
    assert _percents(err, "verifying")[-1] == 100
    code, out, err = _cli(["preview", "out/long.ngc", "-o", "long.png"], tmp_path, terminal=True)
    assert code == 0, err
    assert _percents(err, "replaying")[-1] == 100
    assert err.endswith("\ndrawing ...\r\nprs3-post: wrote long.png\r\n")


def test_a_bar_on_a_stream_that_is_no_terminal_writes_nothing() -> None:
    stream = io.StringIO()
    with ProgressBar("reading", stream=stream) as bar:
        for done in range(11):
            bar(done, 10)
    assert stream.getvalue() == ""


def test_a_bar_redraws_only_when_its_percent_changes() -> None:
    stream = io.StringIO()
    with ProgressBar("reading", stream=stream, enabled=True, after="drawing") as bar:
        for done in (0, 1, 2, 500, 999, 1000):
            bar(done, 1000)
    lines = stream.getvalue().split("\r")
    assert lines[1:] == ["reading [..............................]   0%",
                         "reading [###############...............]  50%",
                         "reading [#############################.]  99%",
                         "reading [##############################] 100%\ndrawing ...\n"]
