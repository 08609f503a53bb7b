"""Writing the outputs (programs, tables, images) so that nothing is ever destroyed.

- A regular file, or a new one, is written to a hidden temp file ``.NAME.*.tmp`` in its folder and
  renamed over the target: a reader sees the old file or the new one, never half of one, and a
  failed write leaves the old file as it was.
- A FIFO or a device (``/dev/null``, a terminal) is written directly: a rename would replace the
  node with a regular file.
- A symbolic link is written through: the file it points to gets the new content, the link stays.
- SIGTERM, SIGINT and SIGHUP during a write remove the temp files, then act as they would have.
- Several outputs (a program and its preview) are written together, both or neither: every temp
  file is written first, then all are renamed (a rename that still fails undoes the ones before it).
- A process may guard its renames (:func:`guard_commits`): a batch's worker renames nothing once the
  command that started it has ended.
- Standard output that cannot be written (``> /dev/full``, a closed pipe, closed with ``>&-``) is an
  :class:`InputError`.

The data is text (written as UTF-8), bytes, or an iterable of such chunks, so that a large program
can be streamed without holding it whole. A :class:`HeadLast` is data whose opening is known only
once the rest is made (a program's header with the counts of a streamed conversion): its body is
spooled to an unnamed temp file first (next to the target; for a FIFO, a device or standard
output in the temp folder), then the head and the spooled body are written, so that memory stays
flat, and a FIFO or device gets nothing when making the body fails.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import os
import signal
import stat
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from prs3_post.core.errors import InputError, OutputClosed

Chunks = str | bytes | Iterable[str | bytes]
"""Text (UTF-8), bytes, or an iterable of text/bytes chunks."""


@dataclass(frozen=True, slots=True)
class HeadLast:
    """An output whose ``head`` (written first) is made after its ``body``: ``head()`` is called once
    the body's chunks are all made (and spooled), so that it can state what the body holds."""

    body: Chunks
    head: Callable[[], Chunks]


Output = Chunks | HeadLast
"""What an output takes: chunks, or a :class:`HeadLast`."""

_SPOOL_PIECE = 1 << 20  # bytes copied at a time from a spooled body

STDOUT = "standard output"
"""How messages name standard output."""

_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGINT", "SIGHUP") if hasattr(signal, name))
_STREAM_ERRNOS = {errno.ENOSPC, errno.EPIPE, errno.EIO, errno.EDQUOT, errno.EFBIG, errno.ENXIO, errno.ECONNRESET}
_TEMP_NAME_MAX = 60  # characters of the target's name kept in its temp file's name
_CLOSED_STDOUT = "it is closed (redirect it to a file or to /dev/null)"
_stdout_was_closed = False  # set once by guard_closed_stdout, for the process
_commit_guard: Callable[[], None] | None = None  # set by guard_commits, for the process


def guard_closed_stdout() -> None:
    """Make a standard output closed by the caller (``prs3-post machines >&-``) fail like a full one.

    Python then starts with ``sys.stdout = None``: every command ended in an AttributeError
    traceback, and file descriptor 1 was free for the next file opened (a program's temp file),
    which anything written to descriptor 1 would have gone into. /dev/null is opened on
    descriptor 1 read-only, and ``sys.stdout`` writes to it: the first write to standard output
    fails (EBADF) and is reported as one that cannot be written (exit 2), while files named by
    ``-o`` are written as always. An open standard output is left alone.
    """
    global _stdout_was_closed
    try:
        os.fstat(1)
        return
    except OSError:
        pass
    fd = os.open(os.devnull, os.O_RDONLY)
    if fd != 1:
        os.dup2(fd, 1)
        os.close(fd)
    sys.stdout = open(1, "w", encoding="utf-8", closefd=False)  # standard output, for the process
    _stdout_was_closed = True


def guard_commits(check: Callable[[], None] | None) -> None:
    """Call ``check()`` before this process renames any temp file into place, with SIGTERM, SIGINT
    and SIGHUP held back until the renames are done: when it raises, nothing is renamed, every temp
    file is removed and its exception propagates. None: no check (the default).

    A batch's worker process checks that the command that started it is still running, so that a
    program finished after the command has ended (killed) is not written: a signal that comes after
    the check waits for the renames, and one before it finds the command gone.
    """
    global _commit_guard
    _commit_guard = check


def remove_temp_files(path: str, since: float) -> None:
    """Remove the temp files of ``path`` (``.NAME.*.tmp`` beside it) changed at or after ``since``
    (:func:`time.time`): what a writer killed by SIGKILL leaves (no cleanup ran in it)."""
    target = Path(os.path.realpath(path))
    with contextlib.suppress(OSError):
        for tmp in target.parent.glob(f"{glob.escape(_temp_prefix(target))}*.tmp"):
            with contextlib.suppress(OSError):
                if tmp.lstat().st_mtime >= since:
                    tmp.unlink()


