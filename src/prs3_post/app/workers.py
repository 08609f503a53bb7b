"""Worker processes for a batch (``convert --jobs``): each runs one task at a time, dies with the
command that started it, and its death costs only the task it held.

- Workers are forked: the work and its settings are inherited, not pickled. Each gets its tasks on
  its own pipe and sends each result back on it, so that the command always knows which task a
  worker holds.
- A worker dies with its parent, however the parent ends (``kill``, ``kill -9``): on Linux the
  kernel sends it SIGTERM then (``prctl(PR_SET_PDEATHSIG)``), and a program being written removes
  its temp file (:mod:`prs3_post.core.output_files`). Everywhere, its pipe then ends (no other
  process holds the command's end), so that an idle worker stops, and before any rename it checks
  that its parent is still there (:func:`~prs3_post.core.output_files.guard_commits`): nothing is
  written after the command has ended.
- A worker that dies holding a task (killed, out of memory) gives a :class:`Died` for that task, and
  a new worker takes its place for the tasks left.
- An exception of the work other than the results it returns is raised in the command, which
  stops the other workers first (as after Ctrl-C).
"""

from __future__ import annotations

import os
import signal
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from prs3_post.core.output_files import guard_commits

if TYPE_CHECKING:  # imported where used: one file converted in this process needs no process (test_startup)
    from multiprocessing.connection import Connection
    from multiprocessing.process import BaseProcess

_Result = TypeVar("_Result")

#: prctl(2)'s option: the signal a process gets when its parent ends.
_PR_SET_PDEATHSIG = 1
#: Seconds the workers get to stop by themselves after Ctrl-C before they are sent SIGTERM.
STOP_GRACE = 2.0


@dataclass(frozen=True, slots=True)
class Died:
    """A worker ended while it held a task (``exitcode``: negative, the signal that ended it)."""

    exitcode: int

    @property
    def reason(self) -> str:
        """``signal 9`` or ``exit status 3``."""
        return f"signal {-self.exitcode}" if self.exitcode < 0 else f"exit status {self.exitcode}"


class ParentGone(BaseException):
    """The command that started this worker has ended: stop, writing nothing (a BaseException, so
    that no handler of errors of the work takes it for one)."""


@dataclass(slots=True)
class _Worker:
    process: BaseProcess
    conn: Connection                    # the command's end of the worker's pipe
    task: int | None = None             # the task it holds


def run_tasks(work: Callable[[int], _Result], tasks: Sequence[int], jobs: int, *,
              setup: Callable[[], None], done: Callable[[int, _Result | Died], bool]) -> list[int]:
    """Run ``work(task)`` for every task in at most ``jobs`` worker processes.

    Parameters
    ----------
    work : called in a worker; its result must pickle
    setup : called in each worker when it starts
    done : called here with each task and its result (or :class:`Died`) as it comes; True stops the
        batch: no further task is started, those under way finish

    Returns
    -------
    list[int] — the tasks not started
    """
    import multiprocessing
    from multiprocessing.connection import wait

    context = multiprocessing.get_context("fork")
    parent = os.getpid()
    pending = list(tasks)
    workers: list[_Worker] = []

    def start() -> _Worker:
        ours, theirs = context.Pipe()
        inherited = [w.conn for w in workers] + [ours]         # the command's ends: closed in the worker
        process = context.Process(target=_serve, args=(theirs, work, setup, parent, inherited), daemon=True)
        process.start()
        theirs.close()
        worker = _Worker(process, ours)
        workers.append(worker)
        return worker

    def retire(worker: _Worker) -> None:
        worker.conn.close()
        worker.process.join()
        workers.remove(worker)

    def dispatch() -> None:
        while pending and not stop:
            idle = next((w for w in workers if w.task is None), None)
            if idle is None:
                return
            try:
                idle.conn.send(pending[0])
            except OSError:                             # it ended while idle (killed): another takes its place
                retire(idle)
                start()
                continue
            idle.task = pending.pop(0)

    stop = False
    try:
        for _ in range(min(jobs, len(pending))):
            start()
        while True:
            dispatch()
            busy = [w for w in workers if w.task is not None]
            if not busy:
                break
            ready = wait([w.conn for w in busy] + [w.process.sentinel for w in busy])
            for worker in busy:
                task = worker.task
                if task is None or (worker.conn not in ready and worker.process.sentinel not in ready):
                    continue
                result: _Result | Died = _result(worker)
                worker.task = None
                if isinstance(result, Died):
                    retire(worker)
                    result = Died(worker.process.exitcode or 0)
                    if pending and not stop:
                        start()
                stop = done(task, result) or stop
    except BaseException:                               # Ctrl-C, an error: stop the workers, whose writes clean up
        _stop(workers)
        raise
    for worker in workers:
        worker.conn.close()                             # the worker's next read ends: it exits
    for worker in workers:
        worker.process.join()
    return pending


def _result(worker: _Worker) -> Any:
    """What the worker sent (an exception of the work is raised), or :class:`Died` when it ended."""
    try:
        ok, value = worker.conn.recv()
    except (EOFError, OSError):
        return Died(0)                                  # the exit code is known once it is joined
    if not ok:
        error, trace = value
        raise error from _RemoteTraceback(trace)
    return value


class _RemoteTraceback(Exception):
    """Where in the worker an exception was raised (its traceback, as text)."""

    def __str__(self) -> str:
        return str(self.args[0])


def _stop(workers: list[_Worker]) -> None:
    """After Ctrl-C: a terminal sends SIGINT to every worker too, and each interrupted write removes its
    temp file; a second signal during that cleanup could cut it short, so SIGTERM goes only to the
    workers still running after :data:`STOP_GRACE` (those the signal did not reach)."""
    for worker in workers:
        worker.conn.close()                             # an idle worker exits at once
    deadline = time.monotonic() + STOP_GRACE
    for worker in workers:
        worker.process.join(max(0.0, deadline - time.monotonic()))
    for worker in workers:
        if worker.process.is_alive():
            worker.process.terminate()                  # SIGTERM: write_atomic removes its temp file
            worker.process.join()


def _serve(conn: Connection, work: Callable[[int], object], setup: Callable[[], None], parent: int,
           inherited: list[Connection]) -> None:
    """A worker's life: tasks from ``conn`` until it ends (the command closed it, or ended)."""
    try:
        for other in inherited:
            other.close()
        _die_with(parent)
        guard_commits(lambda: _check_parent(parent))
        setup()
        while True:
            try:
                task = conn.recv()
            except (EOFError, OSError):
                return
            try:
                message: tuple[bool, object] = (True, work(task))
            except Exception as exc:                    # raised in the command, with where it came from
                message = (False, (exc, "".join(traceback.format_exception(exc))))
            try:
                conn.send(message)
            except (BrokenPipeError, ConnectionResetError):
                return
            except Exception as exc:                    # a result or an exception that does not pickle
                conn.send((False, (RuntimeError(f"{type(exc).__name__}: {exc}"), "")))
    except (KeyboardInterrupt, ParentGone):             # Ctrl-C (the command stops the batch), or no command left
        return


def _die_with(parent: int) -> None:
    """Have the kernel send this process SIGTERM when ``parent`` ends (Linux; elsewhere the pipe's
    end and :func:`_check_parent` stop it); if it has ended already, stop now."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):                   # no prctl: not Linux
        pass
    _check_parent(parent)                               # it ended before the request took effect


def _check_parent(parent: int) -> None:
    """Raise :class:`ParentGone` when the command has ended (this process was given to another parent)."""
    if os.getppid() != parent:
        raise ParentGone
