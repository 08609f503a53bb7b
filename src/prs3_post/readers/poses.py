"""Pose tables (CSV) for ``prs3-post ik --batch``: one pose per line, keeping its line number."""

from __future__ import annotations

import csv
import io
import itertools
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from prs3_post.core.errors import InputError, quoted
from prs3_post.core.input_files import open_input
from prs3_post.core.types import FloatArray, IntArray

POSE_COLUMNS = ("tip_x", "tip_y", "tip_z", "axis_x", "axis_y", "axis_z")
#: The magnitude each column may have, and its unit: what ``ik --tip``/``--axis`` allow (a kilometre;
#: direction components, normalized later). Beyond, and NaN or infinity, a value is an input error.
POSE_LIMITS = ((1e6, "mm"),) * 3 + ((1e6, ""),) * 3
#: Lines of a pose table read at a time (a chunk of rows: a few MB).
CHUNK_LINES = 65536


@dataclass(frozen=True, slots=True)
class PoseTable:
    """Poses read from a CSV file.

    Attributes
    ----------
    tip : (N, 3) float — mm
    axis : (N, 3) float — as written (not yet unit length)
    line : (N,) int — 1-based line number of each pose in the file
    """

    tip: FloatArray
    axis: FloatArray
    line: IntArray


def read_poses(path: str) -> PoseTable:
    """Read a CSV with the header ``tip_x,tip_y,tip_z,axis_x,axis_y,axis_z`` (that order, mm).

    Blank lines are ignored; anything else that is not six numbers within POSE_LIMITS is an error
    naming the line.
    The whole table at once (:func:`iter_poses` reads it in chunks).

    Raises
    ------
    InputError
    """
    chunks = list(iter_poses(path))
    if not chunks:
        return PoseTable(tip=np.zeros((0, 3)), axis=np.zeros((0, 3)), line=np.zeros(0, dtype=np.int64))
    return PoseTable(tip=np.concatenate([c.tip for c in chunks]), axis=np.concatenate([c.axis for c in chunks]),
                     line=np.concatenate([c.line for c in chunks]))


def iter_poses(path: str, *, chunk_lines: int = CHUNK_LINES) -> Iterator[PoseTable]:
    """The poses of a CSV (as :func:`read_poses` reads it), ``chunk_lines`` lines of the file at a
    time, so that a table of any length is read in bounded memory.

    A problem is raised when its chunk is read: the chunks before it have been yielded.

    Raises
    ------
    InputError
    """
    expected = ",".join(POSE_COLUMNS)
    with open_input(path, "a CSV file") as stream:
        offset, number = 0, 0                            # bytes and lines read so far
        while True:
            raw = list(itertools.islice(stream, chunk_lines))
            if not raw:
                break
            if number == 0:
                header = _first_line(raw[0])
                check_header(header, path)
                offset, number = len(header), 1
                raw[0] = raw[0][len(header):]            # CR-only line ends: the whole table (see _first_line)
            data = b"".join(raw)
            table, count = _parse_plain(data, number)
            if table is None:
                try:
                    lines = data.decode("utf-8").splitlines()
                except UnicodeDecodeError as exc:
                    raise InputError(f"not UTF-8 text: {exc.reason} at byte {offset + exc.start}", path=path) from exc
                table = _parse_fast(lines, number) or _parse_careful(lines, number, path)
                count = len(lines)
            check_range(table, path)
            yield table
            offset, number = offset + len(data), number + count
        if number == 0:
            raise InputError(f"expected the header {expected}, got an empty file", path=path, line=1)


def _first_line(line: bytes) -> bytes:
    """``line`` (from a file read in lines cut at LF) up to its first line end: CR, LF or CRLF. A table
    with CR-only line ends is one such line, of which the header is only the start (the rest is read
    as the table's lines, cut at CR as the text readers cut them)."""
    cr = line.find(b"\r")
    if cr < 0 or line[cr:] in (b"\r", b"\r\n"):
        return line
    return line[:cr + 2] if line[cr + 1:cr + 2] == b"\n" else line[:cr + 1]


def check_header(line: bytes, path: str) -> None:
    """The first line must be the header (after a spreadsheet's byte order mark, if any).

    Raises
    ------
    InputError
    """
    try:
        text = line.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text: {exc.reason} at byte {exc.start}", path=path) from exc
    try:
        header = next(csv.reader(text.splitlines()[:1]), [])
    except csv.Error as exc:                       # a field over the csv module's limit (131072 characters)
        raise InputError(f"cannot read the line as CSV: {exc}", path=path, line=1) from exc
    if [h.strip() for h in header] != list(POSE_COLUMNS):
        raise InputError(f"expected the header {','.join(POSE_COLUMNS)}, got {','.join(header)!r}", path=path,
                         line=1)


#: The bytes of a plain table: printable ASCII and ``\n`` (other line breaks, tabs, UTF-8: read by the others).
_PLAIN_BYTES = bytes(range(0x20, 0x7F)) + b"\n"


