"""`verify --cross-check`: a program read a second time by pygcode, a G-code library we did not write,
and compared with our reading word by word and move by move.

    PROGRAM ──► our lexer (each line's words) ─────┐
            ──► our program reader (the moves) ────┼──► disagreements: file:line, what, both readings
            ──► pygcode: Block + Machine ──────────┘

What is compared
----------------
- Every line's words, letter and value (``prog.ngc:57: U: ours 36.2244, pygcode 36.224``); a line
  pygcode refuses names its words as we read them and pygcode's reason; a line our reader refuses
  names the reason and stops the move comparison (the reader reads no further either).
- Every move: pygcode's modal machine (its ``Machine``, with the dialect's axis letters) must move on
  exactly the lines where our reader makes a move (``move: ours G1, pygcode no move``), in the same
  motion mode (G0 / G1), to the same position on every axis (the modal values carried from earlier
  lines), and a G1 in the same feed mode (G93) with the same F.
  Values are compared exactly: both readers convert the same decimal text with ``float`` (correctly
  rounded), so a difference is never rounding.

pygcode is handed each line through its comment splitter and its ``Block`` (not its ``Line``, whose
``%...%`` "macro" takes a ``%`` anywhere, even inside a comment such as a header's ``skipped % 2``;
LinuxCNC, like our reader, reads ``%`` only as a line of its own). A ``%`` line is a program delimiter
for both and is not handed to pygcode. pygcode's documented departures from LinuxCNC (see
tests/core/test_lexer.py) are not hidden: a program that uses them is reported, which is the point.

pygcode is imported here, inside :func:`cross_check`: `verify` without ``--cross-check`` never loads it.
It reads about 7,000 lines per CPU second (140 CPU s for a million-line program; the command's help says so).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from prs3_post.core.errors import InputError, LexError
from prs3_post.core.input_files import iter_pieces
from prs3_post.core.lexer import lex_words, split_comments
from prs3_post.core.toolpath import MoveKind
from prs3_post.kinematics.protocol import Kinematics, joint_letters
from prs3_post.machine.loading import Dialect
from prs3_post.readers.program import ProgramStream

#: Bytes of the file read at a time.
_PIECE_BYTES = 1 << 20
#: Disagreements kept (and listed) of a program; the count covers them all.
SHOWN = 20


@dataclass(frozen=True, slots=True)
class Disagreement:
    """One word or move read differently.

    Attributes
    ----------
    line : int — 1-based line of the program
    what : str — the word's letter (``U``), ``line`` (refused by one reader), ``move``, ``feed mode``
    ours, pygcode : str — each reading, as text (``36.2244``, ``G1``, ``no move``, ``refused (...)``)
    """

    line: int
    what: str
    ours: str
    pygcode: str

    def message(self, path: str) -> str:
        """``prog.ngc:57: U: ours 36.2244, pygcode 36.224``."""
        return f"{path}:{self.line}: {self.what}: ours {self.ours}, pygcode {self.pygcode}"


@dataclass(frozen=True, slots=True)
class CrossCheck:
    """What the cross-check found.

    Attributes
    ----------
    path : str
    lines : int — lines handed to pygcode (every line but ``%`` lines)
    moves : int — our reader's moves compared with pygcode's
    count : int — disagreements found
    shown : tuple of Disagreement — the first :data:`SHOWN` of them, in line order
    """

    path: str
    lines: int
    moves: int
    count: int
    shown: tuple[Disagreement, ...]

    @property
    def ok(self) -> bool:
        return self.count == 0

    def text(self) -> str:
        """``cross-check: 85 lines read by pygcode, 0 disagreements`` and a line per disagreement shown."""
        plural = "" if self.count == 1 else "s"
        out = [f"cross-check: {self.lines} lines read by pygcode, {self.count} disagreement{plural}"]
        out += [f"  {d.message(self.path)}" for d in self.shown]
        if self.count > len(self.shown):
            out.append(f"  ... and {self.count - len(self.shown)} more")
        return "\n".join(out) + "\n"

    def record(self) -> dict[str, Any]:
        """JSON-ready: the counts and the disagreements shown."""
        return {"reader": "pygcode", "lines": self.lines, "moves": self.moves, "disagreements": self.count,
                "shown": [{"line": d.line, "what": d.what, "ours": d.ours, "pygcode": d.pygcode} for d in self.shown]}


def _number(value: float) -> str:
    """The shortest text that reads back as ``value`` (``36.2244``, ``1``, ``-0.5``)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _pygcode_value(value: object) -> str:
    """A pygcode word's value as text: a number as :func:`_number` writes it, else quoted (an O word's
    string: pygcode takes the rest of the line)."""
    try:
        return _number(float(value))  # type: ignore[arg-type]  # str, int or float: whatever its word class is
    except ValueError:
        return repr(value)