def is_stdout(path: str | None) -> bool:
    """No path, or ``-``: the output goes to standard output."""
    return path is None or path == "-"


def write_atomic(path: str, data: Output) -> None:
    """Write ``data`` to the file ``path`` without ever leaving half a file (see the module docstring).

    Raises
    ------
    InputError
        ``is a folder or empty: give a file name``, ``cannot write the output here: <reason>`` (no
        such folder, no permission, name too long), ``cannot write the output: <reason>``.
    """
    write_outputs([(path, data)])


def check_writable(path: str) -> None:
    """Fail now, as :func:`write_atomic` would at the end, when ``path`` cannot be written (no such
    folder, no permission, a folder, a name too long), so that a command can refuse before any work.
    A probe temp file is made in the folder and removed at once; a FIFO or device is not opened.

    Raises
    ------
    InputError
        As :func:`write_atomic`.
    """
    if is_stdout(path):
        return
    stage = _stage(path, b"")
    if stage.tmp is not None:
        stage.tmp.unlink(missing_ok=True)


def write_outputs(items: Sequence[tuple[str | None, Output]]) -> None:
    """Write several outputs, all or none: ``(path, data)`` pairs; a path of None or ``-`` is standard output.

    Every file output is first written to its temp file (FIFOs and devices: written directly,
    after the temp files), standard output next, and only then are the temp files renamed. So a
    folder that does not exist, a full disk or a broken pipe leaves every target as it was (what
    already went to standard output or into a FIFO cannot be taken back).

    Raises
    ------
    InputError
        As :func:`write_atomic`, naming the output that failed.
    """
    staged: list[_Staged] = []
    with _cleanup_on_signals():
        try:
            for path, data in items:
                if not is_stdout(path):
                    staged.append(_stage(str(path), data))
            for stage in staged:
                if stage.tmp is None:
                    _write_direct(stage)
            for path, data in items:
                if is_stdout(path):
                    write_stdout(data)
            _guarded_commit([s for s in staged if s.tmp is not None])
        finally:
            for stage in staged:
                if stage.tmp is not None:
                    stage.tmp.unlink(missing_ok=True)


def write_stdout(data: Output) -> None:
    """Write ``data`` to standard output (text through ``sys.stdout``, bytes to its buffer), once it is
    all made: chunks are spooled to an unnamed temp file first, so that an error while making them
    writes nothing (a program or table is whole or absent, on standard output as in a file).

    Raises
    ------
    InputError
        ``standard output: cannot write: No space left on device`` (or the pipe's reason).
    """
    if not isinstance(data, (str, bytes, HeadLast)):    # made whole first: a failure midway writes nothing
        data = HeadLast(body=data, head=lambda: b"")
    try:
        for chunk in _spooled(data, None) if isinstance(data, HeadLast) else _chunks(data):
            if isinstance(chunk, bytes):
                sys.stdout.flush()
                sys.stdout.buffer.write(chunk)
            else:
                sys.stdout.write(chunk)
        sys.stdout.flush()
    except OSError as exc:
        raise _stdout_error(exc) from exc


def stdout_error(exc: OSError) -> InputError | None:
    """The error to report for ``exc`` if it is a failed write to a stream (standard output), else None.

    Everything else that does I/O here names its file (``exc.filename``); a write or flush of
    standard output does not. Standard output is then silenced, so that the interpreter's own
    flush at exit does not fail again with a traceback.
    """
    if exc.filename is not None or not (exc.errno in _STREAM_ERRNOS or _closed_stdout(exc)):
        return None
    return _stdout_error(exc)


def refuse_standard_streams_twice(outputs: Mapping[str, str | None],
                                  inputs: Mapping[str, str | Sequence[str] | None]) -> None:
    """Refuse ``-`` for two inputs (standard input can be read once) or for two outputs (two outputs
    would be mixed on standard output).

    Parameters
    ----------
    outputs, inputs : {name for messages: path as given, or several paths (an input's)}

    Raises
    ------
    InputError
        ``<stdin>: given for PROGRAM.ngc and --against: standard input is one input; give the other a file`` or
        ``standard output: -o and --report both write to it: give one of them a file``.
    """
    readers = [name for name, value in inputs.items()
               for path in ((value,) if value is None or isinstance(value, str) else value) if path == "-"]
    if len(readers) > 1 and len(set(readers)) == 1:
        raise InputError(f"given {len(readers)} times for {readers[0]}: standard input is one input; give it once",
                         path="-")
    if len(readers) > 1:
        others = "others" if len(set(readers)) > 2 else "other"
        raise InputError(f"given for {' and '.join(dict.fromkeys(readers))}: standard input is one input; give the "
                         f"{others} a file", path="-")
    writers = [name for name, path in outputs.items() if path == "-"]
    if len(writers) > 1:
        raise InputError(f"{' and '.join(writers)} both write to it: give one of them a file", path=STDOUT)


