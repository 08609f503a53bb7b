"""Read a prs3-post program (actuator-space G-code) back into a :class:`~prs3_post.toolpath.JointProgram`.

This is the input side of ``prs3-post verify`` and ``prs3-post preview``: it understands exactly
what the emitter (:mod:`prs3_post.emit.gcode`) writes, in any dialect, and rejects everything
else with an :class:`~prs3_post.errors.InputError` naming the file and the line, so that nothing
in a program is skipped silently.

Understood
----------
- The axis letters of the dialect (``[axes]``: stage X, Y and strokes T1, T2, T3); any other axis
  letter (A B C U V W X Y Z) is an error (``word 'Z' is not an axis of dialect linuxcnc (axes: X Y
  U V W)``). On a machine without a stage (``stage=False``) the stage letters are errors too.
- G0 G1 G4 G17 G21 G40 G49 G54 G61 G64 G80 G90 G93 G94; M0 M2 M3 M5 M6 M7 M8 M9 M30; F, S, T, P
  (with G4 or G64), N (first word), an ``O`` line, ``%`` lines, comments in the dialect's
  delimiters. Numbers are plain decimals (``-12.5``, ``.5``, ``5.``); spaces between and inside
  words are ignored and letters may be lower case, as LinuxCNC reads them.
- Modal state as LinuxCNC keeps it: G0/G1 stays active (Fanuc-style lines with axis words only),
  an axis keeps its value until a word changes it, G93/G94 is the feed mode.

Rules (LinuxCNC's, and the emitter's): every G1 runs under G93 with its own F > 0 (``F = 1 /
minutes``); F appears only on G1 lines; the first move sets every axis (the start position is
otherwise unknown); one code per modal group and no letter twice on a line; the program ends with
M2 or M30 and only comments, blank lines and a closing ``%`` follow. A file that is not UTF-8
text, has control bytes, or does not read as G-code words is refused as not G-code.

Parsing: each line's code (comments removed) is scanned by a strict regular expression here, and
cross-checked word for word with pygcode's reading of the same text; a disagreement is an error
(pygcode alone silently drops some characters, e.g. NUL bytes, or truncates ``T1.5`` to ``T1``).

Every move keeps its 1-based line number (``JointProgram.source``), for the reports.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from prs3_post.config import AXIS_LETTERS, Dialect
from prs3_post.errors import InputError
from prs3_post.readers.files import read_input
from prs3_post.toolpath import Event, EventKind, JointProgram, MoveKind

__all__ = ["ALLOWED_G", "ALLOWED_M", "ProgramFile", "load_program", "read_program"]

#: G-codes the emitter writes, with their modal group (one code per group and line).
ALLOWED_G: dict[int, str] = {
    0: "motion", 1: "motion", 80: "motion", 4: "dwell", 17: "plane", 21: "units", 40: "cutter compensation",
    49: "tool length offset", 54: "coordinate system", 61: "path control", 64: "path control",
    90: "distance mode", 93: "feed mode", 94: "feed mode",
}
#: M-codes the emitter writes, with their modal group.
ALLOWED_M: dict[int, str] = {0: "stop", 2: "stop", 30: "stop", 3: "spindle", 5: "spindle", 6: "tool change",
                             7: "coolant", 8: "coolant", 9: "coolant"}
#: Word letters other than axes: what each is for.
_OTHER_LETTERS = "GMNFSTPO"
_NUMBER = r"-?(?:\d+(?:\.\d*)?|\.\d+)"
_WORD = re.compile(rf"([A-Z])({_NUMBER})")
_AXIS_NAMES = ("stage X", "stage Y", "actuator T1", "actuator T2", "actuator T3")


@dataclass(frozen=True, slots=True)
class ProgramFile:
    """A program read back from G-code.

    Attributes
    ----------
    path : str — as given (shown in messages)
    dialect : str — the dialect's name
    moves : JointProgram — one row per G0/G1 line: ``stage`` (N, 2) mm (zeros without a stage),
        ``strokes`` (N, 3) mm, ``inverse_time`` (N,) 1/min (the F of each G1, 0 for G0), ``source``
        (N,) the 1-based line number, and the events (spindle, coolant, tool change, dwell in s, stop)
    lines : tuple of str — the file's lines without line endings (``lines[n - 1]`` is line n)
    end_line : int — the line of M2 / M30
    blending_lines : tuple of int — lines that switch on G64 path blending (the control may round
        corners in joint space; the replay assumes exact stops, as G61 asks)
    """

    path: str
    dialect: str
    moves: JointProgram
    lines: tuple[str, ...]
    end_line: int
    blending_lines: tuple[int, ...]


def load_program(path: str, dialect: Dialect, *, stage: bool = True) -> ProgramFile:
    """Read a program file (see the module docstring for what is understood).

    Parameters
    ----------
    path : str
    dialect : Dialect — letters, comment delimiters, dwell unit and line length of the program
    stage : bool — the machine has an XY stage (False: stage words are errors, stage = 0)

    Returns
    -------
    ProgramFile

    Raises
    ------
    InputError
        ``path: message`` for a file that cannot be read or is not text, ``path:line: message``
        for the first line that is not understood.
    """
    data = read_input(path, "a G-code program")
    return read_program(text_from_bytes(data, path), dialect, path=path, stage=stage)


def text_from_bytes(data: bytes, path: str) -> str:
    """The program text of a file's bytes; binary data, non-UTF-8 and empty files are refused.

    Raises
    ------
    InputError
        ``not a G-code program: ...`` with what was found.
    """
    if not data.strip():
        raise InputError("not a G-code program: the file is empty", path=path)
    if data.startswith(b"\xef\xbb\xbf"):
        raise InputError("starts with a UTF-8 byte-order mark, which LinuxCNC rejects ('Bad character')", path=path)
    codes = np.frombuffer(data, dtype=np.uint8)
    control = np.flatnonzero(((codes < 32) & ~np.isin(codes, (9, 10, 13))) | (codes == 127))
    if len(control):
        at = int(control[0])
        raise InputError(f"not a G-code program: binary data (byte 0x{codes[at]:02x} at offset {at})", path=path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a G-code program: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
                         f"{exc.start})", path=path) from exc


def _strip_comments(line: str, open_: str, close: str) -> tuple[str, str | None]:
    """The line's code without comments, and an error text for an unclosed comment (or None)."""
    code: list[str] = []
    pos = 0
    while True:
        start = line.find(open_, pos)
        if start < 0:
            code.append(line[pos:])
            return "".join(code), None
        code.append(line[pos:start])
        if not close:
            return "".join(code), None
        end = line.find(close, start + len(open_))
        if end < 0:
            return "", f"comment opened with {open_!r} at column {start + 1} is not closed with {close!r}"
        if open_ in line[start + len(open_):end]:
            return "", f"comment at column {start + 1} contains another {open_!r} (LinuxCNC rejects nested comments)"
        pos = end + len(close)


