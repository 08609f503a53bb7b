"""How a CL file is written: its major words and limits, records (continuations joined, ``$$`` comments
split off), numbers, and the file's length unit (see :mod:`prs3_post.readers.cl.reader`)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

from prs3_post.core.defaults import MM_PER_INCH
from prs3_post.core.errors import InputError
from prs3_post.core.toolpath import MoveKind
from prs3_post.readers.common import MAX_RECORD_CHARS

#: Records that only drive a CAM system's display: skipped on purpose, and counted.
DISPLAY_WORDS: frozenset[str] = frozenset({"PAINT", "TOOL PATH"})
#: The NX listing trailer, skipped (and counted) after END-OF-PATH or FINI.
LISTING_TRAILER = "Tool Path Listing"
#: MSYS axes must be unit and orthogonal within this (they are printed with 7 decimals).
FRAME_TOLERANCE = 1e-5
#: A tool vector must have length 1 within this (it is then normalized).
AXIS_LENGTH_TOLERANCE = 1e-3
# A coordinate or length (GOTO/, CIRCLE/, MSYS/, CYCLE/) must lie within ±MAX_COORDINATE_MM, as an STL part's:
# a kilometre is far beyond any machine, so more is a typo or a unit error (bad input, not a point out of reach).

KNOWN_WORDS = ("GOTO", "FROM", "GOHOME", "RAPID", "FEDRAT", "MULTAX", "TLAXIS", "MSYS", "UNITS", "LOADTL",
               "LOAD", "SELECT", "TLDATA", "SPINDL", "COOLNT", "CYCLE", "CIRCLE", "PPRINT", "END-OF-PATH",
               "FINI", "STOP", "OPSTOP")
_NUMBER_TEXT = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"   # ASCII digits (\\d takes ١ too)
NUMBER = re.compile(rf"{_NUMBER_TEXT}\Z")
NUMBER_LIST = re.compile(rf"[ \t]*{_NUMBER_TEXT}[ \t]*(?:,[ \t]*{_NUMBER_TEXT}[ \t]*)*\Z")
TRAILER = re.compile(r"Tool Path Listing has \d+ lines\.\Z")
FEED_UNITS = {"MMPM": (1.0, False), "IPM": (MM_PER_INCH, False), "MMPR": (1.0, True), "IPR": (MM_PER_INCH, True)}
_UNIT_WORDS = {"MM": "mm", "INCHES": "inch", "INCH": "inch"}
RAPID, FEED = int(MoveKind.RAPID), int(MoveKind.FEED)


# --------------------------------------------------------------------------------------------
# Records
# --------------------------------------------------------------------------------------------
class Record(NamedTuple):
    line: int
    word: str                   # major word, upper case ("$$" for a comment line)
    rest: str | None            # the text after the slash (None without one; PPRINT: its text)
    text: str                   # the record as written (continuations joined), for messages
    comment: str | None         # inline $$ comment

    @property
    def args(self) -> tuple[str, ...]:
        """The arguments, stripped, as written (split on demand: GOTOs are read without it)."""
        return () if self.rest is None else tuple(arg.strip() for arg in self.rest.split(","))


def decoded_text(data: bytes, path: str, offset: int = 0) -> str:
    """The text of (a piece of) a file; binary data and non-UTF-8 are refused (``offset``: of the piece).
    The control bytes are looked for by csrc/lex.c's one pass where it was built, else by numpy."""
    from prs3_post.core import native  # ctypes: loaded only where a file is read

    scanned = native.scan_text(data)
    if scanned is None:
        codes = np.frombuffer(data, dtype=np.uint8)
        control = np.flatnonzero(((codes < 32) & (codes != 9) & (codes != 10) & (codes != 13)) | (codes == 127))
        at = int(control[0]) if len(control) else -1
    else:
        at = scanned[0]
    if at >= 0:
        raise InputError(f"not a CL file: binary data (byte 0x{data[at]:02x} at offset {offset + at})", path=path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a CL file: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                         f"{offset + exc.start})", path=path) from exc


def _split_comment(line: str) -> tuple[str, str | None]:
    at = line.find("$$")
    if at < 0:
        return line, None
    return line[:at], line[at + 2:].strip()


class Assembler:
    """Lines → records: continuations (a trailing single ``$``) joined, ``$$`` comments split off."""

    __slots__ = ("comment", "path", "pending", "size", "start")

    def __init__(self, path: str):
        self.path = path
        self.pending: list[str] = []
        self.size = 0                                # characters of the pending record so far
        self.start = 0
        self.comment: str | None = None

    def push(self, number: int, raw: str) -> Record | None:
        """The record that line ``number`` completes, or None (blank line, or continued)."""
        code, comment = _split_comment(raw)
        code = code.strip()
        if not self.pending:
            self.start = number
            if not code:
                return None if comment is None else Record(number, "$$", None, raw.strip(), comment)
        if comment is not None:
            self.comment = comment if self.comment is None else f"{self.comment} {comment}"
        self.size += len(code)
        if self.size > MAX_RECORD_CHARS:                 # before any work on it (a GOTO of millions of values)
            raise InputError(f"a record of {self.size:,} characters or more: longer than any CL record may be "
                             f"({MAX_RECORD_CHARS:,} at most); found {quote(''.join(self.pending) + code)}",
                             path=self.path, line=self.start)
        if code.endswith("$"):
            self.pending.append(code[:-1])
            return None
        self.pending.append(code)
        joined = "".join(self.pending)
        comment, self.comment = self.comment, None
        self.pending, self.size = [], 0
        return _split(self.start, joined, comment)

    def close(self) -> None:
        """The end of the file: a continued record there is truncated."""
        if self.pending:
            raise InputError(f"truncated record: {quote(''.join(self.pending))} continues with '$' but the file "
                             "ends (a continued record needs its next line)", path=self.path, line=self.start)