def refuse_overwriting(outputs: Mapping[str, str | None], inputs: Mapping[str, str | None]) -> None:
    """Refuse outputs that are one of the inputs, or the same file as another output.

    Parameters
    ----------
    outputs, inputs : {name for messages: path as given} — None and ``-`` (standard streams) are skipped.
        Paths are compared resolved (symbolic links, ``./``, ``..``), and as files where both exist
        (hard links).

    Raises
    ------
    InputError
        ``part.stl: is also the input PART.stl: writing --output would destroy it (choose another file)``
        or ``x.png: --output and --preview name the same file: one would overwrite the other``.
    """
    files = [(name, path) for name, path in outputs.items() if path is not None and not is_stdout(path)]
    for i, (name, path) in enumerate(files):
        for other_name, other in inputs.items():
            if other is not None and not is_stdout(other) and _same_file(path, other):
                raise InputError(f"is also the input {other_name}: writing {name} would destroy it "
                                 "(choose another file)", path=path)
        for other_name, other in files[:i]:
            if _same_file(path, other):
                raise InputError(f"{other_name} and {name} name the same file: one would overwrite the other",
                                 path=path)


# ----------------------------------------------------------------------------- helpers


@dataclass(slots=True)
class _Staged:
    """One file output on its way: the path as given, where the data goes, and its temp file."""

    path: str                   # as the user gave it (messages)
    target: Path                # symbolic links resolved
    data: Chunks | None         # kept only for direct targets (written after the staging)
    tmp: Path | None            # None: a FIFO or device, written directly
    existed: bool               # a regular file is replaced (False: a new file)


