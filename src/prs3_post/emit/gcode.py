"""Write a :class:`~prs3_post.toolpath.JointProgram` as G-code text in a :class:`~prs3_post.config.Dialect`.

Pure: :func:`emit_program` returns the program as a string and never opens a file; the CLI writes it.
The output is a function of its inputs only (no time stamps, host names or paths unless the caller
puts them in ``header``).

What is written, in order::

    %                                  program.percent
    O1000 (PRS3-POST)                  program.number / program.name
    (key: value)                       the caller's header, then the axis map and the feed mode
    G17 G21 G40 G49 G54 G80 G90 G94    blocks.safe_start, then blocks.preamble
    G61
    G0 X.. Y.. U.. V.. W..             motion rows, with the events before each row
    G93                                once, before the first feed row
    G1 U.. V.. F..                     every G1 carries F (inverse time, 1/min, > 0)
    G94                                back to units/min, if G93 was written
    M2                                 blocks.postamble, then program.end_code
    %

Why the motion looks like this (LinuxCNC's rules, DESIGN.md "Output"): the moves are joint-space
moves, so the programmed tip feed can only be held with G93 inverse time (each G1 takes 1/F min,
whatever the joints do). Under G93 every G1 needs its own F, every G93/G94 word resets F to 0, and
F0 is silently raised to 0.1, so an F that would print as 0 is an error here. Numbers are fixed
decimals (``1e-05`` would be read as an E word; ``nan``/``inf`` are refused); an axis word whose
*formatted* text is the same as the last one written for that axis is left out.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Iterable

import numpy as np

from prs3_post.config import CommentStyle, Dialect
from prs3_post.errors import LimitError
from prs3_post.toolpath import Event, EventKind, JointProgram, MoveKind

__all__ = ["emit_program", "format_word", "inert", "sanitize_comment"]

#: Indent of the continuation lines of a comment too long for one line.
_CONTINUATION = "  "


def format_word(letter: str, value: float, decimals: int) -> str:
    """One G-code word with fixed decimals: never exponent notation, never ``-0.000``.

    Parameters
    ----------
    letter : str
        The word letter (``X``).
    value : float
        The number; rounded half-even on its binary value by Python's fixed-point formatting.
    decimals : int
        Digits after the decimal point (0: no decimal point).

    Returns
    -------
    str
        e.g. ``X-12.3457``; ``X0.0000`` for ``-0.00004``.

    Raises
    ------
    ValueError
        When ``value`` is nan or infinite (the caller, which knows the row, reports it).

    Examples
    --------
    >>> format_word("X", -0.00004, 4), format_word("U", 1e-5, 4), format_word("F", 2.0, 0)
    ('X0.0000', 'U0.0000', 'F2')
    """
    if not math.isfinite(value):
        raise ValueError(f"{letter}: {value!r} is not a finite number")
    text = f"{value:.{decimals}f}"
    return f"{letter}{text[1:] if text.startswith('-') and float(text) == 0 else text}"


def sanitize_comment(text: str, style: CommentStyle) -> str:
    """Make ``text`` safe to put between the comment delimiters of ``style`` (one line, no delimiter).

    Each character of ``style.replace`` is replaced first; then control characters (newline, tab,
    CR, ...) become ``style.control`` and any other character outside printable ASCII becomes
    ``style.non_ascii``; then the text is upper-cased if the style asks for it (after the
    replacements, so that only ASCII is upper-cased); last, a text that starts with one of the
    controller's ``active_words`` and a comma (LinuxCNC's ``MSG,``, ``DEBUG,``, ...; leading
    spaces and case do not matter to it) gets that comma turned into a period (:func:`inert`).

    Parameters
    ----------
    text : str
        Any text (a header value, an operator comment from the CAM input, ...).
    style : CommentStyle
        The dialect's comment style; its loader guarantees that no replacement contains a delimiter.

    Returns
    -------
    str
        Printable ASCII without any character of ``style.open`` or ``style.close``.

    Examples
    --------
    >>> from prs3_post.config import load_dialect
    >>> sanitize_comment("hole (1)\\nat 26.6°", load_dialect("linuxcnc").comments)
    'hole [1] at 26.6 deg'
    >>> sanitize_comment(" msg, stop here", load_dialect("linuxcnc").comments)
    ' msg. stop here'
    """
    replace = dict(style.replace)
    out: list[str] = []
    for char in text:
        if char in replace:
            out.append(replace[char])
        elif " " <= char <= "~":
            out.append(char)
        elif ord(char) < 32 or ord(char) == 127 or 128 <= ord(char) < 160:  # C0, DEL, C1 controls
            out.append(style.control)
        else:
            out.append(style.non_ascii)
    safe = "".join(out)
    return inert(safe.upper() if style.uppercase else safe, style)


def inert(text: str, style: CommentStyle) -> str:
    """``text``, with the comma after a leading active word made a period so the controller does
    not act on it (``MSG, x`` → ``MSG. x``: a plain comment, and the same length).

    >>> from prs3_post.config import load_dialect
    >>> inert("  Debug, x", load_dialect("linuxcnc").comments), inert("debugging, x", load_dialect("linuxcnc").comments)
    ('  Debug. x', 'debugging, x')
    """
    head = text.lstrip().split(",", 1)
    if len(head) == 2 and head[0].strip().upper() in style.active_words:
        return text.replace(",", ".", 1)
    return text


class _Lines:
    """The program's lines: block numbers, comment wrapping and the line-length limit in one place."""

    def __init__(self, dialect: Dialect, numbered: bool, start: int, step: int):
        self.dialect = dialect
        self.numbered, self.start, self.number, self.step = numbered, start, start, step
        # LinuxCNC counts the CR of a CRLF ending towards its limit.
        self.limit = dialect.max_line_length - (len(dialect.line_ending) - 1)
        self.lines: list[str] = []

    def raw(self, text: str) -> None:
        """A line written as it is, never numbered (``%``, the ``O`` line)."""
        self.lines.append(text)

    def block(self, text: str, where: str) -> None:
        """A block, numbered when numbering is on; a line over the limit is a LimitError at ``where``."""
        if self.numbered:
            text = f"{self.dialect.line_numbers.letter}{self.number} {text}"
            self.number += self.step
            if self.number > self.dialect.line_numbers.wrap_after:
                self.number = self.start  # the first number of this program (the CLI may override it)
        if len(text) > self.limit:
            raise LimitError(
                f"{where}: the block is {len(text)} characters, the dialect allows {self.limit}: {text[:60]}..."
            )
        self.lines.append(text)

    def comment(self, text: str) -> None:
        """A comment, sanitized, split over as many unnumbered lines as it needs."""
        style = self.dialect.comments
        width = self.limit - len(style.open) - len(style.close)
        # Sanitizing first: it can lengthen the text, and it leaves one line of printable ASCII.
        parts = textwrap.wrap(
            sanitize_comment(text, style),
            width=width,
            subsequent_indent=_CONTINUATION,
            break_on_hyphens=False,
        ) or [""]
        # a continuation line could start with an active word again: guard every line
        self.lines.extend(f"{style.open}{inert(part, style)}{style.close}" for part in parts)

    def text(self) -> str:
        ending = self.dialect.line_ending
        return ending.join(self.lines) + ending


