"""Opening and reading input files, with the same checks and clear errors for every reader.

Only regular files are read: a FIFO would block forever waiting for a writer, and a device such
as ``/dev/zero`` never ends. Each kind of input has a size limit (:data:`SIZE_LIMITS`), far above
any real part, program or table, so that a wrong file is refused at once instead of filling the
memory.

The file name ``-`` is standard input, for the kinds of input in :data:`STDIN_KINDS` (a program, a
CL file, a pose table): the readers read a file more than once (its header, then its body; its
hash; again to name a problem), so standard input is copied once, on its first opening, into an
unnamed temp file (the *spool*; up to the kind's size limit), and every opening of ``-`` reads
that copy from its start. Messages name it ``<stdin>``
(:func:`~prs3_post.core.errors.shown_path`).
"""

from __future__ import annotations

import atexit
import errno
import io
import os
import re
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, BinaryIO

import numpy as np

from prs3_post.core.errors import STDIN_PATH, InputError
from prs3_post.core.types import Progress

if TYPE_CHECKING:
    from hashlib import _Hash as Hash

MB = 1_000_000
SIZE_LIMITS: dict[str, int] = {
    "an STL file": 500 * MB,          # ~10 million triangles in binary STL
    "a G-code program": 1000 * MB,    # ~25 million lines
    "a CL file": 1000 * MB,           # ~25 million records (read in pieces: iter_pieces)
    "a CSV file": 1000 * MB,          # ~15 million poses
    "a TOML file": 1 * MB,            # a machine or dialect description is a few kB
    "a tool table": 1 * MB,           # some 10,000 tools
}
"""Bytes, the largest file read for each kind of input (keyed by the ``what`` of :func:`read_input`)."""
DEFAULT_SIZE_LIMIT = 1000 * MB
"""Bytes, the limit for a kind of input not in :data:`SIZE_LIMITS` (``a file``: any of them)."""

STDIN_KINDS = frozenset({"a G-code program", "a CL file", "a CSV file", "a file"})
"""The kinds of input (the ``what`` of :func:`open_input`) that ``-`` may name: standard input. A part,
a TOML file or a tool table is always a file (they are read alongside the one input that may be
standard input)."""