def _quote(text: str, limit: int = 40) -> str:
    text = text.strip()
    return f"'{text[:limit]}...'" if len(text) > limit else f"'{text}'"


def _scan_words(code: str) -> tuple[list[tuple[str, float, str]], str | None]:
    """``(letter, value, text)`` of each word of comment-free code, or an error text."""
    squeezed = re.sub(r"[ \t]+", "", code).upper()
    words: list[tuple[str, float, str]] = []
    pos = 0
    while pos < len(squeezed):
        match = _WORD.match(squeezed, pos)
        if match is None:
            return [], "bad"
        words.append((match.group(1), float(match.group(2)), match.group(0)))
        pos = match.end()
    return words, None


def _pygcode_words(code: str) -> list[tuple[str, float]]:
    """pygcode's reading of the same code, as ``(letter, value)``; raises what pygcode raises."""
    import pygcode  # only `verify` and `preview` read programs: the other commands need not load it

    line = pygcode.Line(code)
    return [(w.letter.upper(), float(w.value)) for w in line.block.words]


def _code_name(letter: str, value: float) -> str:
    return f"{letter}{int(value)}" if value == int(value) else f"{letter}{value:g}"


def read_program(text: str, dialect: Dialect, *, path: str, stage: bool = True) -> ProgramFile:
    """Read program text (see the module docstring); ``path`` is only used in messages.

    Raises
    ------
    InputError
    """
    reader = _Reader(dialect, path, stage)
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()                                    # the final line ending
    crlf = [ln.endswith("\r") for ln in lines]
    lines = [ln[:-1] if cr else ln for ln, cr in zip(lines, crlf, strict=True)]
    for number, (line, cr) in enumerate(zip(lines, crlf, strict=True), start=1):
        reader.line(number, line, crlf=cr)
    return reader.finish(tuple(lines))