def _stage(path: str, data: Output) -> _Staged:
    """Check the target and write its temp file (or, for a FIFO or device, only check it)."""
    if not path or path.endswith(("/", os.sep)):
        raise InputError("is a folder or empty: give a file name", path=path or "''")
    target = Path(os.path.realpath(path))              # write through a symbolic link
    try:
        mode: int | None = os.stat(target).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:                              # name too long, loop of links, no permission
        raise InputError(f"cannot write the output here: {exc.strerror}", path=path) from exc
    if mode is not None and stat.S_ISDIR(mode):
        raise InputError("is a folder or empty: give a file name", path=path)
    if mode is not None and not stat.S_ISREG(mode):
        if isinstance(data, HeadLast):                  # made before the FIFO or device gets a byte
            try:
                data = _spooled(data, None)
            except OSError as exc:
                raise InputError(f"cannot write the output: {exc.strerror}", path=path) from exc
        return _Staged(path, target, data, None, existed=True)
    try:
        fd, name = tempfile.mkstemp(prefix=_temp_prefix(target), suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise InputError(f"cannot write the output here: {exc.strerror}", path=path) from exc
    stage = _Staged(path, target, None, Path(name), existed=mode is not None)
    try:
        with os.fdopen(fd, "wb") as stream:
            _write_chunks(stream, _spooled(data, target.parent) if isinstance(data, HeadLast) else data)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(name, 0o666 & ~umask)                  # the usual permissions, not mkstemp's 0600
    except OSError as exc:
        Path(name).unlink(missing_ok=True)
        raise InputError(f"cannot write the output: {exc.strerror}", path=path) from exc
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise
    return stage


def _write_direct(stage: _Staged) -> None:
    """A FIFO or device: open it (no create) and write; a FIFO waits for its reader."""
    try:
        with open(os.open(stage.target, os.O_WRONLY), "wb") as stream:
            _write_chunks(stream, stage.data or b"")
    except OSError as exc:
        raise InputError(f"cannot write the output: {exc.strerror}", path=stage.path) from exc


def _temp_prefix(target: Path) -> str:
    return f".{target.name[:_TEMP_NAME_MAX]}."


def _guarded_commit(staged: Sequence[_Staged]) -> None:
    """:func:`_commit`, after the process's :func:`guard_commits` check if it has one."""
    check = _commit_guard
    if check is None:
        _commit(staged)
        return
    held = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        check()
        _commit(staged)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


def _commit(staged: Sequence[_Staged]) -> None:
    """Rename every temp file over its target; if one fails, put back what the earlier ones replaced."""
    done: list[tuple[_Staged, Path | None]] = []       # renamed, with the old file kept to undo it
    stage = staged[0] if staged else None
    try:
        for stage in staged:
            backup = None
            if stage.existed and len(staged) > 1:
                backup = _hard_link_aside(stage)
            os.replace(stage.tmp, stage.target)         # type: ignore[arg-type]  # staged: tmp is set
            stage.tmp = None
            done.append((stage, backup))
    except OSError as exc:
        for renamed, backup in done:
            if backup is not None:
                os.replace(backup, renamed.target)
            elif not renamed.existed:
                renamed.target.unlink(missing_ok=True)
        raise InputError(f"cannot write the output: {exc.strerror}", path=stage.path if stage else "") from exc
    finally:
        for _, backup in done:
            if backup is not None:
                backup.unlink(missing_ok=True)


def _hard_link_aside(stage: _Staged) -> Path | None:
    """A second name for the file a rename is about to replace (None where hard links fail)."""
    backup = stage.target.with_name(f"{stage.tmp.name}.old" if stage.tmp else ".old.tmp")
    try:
        os.link(stage.target, backup)
    except OSError:
        return None
    return backup


def _spooled(data: HeadLast, folder: Path | None) -> Iterator[str | bytes]:
    """The chunks of ``data``: its body is made now, into an unnamed temp file in ``folder`` (None:
    the temp folder; gone when closed, or when the process ends however it ends), then its head;
    the iterator returned yields the head, then the body read back in pieces."""
    spool = tempfile.TemporaryFile(dir=folder)
    try:
        _write_chunks(spool, data.body)
        head = list(_chunks(data.head()))
        spool.seek(0)
    except BaseException:
        spool.close()
        raise

    def pieces() -> Iterator[str | bytes]:
        with spool:
            yield from head
            yield from iter(lambda: spool.read(_SPOOL_PIECE), b"")

    return pieces()


def _chunks(data: Chunks) -> Iterator[str | bytes]:
    if isinstance(data, (str, bytes)):
        yield data
    else:
        yield from data


def _write_chunks(stream: BinaryIO, data: Chunks) -> None:
    stream.writelines(chunk.encode("utf-8") if isinstance(chunk, str) else chunk for chunk in _chunks(data))


def _same_file(a: str, b: str) -> bool:
    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
        return os.path.exists(a) and os.path.exists(b) and os.path.samefile(a, b)
    except (OSError, ValueError):                       # a name too long cannot be an existing input
        return False


def _closed_stdout(exc: OSError) -> bool:
    """A write to the standard output that :func:`guard_closed_stdout` found closed."""
    return _stdout_was_closed and exc.errno == errno.EBADF


def _stdout_error(exc: OSError) -> InputError:
    """The error for a standard output that cannot be written; silences it for the exit flush."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    reason = _CLOSED_STDOUT if _closed_stdout(exc) else exc.strerror or exc
    if exc.errno == errno.EPIPE:                         # its reader went away (| head): not an error of ours
        return OutputClosed(f"cannot write: {reason}", path=STDOUT)
    return InputError(f"cannot write: {reason}", path=STDOUT)


class _Interrupted(BaseException):
    """A signal arrived while temp files existed: unwind (removing them), then act on it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _cleanup_on_signals() -> Iterator[None]:
    """Turn SIGTERM/SIGINT/SIGHUP into an exception while writing, so that ``finally`` removes the
    temp files; afterwards the signal is raised again with its previous handler (the default ends
    the process as the signal would). Signals the process ignores stay ignored. A signal that comes
    while the first one unwinds is let go (the first one is acted on): raised inside an ``except`` or
    ``finally`` block it would cut the removal of a temp file short (a busy machine delivers a
    terminal's SIGINT and the batch's SIGTERM together)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    unwinding: list[int] = []

    def handler(signum: int, frame: object) -> None:
        if unwinding:
            return
        unwinding.append(signum)
        raise _Interrupted(signum)

    previous = {s: signal.getsignal(s) for s in _SIGNALS}
    for s, old in previous.items():
        if old is not signal.SIG_IGN and old is not None:   # None: a handler not set from Python
            signal.signal(s, handler)
    try:
        yield
    except _Interrupted as interrupted:
        _restore(previous)
        signal.raise_signal(interrupted.signum)
        raise KeyboardInterrupt from None               # the handler returned: stop anyway
    finally:
        _restore(previous)


def _restore(previous: Mapping[int, object]) -> None:
    for s, old in previous.items():
        if old is not None:
            signal.signal(s, old)  # type: ignore[arg-type]
