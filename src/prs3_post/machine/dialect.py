"""The G-code dialect types (frozen; loaded from TOML by :mod:`prs3_post.machine.loading`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["AXIS_LETTERS", "COMMENT_CONTINUATION", "DWELL_UNITS", "END_CODES", "LINE_ENDINGS", "TOOL_NUMBER_LIMIT",
           "AxisLetters", "CommentStyle", "Decimals", "Dialect", "LineNumbers"]

#: Indent of the continuation lines of a comment too long for one line (the emitter writes them, the
#: header reader joins them, the dialect's line length leaves room for them).
COMMENT_CONTINUATION = "  "
#: RS-274 axis letters a dialect may map a machine axis to. Every other letter already means
#: something in a motion block (G, M, F, S, T, P, N, O, and the arc/cycle words D E H I J K L Q R).
AXIS_LETTERS = "ABCUVWXYZ"
#: Program end codes the emitter may write (both end the program and rewind).
END_CODES = ("M2", "M30")
#: Line endings a dialect may choose (LinuxCNC counts the CR of CRLF towards the line length).
LINE_ENDINGS = {"\n": "LF", "\r\n": "CRLF"}
#: Units of the G4 P word: LinuxCNC reads seconds, Fanuc (P without a decimal point) milliseconds.
DWELL_UNITS = ("s", "ms")
#: The largest ``words.tool_number_max`` (8 digits, as program.number): far beyond it a tool
#: number no longer survives the float of an event value (and LinuxCNC reads T2147483648 as negative).
TOOL_NUMBER_LIMIT = 99_999_999


@dataclass(frozen=True, slots=True)
class AxisLetters:
    """Which word letter each machine axis is written with (all distinct, from :data:`AXIS_LETTERS`).

    Attributes
    ----------
    x, y : str — stage X, Y (not written on a machine without a stage)
    t1, t2, t3 : str — actuator strokes T1, T2, T3
    """

    x: str
    y: str
    t1: str
    t2: str
    t3: str

    def __post_init__(self) -> None:
        letters = (self.x, self.y, self.t1, self.t2, self.t3)
        if any(len(a) != 1 or a not in AXIS_LETTERS for a in letters) or len(set(letters)) != 5:
            raise ValueError(f"axis letters must be 5 distinct letters from {AXIS_LETTERS}, got {letters}")


@dataclass(frozen=True, slots=True)
class Decimals:
    """Digits after the decimal point of each kind of number word.

    Attributes
    ----------
    length : int — 1..8, X Y and actuator words (mm)
    inverse_time : int — 1..8, the G93 F word (1/min)
    spindle : int — 0..8, the S word (rpm)
    dwell : int — 0..8, the G4 P word (in the dialect's dwell unit)
    """

    length: int
    inverse_time: int
    spindle: int
    dwell: int


@dataclass(frozen=True, slots=True)
class LineNumbers:
    """Block numbers (``N10``) in front of every block except ``%``, the ``O`` line and comment lines.

    Attributes
    ----------
    enabled : bool — write them at all (the CLI may override)
    letter : str — the word letter, normally ``N``
    start : int — ≥ 0, the first number (the CLI may override)
    step : int — ≥ 1, the increment (the CLI may override)
    wrap_after : int — ≥ start, the largest number the control accepts; the next one is ``start`` again
    """

    enabled: bool
    letter: str
    start: int
    step: int
    wrap_after: int


@dataclass(frozen=True, slots=True)
class CommentStyle:
    """How a comment is written and how its text is made safe.

    Attributes
    ----------
    open, close : str — what surrounds the text (``(`` and ``)``)
    uppercase : bool — upper-case the text (old Fanuc controls reject lower case)
    replace : tuple of (str, str) — single characters and their replacements, applied first; covers
        every character of ``open`` and ``close`` so that a text can never end its comment early
    control : str — replacement for control characters (newline, tab, CR, ...) not in ``replace``
    non_ascii : str — replacement for any other character outside printable ASCII not in ``replace``
    active_words : tuple of str — words the controller acts on when a comment starts with
        ``WORD,`` (LinuxCNC: ``(MSG, ...)`` pops up a message); in such a text that comma becomes a period
    """

    open: str
    close: str
    uppercase: bool
    replace: tuple[tuple[str, str], ...]
    control: str
    non_ascii: str
    active_words: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class Dialect:
    """A G-code dialect: everything the emitter writes that is not motion data.

    Attributes
    ----------
    name : str — the file's stem (``linuxcnc``)
    description : str — one line for listings
    source : str — where it was loaded from, as shown in messages
    axes : AxisLetters — word letter of each machine axis
    decimals : Decimals — fixed decimals of each kind of number
    line_numbers : LineNumbers — block numbering
    comments : CommentStyle — comment delimiters and sanitizing
    percent : bool — a ``%`` line opens and closes the program
    program_number : int — 0: no ``O`` line; else ``O<n>`` right after the opening ``%``
    program_name : str — comment on the ``O`` line (empty: none)
    end_code : str — ``M2`` or ``M30``
    line_ending : str — ``"\\n"`` or ``"\\r\\n"``
    max_line_length : int — characters per line without the line ending (LinuxCNC: 252)
    safe_start : tuple of str — blocks that put the control in a known state
    preamble : tuple of str — blocks after the safe start, before the first move
    postamble : tuple of str — blocks after the last move, before the end code
    modal_motion : bool — write G0/G1 only when it changes (False: on every motion line)
    dwell_unit : str — unit of the G4 P word, ``s`` or ``ms``
    tool_number_max : int — the largest tool number (T word) the controller takes (1 is the smallest)
    extension : str — the file name ending of its programs (``.ngc``), for outputs named after their input
    """

    name: str
    description: str
    source: str
    axes: AxisLetters
    decimals: Decimals
    line_numbers: LineNumbers
    comments: CommentStyle
    percent: bool
    program_number: int
    program_name: str
    end_code: str
    line_ending: str
    max_line_length: int
    safe_start: tuple[str, ...]
    preamble: tuple[str, ...]
    postamble: tuple[str, ...]
    modal_motion: bool
    dwell_unit: str
    tool_number_max: int
    extension: str = ".ngc"

    def __post_init__(self) -> None:
        if self.end_code not in END_CODES:
            raise ValueError(f"end_code must be one of {END_CODES}, got {self.end_code!r}")
        if self.line_ending not in LINE_ENDINGS:
            raise ValueError(f"line_ending must be LF or CRLF, got {self.line_ending!r}")
        if self.dwell_unit not in DWELL_UNITS:
            raise ValueError(f"dwell_unit must be one of {DWELL_UNITS}, got {self.dwell_unit!r}")
