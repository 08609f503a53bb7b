"""A batch's worker processes (`convert --jobs`): they die with the command, write nothing after it
has ended, and one that dies costs only the file it was converting.

Each test runs the batch in a child process whose workers stop at a known point of their program's
write (they say so, with their pid, on a pipe), so that the signals land at the same place every
time; every process a test started is killed by its pid when the test ends, whatever happened.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from prs3_post.app.workers import Died, run_tasks

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc to see the workers go")

#: The batch, each worker holding once its program's body is made (only writing it and renaming it
#: into place are left): it writes ``NAME PID`` on the pipe (fd argv[1]) and then, by argv[2]:
#: ``pause`` waits for a signal; ``outlive`` ignores SIGTERM and goes on once its parent is gone (a
#: worker that finishes after the command has ended); ``pause-a`` holds only the program of a.cls.
_HELD_BATCH = """
import os, signal, sys, time
from prs3_post.app import convert
from prs3_post.cli.main import main
from prs3_post.core.output_files import HeadLast

ready, mode, write_atomic, parent = int(sys.argv[1]), sys.argv[2], convert.write_atomic, os.getpid()

def held(path, chunks):
    yield from chunks
    if mode == "pause-a" and os.path.basename(path) != "a.ngc":
        return
    if mode == "outlive":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    os.write(ready, f"{os.path.basename(path)} {os.getpid()}\\n".encode())
    if mode == "outlive":
        deadline = time.monotonic() + 60
        while os.getppid() == parent and time.monotonic() < deadline:
            time.sleep(0.01)
        return
    while True:
        signal.pause()

def holding_write(path, data):
    if isinstance(data, HeadLast):
        data = HeadLast(body=held(path, data.body), head=data.head)
    else:
        data = held(path, data)
    write_atomic(path, data)

convert.write_atomic = holding_write
sys.argv[1:] = sys.argv[3:]
main()
"""


def _inputs(folder: Path, names: tuple[str, ...]) -> None:
    text = "UNITS/MM\nFEDRAT/MMPM,500\nRAPID\nGOTO/0,40,10\n" + "".join(
        f"GOTO/{40 * np.sin(t * 1e-2):.4f},{40 * np.cos(t * 1e-2):.4f},-1\n" for t in range(500))
    for name in names:
        (folder / name).write_text(text)


def _alive(pid: int) -> bool:
    """Running (a zombie no one has reaped yet has ended)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


def _gone_within(pids: list[int], seconds: float) -> list[int]:
    """The pids still running after up to ``seconds``."""
    deadline = time.monotonic() + seconds
    while (left := [pid for pid in pids if _alive(pid)]) and time.monotonic() < deadline:
        time.sleep(0.02)
    return left


class _Batch:
    """The held batch in a child process, and the workers that said they hold (name → pid)."""

    def __init__(self, folder: Path, mode: str, names: tuple[str, ...]) -> None:
        self.ready, ready_write = os.pipe()
        env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", _HELD_BATCH, str(ready_write), mode, "convert", *names, "-d", "out",
                 "--part-origin=0,0,-850", "--jobs", "2"],
                cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, pass_fds=(ready_write,))
        finally:
            os.close(ready_write)
        self.workers: dict[str, int] = {}
        self._said = b""

    def wait_for(self, count: int, seconds: float = 120) -> None:
        """Until ``count`` workers hold (no timing: they say so)."""
        deadline = time.monotonic() + seconds
        while len(self.workers) < count:
            if not select.select([self.ready], [], [], max(0.0, deadline - time.monotonic()))[0]:
                pytest.fail(f"{count} workers did not hold within {seconds} s")
            piece = os.read(self.ready, 4096)
            assert piece, "the batch ended before its workers held: " + self.process.communicate()[1].decode()
            self._said += piece
            *lines, self._said = self._said.split(b"\n")
            for line in lines:
                name, pid = line.decode().split()
                self.workers[name] = int(pid)

    def close(self) -> None:
        """Kill what is left of it, by pid."""
        os.close(self.ready)
        for pid in [*self.workers.values(), self.process.pid]:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        self.process.wait(timeout=30)


@pytest.mark.parametrize("parent_signal", [signal.SIGTERM, signal.SIGKILL])
def test_the_workers_die_with_the_command_and_write_nothing(tmp_path: Path, parent_signal: int) -> None:
    """`kill` or `kill -9` of the command while both workers are writing: the workers end too (they
    slept forever, and their programs appeared seconds after the command had ended)."""
    _inputs(tmp_path, ("a.cls", "b.cls"))
    batch = _Batch(tmp_path, "pause", ("a.cls", "b.cls"))
    try:
        batch.wait_for(2)
        os.kill(batch.process.pid, parent_signal)
        assert batch.process.wait(timeout=30) == -parent_signal
        assert _gone_within(list(batch.workers.values()), 30) == []
        assert sorted(os.listdir(tmp_path / "out")) == []          # no program, no temp file
    finally:
        batch.close()