def _words_text(words: list[tuple[str, str]]) -> str:
    return " ".join(f"{letter}{value}" for letter, value in words) or "(no words)"


def _word_disagreements(number: int, ours: list[tuple[str, str]], theirs: list[tuple[str, str]]) -> list[Disagreement]:
    """The letters whose values (in line order) differ, one disagreement per letter."""
    if ours == theirs:
        return []
    found = []
    for letter in dict.fromkeys([w[0] for w in ours] + [w[0] for w in theirs]):
        a = [v for k, v in ours if k == letter]
        b = [v for k, v in theirs if k == letter]
        if a != b:
            found.append(Disagreement(number, letter, " ".join(a) or "(none)", " ".join(b) or "(none)"))
    return found or [Disagreement(number, "word order", _words_text(ours), _words_text(theirs))]


def _our_moves(stream: ProgramStream) -> Iterator[tuple[int, int, list[float], float] | InputError]:
    """Our reader's moves: (line, kind, position of every axis, F), then the reader's error if it refuses
    a line (and nothing after it)."""
    try:
        for chunk in stream:
            joints = chunk.stage.tolist() if chunk.strokes.shape[1] == 0 else [
                s + t for s, t in zip(chunk.stage.tolist(), chunk.strokes.tolist(), strict=True)]
            yield from zip(chunk.source.tolist(), chunk.kind.tolist(), joints, chunk.inverse_time.tolist(),
                           strict=True)
    except InputError as error:
        yield error


def _lines(path: str) -> Iterator[str]:
    """The file's lines (a CR before the LF kept), a piece of the file at a time: memory stays flat."""
    for _, piece in iter_pieces(path, "a G-code program", _PIECE_BYTES):
        yield from piece.decode("utf-8").removesuffix("\n").split("\n")


