"""The compiled line writer (csrc/render.c), lexer (csrc/lex.c) and CL GOTO reader (csrc/goto.c), loaded
with ctypes; numpy does the same where they are absent. csrc/lex.c also holds the CAM readers' other
passes: the check of a file's bytes (:func:`scan_text`), the cut of blocks of lines (:func:`line_end`),
the 3+2 G-code reader's bulk step (:func:`fill_moves`) and the turn of rows to the part frame
(:func:`rows_to_part`), each with its numpy twin in the reader as the reference.

``pip install`` compiles csrc/*.c with the machine's C compiler (hatch_build.py) into
``prs3_post/_native.so``. Where there is no compiler the package installs all the same and every
line is written by numpy (:mod:`prs3_post.core.numbers`): the same bytes, three to four times slower; and
read by numpy (:mod:`prs3_post.core.lexer`, :mod:`prs3_post.readers.cl.reader`): the same values. The C
functions have no Python API in them, so ctypes releases the GIL while they run (``ik --batch``
formats one chunk on a second thread while the next is read and solved).

``PRS3_POST_NATIVE=0`` in the environment turns them off (the tests compare both ways).
"""

from __future__ import annotations

import ctypes
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prs3_post.core.columns import ChoiceColumn
from prs3_post.core.errors import Prs3Warning
from prs3_post.core.types import BoolArray, FloatArray, IntArray

__all__ = ["ENV", "LIBRARY", "NATIVE_VERSION", "SIGNATURES", "FilledMoves", "available", "emit_rows", "fill_moves",
           "lex_text", "library", "line_end", "plain_gotos", "render_block", "scan_text"]

#: The compiled library, beside this module.
LIBRARY = Path(__file__).parent.parent / "_native.so"
#: ``PRS3_POST_NATIVE=0``: numpy writes every line and reads every chunk.
ENV = "PRS3_POST_NATIVE"
#: What ``prs3_native_version()`` of the library must say (csrc/render.c): another version (an old build
#: beside newer sources) is not used.
NATIVE_VERSION = 5
_NUMBER, _CHOICE = 0, 1
#: csrc/render.c's prs3_render_lines results other than a size: out too small, a column it refuses.
_RENDER_OVERFLOW, _RENDER_BAD_COLUMN = -1, -2

_POINTER, _I64, _I32, _U8, _TEXT = ctypes.c_void_p, ctypes.c_int64, ctypes.c_int32, ctypes.c_uint8, ctypes.c_char_p
#: Every function of the compiled library with its argument types, in the order of its C definition
#: (csrc/*.c; each returns an int64): the one place they are written (tests/test_native.py checks each
#: against its C definition). Arrays are passed as addresses, bytes objects as ``char *``.
SIGNATURES: dict[str, list[Any]] = {
    "prs3_native_version": [],
    "prs3_render_lines": [_I64, _I64, _POINTER, _POINTER, _POINTER, _POINTER, _POINTER, _POINTER, _POINTER, _U8,
                          _POINTER, _I64, _I64, _POINTER, _POINTER, _POINTER, _POINTER, _POINTER, _I64, _POINTER],
    "prs3_emit_lines": [_I64, _I64, _POINTER, _POINTER, _I32, _POINTER, _POINTER, _I64, _I64, _POINTER, _I32, _I32,
                        _POINTER, _POINTER, _POINTER, _U8, _TEXT, _I64, _I64, _POINTER, _POINTER, _POINTER,
                        _POINTER, _I64, _POINTER, _POINTER],
    "prs3_lex_columns": [_TEXT, _I64, _TEXT, _I64, _POINTER, _POINTER, _POINTER, _I64, _POINTER],
    "prs3_scan_text": [_TEXT, _I64, _POINTER],
    "prs3_line_end": [_TEXT, _I64, _I64, _I64],
    "prs3_fill_moves": [_POINTER, _POINTER, _I64, _POINTER, _POINTER, _POINTER, _I64, _POINTER, _POINTER, _POINTER,
                        _POINTER, _POINTER],
    "prs3_rows_to_part": [_POINTER, _I64, _POINTER, _POINTER, _POINTER],
    "prs3_line_roles": [_POINTER, _POINTER, _I64, _POINTER, _POINTER],
    "prs3_plain_gotos": [_TEXT, _I64, _TEXT, _TEXT, _POINTER, _POINTER, _I64],
}

