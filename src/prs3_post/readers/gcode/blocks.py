"""What each G-code block does (:mod:`prs3_post.readers.gcode.reader` lists what is read): the modal state
as the lines go by, and the rows and events they make."""

from __future__ import annotations

import math
from array import array
from collections import Counter

import numpy as np

from prs3_post.core.defaults import MAX_SPINDLE_RPM, MIN_SPINDLE_RPM, MM_PER_INCH
from prs3_post.core.errors import InputError, LexError
from prs3_post.core.lexer import (
    Word,
    code_name,
    lex_words,
    quote,
    split_comments,
)
from prs3_post.core.toolpath import Coolant, Event, EventKind, Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.machine.dialect import TOOL_NUMBER_LIMIT
from prs3_post.part.workplane import WorkPlane, euler_zxz_deg
from prs3_post.readers.common import (
    DIALECT_TOOLS,
    MAX_FEED_MM_MIN,
    MAX_RECORD_CHARS,
    MIN_FEED_MM_MIN,
    join_toolpaths,
)
from prs3_post.readers.gcode.summary import GcodeCounts, GcodeCycle, GcodeFile, GcodePlane
from prs3_post.readers.gcode.words import (
    AXES,
    CODES_READ,
    CYCLES,
    FEED,
    G_GROUPS,
    HINTS,
    M_GROUPS,
    OFFSETS,
    P3_MAX_COSINE,
    PECK_GAP_MM,
    PLANES,
    RAPID,
    USES,
    VALUE_LETTERS,
    WORDS_READ,
    Block,
    Cycle,
    PendingP3,
)
from prs3_post.toolpaths.arcs import MAX_ARC_SEGMENTS, arc_points_3d, arc_segment_count, arc_sweep
from prs3_post.toolpaths.cycles import MAX_PECKS, DrillCycle, Pecking, drill_rows, peck_count


