"""Read simultaneous 5-axis G-code written for another machine (rotary words or tool vectors under TCP).

The result is what :mod:`prs3_post.readers.gcode.reader` gives for a 3+2 program — a part-frame
:class:`~prs3_post.core.toolpath.Toolpath` in mm, streamed in chunks, with an accounting of every line —
but the tool axis of each row comes from the program: from its rotary words through the source
machine's chain, or from its tool vectors, as a :class:`~prs3_post.machine.cam_conventions.SourceConvention`
(``postproc/sources/*.toml``) says. The interpreter is the 3+2 reader's (a subclass: the same words,
modal state, feeds, arcs, comments and messages), with the 5-axis parts added here.

What a block means
------------------
- **TCP** (tool-centre-point control) is switched on and off by the source's codes (``G234``/``G49``,
  ``M428``/``M429``, ``G43.4``/``G49``; the caller may name others). Under TCP, X Y Z are the tool
  tip in the part frame (the program's work offset) and the rotary words (or the vector) only give
  the tool's orientation: the row's axis is :meth:`~prs3_post.machine.cam_conventions.SourceConvention.axes_from_rotary`
  of the rotary values after the block (modal: a word stays until the next one; under G91 rotary
  words are increments too). Between two rows the intended path is the straight tip line with the
  axis on the great circle between the two orientations (the pipeline's linearization): the source
  machine's own rotary interpolation (its joints turning linearly, C the long way from 359° to 1°)
  is not reproduced, only its end points.
- **Outside TCP** X Y Z are the source machine's coordinates; they are the tip in the part frame
  only while every rotary is at its zero (and the tool is vertical), so linear moves are read then
  and refused otherwise. A rotary move outside TCP is refused naming the line — where it would take
  the tip depends on the source machine's pivot geometry, which the source file does not give —
  except a rotary-only move while the tip's position is unknown (at the start, or after a
  machine-coordinate block): that only sets the orientation of the next move (the Haas post's
  ``G0 B.. C..`` before ``G234``), counted in :attr:`FivexCounts.prepositions`.
- **Machine-coordinate blocks** (``G28`` homing, ``G91 G28 B0 C0``, ``G53 G0 Z0``) become nothing
  on this machine, with a COMMENT event and a count (:attr:`FivexCounts.machine_blocks`): they move
  the source machine in its own coordinates. After one, the positions they moved are unknown: the
  next move must be a rapid that gives them all (like the program's first move), and rotary words
  must come again before the next TCP move. The safe path between the last point and that rapid
  is the emitter's joint-space rapid, as between any two rapids.
- **Axis clamps** (``M10``-``M13`` on a Haas) and the source's other inert codes (``G255``) do
  nothing here either: a COMMENT event and a count each.
- **Feeds**: under G94, F is the tip feed (units/min); under G93 (inverse time) a move takes 1/F
  minutes, and its row's tip feed is F × its tip length, so that the program written for this
  machine (G93 again, from tip lengths) gives every input move the same time. A feed move whose tip
  does not move but whose orientation does (a reorientation in place) has no tip feed and no tip
  path to time: refused.
- ``O`` with a program name (``Omnf01_vx_0``, as NX writes it) alone on its line: counted as an O line.
- **Text after the closing** ``%`` (NX's ``Tool Path Listing has 390 lines.``) is reported
  (:attr:`FivexCounts.trailing_lines`, first line) and not read.
- **LinuxCNC expressions and parameters** (``[...]``, ``#<_hal[...]>``, ``#1``) anywhere in the file
  are refused before anything else, naming the first line: their values exist only in LinuxCNC's
  interpreter at run time.

Also refused with the line: a rotary word the source does not have, a zero-length tool vector, a
change of G20/G21 after the first move (inconsistent units), arcs (G2/G3) that change the
orientation (and any arc in a vector source, where I J K are the vector), canned cycles, ``G68.2``.
"""

from __future__ import annotations

import math
import re
from array import array
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np