_library: Any = None                                    # None: not loaded yet; False: not there
_warned = False                                         # the fall back to numpy was reported (once a process)
_function: Any = None                                   # prs3_render_lines, once loaded
_lexer: Any = None                                      # prs3_lex_columns, once loaded (False: not there)
_gotos: Any = None                                      # prs3_plain_gotos, once loaded (False: not there)
_scan: Any = None                                       # prs3_scan_text, once loaded (False: not there)
_line_end: Any = None                                   # prs3_line_end, once loaded (False: not there)
_fill: Any = None                                       # prs3_fill_moves, once loaded (False: not there)
_to_part: Any = None                                    # prs3_rows_to_part, once loaded (False: not there)
_roles: Any = None                                      # prs3_line_roles, once loaded (False: not there)
_emitter: Any = None                                    # prs3_emit_lines, once loaded (False: not there)


def library() -> Any:
    """The compiled library (ctypes.CDLL), or None where it was not built or is turned off.

    Where it is missing, cannot be loaded or is of another version (an editable install whose csrc/
    changed since it was built), numpy takes over, and a :class:`Prs3Warning` says so once a process
    (the output is the same, only slower); not where ``PRS3_POST_NATIVE=0`` asked for numpy."""
    global _library
    if _library is None:
        _library = False
        if os.environ.get(ENV, "1") == "0":
            return None
        if not LIBRARY.is_file():
            _fall_back(f"no compiled library at {LIBRARY} (no C compiler when the package was installed?)")
            return None
        try:
            loaded = ctypes.CDLL(str(LIBRARY))
            version = loaded.prs3_native_version
        except (OSError, AttributeError) as error:       # built for another machine, or before versions
            _fall_back(f"the compiled library {LIBRARY} cannot be used ({error})")
            return None
        version.restype, version.argtypes = ctypes.c_int64, SIGNATURES["prs3_native_version"]
        found = version()
        if found != NATIVE_VERSION:
            _fall_back(f"the compiled library {LIBRARY} is version {found}, this package needs {NATIVE_VERSION} "
                       "(csrc/ changed since it was built: reinstall the package to rebuild it)")
            return None
        _library = loaded
    return _library or None


def _fall_back(reason: str) -> None:
    """Say once a process that numpy writes and reads instead of the compiled library, and why."""
    global _warned
    if not _warned:
        _warned = True
        warnings.warn(f"{reason}; numpy writes and reads instead (the same output, slower; "
                      f"{ENV}=0 chooses numpy without this warning)", Prs3Warning, stacklevel=3)


def _bind(name: str) -> Any:
    """The library's function ``name`` with its argument types from :data:`SIGNATURES` (it returns an
    int64), or False where the library or the function is not there (a library built before the
    function was added)."""
    loaded = library()
    function = getattr(loaded, name, None) if loaded is not None else None
    if function is None:
        return False
    function.restype, function.argtypes = ctypes.c_int64, SIGNATURES[name]
    return function


def _load() -> Any:
    global _function
    if _function is None:
        _function = _bind("prs3_render_lines")
    return _function


def available() -> bool:
    """True when the compiled writer is there and not turned off (``PRS3_POST_NATIVE=0``)."""
    return bool(_load())


def _address(array: np.ndarray) -> int:
    return int(array.ctypes.data)