class Blocks:
    """The modal state of a program as the lines go by; rows in the coordinates of their plane (mm)."""

    #: The largest tool number a T word may have (the stream sets the output dialect's).
    tool_number_max = TOOL_NUMBER_LIMIT

    def __init__(self, path: str, work_plane: WorkPlane, tolerance: float, circle_tolerance: float):
        self.path, self.tolerance, self.circle_tolerance = path, tolerance, circle_tolerance
        # what :meth:`sort` accepts (the 5-axis reader, a subclass, adds its codes and rotary words)
        self.g_groups, self.m_groups, self.value_letters = G_GROUPS, M_GROUPS, VALUE_LETTERS
        self.reader_name, self.codes_read, self.words_read = "the 3+2 G-code reader", CODES_READ, WORDS_READ
        self.hints = HINTS
        self.number = 0
        # rows, flat (x, y, z per row), in the coordinates of plane ``plane_of`` (index into planes)
        self.tip, self.kind, self.feed = array("d"), array("q"), array("d")
        self.source, self.plane_of = array("q"), array("q")
        self.rows = 0
        self.chunk_start = 0
        self.block_lines: int | None = None            # lines of the last block read (read_block)
        self.events: list[Event] = []
        self.base = work_plane
        self.frames: list[WorkPlane] = [work_plane]     # index 0: the work plane; then one per G68.2
        self.frame = 0
        self.tilt: GcodePlane | None = None            # the active G68.2
        self.tilt_ready = True                         # False between G68.2 and G53.1
        self.pending_p3: PendingP3 | None = None
        self.planes: list[GcodePlane] = []
        self.position = [math.nan, math.nan, math.nan]  # mm, current plane; NaN: not known yet
        self.start_pending = False                     # a merged start rapid waits for the full position
        # modal state
        self.motion: float | None = None
        self.plane = 17
        self.scale = 1.0                               # mm per program unit
        self.units_at_first_move: str | None = None
        self.absolute = True
        self.inverse_time = False
        self.retract_to_r = False                      # G99 (else G98)
        self.feed_word: float | None = None            # F as written (program units per minute)
        self.spindle_rpm = 0.0
        self.spindle_on = False
        self.spindle_kind = EventKind.SPINDLE_ON       # the direction: SPINDLE_ON_CCW after M4
        self.tool: int | None = None
        self.cycle: Cycle | None = None
        self.cycles: list[GcodeCycle] = []
        self.percent = 0                               # % lines seen (1: opening, 2: closing)
        self.percent_opened = 0                        # the opening % line's number
        self.code_seen = False
        self.end_line: int | None = None
        # counts
        self.by_word: Counter[str] = Counter()
        self.skipped: Counter[str] = Counter()
        self.records = self.moves = self.start_rapids = self.arcs = self.arc_segments = 0
        self.cycle_holes = self.cycle_rows = self.comments = self.comment_lines = self.blank_lines = 0

    # ---- helpers
    def error(self, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.number)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        self.events.append(Event(before=self.rows - self.chunk_start, kind=kind, value=value, text=text))

    def add_rows(self, tip: FloatArray, kind: int | np.ndarray, feed: float | np.ndarray,
                 source: int | np.ndarray) -> None:
        """Rows (n, 3) mm in the current plane's coordinates."""
        tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
        n = len(tip)
        self.tip.frombytes(tip.tobytes())
        self.kind.frombytes(np.broadcast_to(np.asarray(kind, dtype=np.int64), (n,)).tobytes())
        self.feed.frombytes(np.broadcast_to(np.asarray(feed, dtype=np.float64), (n,)).tobytes())
        self.source.frombytes(np.broadcast_to(np.asarray(source, dtype=np.int64), (n,)).tobytes())
        self.plane_of.frombytes(np.full(n, self.frame, dtype=np.int64).tobytes())
        self.rows += n
        self.position = tip[-1].tolist()
        if self.units_at_first_move is None:
            self.units_at_first_move = "inch" if self.scale != 1.0 else "mm"

    def take(self) -> Toolpath:
        """The rows and events since the last take, in the PART frame (events count from the chunk's start)."""
        local = np.frombuffer(self.tip, dtype=np.float64).reshape(-1, 3)
        plane_of = np.frombuffer(self.plane_of, dtype=np.int64)
        if len(plane_of) and plane_of[0] == plane_of[-1] and (plane_of == plane_of[0]).all():   # one plane
            frame = self.frames[int(plane_of[0])]
            tip, axis = _to_part(frame, local), np.broadcast_to(frame.normal, local.shape)
        else:
            tip = np.zeros_like(local)
            axis = np.zeros_like(local)
            for index in np.unique(plane_of):          # one transform per plane, all its rows at once
                rows = plane_of == index
                tip[rows] = _to_part(self.frames[index], local[rows])
                axis[rows] = self.frames[index].normal
        events = tuple(self.events)                    # counted from the chunk's start already
        chunk = Toolpath(kind=np.frombuffer(self.kind, dtype=np.int64), tip=tip, axis=axis,
                         feed=np.frombuffer(self.feed, dtype=np.float64),
                         source=np.frombuffer(self.source, dtype=np.int64), events=events,
                         source_file=self.path)
        self.tip, self.kind, self.feed = array("d"), array("q"), array("d")
        self.source, self.plane_of = array("q"), array("q")
        self.events = []
        self.chunk_start = self.rows
        return chunk

    def close(self, line_count: int) -> None:
        """The end of the file: nothing may be left open."""
        self.number = line_count
        if self.pending_p3 is not None:
            self.number = self.pending_p3.line
            raise self.error("G68.2 P3 Q1 at the end of the file: its Q2 line (the normal, I J K) is missing")
        if self.start_pending:
            raise self.error("the program ends before its first rapid has all of X, Y and Z: the start position "
                             "of the moves is unknown")
        if not self.code_seen:
            raise InputError("not a G-code program: no code (only comments, blank lines or '%')", path=self.path)
        if self.percent == 1:                          # what LinuxCNC calls 'File ended with no percent sign'
            raise self.error(f"the program opens with '%' (line {self.percent_opened}) but the file ends without "
                             "its closing '%': a program cut short? (a program that opens with '%' ends with '%')")
        if self.cycle is not None:
            self.end_cycle()

    def summary(self) -> GcodeFile:
        counts = GcodeCounts(
            records=self.records, lines=self.number, moves=self.moves, start_rapids=self.start_rapids,
            arcs=self.arcs, arc_segments=self.arc_segments, cycles=len(self.cycles), cycle_holes=self.cycle_holes,
            cycle_rows=self.cycle_rows, planes=len(self.planes), comments=self.comments,
            comment_lines=self.comment_lines, blank_lines=self.blank_lines,
            skipped=tuple(sorted(self.skipped.items())), by_word=tuple(sorted(self.by_word.items())), rows=self.rows)
        return GcodeFile(path=self.path, units=self.units_at_first_move or "mm", toolpath=join_toolpaths([]),
                         counts=counts, work_plane=self.base, planes=tuple(self.planes), cycles=tuple(self.cycles),
                         end_lines=() if self.end_line is None else (self.end_line,))

    # ---- one line
    def line(self, number: int, line: str) -> None:
        self.number = number
        try:
            code, comments = split_comments(line)
        except LexError as exc:
            raise self.error(str(exc)) from exc
        for text in comments:
            self.comments += 1
            self.event(EventKind.COMMENT, text=text.strip())
        code = code.strip()
        if len(code) > MAX_RECORD_CHARS:                 # before its words are read (millions of them)
            raise self.error(f"a block of {len(code):,} characters besides its comments: longer than any G-code "
                             f"block may be ({MAX_RECORD_CHARS:,} at most)")
        if not code:
            if comments:
                self.comment_lines += 1
            else:
                self.blank_lines += 1
            return
        if self.percent >= 2:
            raise self.error(f"text after the closing '%': {quote(code)} (the program ends at the '%')")
        if code == "%":
            self.percent_line()
            return
        if self.end_line is not None:
            raise self.error(f"code after the program end (M2/M30 at line {self.end_line}): {quote(code)}")
        try:
            words = lex_words(code)
        except LexError as exc:
            raise self.error(str(exc)) from exc
        self.code_seen = True
        self.records += 1
        if words[0][0] == "O":
            if len(words) > 1:
                raise self.error(f"an O word (program number) must be alone on its line, found {quote(code)}")
            self.skipped["O"] += 1
            return
        self.block(self.sort(words))

    def percent_line(self) -> None:
        self.skipped["%"] += 1
        if self.percent == 0 and not self.code_seen:
            self.percent, self.percent_opened = 1, self.number   # the opening %
        elif self.percent == 1 or self.end_line is not None:
            self.percent = 2                           # the closing %: nothing but blank lines after it
        else:
            raise self.error("'%' in the middle of the program: '%' opens the program (first line) and closes it")

    def sort(self, words: tuple[Word, ...]) -> Block:
        """The words of one line by kind, checked: known letters and codes, one code per group, each
        letter once, N first."""
        block = Block()
        for position, (letter, value, text) in enumerate(words):
            if not math.isfinite(value):
                raise self.error(f"word {text[:24]!r}: the number is too large")
            if letter == "G" or letter == "M":
                groups = self.g_groups if letter == "G" else self.m_groups
                group = groups.get(value)
                if group is None:
                    name = code_name(letter, value)
                    hint = f": {self.hints[name]}" if name in self.hints else ""
                    raise self.error(f"code {name} is not read by {self.reader_name}{hint} (codes read: "
                                     f"{self.codes_read})")
                codes = block.g if letter == "G" else block.m
                if group in codes:
                    raise self.error(f"{codes[group][1]} and {text} on one line: both are {letter} codes of the "
                                     f"{group} group (one per line)")
                codes[group] = (value, text)
                self.by_word[code_name(letter, value)] += 1
            elif letter == "N":
                if position:
                    raise self.error(f"the line number {text} must be the first word of the line")
            elif letter in self.value_letters:
                if letter in block.values:
                    raise self.error(f"{block.values[letter][1]} and {text} on one line: a word may appear once")
                block.values[letter] = (value, text)
            elif letter == "E":
                raise self.error(f"word {text!r} is not G-code: E is not read here, and a number with an exponent "
                                 "(1e-05) must be written as a plain decimal (0.00001)")
            elif letter == "O":
                raise self.error(f"an O word (program number) must be alone on its line, found {text!r}")
            else:
                raise self.error(f"word {text!r} is not read by {self.reader_name} (words read: {self.words_read})")
        return block

    # ---- one line's words, in LinuxCNC's order of execution
    def block(self, block: Block) -> None:
        g = {group: value for group, (value, _) in block.g.items()}
        m = {group: value for group, (value, _) in block.m.items()}
        if self.pending_p3 is not None and g.get("tilt") != 68.2:
            raise self.error(f"G68.2 P3 Q1 at line {self.pending_p3.line} must be followed by its G68.2 P3 Q2 line "
                             "(the normal, I J K)")
        if "feed mode" in g:
            self.inverse_time = g["feed mode"] == 93
        feed = block.take("F")
        if feed is not None:
            if not feed > 0:
                raise self.error(f"F must be > 0, got {block.values['F'][1]}")
            if not self.inverse_time and feed * self.scale > MAX_FEED_MM_MIN:
                raise self.error(f"{block.values['F'][1]} is {feed * self.scale:.6g} mm/min, more than "
                                 f"{MAX_FEED_MM_MIN:g} mm/min")
            if not self.inverse_time and feed * self.scale < MIN_FEED_MM_MIN:
                raise self.error(f"{block.values['F'][1]} is {feed * self.scale:.6g} mm/min, less than "
                                 f"{MIN_FEED_MM_MIN:g} mm/min (allowed: {MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} "
                                 "mm/min)")
            self.feed_word = feed
        speed = block.take("S")
        if speed is not None:
            if speed < 0:
                raise self.error(f"S must be ≥ 0 rpm, got {block.values['S'][1]}")
            allowed = f"(allowed: 0, or {MIN_SPINDLE_RPM:g} to {MAX_SPINDLE_RPM:g} rpm)"
            if 0 < speed < MIN_SPINDLE_RPM:              # it would print as S0
                raise self.error(f"{block.values['S'][1]} is less than {MIN_SPINDLE_RPM:g} rpm {allowed}")
            if speed > MAX_SPINDLE_RPM:
                raise self.error(f"{block.values['S'][1]} is more than {MAX_SPINDLE_RPM:g} rpm {allowed}")
            self.spindle_rpm = speed
            if self.spindle_on and "spindle" not in m:
                self.event(self.spindle_kind, value=speed)
        tool = block.take("T")
        if tool is not None:
            if tool < 0 or tool != int(tool):
                raise self.error(f"T must be a whole tool number ≥ 0, got {block.values['T'][1]}")
            if tool > self.tool_number_max:
                limit = self.tool_number_max
                raise self.error(f"{block.values['T'][1]} is out of range (allowed: whole tool numbers 0 to {limit}"
                                 f"{DIALECT_TOOLS if limit < TOOL_NUMBER_LIMIT else ''})")
            self.tool = int(tool)
        if "tool change" in m:
            if self.tool is None:
                raise self.error("M6 without a tool number: give T on this line or before")
            self.event(EventKind.TOOL_CHANGE, value=float(self.tool), text=f"tool {self.tool}")
        if "spindle" in m:
            self.spindle(m["spindle"])
        if "coolant" in m:
            code = m["coolant"]
            if code == 9:
                self.event(EventKind.COOLANT_OFF)
            else:
                self.event(EventKind.COOLANT_ON, text=Coolant.from_m_code(code).value)
        if "dwell" in g:
            seconds = block.take("P")
            if seconds is None or seconds < 0:
                raise self.error("G4 needs P, the dwell in seconds (≥ 0)")
            self.event(EventKind.DWELL, value=seconds)
        if "plane" in g:
            self.plane = int(g["plane"])
        if "units" in g:
            self.scale = MM_PER_INCH if g["units"] == 20 else 1.0
        if "distance" in g:
            self.absolute = g["distance"] == 90
        if "return" in g:
            self.retract_to_r = g["return"] == 99
        if "length offset" in g and g["length offset"] == 43:
            block.take("H")
        if "tilt" in g:
            self.tilt_code(g["tilt"], block)
        self.motion_block(g.get("motion"), block)
        unused = [block.values[letter][1] for letter in block.values if letter not in block.used]
        if unused:
            raise self.error(f"word {unused[0]!r} is not used by any code on this line ({USES[unused[0][0]]})")
        if "stop" in m:
            code = m["stop"]
            if code in (0, 1):
                self.event(EventKind.OPTIONAL_STOP if code == 1 else EventKind.STOP)
            else:
                if self.cycle is not None:
                    self.end_cycle()
                self.end_line = self.number

    def spindle(self, code: float) -> None:
        if code == 5:
            self.spindle_on = False
            self.event(EventKind.SPINDLE_OFF)
            return
        if not self.spindle_rpm > 0:
            raise self.error(f"{code_name('M', code)} without a spindle speed: give S (rpm) on this line or before")
        self.spindle_on = True
        self.spindle_kind = EventKind.SPINDLE_ON_CCW if code == 4 else EventKind.SPINDLE_ON
        self.event(self.spindle_kind, value=self.spindle_rpm)

    # ---- planes
    def tilt_code(self, code: float, block: Block) -> None:
        if code == 53.1:
            if self.tilt is None:
                raise self.error("G53.1 without a tilted plane: G53.1 turns the tool axis to the plane of a G68.2, "
                                 "which must come first")
            self.tilt_ready = True
            return
        if code == 69:
            if self.cycle is not None:
                raise self.error(f"G69 while the canned cycle of line {self.cycle.line} is active: end it with G80 "
                                 "first")
            if self.tilt is not None:
                self.change_frame(0)
            self.tilt, self.tilt_ready = None, True
            return
        if "motion" in block.g:
            raise self.error("G68.2 must be on a line without motion codes (its X Y Z are the plane's origin)")
        if self.cycle is not None:
            raise self.error(f"G68.2 while the canned cycle of line {self.cycle.line} is active: end it with G80 "
                             "first")
        form = block.take("P")
        form = 0.0 if form is None else form
        if form not in (0.0, 3.0):
            raise self.error(f"G68.2 P{form:g} is not read: the reader reads P0 (Euler angles X Y Z I J K, the "
                             "default) and P3 (two vectors: Q1 X Y Z I J K, then Q2 I J K)")
        text = " ".join(t for _, t in block.values.values())
        if self.tilt is not None and self.pending_p3 is None:
            raise self.error(f"G68.2 while the tilted plane of line {self.tilt.line} is active: cancel it with G69 "
                             "first")
        origin = np.array([block.take(a) or 0.0 for a in AXES]) * self.scale
        vector = np.array([block.take(a) or 0.0 for a in OFFSETS])
        if form == 0.0:
            order = block.take("Q")
            if order is not None and order != 313:
                raise self.error(f"G68.2 Q{order:g}: the Euler angles are read in the order Z-X-Z only (Q313, "
                                 "the default)")
            self.set_tilt(WorkPlane(origin, euler_zxz_deg(*vector.tolist())), f"G68.2 {text}")
            return
        which = block.take("Q")
        if which == 1.0 and self.pending_p3 is None:
            self.pending_p3 = PendingP3(self.number, f"G68.2 {text}", origin, vector)
            return
        if which != 2.0 or self.pending_p3 is None:
            raise self.error("G68.2 P3 is two lines: Q1 X Y Z I J K (origin, x direction), then Q2 I J K (the "
                             f"normal); found Q{which if which is None else f'{which:g}'}")
        if any(a in block.values for a in AXES):
            raise self.error("G68.2 P3 Q2 takes no X, Y or Z: the origin is on the Q1 line")
        first = self.pending_p3
        self.pending_p3 = None
        x_length, z_length = float(np.linalg.norm(first.x_direction)), float(np.linalg.norm(vector))
        if z_length == 0.0:
            raise self.error("G68.2 P3 Q2: the normal I J K is the zero vector (it must be the plane's z direction, "
                             "the tool axis)")
        if x_length == 0.0:
            self.number = first.line
            raise self.error("G68.2 P3 Q1: the x direction I J K is the zero vector")
        cosine = float(first.x_direction @ vector) / (x_length * z_length)
        if abs(cosine) > P3_MAX_COSINE:
            angle = math.degrees(math.acos(max(-1.0, min(1.0, cosine))))   # clip: rounding past ±1
            raise self.error(f"G68.2 P3: the x direction (line {first.line}) and the normal are {angle:.2f}° apart; "
                             "they must be perpendicular (85° to 95°)")
        z = vector / z_length
        x = first.x_direction / x_length - cosine * z
        x /= np.linalg.norm(x)
        self.set_tilt(WorkPlane(first.origin, np.column_stack([x, np.cross(z, x), z])), f"{first.text}; G68.2 {text}")

    def set_tilt(self, inner: WorkPlane, text: str) -> None:
        plane = GcodePlane(self.number, text, self.base.compose(inner, name=f"G68.2 at line {self.number}"))
        self.planes.append(plane)
        self.frames.append(plane.plane)
        self.change_frame(len(self.frames) - 1)
        self.tilt, self.tilt_ready = plane, False

    def change_frame(self, index: int) -> None:
        """Make plane ``index`` current; the position stays the same point (unknown if any axis is)."""
        if np.isfinite(self.position).all():
            part = self.frames[self.frame].to_part(np.array(self.position))
            self.position = self.frames[index].to_local(part)[0].tolist()
        else:
            if self.start_pending:
                raise self.error("the plane changes before the first rapid has all of X, Y and Z: give the full "
                                 "start position first")
            self.position = [math.nan] * 3
        self.frame = index

    # ---- motion
    def motion_block(self, code: float | None, block: Block) -> None:
        has_axes = any(a in block.values for a in AXES)
        if code is not None:
            if code in CYCLES:
                if self.cycle is None or self.cycle.code != code:
                    level = None                       # another cycle without G80: the same initial level (G98)
                    if self.cycle is not None:
                        level = self.cycle.initial_z
                        self.end_cycle()
                    self.start_cycle(code, level)
            elif self.cycle is not None:
                self.end_cycle()
            self.motion = code
        if not has_axes:
            if code in CYCLES:
                raise self.error(f"{code_name('G', code)} without a hole position: give X, Y (and Z, R)")
            return
        if "tilt" in block.g and block.g["tilt"][0] == 68.2:
            return                                      # X Y Z were the plane's origin
        if self.motion is None or self.motion == 80:
            raise self.error("axis words without a motion mode: give G0, G1, G2, G3 or a canned cycle"
                             if self.motion is None else "axis words after G80: give G0, G1, G2 or G3 first")
        if not self.tilt_ready:
            assert self.tilt is not None  # tilt_ready is False only after a G68.2
            raise self.error(f"a move in the tilted plane of G68.2 (line {self.tilt.line}) before G53.1: give G53.1 "
                             "first, which turns the tool axis to the plane's normal")
        if self.motion in CYCLES:
            self.hole(block)
        elif self.motion in (2.0, 3.0):
            self.arc(block)
        else:
            self.move(block)

    def target(self, block: Block) -> list[float]:
        """The end point of a move, mm in the current plane (NaN where still unknown)."""
        end = list(self.position)
        for index, letter in enumerate(AXES):
            value = block.take(letter)
            if value is None:
                continue
            value *= self.scale
            if self.absolute:
                end[index] = value
            elif math.isnan(end[index]):
                raise self.error(f"incremental {letter} (G91) while the {letter} position is not known yet: give the "
                                 "first position under G90")
            else:
                end[index] += value
        return end

    def feed_for(self, length: float) -> float:
        """mm/min of a feed move of ``length`` mm."""
        word = self.feed_word
        code = code_name("G", self.motion or 0.0)
        if self.inverse_time:
            raise self.error(f"{code} under G93 (inverse time) without F: every feed move under G93 needs its own "
                             "F (1/minute)")
        if word is None:
            raise self.error(f"{code} before any F: the feed rate is unknown (give F, in units per minute)")
        return word * self.scale

    def inverse_time_feed(self, block: Block, length: float) -> float | None:
        """Under G93: mm/min that makes the move of ``length`` mm take 1/F minutes (F of this line)."""
        if not self.inverse_time:
            return None
        word = block.values.get("F")
        if word is None:
            return self.feed_for(length)               # raises the G93 message
        if length == 0.0:
            raise self.error(f"{code_name('G', self.motion or 0.0)} of zero length under G93 (inverse time): its "
                             "time 1/F cannot be kept by a move that goes nowhere")
        feed = word[0] * length
        if not MIN_FEED_MM_MIN <= feed <= MAX_FEED_MM_MIN:       # what F means for this move, in mm/min
            raise self.error(f"{word[1]} under G93 (inverse time) makes this {length:.6g} mm move {feed:.6g} mm/min "
                             f"(allowed: {MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} mm/min)")
        return feed

    def move(self, block: Block) -> None:
        end = self.target(block)
        rapid = self.motion == 0.0
        if not all(math.isfinite(v) for v in end):
            if not rapid:
                raise self.error(f"{code_name('G', self.motion or 1.0)} while the position is not fully known: the "
                                 "first moves must give X, Y and Z (a rapid may give them over several lines)")
            self.position = end
            self.start_pending = True
            self.start_rapids += 1
            return
        self.start_pending = False
        self.moves += 1
        if rapid:
            self.add_rows(np.array(end), RAPID, 0.0, self.number)
            return
        length = math.dist(end, self.position)
        feed = self.inverse_time_feed(block, length)
        self.add_rows(np.array(end), FEED, feed if feed is not None else self.feed_for(length), self.number)

    def arc(self, block: Block) -> None:
        code = code_name("G", self.motion or 2.0)
        if not np.isfinite(self.position).all():
            raise self.error(f"{code} while the position is not fully known: the arc has no start point")
        first, second, normal_axis = PLANES[self.plane]
        plane_name = f"G{self.plane}"
        offset_letters = (OFFSETS[first], OFFSETS[second])
        wrong = OFFSETS[normal_axis]
        if wrong in block.values:
            raise self.error(f"{block.values[wrong][1]} in {plane_name}: the arc centre's offsets in {plane_name} "
                             f"are {offset_letters[0]} and {offset_letters[1]}")
        start = np.array(self.position)
        end = np.array(self.target(block))
        radius_word = block.take("R")
        offsets = [block.take(letter) for letter in offset_letters]
        turns_word = block.take("P")
        turns = 1 if turns_word is None else turns_word
        if turns < 1 or turns != int(turns):
            raise self.error(f"{code} P (turns) must be a whole number ≥ 1, got {block.values['P'][1]}")
        centre = start.copy()
        a, b = start[[first, second]], end[[first, second]]
        if radius_word is not None:
            if any(v is not None for v in offsets):
                raise self.error(f"{code} with both R and {'/'.join(offset_letters)}: give the centre one way")
            radius = abs(radius_word) * self.scale
            chord = b - a
            half = float(np.linalg.norm(chord)) / 2.0
            if half == 0.0:
                raise self.error(f"{code} with R and its end at its start: R cannot make a full circle (give the "
                                 f"centre with {offset_letters[0]} {offset_letters[1]})")
            if radius == 0.0:
                raise self.error(f"{code} R must not be 0")
            if half > radius + self.circle_tolerance:
                raise self.error(f"{code} end point is {2 * half:.4f} mm from its start, more than the diameter "
                                 f"{2 * radius:.4f} of R{radius_word:g}: the end is not on a circle of that radius")
            height = math.sqrt(max(radius * radius - half * half, 0.0))   # clip: a chord a hair over 2R
            left = np.array([-chord[1], chord[0]]) / (2.0 * half)
            side = (1.0 if self.motion == 3.0 else -1.0) * (1.0 if radius_word > 0 else -1.0)
            centre[[first, second]] = (a + b) / 2.0 + side * height * left
        else:
            if all(v is None for v in offsets):
                raise self.error(f"{code} without its centre: give {offset_letters[0]} and/or {offset_letters[1]} "
                                 f"(offsets from the start in {plane_name}) or R")
            centre[[first, second]] = a + np.array([v or 0.0 for v in offsets]) * self.scale
            radius = float(np.linalg.norm(a - centre[[first, second]]))
            if radius == 0.0:
                raise self.error(f"{code} centre offsets are zero: the arc has no radius")
            end_radius = float(np.linalg.norm(b - centre[[first, second]]))
            if abs(end_radius - radius) > self.circle_tolerance:
                shown = " ".join(f"{AXES[i]}{end[i] / self.scale:.4f}" for i in range(3))
                raise self.error(f"{code} end point ({shown}) is {abs(end_radius - radius):.4f} mm "
                                 f"{'outside' if end_radius > radius else 'inside'} the circle through its start "
                                 f"(radius {radius / self.scale:.4f}); the end must lie on the circle within "
                                 f"{self.circle_tolerance:g} mm")
        axis = np.zeros(3)
        axis[normal_axis] = 1.0 if self.motion == 3.0 else -1.0      # G3: counter-clockwise about the normal
        try:
            sweep = arc_sweep(centre, axis, start, end) + 2.0 * math.pi * (int(turns) - 1)
            count = arc_segment_count(radius, sweep, tolerance=self.tolerance)
            if count > MAX_ARC_SEGMENTS:
                raise self.error(f"{code} (radius {radius / self.scale:g}, {int(turns)} turns) needs {count:,} "
                                 f"segments within {self.tolerance:g} mm, more than {MAX_ARC_SEGMENTS:,}")
            points = arc_points_3d(centre, axis, start, end, tolerance=self.tolerance, turns=int(turns) - 1)[1:]
        except ValueError as exc:                        # the start or end on the arc's axis
            raise self.error(f"{code} start or end is at the arc's centre: the arc has no direction there") from exc
        length = math.hypot(sweep * radius, float(end[normal_axis] - start[normal_axis]))
        feed = self.inverse_time_feed(block, length)
        self.add_rows(points, FEED, feed if feed is not None else self.feed_for(length), self.number)
        self.arcs += 1
        self.arc_segments += len(points)

    # ---- canned cycles
    def start_cycle(self, code: float, initial_z: float | None) -> None:
        if self.inverse_time:
            raise self.error(f"{code_name('G', code)} under G93 (inverse time): canned cycles need a feed per minute "
                             "(G94)")
        if not np.isfinite(self.position).all():
            raise self.error(f"{code_name('G', code)} while the position is not fully known: the cycle starts from "
                             "the current position (give X, Y and Z first)")
        self.cycle = Cycle(code, self.number, self.position[2] if initial_z is None else initial_z,
                           fresh=initial_z is None)

    def end_cycle(self) -> None:
        cycle = self.cycle
        assert cycle is not None  # only called with a cycle active
        self.cycles.append(GcodeCycle(cycle.line, code_name("G", cycle.code), cycle.holes))
        self.cycle = None

    def hole(self, block: Block) -> None:
        cycle = self.cycle
        assert cycle is not None  # motion is a cycle code only while one is active
        code = code_name("G", cycle.code)
        if self.inverse_time:
            raise self.error(f"{code} under G93 (inverse time): canned cycles need a feed per minute (G94)")
        if self.plane != 17:
            raise self.error(f"{code} in G{self.plane}: canned cycles are read in G17 only, where the hole goes "
                             "along Z, the tool axis (in G18/G19 it would go sideways)")
        for letter in "ZRQP":
            value = block.take(letter)
            if value is not None:
                setattr(cycle, letter.lower(), value)
        if cycle.z is None or cycle.r is None:
            raise self.error(f"{code} needs Z (the hole's bottom) and R (the retract plane)")
        pecking = CYCLES[cycle.code]
        if pecking is not Pecking.NONE and (cycle.q is None or not cycle.q > 0):
            raise self.error(f"{code} needs Q > 0, the depth of each peck")
        if cycle.code != 82 and "P" in block.values:
            raise self.error(f"{code} takes no P (only G82 dwells at the bottom)")
        if cycle.p is not None and cycle.p < 0:
            raise self.error(f"{code} P (dwell) must be ≥ 0 s, got {cycle.p:g}")
        current = list(self.position)
        x, y = current[0], current[1]
        for index, letter in enumerate("XY"):
            value = block.take(letter)
            if value is not None:
                shifted = value * self.scale + (0.0 if self.absolute else current[index])
                x, y = (shifted, y) if index == 0 else (x, shifted)
        level = current[2]
        if self.absolute:
            r, z = cycle.r * self.scale, cycle.z * self.scale
        else:
            r = level + cycle.r * self.scale
            z = r + cycle.z * self.scale
        if not z < r:
            raise self.error(f"{code} bottom Z {z / self.scale:g} is not below the retract plane R {r / self.scale:g}: "
                             "the hole goes down the tool axis, from R to Z")
        feed = self.feed_for(0.0)
        # LinuxCNC's preliminary motion: a fresh cycle goes up to R first if it is below it (and that is
        # the level G98 returns to); then across to the hole, at the current level (G99) or the cycle's
        # initial level (G98), then down to R
        before: list[list[float]] = []
        if cycle.fresh and level < r:
            before.append([current[0], current[1], r])
            level = cycle.initial_z = r
        cycle.fresh = False
        level = level if self.retract_to_r else cycle.initial_z
        before.append([x, y, level])
        if before[0] == current:                         # a move that goes nowhere
            del before[0]
        clear = r if self.retract_to_r else max(cycle.initial_z, r)
        if pecking is not Pecking.NONE and (count := peck_count(r - z, (cycle.q or 0.0) * self.scale)) > MAX_PECKS:
            raise self.error(f"{code} Q{cycle.q:g} would drill {(r - z) / self.scale:g} from R to Z in "
                             f"{count:,} pecks, more than {MAX_PECKS:,}: use a larger Q")
        drill = DrillCycle(depth=r - z, clearance=0.0, retract=clear - r, feed=feed, pecking=pecking,
                           peck=(cycle.q or 0.0) * self.scale, gap=PECK_GAP_MM,
                           dwell=(cycle.p or 0.0) if cycle.code == 82 else 0.0)
        tip, kind, bottom = drill_rows(np.array([[x, y, r]]), np.array([[0.0, 0.0, 1.0]]), drill)
        if level == r:                                   # the cycle's first rapid goes nowhere
            tip, kind, bottom = tip[1:], kind[1:], bottom - 1
        rows = np.vstack([np.array(before).reshape(-1, 3), tip])
        kinds = np.concatenate([np.full(len(before), RAPID), kind])
        first = self.rows
        self.add_rows(rows, kinds, np.where(kinds == FEED, feed, 0.0), self.number)
        if drill.dwell > 0:
            self.events.append(Event(before=first - self.chunk_start + len(before) + int(bottom[0]) + 1,
                                     kind=EventKind.DWELL,
                                     value=drill.dwell))
        cycle.holes += 1
        self.cycle_holes += 1
        self.cycle_rows += len(rows)


def _to_part(frame: WorkPlane, local: FloatArray) -> FloatArray:
    """``frame.to_part(local)``: (N, 3) mm, in C where it was built (the same bits, one pass)."""
    from prs3_post.core import native  # ctypes: loaded only where rows are read

    tip = native.rows_to_part(local, frame.rotation, frame.origin)
    return frame.to_part(local) if tip is None else tip
