"""Read ahead: a chunked stream's next items made on a second thread, or in a second process, while the
consumer works on this one.

Used where reading a chunk (bytes, lexing: C or numpy, which release the interpreter lock) and
using it (replay, post-processing) are both heavy: ``verify`` and ``convert``. The items come in
order, and an error of the producer is raised where its item would have come, so what a consumer
sees (values, messages, which error comes first) does not depend on the thread or process.

A thread shares the interpreter lock: the Python between numpy's loops on both sides takes turns.
:func:`read_in_process` runs the producer in a forked process instead, which sends each item
pickled through a pipe (a chunk of 10,000 rows: under a megabyte, some 0.3 ms each way), so that the
two really run at once; for a large input only (forking costs a few milliseconds).
"""

from __future__ import annotations

import os
import pickle
import signal
import threading
import warnings
from collections.abc import Callable, Iterable, Iterator
from queue import Full, Queue
from typing import TYPE_CHECKING, Any, TypeVar

from prs3_post.core.errors import Prs3Error

if TYPE_CHECKING:
    from multiprocessing.connection import Connection

__all__ = ["read_ahead", "read_in_process"]

_Item = TypeVar("_Item")
_Final = TypeVar("_Final")


def read_ahead(items: Iterable[_Item], depth: int = 2) -> Iterator[_Item]:
    """The items of ``items`` in order, produced by a thread up to ``depth`` ahead of the consumer:
    reading and lexing the next chunk of a program overlaps the replay of this one (numpy releases
    the interpreter lock in both). An exception of the producer is raised here, where its item
    would have come; a consumer that stops early stops the producer.
    """
    queue: Queue[tuple[str, Any]] = Queue(maxsize=max(1, depth))
    stop = threading.Event()

    def put(entry: tuple[str, Any]) -> bool:
        while not stop.is_set():
            try:
                queue.put(entry, timeout=0.05)
                return True
            except Full:
                continue
        return False

    def produce() -> None:
        try:
            for item in items:
                if not put(("item", item)):
                    return
            put(("end", None))
        except Exception as exc:
            put(("error", exc))

    thread = threading.Thread(target=produce, name="read-ahead", daemon=True)
    thread.start()
    try:
        while True:
            kind, value = queue.get()
            if kind == "item":
                yield value
            elif kind == "error":
                raise value
            else:
                return
    finally:
        stop.set()
        thread.join()


def read_in_process(items: Iterable[_Item], final: Callable[[], _Final],
                    on_final: Callable[[_Final], None]) -> Iterator[_Item]:
    """The items of ``items`` in order, produced by a forked child process; when they are all through,
    ``final()`` is evaluated there (the producer's state once done: a reader's summary) and given to
    ``on_final`` here. An exception of the producer is raised here, where its item would have come
    (it and the items must pickle; :class:`~prs3_post.core.errors.Prs3Error` and the toolpath types do).
    A consumer that stops early, or is interrupted (Ctrl-C: the child ignores SIGINT), kills the
    child; the child writes to nothing but the pipe, and leaves with ``os._exit`` (no cleanup of the
    parent's, such as removing a temp file, ever runs in it).
    """
    from multiprocessing.connection import Pipe  # only convert's large inputs need it (see test_startup)

    receive, send = Pipe(duplex=False)
    _widen(send)
    # no signal between the fork and the child's own handlers: the parent's Python handlers (the atomic
    # writer's) would unwind the parent's frames in the child, and remove the parent's temp file
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _CHILD_SIGNALS)
    try:
        with warnings.catch_warnings():
            # Python 3.12 warns about forking a process with threads (a lock another thread holds would
            # stay held in the child): the child here only reads a file and runs numpy's element-wise
            # code, and the threads this package starts (kinematics blocks, read_ahead) are joined
            # before they return
            warnings.simplefilter("ignore", DeprecationWarning)
            pid = os.fork()
        if pid == 0:                                   # the child: Ctrl-C is the parent's to act on, and
            for number, action in _CHILD_SIGNALS.items():   # a SIGTERM or SIGHUP ends it as the default does
                signal.signal(number, action)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
    if pid == 0:
        code = 0
        try:
            receive.close()
            _produce(items, final, send)
        except BaseException:                          # the parent went away (broken pipe), or worse
            code = 1
        finally:
            os._exit(code)
    send.close()
    try:
        while True:
            kind, value = pickle.loads(_receive(receive, pid))
            if kind == "item":
                yield value
            elif kind == "error":
                raise value
            else:
                on_final(value)
                return
    finally:
        receive.close()
        _reap(pid)


#: The child's handlers of the signals a terminal or a batch sends.
_CHILD_SIGNALS = {getattr(signal, name): action for name, action in
                  (("SIGINT", signal.SIG_IGN), ("SIGTERM", signal.SIG_DFL), ("SIGHUP", signal.SIG_DFL))
                  if hasattr(signal, name)}

#: Bytes the pipe holds (Linux's largest by default): the child runs a chunk or so ahead instead of
#: waiting, 64 KB into its next chunk, for the consumer to finish this one.
PIPE_BYTES = 1 << 20


def _widen(connection: Connection) -> None:
    """The pipe's buffer widened to :data:`PIPE_BYTES` where the system allows it (else left as it is)."""
    try:
        import fcntl

        fcntl.fcntl(connection.fileno(), fcntl.F_SETPIPE_SZ, PIPE_BYTES)
    except (ImportError, AttributeError, OSError):
        pass


def _produce(items: Iterable[Any], final: Callable[[], Any], send: Connection) -> None:
    try:
        for item in items:
            send.send_bytes(pickle.dumps(("item", item), protocol=pickle.HIGHEST_PROTOCOL))
        message = ("end", final())
    except Exception as exc:
        message = ("error", exc)
    try:
        data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:                                  # an error that does not pickle: its type and text
        error = message[1]
        data = pickle.dumps(("error", RuntimeError(f"{type(error).__name__}: {error}")))
    send.send_bytes(data)
    send.close()


def _receive(connection: Connection, pid: int) -> bytes:
    try:
        return connection.recv_bytes()
    except EOFError:                                   # the child died without a word (killed, out of memory)
        pass
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        guess = ", out of memory?" if number == signal.SIGKILL else ""
        how = f"was killed by signal {number} ({signal.Signals(number).name}{guess})"
    else:
        how = f"ended with status {os.waitstatus_to_exitcode(status)}"
    raise Prs3Error(f"the process reading the input {how} before the end of the input: nothing was converted")


def _reap(pid: int) -> None:
    """Wait for the child (killed first if still running: the consumer stopped early)."""
    try:
        done, _ = os.waitpid(pid, os.WNOHANG)
        if done == 0:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
    except ChildProcessError:                          # reaped already
        pass