def render_block(columns: Sequence, present: BoolArray, lo: int, hi: int, separator: bytes,
                 ending: bytes) -> tuple[np.ndarray, IntArray]:
    """Rows ``lo:hi`` of :func:`prs3_post.core.numbers.render_rows`: (their bytes, each line's length with its
    ending), as the numpy writer gives them. Call only where :func:`available`."""
    m, width = hi - lo, len(columns)
    kind = np.zeros(width, dtype=np.int32)
    decimals = np.zeros(width, dtype=np.int32)
    first_text = np.zeros(width + 1, dtype=np.int64)    # and the count of texts: each column's choices
    kept: list[np.ndarray] = []                          # the value columns, alive through the call
    texts: list[bytes] = []
    overrides: list[tuple[int, int, bytes]] = []         # (row, column, text after the prefix)
    room = 0                                             # bytes a line needs at most
    for j, column in enumerate(columns):
        first_text[j] = len(texts)
        if isinstance(column, ChoiceColumn):
            kind[j] = _CHOICE
            kept.append(np.ascontiguousarray(column.choice[lo:hi], dtype=np.int64))
            texts.extend(column.texts)
            room += 1 + max((len(t) for t in column.texts), default=0)
            continue
        prefix, numbers = column
        kept.append(np.ascontiguousarray(numbers.scaled[lo:hi], dtype=np.int64))
        decimals[j] = numbers.decimals
        texts.append(prefix)
        first, last = np.searchsorted(numbers.odd, [lo, hi])
        odd_texts = [text.encode("ascii") for text in numbers.odd_text[first:last]]
        overrides += [(row - lo, j, text) for row, text in zip(numbers.odd[first:last].tolist(), odd_texts,
                                                                strict=True)]
        room += 1 + len(prefix) + max(44, max((len(t) for t in odd_texts), default=0))
    overrides.sort(key=lambda item: (item[0], item[1]))
    first_text[width] = len(texts)
    text_start = np.zeros(len(texts) + 1, dtype=np.int64)
    np.cumsum([len(t) for t in texts], out=text_start[1:])
    text_bytes = np.frombuffer(b"".join(texts) + b"\0", dtype=np.uint8)
    pointers = np.array([_address(a) for a in kept], dtype=np.uint64)
    on = np.ascontiguousarray(present[lo:hi], dtype=np.bool_)
    ending_bytes = np.frombuffer(ending + b"\0", dtype=np.uint8)
    override_row = np.array([row for row, _, _ in overrides] + [0], dtype=np.int64)
    override_col = np.array([col for _, col, _ in overrides] + [0], dtype=np.int64)
    override_start = np.zeros(len(overrides) + 1, dtype=np.int64)
    np.cumsum([len(t) for _, _, t in overrides], out=override_start[1:])
    override_bytes = np.frombuffer(b"".join(t for _, _, t in overrides) + b"\0", dtype=np.uint8)
    capacity = m * (room + len(ending) + 64) + 64
    out = np.empty(capacity, dtype=np.uint8)
    lengths = np.zeros(m, dtype=np.int64)
    size = _load()(width, m, _address(pointers), _address(kind), _address(decimals), _address(first_text),
                   _address(text_start), _address(text_bytes), _address(on), separator[0],
                   _address(ending_bytes), len(ending), len(overrides), _address(override_row),
                   _address(override_col), _address(override_start), _address(override_bytes), _address(out),
                   capacity, _address(lengths))
    if size == _RENDER_BAD_COLUMN:
        raise ValueError("prs3_render_lines: a number column's decimals are not 0 to 19, or a choice is not one "
                         "of its column's texts")
    if size < 0:
        raise AssertionError("prs3_render_lines: the output buffer was too small")   # room is an upper bound
    return out[:size], lengths


#: csrc/render.c's ROOM_PER_NUMBER: the bytes a number word takes at most with its separator.
_ROOM_PER_NUMBER = 24