class _Reader:
    """The modal state of LinuxCNC's interpreter, as far as prs3-post programs use it."""

    def __init__(self, dialect: Dialect, path: str, stage: bool):
        self.dialect, self.path, self.stage = dialect, path, stage
        ax = dialect.axes
        self.letters = (ax.x, ax.y, ax.t1, ax.t2, ax.t3)
        self.axis_index = {letter: i for i, letter in enumerate(self.letters)}
        self.axes_text = " ".join(self.letters if stage else self.letters[2:])
        self.motion: int | None = None                # 0, 1 or None (after G80 / at start)
        self.inverse_time = False                      # G93 active
        self.spindle: float | None = None              # last S
        self.tool: int | None = None                   # last T
        self.position = np.full(5, np.nan) if stage else np.array([0.0, 0.0, np.nan, np.nan, np.nan])
        self.kind: list[int] = []
        self.joints: list[np.ndarray] = []
        self.feed: list[float] = []
        self.source: list[int] = []
        self.events: list[Event] = []
        self.end_line: int | None = None
        self.percent = 0                               # % lines seen
        self.blending: list[int] = []
        self.code_seen = False
        self.number = 0

    def error(self, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.number)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        self.events.append(Event(before=len(self.kind), kind=kind, value=value, text=text))

    # ------------------------------------------------------------------ one line
    def line(self, number: int, line: str, *, crlf: bool = False) -> None:
        """One line without its ending; ``crlf``: it ended in a CR (``\\r\\n``), which LinuxCNC counts
        towards its line-length limit (the emitter allows one character less for CRLF, too)."""
        self.number = number
        limit = self.dialect.max_line_length - (1 if crlf else 0)
        if len(line) > limit:
            ending = f" with a CRLF line ending (LinuxCNC counts the CR; {limit + 1} with LF)" if crlf else ""
            raise self.error(f"the line is {len(line)} characters, dialect {self.dialect.name} allows {limit}{ending}")
        style = self.dialect.comments
        code, problem = _strip_comments(line, style.open, style.close)
        if problem:
            raise self.error(problem)
        code = code.strip()
        if self.percent >= 2:
            if line.strip():
                raise self.error(f"text after the closing '%': {_quote(line)} (LinuxCNC never reads it)")
            return
        if code == "%":
            if self.percent == 0 and not self.code_seen:
                self.percent = 1                       # the opening %
                return
            if self.end_line is None:
                raise self.error("'%' before the program end (M2 or M30): only the first line and the lines "
                                 "after the end may be '%'")
            self.percent = 2                           # the closing %: LinuxCNC reads no further
            return
        if not code:
            return
        if self.end_line is not None:
            raise self.error(f"code after the program end (line {self.end_line}): {_quote(code)} "
                             "(LinuxCNC never reads it)")
        words, bad = _scan_words(code)
        if bad:
            raise self.error(f"not G-code: cannot read {_quote(code)} as words "
                             "(a letter and a number each, e.g. G1 X-1.5)")
        self.code_seen = True
        self.words(words, code)

    def words(self, words: list[tuple[str, float, str]], code: str) -> None:
        # ---- which words, where: letters first, then codes and groups
        if words[0][0] == "O":
            if len(words) > 1:
                raise self.error("an O (program number) word must be alone on its line")
            return
        seen: dict[str, str] = {}
        g_codes: dict[str, int] = {}
        m_codes: dict[str, int] = {}
        axes: dict[int, float] = {}
        values: dict[str, float] = {}
        for position, (letter, value, text) in enumerate(words):
            if letter in AXIS_LETTERS:
                if letter not in self.axis_index or (not self.stage and self.axis_index[letter] < 2):
                    if letter in self.axis_index:
                        raise self.error(f"word '{letter}' is the stage {'XY'[self.axis_index[letter]]} axis of "
                                         f"dialect {self.dialect.name}, and the machine has no stage "
                                         f"(axes: {self.axes_text})")
                    raise self.error(f"word '{letter}' is not an axis of dialect {self.dialect.name} "
                                     f"(axes: {self.axes_text})")
            elif letter not in _OTHER_LETTERS:
                raise self.error(f"word '{letter}' is not used in prs3-post programs (words read: G M N F S T P "
                                 f"and the axes {self.axes_text})")
            if letter in "GM":
                table = ALLOWED_G if letter == "G" else ALLOWED_M
                name = _code_name(letter, value)
                if value != int(value) or int(value) not in table:
                    allowed = " ".join(f"{letter}{c}" for c in sorted(table))
                    raise self.error(f"{name} is not a code prs3-post programs use (allowed: {allowed})")
                group = table[int(value)]
                groups = g_codes if letter == "G" else m_codes
                if group in groups:
                    other = _code_name(letter, groups[group])
                    raise self.error(f"{other} and {name} are in the same modal group ({group}): one per line")
                groups[group] = int(value)
                continue
            if letter in seen:
                raise self.error(f"word '{letter}' appears twice ({seen[letter]} and {text})")
            seen[letter] = text
            if letter == "N":
                if position != 0:
                    raise self.error(f"the block number {text} must be the first word of the line")
            elif letter == "O":
                raise self.error("an O (program number) word must be alone on its line")
            elif letter in AXIS_LETTERS:
                axes[self.axis_index[letter]] = value
            else:
                values[letter] = value
        self.cross_check(words, code)

        # ---- meaning, in LinuxCNC's order of execution
        if "feed mode" in g_codes:
            self.inverse_time = g_codes["feed mode"] == 93
        motion = g_codes.get("motion", self.motion)
        if motion == 80:
            motion = None
        moves = bool(axes) or ("motion" in g_codes and g_codes["motion"] != 80)
        if axes and motion is None:
            raise self.error("axis words without a motion mode (G0 or G1)")
        if axes and "dwell" in g_codes:
            raise self.error("G4 (dwell) with axis words: the dwell and the move need their own lines")
        if "F" in values:
            if not (moves and motion == 1):
                raise self.error("F word on a line without a G1 move (prs3-post programs carry F only on G1 lines)")
            if not values["F"] > 0:
                raise self.error(f"{seen['F']}: the feed must be > 0 (LinuxCNC raises F0 to 0.1 /min)")
        if moves and motion == 1:
            if not self.inverse_time:
                raise self.error("G1 under G94 (units per minute): prs3-post programs feed in G93 inverse time, "
                                 "where F = 1 / minutes of the move")
            if "F" not in values:
                raise self.error("G1 without F under G93 (inverse time needs an F word on every G1)")
        if "S" in values:
            if values["S"] < 0:
                raise self.error(f"{seen['S']}: the spindle speed must be ≥ 0 rpm")
            self.spindle = values["S"]
        if "T" in values:
            if values["T"] < 0 or values["T"] != int(values["T"]):
                raise self.error(f"{seen['T']}: the tool number must be a whole number ≥ 0")
            self.tool = int(values["T"])
        if "P" in values and "dwell" not in g_codes and g_codes.get("path control") != 64:
            raise self.error(f"word 'P' ({seen['P']}) needs G4 (dwell) or G64 on the same line")
        if m_codes.get("tool change") == 6:
            if self.tool is None:
                raise self.error("M6 (tool change) without a tool number T")
            self.event(EventKind.TOOL_CHANGE, float(self.tool), f"T{self.tool}")
        spindle = m_codes.get("spindle")
        if spindle == 3:
            if self.spindle is None or not self.spindle > 0:
                raise self.error("M3 (spindle on) without a spindle speed S > 0")
            self.event(EventKind.SPINDLE_ON, self.spindle)
        elif spindle == 5:
            self.event(EventKind.SPINDLE_OFF)
        coolant = m_codes.get("coolant")
        if coolant in (7, 8):
            self.event(EventKind.COOLANT_ON, 0.0, "mist" if coolant == 7 else "flood")
        elif coolant == 9:
            self.event(EventKind.COOLANT_OFF)
        if "dwell" in g_codes:
            if "P" not in values or values["P"] < 0:
                raise self.error("G4 (dwell) needs a P word ≥ 0 "
                                 f"({'seconds' if self.dialect.dwell_unit == 's' else 'milliseconds'})")
            seconds = values["P"] / 1000.0 if self.dialect.dwell_unit == "ms" else values["P"]
            self.event(EventKind.DWELL, seconds)
        if g_codes.get("path control") == 64:
            self.blending.append(self.number)
        self.motion = motion
        if moves:
            assert motion is not None  # checked above: a move needs a motion mode  # noqa: S101
            self.move(motion, axes, values.get("F", 0.0))
        stop = m_codes.get("stop")
        if stop == 0:
            self.event(EventKind.STOP)
        elif stop in (2, 30):
            self.end_line = self.number

    def cross_check(self, words: list[tuple[str, float, str]], code: str) -> None:
        """pygcode must read the same words from the same code; else it is not plain G-code."""
        import pygcode.exceptions

        try:
            theirs = _pygcode_words(code)
        except (pygcode.exceptions.GCodeBlockFormatError, pygcode.exceptions.GCodeWordStrError,
                pygcode.exceptions.GCodeParameterError, AssertionError, ValueError) as exc:
            raise self.error(f"not G-code that pygcode reads: {exc}") from exc
        ours = [(letter, value) for letter, value, _ in words]
        if theirs != ours:
            shown = " ".join(_code_name(letter, value) for letter, value in theirs)
            raise self.error(f"pygcode reads {_quote(code)} as {shown!r}: not plain G-code")

    def move(self, motion: int, axes: dict[int, float], feed: float) -> None:
        for index, value in axes.items():
            self.position[index] = value
        missing = [i for i in range(5) if np.isnan(self.position[i])]
        if missing:
            names = ", ".join(f"{self.letters[i]} ({_AXIS_NAMES[i]})" for i in missing)
            raise self.error(f"the first move must set every axis ({self.axes_text}); missing: {names}")
        self.kind.append(int(MoveKind.FEED if motion == 1 else MoveKind.RAPID))
        self.joints.append(self.position.copy())
        self.feed.append(feed)
        self.source.append(self.number)

    # ------------------------------------------------------------------ the end
    def finish(self, lines: tuple[str, ...]) -> ProgramFile:
        if self.end_line is None:
            if not self.code_seen:
                raise InputError("not a G-code program: no code, only comments and blank lines", path=self.path)
            raise InputError(f"the program never ends: no M2 or M30 in its {len(lines)} lines (truncated file?)",
                             path=self.path)
        joints = np.array(self.joints, dtype=np.float64).reshape(-1, 5)
        moves = JointProgram(
            kind=np.array(self.kind, dtype=np.int64), stage=joints[:, :2], strokes=joints[:, 2:],
            inverse_time=np.array(self.feed, dtype=np.float64), source=np.array(self.source, dtype=np.int64),
            events=tuple(self.events),
        )
        return ProgramFile(path=self.path, dialect=self.dialect.name, moves=moves, lines=lines,
                           end_line=self.end_line, blending_lines=tuple(self.blending))