from prs3_post.core.errors import ConfigError, InputError, LexError
from prs3_post.core.lexer import Word, code_name, decode, quote, split_comments
from prs3_post.core.toolpath import EventKind, Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.machine.cam_conventions import Orientation, SourceConvention
from prs3_post.machine.loading import file_given
from prs3_post.part.workplane import WorkPlane
from prs3_post.readers.common import join_toolpaths
from prs3_post.readers.gcode.bulk import LineReader
from prs3_post.readers.gcode.reader import CHUNK_LINES, GcodeStream
from prs3_post.readers.gcode.summary import GcodeFile
from prs3_post.readers.gcode.words import CODES_READ, G_GROUPS, HINTS, M_GROUPS, VALUE_LETTERS, Block
from prs3_post.readers.protocol import SourceNotes

__all__ = ["FivexCounts", "FivexFile", "FivexStream", "check_quiet_codes", "check_tcp_codes", "parse_fivex",
           "read_fivex"]

_XYZ = "XYZ"
#: A LinuxCNC expression or parameter somewhere in a line (checked on the code without comments).
_EXPRESSION = re.compile(r"[\[\]#]")
#: Codes of the 3+2 reader the 5-axis reader does not take: tilted planes (the orientation comes
#: from the rotary words here) and canned cycles (they would drill along the program's Z, not along
#: the tool).
_NOT_READ = {68.2: "G68.2", 69: "G69", 53.1: "G53.1", 81: "G81", 82: "G82", 83: "G83", 73: "G73"}
#: An O word with a program name rather than a number, alone on its line (``Omnf01_vx_0``).
_PROGRAM_NAME = re.compile(r"[Oo][A-Za-z0-9_]*[A-Za-z_][A-Za-z0-9_]*")
_MACHINE_CODES = {28.0: "home (G28)", 53.0: "machine coordinates (G53)"}


@dataclass(frozen=True, slots=True)
class FivexCounts:
    """What the 5-axis parts of a program held (the rest is in :class:`~prs3_post.readers.gcode.reader.GcodeCounts`).

    Attributes
    ----------
    tcp_on, tcp_off : int — blocks that switched TCP on, off
    tcp_moves : int — moves read under TCP
    orientation_changes : int — rows whose tool axis differs from the row before
    prepositions : int — rotary-only moves outside TCP while the tip's position was unknown (no row)
    machine_blocks : tuple of (str, int) — machine-coordinate blocks by kind (``G28``, ``G53``): no row
    clamps : tuple of (str, int) — clamp codes by code: no row
    inert : tuple of (str, int) — the source's inert codes by code: no row
    trailing_lines : int — non-blank lines after the closing ``%`` (not read)
    trailing_first : int — the first of them (0: none)
    """

    tcp_on: int
    tcp_off: int
    tcp_moves: int
    orientation_changes: int
    prepositions: int
    machine_blocks: tuple[tuple[str, int], ...]
    clamps: tuple[tuple[str, int], ...]
    inert: tuple[tuple[str, int], ...]
    trailing_lines: int
    trailing_first: int


@dataclass(frozen=True, slots=True)
class FivexFile:
    """A 5-axis program read into a part-frame toolpath.

    Attributes
    ----------
    gcode : GcodeFile — path, units, toolpath (PART frame, mm, the program's axes), the 3+2 counts
    source : SourceConvention — the convention it was read with
    tcp_on, tcp_off : tuple of str — the TCP codes used (the source's, or the caller's)
    counts : FivexCounts
    """

    gcode: GcodeFile
    source: SourceConvention
    tcp_on: tuple[str, ...]
    tcp_off: tuple[str, ...]
    counts: FivexCounts

    @property
    def toolpath(self) -> Toolpath:
        return self.gcode.toolpath