def _plain(data: bytes) -> bool:
    """Only printable ASCII and ``\n`` line ends, and no blank line (spaces at most)."""
    if data.translate(None, _PLAIN_BYTES) or b"\n\n" in data or data.startswith(b"\n"):
        return False
    return b" " not in data or re.search(rb"(?:^|\n) *(?:\n|$)", data) is None


def _parse_plain(data: bytes, before: int) -> tuple[PoseTable | None, int]:
    """The lines of ``data`` (``before`` lines of the file come before them) read by numpy's C parser
    straight from the bytes, when they are plain (printable ASCII, ``\n`` line ends, no blank line)
    and six numbers each: (the table, the line count); (None, 0) otherwise."""
    if not data or not _plain(data):
        return None, 0
    try:
        table = np.loadtxt(io.BytesIO(data), delimiter=",", dtype=np.float64, ndmin=2, comments=None)
    except ValueError:
        return None, 0
    count = data.count(b"\n") + (not data.endswith(b"\n"))
    if table.shape != (count, 6):
        return None, 0
    return PoseTable(tip=table[:, :3], axis=table[:, 3:],
                     line=np.arange(before + 1, before + 1 + count, dtype=np.int64)), count


def check_range(table: PoseTable, path: str) -> None:
    """Refuse a value beyond POSE_LIMITS (or NaN, infinity): the first such line, its column and the range.

    Raises
    ------
    InputError
        ``poses.csv:7: tip_x = 1e+308 mm is out of range (allowed: within ±1e+06 mm)``.
    """
    values = np.column_stack([table.tip, table.axis])
    limits = np.array([limit for limit, _ in POSE_LIMITS])
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(values) <= limits)               # NaN too
    rows = np.flatnonzero(bad.any(axis=1))
    if rows.size:
        row = int(rows[0])
        column = int(np.argmax(bad[row]))
        limit, unit = POSE_LIMITS[column]
        unit = f" {unit}" if unit else ""
        raise InputError(f"{POSE_COLUMNS[column]} = {float(values[row, column]):.6g}{unit} is out of range (allowed: "
                         f"within ±{limit:.6g}{unit})", path=path, line=int(table.line[row]))


#: A number of a pose table: a plain decimal, as numpy's parser reads it (NaN and infinity: out of range).
_PLAIN_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:nan|inf|infinity)",
                           re.IGNORECASE)


def _parse_careful(lines: list[str], before: int, path: str) -> PoseTable:
    """Line by line with the csv module: finds the first problem and names its line (``before``
    lines of the file come before ``lines``)."""
    expected = ",".join(POSE_COLUMNS)
    values: list[list[float]] = []
    line_numbers: list[int] = []
    rows = csv.reader(lines)
    for number, row in enumerate(_csv_rows(rows, before, path), start=before + 1):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(POSE_COLUMNS):
            raise InputError(f"expected 6 values ({expected}), got {len(row)}", path=path, line=number)
        for cell in row:                   # float() also takes '1_0', '١', ' nan ': only plain decimals here
            if not _PLAIN_NUMBER.fullmatch(cell.strip(" ")):
                raise InputError(f"not a number: {quoted(cell)}", path=path, line=number)
        values.append([float(cell) for cell in row])
        line_numbers.append(number)
    table = np.array(values, dtype=np.float64).reshape(-1, 6)
    return PoseTable(tip=table[:, :3], axis=table[:, 3:], line=np.array(line_numbers, dtype=np.int64))


def _csv_rows(rows: Iterator[list[str]], before: int, path: str) -> Iterator[list[str]]:
    """The csv reader's rows; its own error (a field over its 131072-character limit) as an InputError
    naming the line (``before`` lines of the file come before the reader's first)."""
    number = before
    try:
        for row in rows:
            number += 1
            yield row
    except csv.Error as exc:
        raise InputError(f"cannot read the line as CSV: {exc}", path=path, line=number + 1) from exc


def _parse_fast(lines: list[str], before: int) -> PoseTable | None:
    """numpy's C parser for well-formed lines; None whenever anything is off (the careful
    line-by-line reader then finds the first problem and names its line)."""
    if any(not line or line.isspace() for line in lines):     # blank lines: skipped, the numbers go on
        numbers = np.array([before + i + 1 for i, line in enumerate(lines) if line.strip()], dtype=np.int64)
        body = [lines[n - before - 1] for n in numbers.tolist()]
    else:
        numbers, body = np.arange(before + 1, before + 1 + len(lines), dtype=np.int64), lines
    try:
        table = np.loadtxt(body, delimiter=",", dtype=np.float64, ndmin=2, comments=None) if body else np.zeros((0, 6))
    except ValueError:
        return None
    if table.shape[1] != 6:
        return None
    return PoseTable(tip=table[:, :3], axis=table[:, 3:], line=numbers)
