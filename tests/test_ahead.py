"""Reading ahead in a forked process: the same items, errors and bytes as reading in this one.

``read_in_process`` is what ``convert`` uses for a large input (``PROCESS_READ_BYTES``); here the
threshold is lowered to 0 so that the corpus files and the bad inputs go through the child too.
"""

from __future__ import annotations

import json
import os
import pickle
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import compare_golden

import prs3_post.app.convert as convert
import prs3_post.app.read_ahead as ahead
from prs3_post.app.read_ahead import read_in_process
from prs3_post.cli.main import main
from prs3_post.core.errors import FeatureError, InputError, LimitError, Prs3Error
from prs3_post.core.toolpath import Event, EventKind, Toolpath
from prs3_post.emit.header import read_header

REPO = Path(__file__).resolve().parents[1]
CORPUS = REPO.parent / "shared" / "corpus" / "cl"
GOLDEN = REPO / "fixtures" / "golden"


def _children() -> set[int]:
    """The pids of this process's children that have not been reaped (zombies included)."""
    task = Path(f"/proc/{os.getpid()}/task")
    found: set[int] = set()
    for thread in task.iterdir():
        children = thread / "children"
        if children.exists():
            found |= {int(pid) for pid in children.read_text().split()}
    return found


def test_items_come_in_order_and_the_final_state_comes_back() -> None:
    state = {"done": False}

    def items():
        yield from range(50)
        state["done"] = True                           # in the child

    final = []
    assert list(read_in_process(items(), final=lambda: state["done"], on_final=final.append)) == list(range(50))
    assert final == [True]
    assert state == {"done": False}                    # the child's state, not this process's


def test_an_error_comes_where_its_item_would_have_come_with_its_attributes() -> None:
    def failing():
        yield from (1, 2, 3)
        raise InputError("GOTO/ needs 3 or 6 values, got 4", path="part.cls", line=4)

    seen = []
    with pytest.raises(InputError) as raised:
        for item in read_in_process(failing(), final=lambda: None, on_final=lambda _: None):
            seen.append(item)
    assert seen == [1, 2, 3]
    assert str(raised.value) == "part.cls:4: GOTO/ needs 3 or 6 values, got 4"
    assert (raised.value.path, raised.value.line, raised.value.exit_code) == ("part.cls", 4, 2)


def test_an_error_that_does_not_pickle_comes_as_its_type_and_text() -> None:
    class Local(Exception):                            # a class pickle cannot find by name
        pass

    def failing():
        yield 1
        raise Local("odd")

    with pytest.raises(RuntimeError, match=r"^Local: odd$"):
        list(read_in_process(failing(), final=lambda: None, on_final=lambda _: None))


def test_a_consumer_that_stops_early_leaves_no_child() -> None:
    def endless():
        n = 0
        while True:
            yield n
            n += 1

    before = _children()
    for item in read_in_process(endless(), final=lambda: None, on_final=lambda _: None):
        if item == 5:
            break
    assert _children() == before


def test_a_child_that_dies_is_an_error_not_an_end() -> None:
    def dying():
        yield 1
        os.kill(os.getpid(), signal.SIGKILL)
        yield 2

    with pytest.raises(Prs3Error) as raised:
        list(read_in_process(dying(), final=lambda: None, on_final=lambda _: None))
    assert str(raised.value) == ("the process reading the input was killed by signal 9 (SIGKILL, out of memory?) "
                                 "before the end of the input: nothing was converted")
    assert _children() == set()


@pytest.mark.parametrize("error", [InputError("bad", path="a.ngc", line=3), InputError("bad", path="a.ngc"),
                                   LimitError("T1 above"), FeatureError("too big", key="side", operation=2)])
def test_errors_pickle_with_their_attributes(error: Exception) -> None:
    back = pickle.loads(pickle.dumps(error))
    assert (type(back), str(back), back.__dict__) == (type(error), str(error), error.__dict__)


def test_a_toolpath_pickles_read_only() -> None:
    path = Toolpath(kind=[0, 1], tip=[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], axis=np.broadcast_to([0.0, 0.0, 1.0], (2, 3)),
                    feed=[0.0, 500.0], source=[3, 4], events=(Event(1, EventKind.COMMENT, text="x"),),
                    source_file="a.cls")
    back = pickle.loads(pickle.dumps(path, protocol=pickle.HIGHEST_PROTOCOL))
    for name in ("kind", "tip", "axis", "feed", "source"):
        assert np.array_equal(getattr(back, name), getattr(path, name))
        assert getattr(back, name).dtype == getattr(path, name).dtype
        assert not getattr(back, name).flags.writeable
    assert (back.events, back.source_labels, back.source_file) == (path.events, (), "a.cls")