def read_fivex(path: str, source: SourceConvention, *, tolerance: float, tcp_on: tuple[str, ...] | None = None,
               tcp_off: tuple[str, ...] | None = None, circle_tolerance: float) -> FivexFile:
    """Read a whole 5-axis G-code file (see the module docstring).

    Parameters
    ----------
    path : str — shown unchanged in messages
    source : SourceConvention — how the program gives its orientation (:func:`prs3_post.machine.loading.load_source`)
    tolerance : float — mm, > 0, chordal tolerance of arcs (constant orientation only)
    tcp_on, tcp_off : tuple of str, optional — the codes that switch TCP on and off (None: the source's)
    circle_tolerance : float — mm, how far an arc's end may be from its circle

    Raises
    ------
    InputError
        ``path:line: message``; ConfigError for TCP codes that the reader reads as something else.
    """
    return FivexStream(path, source, tolerance=tolerance, tcp_on=tcp_on, tcp_off=tcp_off,
                       circle_tolerance=circle_tolerance).whole_fivex()


def parse_fivex(text: str, source: SourceConvention, *, path: str, tolerance: float,
                tcp_on: tuple[str, ...] | None = None, tcp_off: tuple[str, ...] | None = None,
                circle_tolerance: float, chunk_lines: int = CHUNK_LINES) -> FivexFile:
    """Read 5-axis G-code text; ``path`` only names it. Parameters as :func:`read_fivex`."""
    return FivexStream(path, source, tolerance=tolerance, tcp_on=tcp_on, tcp_off=tcp_off,
                       circle_tolerance=circle_tolerance, chunk_lines=chunk_lines, text=text).whole_fivex()


class FivexStream(GcodeStream):
    """A 5-axis G-code file read in chunks of lines (as :class:`~prs3_post.readers.gcode.reader.GcodeStream`).

    Iterate it for part-frame toolpath chunks; afterwards :attr:`summary` is the
    :class:`~prs3_post.readers.gcode.reader.GcodeFile` (empty toolpath) and :attr:`fivex` the
    :class:`FivexFile` (empty toolpath).
    """

    def __init__(self, path: str, source: SourceConvention, *, tolerance: float,
                 tcp_on: tuple[str, ...] | None = None, tcp_off: tuple[str, ...] | None = None,
                 circle_tolerance: float, chunk_lines: int = CHUNK_LINES,
                 text: str | None = None):
        super().__init__(path, tolerance=tolerance, circle_tolerance=circle_tolerance, chunk_lines=chunk_lines,
                         text=text)
        self.source = source
        self.tcp_on = source.tcp_on if tcp_on is None else tuple(tcp_on)
        self.tcp_off = source.tcp_off if tcp_off is None else tuple(tcp_off)
        check_tcp_codes(source, self.tcp_on, self.tcp_off)
        check_quiet_codes(source)
        self.fivex: FivexFile | None = None
        self._percents = 0                             # '%' lines seen by _scan (the second closes the program)
        self._five: _FivexReader | None = None

    def _check_piece(self, piece: bytes, offset: int, first: int) -> int:
        """Every piece decoded and scanned (the 3+2 reader's shortcut looks for rotary words only)."""
        self._scan(decode(piece, offset=offset), first)
        return piece.count(b"\n")

    def _scan(self, text: str, first: int) -> None:
        """Refuse LinuxCNC expressions and parameters, naming the first line that has one (up to the
        closing ``%``: what follows it is not read)."""
        if self._percents >= 2 or not (_EXPRESSION.search(text) or "%" in text):
            return
        for number, line in enumerate(text.split("\n"), start=first):
            if line.strip() == "%":
                self._percents += 1
                if self._percents >= 2:
                    return
            if not _EXPRESSION.search(line):
                continue
            try:
                code, _ = split_comments(line)
            except LexError:
                return                                   # the careful reader names what is wrong there
            if _EXPRESSION.search(code):
                raise InputError(f"LinuxCNC expression or parameter in {quote(code)}: its values exist only in "
                                 "LinuxCNC's interpreter at run time (HAL pins, parameters), so the program "
                                 "cannot be converted; write it in plain numbers", path=self.path, line=number)

    def _reader(self) -> _FivexReader:
        self._five = _FivexReader(self.path, self.tolerance, self.circle_tolerance, self.source, self.tcp_on,
                                  self.tcp_off)
        return self._five

    def __iter__(self) -> Iterator[Toolpath]:
        yield from super().__iter__()
        assert self._five is not None and self.summary is not None  # set by the iteration
        self.fivex = FivexFile(gcode=self.summary, source=self.source, tcp_on=self.tcp_on, tcp_off=self.tcp_off,
                               counts=self._five.fivex_counts())

    #: Not read ahead by a thread: the 5-axis state is read between chunks (the program's first comment).
    reads_ahead = False
    #: The tool axes are the program's own orientations (no setup, which turns the part about z, changes them).
    refuses_tilt = True

    @property
    def read_as(self) -> str:
        """What the program is read as (the report and the program's first comment say it)."""
        return (f"5-axis source {self.source.name}, TCP {'/'.join(self.tcp_on)} on, {'/'.join(self.tcp_off)} "
                "off; between two input points the intended path is the straight tip line with the tool axis on "
                "the great circle (the source machine's rotary interpolation is not reproduced)")

    def skipped(self) -> tuple[tuple[str, int], ...]:
        """The 3+2 reader's skipped records, then the 5-axis blocks that became no row."""
        assert self.fivex is not None and self.summary is not None  # set when the iteration ends
        c = self.fivex.counts
        out = [(f"{code} (machine coordinates, not converted)", n) for code, n in c.machine_blocks]
        out += [(f"{code} (axis clamp)", n) for code, n in c.clamps]
        out += [(f"{code} (no effect here)", n) for code, n in c.inert]
        if c.prepositions:
            out.append(("rotary positioning outside TCP (sets the next orientation)", c.prepositions))
        if c.trailing_lines:
            out.append((f"text after the closing % (from line {c.trailing_first})", c.trailing_lines))
        return self.summary.counts.skipped + tuple(out)

    def notes(self) -> SourceNotes:
        """The source convention (its shipped name or file) and the TCP codes, for the program's header."""
        source = self.source
        return SourceNotes(five_axis=file_given(source.source, "sources", source.name) or source.name,
                           tcp_on=self.tcp_on, tcp_off=self.tcp_off)

    def whole_fivex(self) -> FivexFile:
        """All chunks joined: the whole file's :class:`FivexFile`."""
        chunks = list(self)
        assert self.fivex is not None  # set by the iteration
        return replace(self.fivex, gcode=replace(self.fivex.gcode, toolpath=join_toolpaths(chunks)))