def emit_rows(axis_values: Sequence[FloatArray], decimals: int, first_present: Sequence[bool], kind: IntArray,
              previous_kind: int, restate: IntArray, modal_motion: bool, feed: FloatArray, feed_decimals: int,
              prefixes: Sequence[bytes], ending: bytes, inserts: tuple[IntArray, IntArray, np.ndarray],
              numbers: tuple[bytes, IntArray] | None = None) -> tuple[np.ndarray, IntArray, IntArray] | None:
    """Motion lines of a program's rows in one pass (:meth:`prs3_post.emit.gcode.ProgramEmitter._emit_rows`
    makes the same bytes with numpy): (their bytes, where each row's inserted lines then its line start
    (M + 1,), each line's length with its ending (M,)); None where the compiled writer is not there or
    turned off, or where a value is not written from an exact integer (near a tie, or too large).

    Parameters
    ----------
    axis_values : sequence of (M,) float — each axis's values (any stride), written with ``decimals``
        after the point where it differs (as printed) from the row before
    first_present : sequence of bool — each axis word is written on row 0
    kind : (M,) int — 0 rapid (G0), 1 feed (G1 ... F)
    previous_kind : int — the row before's kind (-1: unknown, the motion word is written)
    restate : (K,) int — rows (increasing) where every axis word and the motion word are written
    modal_motion : bool — G0/G1 only where it changes (and on restate rows and lines without axis word)
    feed : (M,) float — the F words' values (any stride; read on feed rows), ``feed_decimals`` after the point
    prefixes : sequence of bytes — each axis's word letter
    ending : bytes — the line ending
    inserts : (K,) int, (K + 1,) int, (B,) uint8 — lines put before their row: line k, ``bytes[starts[k]:
        starts[k + 1]]``, before row ``rows[k]`` (< M, increasing), e.g. comments
    numbers : (bytes, (M,) int), optional — the block numbers' letter and each line's number, written first
    """
    global _emitter
    if _emitter is None:
        _emitter = _bind("prs3_emit_lines")
    if not _emitter:
        return None
    m, axes = len(kind), len(axis_values)
    kept = []                                            # the value columns (axes, then F), alive through the call
    strides = np.zeros(axes + 1, dtype=np.int64)
    for j, values in enumerate([*axis_values, feed]):
        if values.dtype != np.float64 or values.strides[0] <= 0 or values.strides[0] % 8:
            values = np.ascontiguousarray(values, dtype=np.float64)
        kept.append(values)
        strides[j] = values.strides[0] // 8 if m else 1
    pointers = np.array([_address(a) for a in kept], dtype=np.uint64)
    texts = [*prefixes, b"G0", b"G1", b"F", b"" if numbers is None else numbers[0]]
    block_numbers = None if numbers is None else np.ascontiguousarray(numbers[1], dtype=np.int64)
    if block_numbers is not None and len(block_numbers) != m:
        raise ValueError(f"emit_rows: {len(block_numbers)} block numbers for {m} rows")
    text_start = np.zeros(len(texts) + 1, dtype=np.int64)
    np.cumsum([len(t) for t in texts], out=text_start[1:])
    text_bytes = np.frombuffer(b"".join(texts) + b"\0", dtype=np.uint8)
    first = np.array(first_present, dtype=np.uint8)
    kinds = np.ascontiguousarray(kind, dtype=np.int64)
    restate_rows = np.ascontiguousarray(restate, dtype=np.int64)
    insert_row = np.ascontiguousarray(inserts[0], dtype=np.int64)
    insert_start = np.ascontiguousarray(inserts[1], dtype=np.int64)
    insert_bytes = np.ascontiguousarray(inserts[2], dtype=np.uint8)
    if len(insert_start) != len(insert_row) + 1 or (len(insert_row) and not (
            0 <= insert_start[0] and insert_start[-1] <= len(insert_bytes) and (np.diff(insert_start) >= 0).all()
            and 0 <= insert_row[0] and insert_row[-1] < m and (np.diff(insert_row) >= 0).all())):
        raise ValueError("emit_rows: the inserted lines are not rows < M in order and spans of their bytes")
    capacity = (int(insert_start[-1] - insert_start[0]) + m * (int(text_start[-1]) + _ROOM_PER_NUMBER * (axes + 2)
                + len(ending)) + 64)
    out = np.empty(capacity, dtype=np.uint8)
    starts = np.zeros(m + 1, dtype=np.int64)
    lengths = np.zeros(m, dtype=np.int64)
    size = _emitter(m, axes, _address(pointers), _address(strides), decimals, _address(first), _address(kinds),
                    previous_kind, len(restate_rows), _address(restate_rows), int(modal_motion), feed_decimals,
                    None if block_numbers is None else _address(block_numbers), _address(text_start),
                    _address(text_bytes), ord(" "), ending, len(ending), len(insert_row), _address(insert_row),
                    _address(insert_start), _address(insert_bytes), _address(out), capacity, _address(starts),
                    _address(lengths))
    if size <= -2:
        return None
    if size < 0:
        raise AssertionError("prs3_emit_lines: the output buffer was too small")   # capacity is an upper bound
    return out[:size], starts, lengths