def cross_check(path: str, dialect: Dialect, *, stage: bool, kinematics: Kinematics,
                shown: int = SHOWN) -> CrossCheck:
    """Read the program at ``path`` with pygcode and with our reader, and list where they disagree.

    Parameters
    ----------
    path : str — the program
    dialect : Dialect — its letters and comment delimiters (as `verify` reads it)
    stage : bool — the machine has an XY stage
    kinematics : Kinematics — whose joints the program moves
    shown : int — disagreements kept (all are counted)

    Raises
    ------
    InputError
        A file that cannot be read, or that is not text (as our reader says it; pygcode is not asked).
    """
    from pygcode.block import Block
    from pygcode.comment import split_line
    from pygcode.gcodes import GCodeInverseTimeMode, GCodeLinearMove, GCodeMotion, GCodeRapidMove
    from pygcode.machine import Machine

    letters = (dialect.axes.x, dialect.axes.y,
               *joint_letters(kinematics.joint_names, kinematics.default_letters, dialect.axes))
    stream = ProgramStream(path, dialect, stage=stage, kinematics=kinematics)
    stream.check()                                   # not text: our reader's message, before pygcode reads a line
    delimiters = ((dialect.comments.open, dialect.comments.close),)

    machine = type("AxesMachine", (Machine,), {"axes": set(letters)})()   # pygcode's, with the program's axes
    moves = _our_moves(stream)
    pending = next(moves, None)
    found: list[Disagreement] = []
    count = read = compared = 0

    told: set[str] = set()                           # what was told of the line being read

    def add(items: list[Disagreement]) -> None:
        nonlocal count
        count += len(items)
        told.update(d.what for d in items)
        found.extend(items[:max(0, shown - len(found))])

    for number, raw in enumerate(_lines(path), start=1):
        line = raw[:-1] if raw.endswith("\r") else raw
        told.clear()
        code, ours, refusal = "", None, ""
        try:
            code, _ = split_comments(line, delimiters)
            if code.strip() == "%":
                continue                             # a program delimiter, for LinuxCNC and our reader
            ours = [(k, _number(v)) for k, v, _ in lex_words(code.strip())]
        except LexError as error:
            refusal = str(error)
        read += 1
        theirs: list[tuple[str, str]] | None = None
        gcodes: list[Any] = []
        try:
            block_text, _ = split_line(line)
            block = Block(block_text)
            theirs = [(w.letter, _pygcode_value(w.value)) for w in block.words]
            gcodes = machine.block_modal_gcodes(block)
            for gcode in gcodes:                     # sorted in pygcode's execution order
                gcode.process(machine)
        except Exception as error:                   # whatever pygcode raises is its refusal of the line
            theirs_refusal = f"refused ({type(error).__name__}: {error})"
            theirs, gcodes = None, []
        line_told = ours is None or theirs is None
        if ours is not None and theirs is None:
            add([Disagreement(number, "line", _words_text(ours), theirs_refusal)])
        elif ours is None and theirs is not None:
            add([Disagreement(number, "line", f"refused ({refusal})", _words_text(theirs))])
        elif ours is not None and theirs is not None:
            add(_word_disagreements(number, ours, theirs))
        # the moves: pygcode's motion on this line against our reader's move (while it reads)
        if isinstance(pending, InputError):
            if pending.line == number:
                if not line_told:
                    add([Disagreement(number, "line", f"refused ({pending.args[0]})",
                                      _words_text(theirs or []))])
                pending = None                       # our reader reads no further: no more moves to compare
            continue                                 # (the moves of the refused line's chunk are not compared)
        if pending is None:
            continue
        motion = [g for g in gcodes if isinstance(g, GCodeMotion) and g.modal_group == GCodeMotion.modal_group
                  and set(g.params) & set(letters)]
        theirs_move = "no move"
        if motion:
            theirs_move = ("G0" if isinstance(motion[0], GCodeRapidMove) else
                           "G1" if isinstance(motion[0], GCodeLinearMove) else str(motion[0].word))
        ours_move = "no move"
        if pending[0] == number:
            _, kind, position, feed = pending
            ours_move = "G0" if kind == MoveKind.RAPID else "G1"
            pending = next(moves, None)
            compared += 1
        if ours_move != theirs_move:
            add([] if theirs is None else [Disagreement(number, "move", ours_move, theirs_move)])
            continue
        if ours_move == "no move":
            continue
        at = machine.pos.values
        add([Disagreement(number, f"{letter} (modal)", _number(mine), _number(at[letter]))
             for letter, mine in zip(letters, position, strict=True)
             if (stage or letter not in letters[:2]) and mine != at[letter] and letter not in told])
        if ours_move == "G1":
            mode = machine.mode.feed_rate_mode
            if not isinstance(mode, GCodeInverseTimeMode):
                add([Disagreement(number, "feed mode", "G93", "none" if mode is None else str(mode.word))])
            rate = machine.mode.feed_rate
            theirs_feed = float(rate.word.value) if rate is not None else 0.0
            if theirs_feed != feed:
                add([Disagreement(number, "F (modal)", _number(feed), _number(theirs_feed))])
    if isinstance(pending, InputError) and pending.line is None:
        add([Disagreement(0, "program", f"refused ({pending.args[0]})", "read")])
    return CrossCheck(path=path, lines=read, moves=compared, count=count, shown=tuple(found))