def _split(line: int, code: str, comment: str | None) -> Record:
    word, slash, rest = code.partition("/")
    word = word.strip().upper()
    if word == "PPRINT" or (not slash and code.upper().startswith("PPRINT ")):
        text = rest if slash else code[len("PPRINT"):]
        return Record(line, "PPRINT", text.strip(), code, comment)
    return Record(line, word, rest if slash else None, code, comment)


def quote(text: str, limit: int = 60) -> str:
    text = text.strip()
    return f"'{text[:limit]}...'" if len(text) > limit else f"'{text}'"


#: A line that may start a UNITS/ or FEDRAT/ record (the records that set the file's length unit).
_UNIT_LINE = re.compile(r"^[ \t]*(?:UNITS|FEDRAT)[ \t]*/", re.MULTILINE | re.IGNORECASE)


def unit_records(pieces: Iterator[str], path: str) -> list[Record]:
    """The UNITS/ and FEDRAT/ records of the whole file, found without reading every record (a FEDRAT/
    line that repeats an earlier one word for word, without ``$``, is left out: its feed unit is known
    already, and only the first line of each unit is used)."""
    found: list[Record] = []
    first_line = 1
    carry, carry_line = "", 0                        # a continued record cut by a piece's end
    fedrat_lines: set[str] = set()                   # whole FEDRAT/ lines read already
    for piece in pieces:
        text = carry + piece
        if carry:
            first_line, carry = carry_line, ""
        number, counted_to = first_line, 0
        for match in _unit_lines(text):
            fedrat = match[0].lstrip(" \t").upper().startswith("F")
            if fedrat:
                end = text.find("\n", match.start())
                line = text[match.start():] if end < 0 else text[match.start():end]
                if "$" in line or end < 0:
                    fedrat = False                       # a continued record, or the piece's last line: read it
                elif line in fedrat_lines:
                    continue
            # line numbers and lines are taken from the match on, never from the piece's start: a piece
            # with many FEDRAT/ records costs linear, not quadratic, time
            number += text.count("\n", counted_to, match.start())
            counted_to = match.start()
            assembler = Assembler(path)
            for offset, raw in enumerate(_lines_from(text, match.start())):
                record = assembler.push(number + offset, raw)
                if record is not None:
                    found.append(record)
                    if fedrat:
                        fedrat_lines.add(line)
                    break
            else:
                carry, carry_line = text[match.start():], number
                break
        if not carry:
            first_line += text.count("\n")
    return found


def _unit_lines(text: str) -> Iterator[re.Match[str]]:
    """``_UNIT_LINE.finditer(text)``, faster: in ASCII text only the lines where ``units`` or ``fedrat``
    (any case) occurs are tried (the pattern's scan of every line start is what the reader's first pass
    would spend its time on)."""
    if not text.isascii():                          # lower() keeps every position only in ASCII
        yield from _UNIT_LINE.finditer(text)
        return
    lower = text.lower()
    starts: set[int] = set()
    for word in ("units", "fedrat"):
        at = lower.find(word)
        while at >= 0:
            starts.add(text.rfind("\n", 0, at) + 1)
            at = lower.find(word, at + len(word))
    for start in sorted(starts):
        match = _UNIT_LINE.match(text, start)
        if match is not None:
            yield match


def _lines_from(text: str, start: int) -> Iterator[str]:
    """The lines of ``text`` from ``start`` on, without line ends (a final line end ends the last line)."""
    while start < len(text):
        end = text.find("\n", start)
        if end == -1:
            yield text[start:]
            return
        yield text[start:end]
        start = end + 1


def units_of_file(records: list[Record], path: str, caller: str | None) -> str:
    """The file's length unit: UNITS/, else the caller's, else implied by the feed units, else mm."""
    declared: tuple[str, int] | None = None
    feed_units: dict[str, int] = {}
    for record in records:
        if record.word == "UNITS":
            if len(record.args) != 1 or record.args[0].upper() not in _UNIT_WORDS:
                raise InputError(f"UNITS/ expects one of MM, INCHES; found {quote(record.text)}",
                                 path=path, line=record.line)
            unit = _UNIT_WORDS[record.args[0].upper()]
            if declared is not None and declared[0] != unit:
                raise InputError(f"UNITS/{record.args[0]} contradicts UNITS/ at line {declared[1]} "
                                 f"({declared[0]}): one length unit per file", path=path, line=record.line)
            declared = (unit, record.line)
        elif record.word == "FEDRAT":
            for arg in record.args:
                if arg.upper() in FEED_UNITS:
                    feed_units.setdefault("inch" if arg.upper().startswith("I") else "mm", record.line)
    if declared is not None:
        if caller is not None and caller != declared[0]:
            raise InputError(f"the file says UNITS/ {declared[0]} but {caller} was asked for: leave the unit out "
                             "or give the file's own", path=path, line=declared[1])
        return declared[0]
    if caller is not None:
        return caller
    if len(feed_units) == 2:
        raise InputError(f"feeds in both MMPM/MMPR (line {feed_units['mm']}) and IPM/IPR (line "
                         f"{feed_units['inch']}) and no UNITS/ record: the length unit of the file is "
                         "ambiguous; give it (mm or inch)", path=path)
    return "inch" if "inch" in feed_units else "mm"


def parse_number(text: str, what: str) -> float | str:
    """A float, or an error text."""
    if not NUMBER.match(text):
        return f"{what}: {text!r} is not a number (expected a decimal like -12.5, .5 or 1.5E+02)"
    value = float(text)
    if not math.isfinite(value):
        return f"{what}: {quote(text, 40)} is too large to be a finite number"
    return value