def test_a_worker_that_finishes_after_the_command_has_ended_writes_nothing(tmp_path: Path) -> None:
    """Workers that go on after `kill -9` of the command (SIGTERM ignored: as where no signal tells
    them) do not rename their programs into place, and end."""
    _inputs(tmp_path, ("a.cls", "b.cls"))
    batch = _Batch(tmp_path, "outlive", ("a.cls", "b.cls"))
    try:
        batch.wait_for(2)
        os.kill(batch.process.pid, signal.SIGKILL)
        assert batch.process.wait(timeout=30) == -signal.SIGKILL
        assert _gone_within(list(batch.workers.values()), 30) == []
        assert sorted(os.listdir(tmp_path / "out")) == []
    finally:
        batch.close()


def test_a_killed_worker_costs_only_its_file(tmp_path: Path) -> None:
    """`kill -9` of the worker converting a.cls: one line says so, b.cls and c.cls are still converted
    (it was a BrokenProcessPool traceback, and the other worker's finished program was lost), exit 1."""
    _inputs(tmp_path, ("a.cls", "b.cls", "c.cls"))
    batch = _Batch(tmp_path, "pause-a", ("a.cls", "b.cls", "c.cls"))
    try:
        batch.wait_for(1)
        os.kill(batch.workers["a.ngc"], signal.SIGKILL)
        stdout, stderr = (stream.decode() for stream in batch.process.communicate(timeout=120))
        died = "a worker died while converting a.cls (signal 9)"
        assert "Traceback" not in stderr
        assert batch.process.returncode == 1, stderr
        assert f"failed\ta.cls\t-\t{died}\n" in stdout
        assert sorted(line.split("\t")[:2] for line in stdout.splitlines()) == [
            ["failed", "a.cls"], ["ok", "b.cls"], ["ok", "c.cls"]]
        assert stderr.splitlines()[0].startswith("prs3-post: converted 2 of 3 files, ")
        assert stderr.splitlines()[1:] == ["prs3-post: 1 failed:", f"  {died}"]
        assert sorted(os.listdir(tmp_path / "out")) == ["b.ngc", "c.ngc"]  # a.cls's temp file removed too
    finally:
        batch.close()


# ----------------------------------------------------------------------------- run_tasks itself


def _pid_of(task: int) -> tuple[int, int]:
    if task == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    return task, os.getpid()


def test_a_worker_killed_while_busy_fails_its_task_only() -> None:
    seen: dict[int, object] = {}
    left = run_tasks(_pid_of, [0, 1, 2, 3], 2, setup=lambda: None,
                     done=lambda task, result: seen.__setitem__(task, result) or False)
    assert left == []
    assert seen[1] == Died(-signal.SIGKILL)
    assert Died(-signal.SIGKILL).reason == "signal 9" and Died(3).reason == "exit status 3"
    assert [seen[t][0] for t in (0, 2, 3)] == [0, 2, 3]      # type: ignore[index]


def test_a_worker_killed_while_idle_is_replaced() -> None:
    """Its next task goes to a new worker (sending it to the dead one fails), not reported as killed."""
    seen: dict[int, object] = {}

    def done(task: int, result: object) -> bool:
        seen[task] = result
        if task == 0:                                   # the worker waits for its next task: kill it there
            pid = result[1]                             # type: ignore[index]
            os.kill(pid, signal.SIGKILL)
            assert _gone_within([pid], 30) == []
        return False

    assert run_tasks(lambda task: (task, os.getpid()), [0, 2], 1, setup=lambda: None, done=done) == []
    assert seen[2][0] == 2 and seen[2][1] != seen[0][1]  # type: ignore[index]


def _fails(task: int) -> int:
    if task == 1:
        raise ValueError("a bug")
    return task


def test_an_exception_of_the_work_is_raised_here_with_its_traceback() -> None:
    with pytest.raises(ValueError, match="a bug") as raised:
        run_tasks(_fails, [0, 1], 1, setup=lambda: None, done=lambda task, result: False)
    assert "in _fails" in str(raised.value.__cause__)


def test_a_stop_leaves_the_tasks_not_started() -> None:
    done: list[int] = []
    left = run_tasks(lambda task: task, [0, 1, 2, 3], 1, setup=lambda: None,
                     done=lambda task, result: done.append(task) or True)
    assert (done, left) == ([0], [1, 2, 3])