@pytest.fixture
def in_process(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Every input read by a forked process (two threads allowed: the read-ahead's condition); the
    test fails if none was forked."""
    monkeypatch.setattr(convert, "PROCESS_READ_BYTES", 0)
    monkeypatch.setenv("PRS3_POST_THREADS", "2")
    forks = []
    fork = os.fork

    def counted() -> int:
        pid = fork()
        if pid:
            forks.append(pid)
        return pid

    monkeypatch.setattr(ahead.os, "fork", counted)
    yield
    assert forks, "no input was read by a forked process"


@pytest.mark.skipif(not CORPUS.is_dir(), reason="the corpus (../shared/corpus) is not here")
@pytest.mark.parametrize(("name", "origin"), [("humman_deep_drill.clsf", "94.5,0,-996"),
                                              ("mech491_APT_Variable_Axis.cls", "-44,-81.3,-786.7")])
def test_a_corpus_file_read_in_a_child_gives_the_golden_program(name: str, origin: str, tmp_path: Path,
                                                                in_process: None) -> None:
    cwd = os.getcwd()
    os.chdir(CORPUS)
    try:
        result = CliRunner().invoke(main, ["convert", name, "-o", str(tmp_path), "--jobs", "1",
                                           f"--part-origin={origin}"])
    finally:
        os.chdir(cwd)
    assert result.exit_code == 0, result.output
    compare_golden((tmp_path / (Path(name).stem + ".ngc")).read_text(), GOLDEN / f"convert-{Path(name).stem}.ngc",
                   update=False)


def test_a_g68_program_read_in_a_child_gives_the_golden_program(tmp_path: Path, in_process: None) -> None:
    src = REPO / "fixtures" / "gcode" / "g68-peck-arc.ngc"
    result = CliRunner().invoke(main, ["convert", str(src), "-o", str(tmp_path), "--jobs", "1",
                                       "--part-origin=-60.9,-10.9,-745"])
    assert result.exit_code == 0, result.output
    compare_golden((tmp_path / src.name).read_text(), GOLDEN / f"convert-{src.name}", update=False)


@pytest.mark.parametrize(("suffix", "text", "code", "reason"), [
    (".cls", "RAPID\nGOTO/1,2,3\nGOTO/1,2,$\n", 2,
     ":3: truncated record: 'GOTO/1,2,' continues with '$' but the file ends (a continued record needs its next line)"),
    (".ngc", "G21 G90\nG0 X0 Y0 Z5\nG1 X1 F100\nG1 X2 Y1e-05\n", 2,
     ":4: word 'E-05' is not G-code: E is not read here, and a number with an exponent (1e-05) must be written "
     "as a plain decimal (0.00001)"),
])
def test_a_bad_input_read_in_a_child_fails_with_its_message(suffix: str, text: str, code: int, reason: str,
                                                            tmp_path: Path, in_process: None) -> None:
    src = tmp_path / f"bad{suffix}"
    src.write_text(text)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(src), "-o", str(out), "--jobs", "1", "--part-origin=0,0,-850"])
    assert result.exit_code == code
    assert result.stdout.split("\t")[3].rstrip("\n") == f"{src}{reason}"
    assert list(out.iterdir()) == []
    assert _children() == set()


def test_a_point_out_of_reach_stops_the_reading_child(tmp_path: Path, in_process: None) -> None:
    """The error comes from this process (the post-processing) while the child still has lines to send:
    the child is stopped, nothing is written."""
    src = tmp_path / "far.cls"
    moves = "".join(f"GOTO/{k % 7},0,100\n" for k in range(60_000))
    src.write_text(f"FEDRAT/100\nRAPID\nGOTO/0,0,100\nGOTO/0,0,-500\n{moves}")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(src), "-o", str(out), "--jobs", "1"])
    assert result.exit_code == 1
    assert result.stdout.split("\t")[3].startswith(f"{src}:4: T1 stroke 865.5270 mm is above the maximum")
    assert list(out.iterdir()) == []
    assert _children() == set()


@pytest.mark.skipif(not CORPUS.is_dir(), reason="the corpus (../shared/corpus) is not here")
def test_the_report_of_a_file_post_processed_in_a_child_is_the_same(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The counts the child's post-processing and reader made come back: the same --report as in one process."""
    src = CORPUS / "mech491_APT_Variable_Axis.cls"
    reports = []
    for threshold in (1 << 60, 0):
        monkeypatch.setattr(convert, "PROCESS_READ_BYTES", threshold)
        monkeypatch.setenv("PRS3_POST_THREADS", "2")
        report = tmp_path / f"report-{len(reports)}.json"
        result = CliRunner().invoke(main, ["convert", str(src), "-o", str(tmp_path / f"out-{len(reports)}"),
                                           "--jobs", "1", "--part-origin=-44,-81.3,-786.7", "--report", str(report)])
        assert result.exit_code == 0, result.output
        files = json.loads(report.read_text())["files"]
        for entry in files:
            entry.pop("seconds", None)
            entry.pop("output", None)
        reports.append(files)
    assert reports[0] == reports[1]
    assert reports[0][0]["report"]["subdivisions"] > 0        # the axis turns: the child subdivided moves


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="F_SETPIPE_SZ is Linux's")
def test_the_pipe_holds_a_chunk() -> None:
    """A 64 KB pipe made the child wait for the consumer after 64 KB of its next chunk (0.7 s of wall
    clock on the million-line bench file against 0.95)."""
    import fcntl
    from multiprocessing.connection import Pipe

    receive, send = Pipe(duplex=False)
    try:
        ahead._widen(send)
        if int(Path("/proc/sys/fs/pipe-max-size").read_text()) < ahead.PIPE_BYTES:
            pytest.skip("this system's pipes are capped below 1 MB")
        assert fcntl.fcntl(send.fileno(), fcntl.F_GETPIPE_SZ) == ahead.PIPE_BYTES
    finally:
        receive.close()
        send.close()


#: A conversion whose every file is read by a forked process, held once its first chunk is emitted:
#: it says so on the file descriptor given, with its reading child's pid, and waits for a signal.
_HELD = """
import os, signal, sys
import prs3_post.app.convert as convert
import prs3_post.emit.gcode as gcode
from prs3_post.cli.main import main

ready = int(sys.argv[1])
convert.PROCESS_READ_BYTES = 0
os.environ["PRS3_POST_THREADS"] = "2"
rows = gcode.ProgramEmitter.rows

def held(self, program):
    text = rows(self, program)
    children = open(f"/proc/{os.getpid()}/task/{os.getpid()}/children").read().split()
    os.write(ready, (" ".join(children) + "\\n").encode())
    while True:
        signal.pause()

gcode.ProgramEmitter.rows = held
sys.argv[1:] = sys.argv[2:]
main()
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_to_the_group_leaves_no_file_and_no_child(tmp_path: Path, signum: int) -> None:
    """Ctrl-C (SIGINT) or SIGTERM to the process group while the child is reading: the temp file is
    removed (by the parent: the child never runs the parent's handlers), and the child has ended."""
    src = tmp_path / "part.cls"
    src.write_text("UNITS/MM\nFEDRAT/MMPM,500\nRAPID\nGOTO/0,40,10\n" + "".join(
        f"GOTO/{k % 40},{k % 37},-1\n" for k in range(30_000)))
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    ready_read, ready_write = os.pipe()
    try:
        process = subprocess.Popen(
            [sys.executable, "-c", _HELD, str(ready_write), "convert", str(src), "-o", str(out),
             "--part-origin=0,0,-850", "--jobs", "1"],
            env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            pass_fds=(ready_write,))
        os.close(ready_write)
        if not select.select([ready_read], [], [], 300)[0]:
            process.kill()
            pytest.fail("the conversion neither emitted nor ended in 300 s")
        said = os.read(ready_read, 200).decode().split()
        assert said, "the conversion ended first: " + process.communicate()[1].decode()
    finally:
        os.close(ready_read)
    child = int(said[0])
    assert len(list(out.glob(".*.tmp"))) == 1           # what the signal must clean up
    os.killpg(process.pid, signum)
    assert process.wait(timeout=60) != 0
    assert sorted(os.listdir(out)) == []
    assert _ended(child)


def _ended(pid: int, seconds: float = 30.0) -> bool:
    """Whether process ``pid`` is gone or a zombie (dead: a SIGTERM to the group ends the child as
    it ends the parent, whose Python no longer runs to reap it; init does) within ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return True
        if state == "Z":
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("forked", [True, False], ids=["forked", "one process"])
def test_an_input_replaced_while_it_is_read_is_hashed_as_it_was_read(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                      forked: bool) -> None:
    """An editor saving a new version over the input (or deleting it) while it is converted: the
    header's SHA-256 is that of the bytes converted (the reader hashes what it reads; the file
    was hashed again by name afterwards, which named the new file, or failed with 'file not
    found' once it was deleted)."""
    import hashlib

    from prs3_post.readers.gcode.reader import GcodeStream

    src = tmp_path / "part.ngc"
    src.write_text("G21 G90\nG0 X0 Y0 Z5\n" + "".join(f"G1 X{k % 40} Y{k % 37} Z-1 F500\n" for k in range(3000)))
    converted = hashlib.sha256(src.read_bytes()).hexdigest()
    newer = tmp_path / "newer.ngc"
    newer.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 X1 Y1 Z-1 F500\n")
    pieces = GcodeStream._pieces

    def replaced_after_the_first_piece(self: GcodeStream):
        self.piece_bytes = 4096                        # several pieces
        for number, piece in enumerate(pieces(self)):
            yield piece
            if number == 0:
                os.replace(newer, src)

    monkeypatch.setattr(GcodeStream, "_pieces", replaced_after_the_first_piece)
    monkeypatch.setattr(convert, "PROCESS_READ_BYTES", 0 if forked else 1 << 60)
    monkeypatch.setenv("PRS3_POST_THREADS", "2")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(src), "-o", str(out), "--jobs", "1", "--part-origin=0,0,-850"])
    assert result.exit_code == 0, result.output
    header = read_header(str(out / "part.ngc"))
    assert header.source_sha256 == converted
    assert header.counts is not None and header.counts.moves == 3001