def lex_text(text: bytes, codes: bytes, width: int, rows: int | None = None
             ) -> tuple[FloatArray, np.ndarray, IntArray, IntArray] | None:
    """The lexer's fast path (:func:`prs3_post.core.lexer._lex_lines`) in C: values (N, width), the line
    kinds (N,) uint8 (``lexer.LINE_*``), where each line starts (N + 1,: line k is
    ``text[bounds[k]:bounds[k + 1] - 1]``) and the comment spans (N, 2) (positions in ``text``, written on
    the comment lines only) of ``text`` (lines each ending in LF), ``codes`` the lexer's byte-code table of
    ``width`` letters; None where the compiled lexer is not there or turned off. ``rows``: a guess of
    N, to skip counting the lines (they are counted where the text has more)."""
    global _lexer
    if _lexer is None:
        _lexer = _bind("prs3_lex_columns")
    if not _lexer:
        return None
    lexed = _lex_into(text, codes, width, rows) if rows else None
    lexed = lexed or _lex_into(text, codes, width, text.count(b"\n"))
    if lexed is None:
        raise AssertionError("prs3_lex_columns: -1 with room for every line (the text must end with a LF)")
    return lexed


def _lex_into(text: bytes, codes: bytes, width: int, room: int
              ) -> tuple[FloatArray, np.ndarray, IntArray, IntArray] | None:
    """prs3_lex_columns with room for ``room`` lines: its outputs cut to the lines read, None where more."""
    values = np.zeros((room, width))                     # every cell written (calloc: no pass over it)
    kinds = np.zeros(room, dtype=np.uint8)
    ends = np.zeros(room + 1, dtype=np.int64)
    spans = np.zeros((room, 2), dtype=np.int64)
    done = _lexer(text, len(text), codes, width, _address(values), _address(kinds), _address(ends), room,
                  _address(spans))
    if done < 0:
        return None
    return values[:done], kinds[:done], ends[:done + 1], spans[:done]


def scan_text(data: bytes) -> tuple[int, bool, int, int] | None:
    """csrc/lex.c's prs3_scan_text of ``data``: (the offset of the first control byte or -1, a byte not
    ASCII, the LFs, the offset of the first rotary hint or -1); None where the compiled library is not
    there or turned off."""
    global _scan
    if _scan is None:
        _scan = _bind("prs3_scan_text")
    if not _scan:
        return None
    found = np.zeros(4, dtype=np.int64)
    _scan(data, len(data), _address(found))
    control, high, lines, rotary = found.tolist()
    return control, bool(high), lines, rotary


def line_end(data: bytes, start: int, count: int) -> int | None:
    """The offset just after the ``count``-th LF of ``data[start:]`` (``count`` ≥ 1), or ``-1 - (the LFs
    there)`` where it has fewer (csrc/lex.c's prs3_line_end); None where the compiled library is not there."""
    global _line_end
    if _line_end is None:
        _line_end = _bind("prs3_line_end")
    if not _line_end:
        return None
    return int(_line_end(data, len(data), start, count))


#: What :func:`fill_moves` gives for the m moves of a run: tip (m, 3) mm, kind (m,), feed (m,) mm/min,
#: source (m,) line numbers, the state after the run (5,) (motion, F word, X Y Z mm; NaN: none) and the
#: G0 and G1 words counted (2,).
FilledMoves = tuple[FloatArray, IntArray, FloatArray, IntArray, FloatArray, IntArray]