def check_tcp_codes(source: SourceConvention, tcp_on: tuple[str, ...], tcp_off: tuple[str, ...]) -> None:
    """TCP codes must be G/M codes the reader does not read as something else (G49 may switch TCP off),
    and no code may switch TCP both on and off.

    Raises
    ------
    ConfigError
        ``tcp.on: G1 is read as itself (motion group), it cannot switch TCP``, ``tcp: G43.4 both switches ...``.
    """
    for name, codes in (("tcp.on", tcp_on), ("tcp.off", tcp_off)):
        if not codes:
            raise ConfigError(f"{name}: give at least one code", path=source.source)
        for code in codes:
            match = re.fullmatch(r"([GM])([0-9]+(?:\.[0-9]+)?)", code)
            if match is None:
                raise ConfigError(f"{name}: {code!r} is not a G or M code (e.g. G43.4, M428)", path=source.source)
            value = float(match[2])
            groups = G_GROUPS if match[1] == "G" else M_GROUPS
            if value in groups and not (code == "G49" and name == "tcp.off"):
                raise ConfigError(f"{name}: {code} is read as itself ({groups[value]} group), it cannot switch TCP",
                                  path=source.source)
    both = sorted(set(tcp_on) & set(tcp_off))
    if both:
        raise ConfigError(f"tcp: {both[0]} both switches TCP on and off", path=source.source)