_NOT_REGULAR = (
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def open_input(path: str, what: str) -> BinaryIO:
    """Open the regular file at ``path`` for reading (binary), after checking its kind and size.

    Parameters
    ----------
    path : str — as the user gave it (messages show it unchanged)
    what : str — what the file should be (``an STL file``): for messages, and the key of its size limit

    Returns
    -------
    BinaryIO
        Positioned at the start; the caller closes it.

    Raises
    ------
    InputError
        ``<stdin>: standard input is not read as <what>: give a file ...`` (for ``-``, but for
        the kinds in :data:`STDIN_KINDS`), ``<stdin>: cannot read: it is closed ...``,
        ``file not found``, ``is a directory, not <what>``, ``permission denied``,
        ``is a FIFO (named pipe), not a regular file: give <what>``,
        ``is 1.2 GB, more than the 500 MB limit for <what>`` or ``cannot read the file: <reason>``.
    """
    if path == STDIN_PATH:
        if what not in STDIN_KINDS:
            raise InputError(f"standard input is not read as {what}: give a file (a file named '-' is ./-)",
                             path=path)
        spool = _stdin_spool()
        limit = SIZE_LIMITS.get(what, DEFAULT_SIZE_LIMIT)
        if spool.size > limit:
            raise InputError(f"is more than the {format_bytes(limit)} limit for {what}", path=path)
        return spool.open()
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))   # a FIFO must not block the open
    except FileNotFoundError as exc:
        raise InputError("file not found", path=path) from exc
    except PermissionError as exc:
        raise InputError("permission denied", path=path) from exc
    except OSError as exc:
        raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputError(f"is a directory, not {what}", path=path)
        for test, kind in _NOT_REGULAR:
            if test(info.st_mode):
                raise InputError(f"is {kind}, not a regular file: give {what}", path=path)
        limit = SIZE_LIMITS.get(what, DEFAULT_SIZE_LIMIT)
        if info.st_size > limit:
            raise InputError(f"is {format_bytes(info.st_size)}, more than the {format_bytes(limit)} limit "
                             f"for {what}", path=path)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return open(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


class _Spool:
    """Standard input, copied into an unnamed temp file (see the module docstring)."""

    def __init__(self, stdin: object, stream: BinaryIO, size: int):
        self.stdin, self.stream, self.size = stdin, stream, size

    def open(self) -> BinaryIO:
        """A new reader of the copy, at its start, with its own position (two may read it at once:
        a reader and a second pass that names a problem)."""
        fd = self.stream.fileno()
        try:
            return open(f"/proc/self/fd/{fd}", "rb")    # Linux: the same unnamed file, its own offset
        except OSError:
            pass
        self.stream.seek(0)                             # elsewhere: a copy in memory
        return io.BytesIO(self.stream.read())

    def close(self) -> None:
        self.stream.close()


_spool: _Spool | None = None
_SPOOL_PIECE = 1 << 20


def _stdin_spool() -> _Spool:
    """The copy of standard input (made now, on the first call for this ``sys.stdin``).

    Raises
    ------
    InputError
        ``<stdin>: cannot read: it is closed ...``, ``is more than the 1.0 GB limit ...``, or the reason.
    """
    global _spool
    stdin = sys.stdin
    if _spool is not None and _spool.stdin is stdin:
        return _spool
    if _spool is not None:
        _spool.close()
        _spool = None
    if stdin is None:                                   # `<&-`: Python starts with no sys.stdin
        raise InputError("cannot read: it is closed (give a file, or redirect standard input from one)",
                         path=STDIN_PATH)
    limit = max(SIZE_LIMITS[kind] for kind in SIZE_LIMITS if kind in STDIN_KINDS)
    stream = tempfile.TemporaryFile()
    size = 0
    try:
        source = stdin.buffer
        while piece := source.read(_SPOOL_PIECE):
            size += len(piece)
            if size > limit:
                raise InputError(f"is more than the {format_bytes(limit)} limit for any input", path=STDIN_PATH)
            stream.write(piece)
        stream.flush()
    except (OSError, ValueError) as exc:               # ValueError: a closed file object
        stream.close()
        if not isinstance(exc, OSError) or exc.errno == errno.EBADF:
            raise InputError("cannot read: it is closed (give a file, or redirect standard input from one)",
                             path=STDIN_PATH) from exc
        raise InputError(f"cannot read: {exc.strerror or exc}", path=STDIN_PATH) from exc
    except BaseException:                               # the limit, or Ctrl-C while reading
        stream.close()
        raise
    _spool = _Spool(stdin, stream, size)
    atexit.register(stream.close)                     # (it is gone with the process in any case)
    return _spool


def read_input(path: str, what: str) -> bytes:
    """The whole regular file at ``path`` (checked as :func:`open_input` does).

    Raises
    ------
    InputError
        As :func:`open_input`; also when the file grew past its limit while being read.
    """
    limit = SIZE_LIMITS.get(what, DEFAULT_SIZE_LIMIT)
    with open_input(path, what) as stream:
        try:
            data = stream.read(limit + 1)
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    if len(data) > limit:
        raise InputError(f"is more than the {format_bytes(limit)} limit for {what}", path=path)
    return data


def read_text(path: str, what: str) -> str:
    """The regular file at ``path`` as UTF-8 text (a BOM is allowed).

    Raises
    ------
    InputError
        As :func:`read_input`, or ``line 3: not UTF-8 text (byte 0xe9): save the file as UTF-8``.
    """
    data = read_input(path, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"not UTF-8 text (byte 0x{data[exc.start]:02x}): save the file as UTF-8",
                         path=path, line=line) from exc


def file_sha256(path: str) -> str:
    """Lower-case hex SHA-256 of a file's bytes.

    Raises
    ------
    InputError
        The file cannot be read.
    """
    import hashlib  # only where a file is hashed (about 3 ms of every start otherwise)

    with open_input(path, "a file") as stream:          # read in pieces: a part may be large
        digest = hashlib.sha256()
        try:
            for piece in iter(lambda: stream.read(1 << 20), b""):
                digest.update(piece)
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    return digest.hexdigest()


def format_bytes(size: int) -> str:
    """``1.2 GB``, ``500 MB``, ``12 kB``, ``80 bytes`` (decimal units, 2 significant digits at most).

    >>> format_bytes(500_000_000), format_bytes(1_234_567_890), format_bytes(12_345), format_bytes(80)
    ('500 MB', '1.2 GB', '12 kB', '80 bytes')
    """
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            value = size / scale
            return f"{value:.2g} {unit}" if value < 10 else f"{value:.0f} {unit}"
    return f"{size} bytes"


def iter_pieces(path: str, what: str, piece_bytes: int = 1 << 20, digest: Hash | None = None,
                progress: Progress | None = None) -> Iterator[tuple[int, bytes]]:
    """``(offset, bytes)`` pieces of the regular file at ``path``, each ending at a line end (or the file's end).

    For readers that stream a file: memory holds one piece, not the file. Checked and opened as
    :func:`open_input` does (``what`` as there); errors are raised when the iteration reaches them.
    ``digest`` (a :mod:`hashlib` hash), when given, is updated with every byte read: the hash of the
    bytes the pieces are, whatever happens to the file's name meanwhile. ``progress``, when given, is
    told the bytes read so far and the file's size after each read.
    """
    with open_input(path, what) as stream:
        offset, rest = 0, b""
        size, done = (_size_of(stream) if progress is not None else 0), 0
        while True:
            try:
                block = stream.read(piece_bytes)
            except OSError as exc:
                raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
            if not block:
                break
            if progress is not None:
                done += len(block)
                progress(done, max(size, done))
            if digest is not None:
                digest.update(block)
            block = rest + block
            cut = block.rfind(b"\n") + 1
            if cut == 0:
                rest = block
                continue
            yield offset, block[:cut]
            offset, rest = offset + cut, block[cut:]
        if rest:
            yield offset, rest


def _size_of(stream: BinaryIO) -> int:
    """Bytes in the file ``stream`` reads (0 when it cannot say)."""
    try:
        return os.fstat(stream.fileno()).st_size
    except (OSError, ValueError, io.UnsupportedOperation):   # (the copy of standard input in memory)
        return len(stream.getbuffer()) if isinstance(stream, io.BytesIO) else 0


def input_size(path: str) -> int:
    """Bytes in the input ``path`` (``-``: standard input, copied now if it is not yet); 0 when it
    cannot be read (its reader says why)."""
    try:
        if path == STDIN_PATH:
            return _stdin_spool().size
        return os.stat(path).st_size
    except (OSError, InputError):
        return 0


def lf_line_ends(text: str) -> str:
    """``text`` with its CR and CRLF line ends made LF where it has a CR that is no CRLF's (CR-only line
    ends, as old Mac editors write them, or mixed ones); else ``text`` itself, not copied (a reader
    that takes CRLF strips the CR, or reads it as whitespace). Each CR, CRLF or LF ends one line.

    >>> lf_line_ends("a\\rb\\r\\nc\\n"), lf_line_ends("a\\r\\nb")
    ('a\\nb\\nc\\n', 'a\\r\\nb')
    """
    if "\r" in text and _LONE_CR.search(text) is not None:
        return text.replace("\r\n", "\n").replace("\r", "\n")
    return text


def lf_line_end_bytes(data: bytes) -> bytes:
    """:func:`lf_line_ends` for bytes (ASCII-compatible text: a CR byte is a CR in UTF-8 too).

    >>> lf_line_end_bytes(b"a\\rb\\r\\n")
    b'a\\nb\\n'
    """
    if b"\r" in data and _LONE_CR_BYTES.search(data) is not None:
        return data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    return data


#: A CR that is no CRLF's (one pass: half the time of counting CRs and CRLFs).
_LONE_CR = re.compile(r"\r(?!\n)")
_LONE_CR_BYTES = re.compile(rb"\r(?!\n)")


def line_chunks(texts: Iterable[str], chunk_lines: int) -> Iterator[list[str]]:
    """The lines of text pieces that end at line ends (as :func:`iter_pieces` cuts them, decoded), without
    their line ends, ``chunk_lines`` at a time (the last chunk shorter).

    >>> list(line_chunks(["a\\nb\\r\\n", "c\\n", "d"], 2))
    [['a', 'b\\r'], ['c', 'd']]
    """
    pending: list[str] = []
    for text in texts:
        lines = text.split("\n")
        if lines[-1] == "":
            lines.pop()                                  # the piece's final line end
        pending += lines
        while len(pending) >= chunk_lines:
            yield pending[:chunk_lines]
            del pending[:chunk_lines]
    if pending:
        yield pending


def line_blocks(pieces: Iterable[tuple[int, bytes]], chunk_lines: int) -> Iterator[tuple[int, bytes]]:
    """``(offset, bytes)`` blocks of ``chunk_lines`` whole lines each, with their LFs, from ``(offset,
    bytes)`` pieces that end at line ends (as :func:`iter_pieces` cuts them); the last block holds
    the lines left (fewer, and its last line may end at the end of the file, without an LF). Each
    byte is copied once, into its block (a block within a piece is a slice of it; one across pieces
    is joined from their parts).

    >>> list(line_blocks([(0, b"a\\nb\\n"), (4, b"c\\nd")], 3))
    [(0, b'a\\nb\\nc\\n'), (6, b'd')]
    """
    parts: list[memoryview] = []                      # the lines not handed out yet, from earlier pieces
    waiting, parts_at = 0, 0                           # their LFs, and where the first starts in the file
    for offset, piece in pieces:
        view, cut = memoryview(piece), 0
        line_end = _line_ends(piece)
        while (stop := line_end(cut, chunk_lines - waiting)) >= 0:
            if parts:
                yield parts_at, b"".join([*parts, view[cut:stop]])
                parts, waiting = [], 0
            else:
                yield offset + cut, piece[cut:stop]
            cut = stop
        waiting += -1 - stop                           # the LFs after the last block's end
        if cut < len(piece):
            if not parts:
                parts_at = offset + cut
            parts.append(view[cut:])
    if parts:
        yield parts_at, b"".join(parts)


def _line_ends(data: bytes) -> Callable[[int, int], int]:
    """``line_end(start, count)``: the offset just after the ``count``-th LF of ``data[start:]`` (``count``
    ≥ 1), or ``-1 - (the LFs there)`` where it has fewer: csrc/lex.c's prs3_line_end, no pass over every
    LF; else numpy's LFs found once."""
    from prs3_post.core import native  # ctypes: loaded only where a file is read in blocks

    if native.line_end(b"\n", 0, 1) is not None:
        def compiled(start: int, count: int) -> int:
            found = native.line_end(data, start, count)
            assert found is not None  # the library answered above
            return found
        return compiled
    line_ends = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == _LF)

    def line_end(start: int, count: int) -> int:
        first = int(np.searchsorted(line_ends, start))
        if first + count <= len(line_ends):
            return int(line_ends[first + count - 1]) + 1
        return -1 - (len(line_ends) - first)
    return line_end


_LF = ord("\n")