@pytest.mark.parametrize("forked", [True, False], ids=["forked", "one process"])
def test_running_out_of_memory_is_one_line_not_a_traceback(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                          forked: bool) -> None:
    """QA ran convert under ``ulimit -v``: numpy's MemoryError, raised in the reading process and
    raised again here, ended in a traceback."""
    from prs3_post.cli.options import OUT_OF_MEMORY
    from prs3_post.readers.cl.reader import ClStream

    def starved(self: ClStream):
        raise MemoryError
        yield                                          # a generator, as the reader is

    monkeypatch.setattr(ClStream, "__iter__", starved)
    monkeypatch.setattr(convert, "PROCESS_READ_BYTES", 0 if forked else 1 << 60)
    monkeypatch.setenv("PRS3_POST_THREADS", "2")
    src = tmp_path / "part.cls"
    src.write_text("RAPID\nGOTO/0,0,10\nGOTO/1,0,10\n")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(src), "-o", str(out), "--jobs", "1", "--part-origin=0,0,-850"])
    assert (result.exit_code, result.stderr) == (1, f"prs3-post: error: {OUT_OF_MEMORY}\n")
    assert list(out.iterdir()) == []


@pytest.mark.skipif(not CORPUS.is_dir(), reason="the corpus (../shared/corpus) is not here")
def test_a_file_read_in_a_child_whose_results_are_kept_here(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the chunks' results are kept (convert_file; the collision check) the child only reads and
    places: the program, the report and the toolpath are those of one process."""
    from prs3_post.machine.loading import load_dialect, load_machine
    from prs3_post.part.setup_transform import Setup

    machine = load_machine("patel2020")
    settings = convert.ConvertSettings(machine=machine, dialect=load_dialect("linuxcnc"),
                                       setup=Setup.resolve(machine, (-44.0, -81.3, -786.7)))
    src = str(CORPUS / "mech491_APT_Variable_Axis.cls")
    monkeypatch.setenv("PRS3_POST_THREADS", "2")
    made = []
    for threshold in (1 << 60, 0):
        monkeypatch.setattr(convert, "PROCESS_READ_BYTES", threshold)
        made.append(convert.convert_file(src, settings))
    alone, forked = made
    assert forked.text == alone.text
    assert forked.report == alone.report
    assert np.array_equal(forked.path.tip, alone.path.tip)