def check_quiet_codes(source: SourceConvention) -> None:
    """Clamp and inert codes must be codes the reader does not read as something else (it drops them
    from their blocks; the source loader has refused motion, feed-mode and program-end codes).

    Raises
    ------
    ConfigError
        ``codes.inert: G90 is read as itself (distance group), it cannot be inert``.
    """
    for name, codes, role in (("codes.clamps", source.clamps, "a clamp"), ("codes.inert", source.inert, "inert")):
        for code in codes:
            groups = G_GROUPS if code[0] == "G" else M_GROUPS
            value = float(code[1:])
            if value in groups:
                raise ConfigError(f"{name}: {code} is read as itself ({groups[value]} group), it cannot be {role}",
                                  path=source.source)


class _FivexReader(LineReader):
    """The 3+2 interpreter plus TCP, rotary words or tool vectors, machine-coordinate blocks and clamps."""

    def __init__(self, path: str, tolerance: float, circle_tolerance: float, source: SourceConvention,
                 tcp_on: tuple[str, ...], tcp_off: tuple[str, ...]):
        super().__init__(path, WorkPlane.identity(), tolerance, circle_tolerance)
        self.convention = source
        self.vector = source.orientation is Orientation.VECTOR
        self.letters = "".join(source.vector_words) if self.vector else source.words
        self.tcp_codes = {code: True for code in tcp_on} | {code: False for code in tcp_off}
        self.quiet_codes = {code: "clamp" for code in source.clamps} | {code: "inert" for code in source.inert}
        g_groups = {v: g for v, g in G_GROUPS.items() if v not in _NOT_READ}
        m_groups = dict(M_GROUPS)
        g_groups.update({28.0: "non-modal", 53.0: "non-modal"})
        for codes, g_group, m_group in ((tcp_on + tcp_off, "length offset", "tcp"), (tuple(self.quiet_codes), "source",
                                                                                       "source")):
            for code in codes:
                if code[0] == "G":
                    g_groups.setdefault(float(code[1:]), g_group)
                else:
                    m_groups.setdefault(float(code[1:]), m_group)
        self.g_groups, self.m_groups = g_groups, m_groups
        self.value_letters = VALUE_LETTERS + "".join(c for c in self.letters if c not in VALUE_LETTERS)
        extra = " ".join(sorted({*self.tcp_codes, *self.quiet_codes, "G28", "G53"}))
        self.reader_name = f"the 5-axis G-code reader (source {source.name})"
        self.codes_read = (" ".join(c for c in CODES_READ.split() if c.rstrip(";") not in _NOT_READ.values())
                           + f"; {extra}")
        tcp_hint = f"a TCP code of another source machine (source {source.name} switches TCP with " + "/".join(
            (*tcp_on, *tcp_off)) + ")"
        self.hints = {code: tcp_hint if code in ("G43.4", "G43.5", "G234", "M428", "M429") else why
                      for code, why in HINTS.items() if code not in ("G28", "G53")}
        self.words_read = f"G M N X Y Z {' '.join(self.letters)} I J K R P F S T H; O alone on its line"
        # state
        self.tcp = False
        self.rotary = [math.nan] * len(self.letters)   # as written (deg) or the vector; NaN: unknown
        self.axis_now: FloatArray | None = None        # unit, part frame (None: unknown)
        self.axis_rows = array("d")
        self.last_axis: FloatArray | None = None
        self.pending: dict[str, float] = {}            # this block's rotary/vector words
        self.code_text = ""
        self.machine_line = 0                          # the last machine-coordinate block, until the next row
        # counts
        self.tcp_on_count = self.tcp_off_count = self.tcp_moves = self.changes = self.prepositions = 0
        self.machine: Counter[str] = Counter()
        self.quiet: Counter[str] = Counter()
        self.trailing_lines = self.trailing_first = 0

    # ---- lines
    def line(self, number: int, line: str) -> None:
        if self.percent >= 2:                          # after the closing %: reported, not read
            self.number = number
            if line.strip():
                self.trailing_lines += 1
                self.trailing_first = self.trailing_first or number
            else:
                self.blank_lines += 1
            return
        if _PROGRAM_NAME.fullmatch(line.strip()) and self.percent < 2 and self.end_line is None:
            self.number = number                       # O and a name (NX writes Omnf01_vx_0): the program name
            self.records += 1
            self.code_seen = True
            self.skipped["O"] += 1
            return
        super().line(number, line)

    def bulk(self, first: int, values: FloatArray, moves: np.ndarray, lines: Sequence[str]) -> bool:
        # runs of X Y Z moves keep the orientation: read in bulk where the state is plain
        if self.axis_now is None or self.machine_line or not (self.tcp or self.at_zero()):
            return False
        done = super().bulk(first, values, moves, lines)
        if done and self.tcp:
            self.tcp_moves += int(np.count_nonzero(moves))
        return done

    def fivex_counts(self) -> FivexCounts:
        clamps = self.convention.clamps
        return FivexCounts(tcp_on=self.tcp_on_count, tcp_off=self.tcp_off_count, tcp_moves=self.tcp_moves,
                           orientation_changes=self.changes, prepositions=self.prepositions,
                           machine_blocks=tuple(sorted(self.machine.items())),
                           clamps=tuple(sorted((c, n) for c, n in self.quiet.items() if c in clamps)),
                           inert=tuple(sorted((c, n) for c, n in self.quiet.items() if c not in clamps)),
                           trailing_lines=self.trailing_lines, trailing_first=self.trailing_first)

    # ---- rows
    def add_rows(self, tip: FloatArray, kind: int | np.ndarray, feed: float | np.ndarray,
                 source: int | np.ndarray) -> None:
        if self.axis_now is None:
            raise self.error(f"a move before the tool orientation is known: give {self.orientation_words()} on it "
                             "or before it")
        n = len(np.asarray(tip).reshape(-1, 3))
        if n and self.last_axis is not None and not np.array_equal(self.last_axis, self.axis_now):
            self.changes += 1
        self.axis_rows.frombytes(np.broadcast_to(self.axis_now, (n, 3)).tobytes())
        self.last_axis = self.axis_now
        self.machine_line = 0
        super().add_rows(tip, kind, feed, source)

    def take(self) -> Toolpath:
        chunk = super().take()
        axis = np.frombuffer(self.axis_rows, dtype=np.float64).reshape(-1, 3).copy()
        self.axis_rows = array("d")
        return replace(chunk, axis=axis)

    # ---- helpers
    def orientation_words(self) -> str:
        return " ".join(self.letters)

    def at_zero(self) -> bool:
        """Every rotary known and at its zero (vector source: no vector given, or the vertical one)."""
        if self.vector:
            v = self.rotary
            return all(math.isnan(x) for x in v) or (v[0] == 0.0 and v[1] == 0.0 and v[2] > 0.0)
        zeros = [r.zero_deg for r in (*self.convention.tables, *self.convention.heads)]
        return all(value == zero for value, zero in zip(self.rotary, zeros, strict=True))

    def shown_rotary(self) -> str:
        return " ".join(f"{letter}{'?' if math.isnan(v) else f'{v:g}'}" for letter, v in zip(self.letters, self.rotary,
                                                                                             strict=True))

    def orientation_of(self, values: list[float]) -> FloatArray | None:
        """The unit axis (part frame) for rotary values / a vector; None when any is unknown."""
        if any(math.isnan(v) for v in values):
            return None
        if self.vector:
            vector = np.array(values, dtype=np.float64)
            return vector / np.linalg.norm(vector)
        return self.convention.axes_from_rotary(np.array([values]))[0]

    # ---- one line
    def block(self, block: Block) -> None:
        self.code_text = " ".join(text for _, text in (*block.g.values(), *block.m.values(), *block.values.values()))
        named = {code_name(letter, value): (letter, group)
                 for letter, codes in (("G", block.g), ("M", block.m)) for group, (value, _) in codes.items()}
        if "units" in block.g and self.units_at_first_move is not None:
            units = "inch" if block.g["units"][0] == 20 else "mm"
            if units != self.units_at_first_move:
                raise self.error(f"inconsistent units: {block.g['units'][1]} ({units}) after moves in "
                                 f"{self.units_at_first_move}; a program's length unit must not change after its "
                                 "first move")
        if "non-modal" in block.g:
            self.machine_block(block, *block.g["non-modal"])
            return
        for code, (letter, group) in named.items():
            if code in self.quiet_codes:
                self.quiet[code] += 1
                what = "axis clamp" if self.quiet_codes[code] == "clamp" else "no effect on this machine"
                self.event(EventKind.COMMENT, text=f"{code}: {what}, not converted")
                del (block.g if letter == "G" else block.m)[group]
            elif code in self.tcp_codes:
                on = self.tcp_codes[code]
                if on and letter == "G":
                    block.take("H")
                self.tcp = on
                if on:
                    self.tcp_on_count += 1
                else:
                    self.tcp_off_count += 1
                if code != "G49":                       # G49 is the 3+2 reader's too (no length offset)
                    del (block.g if letter == "G" else block.m)[group]
        motion = block.g["motion"][0] if "motion" in block.g else self.motion
        self.pending = {}
        for letter in self.letters:
            value = block.take(letter)
            if value is not None:
                self.pending[letter] = value
        if self.vector and motion in (2.0, 3.0):
            raise self.error(f"{code_name('G', motion)} in a vector source: I J K are the tool vector here, not an "
                             "arc's centre (a vector program has no arcs)")
        has_xyz = any(a in block.values for a in _XYZ)
        if self.pending and motion in (2.0, 3.0) and has_xyz:
            raise self.error(f"{code_name('G', motion)} with {self.orientation_words()} words: an arc keeps the "
                             "tool orientation (give the new orientation on a G0/G1)")
        super().block(block)
        if self.pending and not has_xyz:
            self.turn_only(motion)

    def machine_block(self, block: Block, value: float, text: str) -> None:
        """``G28``/``G53``: the source machine moves in its own coordinates; nothing here (module docstring)."""
        others = [t for group, (_, t) in block.g.items() if group not in ("non-modal", "motion", "distance")]
        others += [t for _, t in block.m.values()]
        others += [t for letter, (_, t) in block.values.items() if letter not in _XYZ + self.letters]
        if others:
            raise self.error(f"{others[0]} on the {text} line: a machine-coordinate block is not converted, so it "
                             "may hold only G0/G1, G90/G91 and axis words (put the rest on its own line)")
        if "distance" in block.g:
            self.absolute = block.g["distance"][0] == 90
        if "motion" in block.g:
            self.motion = block.g["motion"][0]
        linear = [a for a in _XYZ if a in block.values] if value == 53.0 or block.values else list(_XYZ)
        rotary = [a for a in self.letters if a in block.values] if block.values else list(self.letters)
        if value == 53.0 and not block.values:
            raise self.error("G53 without axis words: G53 moves in machine coordinates and needs the axes it moves")
        for letter in linear:
            block.take(letter)
            self.position[_XYZ.index(letter)] = math.nan
        for letter in rotary:
            block.take(letter)
            self.rotary[self.letters.index(letter)] = math.nan
        if rotary:
            self.axis_now = self.orientation_of(self.rotary)
        self.machine_line = self.number
        kind = "G28" if value == 28.0 else "G53"
        self.machine[kind] += 1
        self.event(EventKind.COMMENT, text=f"{self.code_text}: {_MACHINE_CODES[value]} of the source machine, not "
                                           "converted")

    def rotary_target(self) -> list[float]:
        """The rotary values (or vector) after this block's words (G91: rotary words are increments)."""
        values = list(self.rotary)
        for letter, value in self.pending.items():
            index = self.letters.index(letter)
            if self.vector or self.absolute:
                values[index] = value
            elif math.isnan(values[index]):
                raise self.error(f"incremental {letter} (G91) while the {letter} position is not known yet: give it "
                                 "under G90 first")
            else:
                values[index] += value
        if self.vector and self.pending:
            if any(letter not in self.pending for letter in self.letters):
                raise self.error(f"a tool vector needs all of {self.orientation_words()} on its line")
            if not math.hypot(*values) > 0.0:
                shown = " ".join(f"{letter}{v:g}" for letter, v in zip(self.letters, values, strict=True))
                raise self.error(f"zero-length tool vector {shown}: the tool axis has no direction")
        return values

    def outside_tcp(self, what: str) -> InputError:
        return self.error(f"{what} outside TCP ({' / '.join(c for c, on in self.tcp_codes.items() if on)} not on): "
                          "without TCP the source machine's X Y Z are not the tool tip in the part frame, and where "
                          "a rotary move takes the tip depends on the source machine's pivot geometry, which the "
                          "source file does not give; it cannot be converted")

    def move(self, block: Block) -> None:
        if self.machine_line and self.motion != 0.0:
            raise self.error(f"{code_name('G', self.motion or 1.0)} after the machine-coordinate block of line "
                             f"{self.machine_line}: the source machine moved in its own coordinates, so the tool's "
                             "position is not known here; the next move must be a rapid (G0)")
        values = self.rotary_target()
        axis: FloatArray | None
        if not self.tcp:
            if self.pending:
                raise self.outside_tcp(f"rotary motion ({self.pending_text()})")
            if not self.at_zero():
                raise self.outside_tcp(f"a linear move with the rotaries at {self.shown_rotary()} (not at their zero)")
            axis = np.array([0.0, 0.0, 1.0])           # every rotary at its zero: the tool is vertical
        else:
            axis = self.orientation_of(values)         # None: unknown (add_rows refuses a row without one)
            if self.motion == 1.0 and self.turns(axis) and self.target(block) == self.position:
                raise self.in_place()
        self.rotary, self.axis_now = values, axis
        rows = self.rows
        super().move(block)
        if self.tcp and self.rows > rows:
            self.tcp_moves += 1

    def turns(self, axis: FloatArray | None) -> bool:
        """Whether ``axis`` is a known orientation other than the current one."""
        return axis is not None and self.axis_now is not None and not np.array_equal(axis, self.axis_now)

    def pending_text(self) -> str:
        return " ".join(f"{letter}{value:g}" for letter, value in self.pending.items())

    def in_place(self) -> InputError:
        return self.error("a feed move that turns the tool about a fixed tip (a reorientation in place): it has no "
                          "tip path, and this machine's program times every move by its tip path (G93), so its "
                          "time cannot be kept; give the tip a move, or turn at rapid (G0)")

    def turn_only(self, motion: float | None) -> None:
        """A block with rotary (or vector) words and no X Y Z: a rotary move at the current tip."""
        if motion not in (0.0, 1.0):
            raise self.error(f"{self.pending_text()} without a motion mode: give G0 or G1")
        values = self.rotary_target()
        known = all(math.isfinite(v) for v in self.position)
        if not self.tcp and known:
            raise self.outside_tcp(f"rotary motion ({self.pending_text()})")
        axis = self.orientation_of(values)
        if not known:                                  # the tip is wherever it is: this sets the next orientation
            self.rotary, self.axis_now = values, axis
            if not self.tcp:
                self.prepositions += 1
            return
        if not self.turns(axis):                       # the same orientation: a move that goes nowhere
            self.rotary = values
            return
        if motion == 1.0:
            raise self.in_place()
        self.rotary, self.axis_now = values, axis
        self.moves += 1
        self.tcp_moves += 1
        self.add_rows(np.array(self.position), 0, 0.0, self.number)

    def sort(self, words: tuple[Word, ...]) -> Block:
        for letter, _, text in words:
            if letter in "ABC" and letter not in self.letters:
                has = (f"its rotary words are {self.orientation_words()}" if not self.vector
                       else f"the orientation is the tool vector {self.orientation_words()}")
                raise self.error(f"rotary word {text!r}: source {self.convention.name} has no {letter} axis ({has})")
        return super().sort(words)