def _row(program: JointProgram, row: int) -> str:
    return f"row {row} from {program.describe(row)}"


def _event_where(program: JointProgram, event: Event) -> str:
    if event.before == len(program):
        return f"{event.kind.value} event after the last row"
    return f"{event.kind.value} event before {_row(program, event.before)}"


def _column(program: JointProgram, values: np.ndarray, letter: str, decimals: int, name: str) -> list[str]:
    """Format one axis column; the first non-finite value is a LimitError naming its row."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        row = int(bad[0])
        raise LimitError(f"{_row(program, row)}: {name} ({letter}) is {float(values[row])!r}, not a finite number")
    return [format_word(letter, v, decimals) for v in values.tolist()]


def _feed_words(program: JointProgram, decimals: int) -> dict[int, str]:
    """The F word of every FEED row; one that is not > 0 once printed is a LimitError naming its row."""
    feed_rows = np.flatnonzero(program.kind == MoveKind.FEED)
    words: dict[int, str] = {}
    for row in feed_rows.tolist():
        value = float(program.inverse_time[row])
        if not (math.isfinite(value) and value > 0):
            raise LimitError(
                f"{_row(program, row)}: inverse-time feed must be a finite number > 0 /min, got {value!r}"
            )
        word = format_word("F", value, decimals)
        if float(word[1:]) == 0:
            raise LimitError(
                f"{_row(program, row)}: inverse-time feed {value:.6g} /min formats to {word} with "
                f"decimals.inverse_time = {decimals} (the move would take {1 / value:.6g} min); "
                "LinuxCNC would raise F0 to 0.1 and run the move at another feed"
            )
        words[row] = word
    return words


def _event_blocks(program: JointProgram, event: Event, dialect: Dialect) -> tuple[str | None, str]:
    """``(comment or None, block)`` for a non-COMMENT event; bad values are a LimitError naming it."""
    where = _event_where(program, event)
    value = float(event.value)
    dec = dialect.decimals
    if event.kind is EventKind.SPINDLE_ON:
        word = format_word("S", value, dec.spindle) if math.isfinite(value) else ""
        if not word or float(word[1:]) <= 0:
            raise LimitError(
                f"{where}: spindle speed must be > 0 rpm once printed with decimals.spindle = {dec.spindle}, "
                f"got {value!r}"
            )
        return None, f"{word} M3"
    if event.kind is EventKind.SPINDLE_OFF:
        return None, "M5"
    if event.kind is EventKind.COOLANT_ON:
        return None, "M7" if event.text == "mist" else "M8"
    if event.kind is EventKind.COOLANT_OFF:
        return None, "M9"
    if event.kind is EventKind.TOOL_CHANGE:
        top = dialect.tool_number_max
        if not (math.isfinite(value) and 0 <= value <= top and value == int(value)):
            raise LimitError(f"{where}: tool number must be a whole number 0..{top} (words.tool_number_max), "
                             f"got {value!r}")
        return (event.text or None), f"T{int(value)} M6"
    if event.kind is EventKind.DWELL:
        if not (math.isfinite(value) and value >= 0):
            raise LimitError(f"{where}: dwell must be a finite number ≥ 0 s, got {value!r}")
        seconds = value * 1000.0 if dialect.dwell_unit == "ms" else value
        return None, f"G4 {format_word('P', seconds, dec.dwell)}"
    if event.kind is EventKind.STOP:
        return None, "M0"
    raise ValueError(f"no G-code for event kind {event.kind!r}")


def _axis_line(dialect: Dialect, stage: bool) -> str:
    ax = dialect.axes
    strokes = f"{ax.t1} {ax.t2} {ax.t3} = actuator strokes T1 T2 T3 mm"
    if stage:
        return f"axes: {ax.x} {ax.y} = stage X Y mm, {strokes}"
    return f"axes: {strokes}, no stage"


def emit_program(
    program: JointProgram,
    dialect: Dialect,
    *,
    header: tuple[tuple[str, str], ...] = (),
    stage: bool = True,
    line_numbers: bool | None = None,
    line_start: int | None = None,
    line_step: int | None = None,
) -> str:
    """The whole program as G-code text in ``dialect``.

    Parameters
    ----------
    program : JointProgram
        Rows in actuator space: ``stage`` (N, 2) mm, ``strokes`` (N, 3) mm, ``inverse_time`` (N,)
        1/min (> 0 on FEED rows), and the events between rows (``before == N``: after the last row).
    dialect : Dialect
        Letters, decimals, comments, numbering and the fixed blocks (see ``postproc/dialects``).
    header : tuple of (str, str)
        ``(key, value)`` pairs written as ``(key: value)`` comments at the top, in order (tool,
        machine, part, face, operation, parameters, units, ...). Long ones are split over lines.
    stage : bool
        The machine has an XY stage. False: X and Y words are never written, and a non-zero stage
        value is an error.
    line_numbers, line_start, line_step : bool, int, int, optional
        Override the dialect's block numbering (None: the dialect's value).

    Returns
    -------
    str
        The program, lines joined and terminated by ``dialect.line_ending``; every line is at most
        ``dialect.max_line_length`` characters (one less with CRLF).

    Raises
    ------
    LimitError
        Naming the row (``row 3 from hole 1 feed``) or event: a non-finite axis value, an
        inverse-time feed that is not > 0 once printed, a stage value on a machine without a
        stage, a bad spindle speed, dwell or tool number, or a block longer than the dialect allows.
    ValueError
        For arguments no caller should pass: a kind that is not a MoveKind, an event outside
        ``0 ..= N``, ``line_start`` outside ``0 ..= line_numbers.wrap_after``, ``line_step < 1``
        (the CLI bounds its options so that these never come from a user).

    Notes
    -----
    An axis word is left out when its formatted text equals the last one written for that axis. The
    first motion line, and the first one after a tool change or a program stop (the operator or
    the tool-change macro may have moved the axes), carry every axis word. With
    ``words.modal_motion`` G0/G1 is also written only when it changes (and always on those lines,
    and on a line that would otherwise carry no axis word).
    """
    n = len(program)
    numbering = dialect.line_numbers
    start = numbering.start if line_start is None else line_start
    step = numbering.step if line_step is None else line_step
    if not 0 <= start <= numbering.wrap_after:
        raise ValueError(f"line_start must be 0..{numbering.wrap_after}, got {start}")
    if step < 1:
        raise ValueError(f"line_step must be ≥ 1, got {step}")
    unknown = np.flatnonzero(~np.isin(program.kind, [MoveKind.RAPID, MoveKind.FEED]))
    if unknown.size:
        raise ValueError(f"row {int(unknown[0])}: kind {int(program.kind[unknown[0]])} is not a MoveKind")
    for event in program.events:
        if not 0 <= event.before <= n:
            raise ValueError(f"{event.kind.value} event: before = {event.before} is outside 0..{n}")

    out = _Lines(dialect, numbering.enabled if line_numbers is None else line_numbers, start, step)
    ax, dec = dialect.axes, dialect.decimals

    # ---- columns, formatted once; errors name the first bad row
    axes: list[tuple[str, np.ndarray, str]] = [
        (ax.t1, program.strokes[:, 0], "actuator stroke T1"),
        (ax.t2, program.strokes[:, 1], "actuator stroke T2"),
        (ax.t3, program.strokes[:, 2], "actuator stroke T3"),
    ]
    stage_axes = [(ax.x, program.stage[:, 0], "stage X"), (ax.y, program.stage[:, 1], "stage Y")]
    if stage:
        axes = stage_axes + axes
    else:
        zero = format_word("", 0.0, dec.length)
        for letter, values, name in stage_axes:
            text = _column(program, values, letter, dec.length, name)
            moved = [row for row, word in enumerate(text) if word[1:] != zero]
            if moved:
                raise LimitError(
                    f"{_row(program, moved[0])}: {name} is {text[moved[0]][1:]} mm on a machine without a stage"
                )
    columns = [_column(program, values, letter, dec.length, name) for letter, values, name in axes]
    feeds = _feed_words(program, dec.inverse_time)
    events_before: dict[int, list[Event]] = {}
    for event in program.events:
        events_before.setdefault(event.before, []).append(event)

    # ---- program start and header
    if dialect.percent:
        out.raw("%")
    if dialect.program_number:
        o_line = f"O{dialect.program_number}"
        if dialect.program_name:
            style = dialect.comments
            o_line += f" {style.open}{sanitize_comment(dialect.program_name, style)}{style.close}"
        out.raw(o_line)
    for key, value in header:
        out.comment(f"{key}: {value}")
    out.comment(_axis_line(dialect, stage))
    out.comment("motion: joint space, G1 feed in G93 inverse time, F = 1 / move time in min")
    for line in dialect.safe_start:
        out.block(line, "blocks.safe_start")
    for line in dialect.preamble:
        out.block(line, "blocks.preamble")

    # ---- motion
    last_words: list[str | None] = [None] * len(columns)
    last_kind: int | None = None
    inverse_time = False

    def emit_events(events: Iterable[Event]) -> None:
        nonlocal last_kind
        for event in events:
            if event.kind is EventKind.COMMENT:
                out.comment(event.text)
                continue
            comment, block = _event_blocks(program, event, dialect)
            if comment is not None:
                out.comment(comment)
            out.block(block, _event_where(program, event))
            if event.kind in (EventKind.TOOL_CHANGE, EventKind.STOP):
                # The tool-change macro or the operator may move the axes: state everything again.
                last_words[:] = [None] * len(columns)
                last_kind = None

    kinds = program.kind.tolist()
    for row in range(n):
        emit_events(events_before.get(row, ()))
        kind = kinds[row]
        if kind == MoveKind.FEED and not inverse_time:
            out.block("G93", _row(program, row))
            inverse_time = True
        words = []
        for j, column in enumerate(columns):
            if column[row] != last_words[j]:
                words.append(column[row])
                last_words[j] = column[row]
        parts = []
        if not dialect.modal_motion or kind != last_kind or not words:
            parts.append("G1" if kind == MoveKind.FEED else "G0")
        parts.extend(words)
        if kind == MoveKind.FEED:
            parts.append(feeds[row])
        last_kind = kind
        out.block(" ".join(parts), _row(program, row))
    emit_events(events_before.get(n, ()))

    # ---- program end
    if inverse_time:
        out.block("G94", "the end of inverse time")
    for line in dialect.postamble:
        out.block(line, "blocks.postamble")
    out.block(dialect.end_code, "program.end_code")
    if dialect.percent:
        out.raw("%")
    return out.text()