def fill_moves(values: FloatArray, moves: np.ndarray, state: FloatArray, limits: FloatArray, codes: IntArray,
               first: int) -> FilledMoves | bool:
    """The 3+2 G-code reader's bulk step in C (csrc/lex.c's prs3_fill_moves; arguments there): the
    :data:`FilledMoves` of a run, False where a line of it needs the careful reader, True where the
    compiled library is not there or turned off (numpy then)."""
    global _fill
    if _fill is None:
        _fill = _bind("prs3_fill_moves")
    if not _fill:
        return True
    values = np.ascontiguousarray(values, dtype=np.float64)
    moves = np.ascontiguousarray(moves, dtype=np.bool_)
    n = len(values)
    if values.shape != (n, 6) or moves.shape != (n,):
        raise ValueError(f"fill_moves: values (n, 6) and moves (n,), got {values.shape} and {moves.shape}")
    after = np.array(state, dtype=np.float64)           # a copy: the caller's state stays as it was
    limits = np.ascontiguousarray(limits, dtype=np.float64)
    codes = np.ascontiguousarray(codes, dtype=np.int64)
    tip = np.zeros((n, 3))
    kind = np.zeros(n, dtype=np.int64)
    feed = np.zeros(n)
    source = np.zeros(n, dtype=np.int64)
    words = np.zeros(2, dtype=np.int64)
    m = _fill(_address(values), _address(moves), n, _address(after), _address(limits), _address(codes), first,
              _address(tip), _address(kind), _address(feed), _address(source), _address(words))
    if m < 0:
        return False
    return tip[:m], kind[:m], feed[:m], source[:m], after, words


def line_roles(values: FloatArray, kinds: np.ndarray) -> tuple[BoolArray, BoolArray] | None:
    """csrc/lex.c's prs3_line_roles: which lines of a lexed block (``values`` (n, 6): N G X Y Z F;
    ``kinds``: the lexer's) are regular G0/G1 moves and which are quiet (the usual comment line, or
    blank); None where the compiled library is not there or turned off."""
    global _roles
    if _roles is None:
        _roles = _bind("prs3_line_roles")
    if not _roles:
        return None
    values = np.ascontiguousarray(values, dtype=np.float64)
    kinds = np.ascontiguousarray(kinds, dtype=np.uint8)
    n = len(kinds)
    if values.shape != (n, 6):
        raise ValueError(f"line_roles: values (n, 6) for n = {n} kinds, got {values.shape}")
    move = np.zeros(n, dtype=np.bool_)
    quiet = np.zeros(n, dtype=np.bool_)
    _roles(_address(values), _address(kinds), n, _address(move), _address(quiet))
    return move, quiet


def rows_to_part(rows: FloatArray, rotation: FloatArray, origin: FloatArray | None) -> FloatArray | None:
    """``WorkPlane(origin, rotation).to_part(rows)`` in C (csrc/lex.c's prs3_rows_to_part: the same bits),
    (N, 3) mm; ``origin`` None: ``workplane.rotate_rows(rows, rotation)``. None where the compiled library
    is not there or turned off."""
    global _to_part
    if _to_part is None:
        _to_part = _bind("prs3_rows_to_part")
    if not _to_part:
        return None
    rows = np.ascontiguousarray(rows, dtype=np.float64).reshape(-1, 3)
    rotation = np.ascontiguousarray(rotation, dtype=np.float64)
    if origin is not None:
        origin = np.ascontiguousarray(origin, dtype=np.float64)
    if rotation.shape != (3, 3) or (origin is not None and origin.shape != (3,)):
        raise ValueError(f"rows_to_part: rotation (3, 3) and origin (3,), got {rotation.shape} and "
                         f"{None if origin is None else origin.shape}")
    out = np.zeros_like(rows)
    _to_part(_address(rows), len(rows), _address(rotation), None if origin is None else _address(origin),
             _address(out))
    return out


def plain_gotos(text: bytes, codes: bytes, pair_bad: bytes, rows: int) -> tuple[FloatArray, BoolArray] | None:
    """The CL reader's bulk GOTO path (:func:`prs3_post.readers.cl.bulk._plain_goto_text`) in C: values (N, 6)
    and read (N,) of ``text`` (a LF, then ``rows`` lines each ending in LF), ``codes`` and ``pair_bad``
    the reader's byte-code and bad-pair tables; None where the compiled reader is not there or turned off."""
    global _gotos
    if _gotos is None:
        _gotos = _bind("prs3_plain_gotos")
    if not _gotos:
        return None
    values = np.zeros((rows, 6))                         # every cell written (calloc: no pass over it)
    read = np.zeros(rows, dtype=np.bool_)
    done = _gotos(text, len(text), codes, pair_bad, _address(values), _address(read), rows)
    if done != rows:
        raise AssertionError(f"prs3_plain_gotos: {done} lines, not {rows} (the text must start and end with a LF)")
    return values, read
