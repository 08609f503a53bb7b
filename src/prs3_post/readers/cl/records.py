"""What each CL record does (:mod:`prs3_post.readers.cl.reader` lists them): the modal state as the records go
by, and the rows and events they make."""

from __future__ import annotations

import math
from array import array
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from prs3_post.core.defaults import MAX_SPINDLE_RPM, MIN_SPINDLE_RPM
from prs3_post.core.errors import InputError
from prs3_post.core.toolpath import Coolant, Event, EventKind, MoveKind, Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.machine.dialect import TOOL_NUMBER_LIMIT
from prs3_post.part.stl import MAX_COORDINATE_MM
from prs3_post.part.workplane import rotate_rows
from prs3_post.readers.cl.summary import ClCounts, ClCycle, ClFile, ClFrame, ClToolData
from prs3_post.readers.cl.syntax import (
    AXIS_LENGTH_TOLERANCE,
    DISPLAY_WORDS,
    FEED,
    FEED_UNITS,
    FRAME_TOLERANCE,
    KNOWN_WORDS,
    LISTING_TRAILER,
    NUMBER,
    NUMBER_LIST,
    RAPID,
    TRAILER,
    Assembler,
    Record,
    parse_number,
    quote,
)
from prs3_post.readers.common import DIALECT_TOOLS, MAX_FEED_MM_MIN, MIN_FEED_MM_MIN, join_toolpaths
from prs3_post.toolpaths.arcs import MAX_ARC_SEGMENTS, arc_points_3d, arc_segment_count, arc_sweep
from prs3_post.toolpaths.cycles import MAX_PECKS, DrillCycle, Pecking, drill_rows, peck_count

_CYCLE_KINDS = {"DRILL": Pecking.NONE, "DEEP": Pecking.FULL_RETRACT, "BRKCHP": Pecking.CHIP_BREAK}

#: What Python's float() reads as NaN or infinity, words to a CL file: refused where a number goes.
_NOT_FINITE = frozenset({"NAN", "INF", "INFINITY"})


# --------------------------------------------------------------------------------------------
# Interpretation
# --------------------------------------------------------------------------------------------
@dataclass(slots=True)
class _Arc:
    line: int
    centre: FloatArray          # mm, local frame
    axis: FloatArray            # unit, local frame, as written (the tool goes clockwise about it)
    radius: float               # mm
    text: str


@dataclass(slots=True)
class _ActiveCycle:
    line: int
    words: tuple[str, ...]
    cycle: DrillCycle
    holes: int = 0


class Records:
    """The modal state of a CL file as the records go by; rows in the LOCAL frame (mm) with their frame."""

    #: The largest tool number a tool change may have (the stream sets the output dialect's).
    tool_number_max = TOOL_NUMBER_LIMIT

    def __init__(self, path: str, scale: float, ignore: frozenset[str], tolerance: float, circle_tolerance: float,
                 apply_msys: bool = True):
        self.path, self.scale, self.ignore, self.apply_msys = path, scale, ignore, apply_msys
        self.tolerance, self.circle_tolerance = tolerance, circle_tolerance
        self.line = 0
        # rows, flat (x, y, z per row): stdlib arrays append a row far faster than numpy blocks
        self.tip = array("d")                         # mm, local frame
        self.axis = array("d")                        # unit, local frame
        self.kind = array("q")
        self.feed = array("d")
        self.source = array("q")
        self.frame_of = array("q")                    # index into self.frames
        self.rows = 0                                 # rows so far (all chunks)
        self.chunk_start = 0                          # row index of the current chunk's first row
        self.events: list[Event] = []                 # this chunk's, ``before`` counted from its start
        self.assembler = Assembler(path)
        self.frames: list[ClFrame] = [ClFrame(0, np.zeros(3), np.eye(3))]
        self.position: tuple[float, float, float] | None = None    # mm, local frame of the current MSYS
        self.tool_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
        self.rapid_next = False
        self.feed_value: float | None = None          # mm/min, or mm/rev when per_rev
        self.per_rev = False
        self.spindle_rpm = 0.0
        self.spindle_on = False
        self.spindle_kind = EventKind.SPINDLE_ON       # the direction: SPINDLE_ON_CCW for CCLW
        self.multax_on: bool | None = None
        self.arc: _Arc | None = None
        self.cycle: _ActiveCycle | None = None
        self.cycles: list[ClCycle] = []
        self.tool_data: list[ClToolData] = []
        self.end_lines: list[int] = []
        self.finished = False                         # FINI seen
        self.after_end = False                        # END-OF-PATH or FINI seen last
        self.by_word: Counter[str] = Counter()
        self.skipped: Counter[str] = Counter()
        #: plain FEDRAT lines read in bulk runs (:meth:`mark`) → the feed and per_rev they set
        self.fedrat_seen: dict[str, tuple[float | None, bool]] = {}
        self.records = self.gotos = self.gotos_with_axis = self.moves = 0
        self.arcs = self.arc_segments = self.cycle_holes = self.cycle_rows = self.comments = 0

    # ---- helpers
    def error(self, message: str) -> InputError:
        return InputError(message, path=self.path, line=self.line)

    def numbers(self, record: Record, args: tuple[str, ...] | None = None) -> list[float]:
        rest = record.rest
        if args is None and rest is not None and NUMBER_LIST.match(rest):   # the common case, checked at once
            values = [float(text) for text in rest.split(",")]
            if "e" not in rest and "E" not in rest and len(rest) < 300:   # else it may overflow to inf
                return values
            if all(math.isfinite(v) for v in values):
                return values
        values = []
        for index, text in enumerate(record.args if args is None else args, start=1):
            if not text:
                raise self.error(f"truncated record {quote(record.text)}: value {index} of {record.word}/ is empty")
            value = parse_number(text, f"{record.word}/ value {index}")
            if isinstance(value, str):
                raise self.error(value)
            values.append(value)
        return values

    def lengths(self, record: Record, values: list[float], indices: Iterable[int]) -> None:
        """Refuse a coordinate or length ``values[i]`` (file units) beyond :data:`MAX_COORDINATE_MM`."""
        for index in indices:
            if not abs(values[index]) * self.scale <= MAX_COORDINATE_MM:        # inf and nan too
                raise self.error(self.length_message(record.args[index], f"{record.word}/ value {index + 1}"))

    def length_message(self, text: str, what: str) -> str:
        unit = "mm" if self.scale == 1.0 else "inch"
        return (f"{what}: {quote(text, 40)} is out of range (allowed: within ±{MAX_COORDINATE_MM / self.scale:g} "
                f"{unit}; is the file in the right units?)")

    def unit_axis(self, values: list[float], what: str) -> tuple[float, float, float]:
        i, j, k = values
        length = math.sqrt(i * i + j * j + k * k)
        if length == 1.0:
            return i, j, k
        shown = ", ".join(f"{v:g}" for v in values)
        if length == 0.0:
            raise self.error(f"{what}: zero tool vector ({shown}); i,j,k must be a unit vector from the tool tip "
                             "toward the spindle")
        if abs(length - 1.0) > AXIS_LENGTH_TOLERANCE:
            raise self.error(f"{what}: tool vector ({shown}) has length {length:.6g}; i,j,k must be a unit vector "
                             f"(length 1 within {AXIS_LENGTH_TOLERANCE:g})")
        return i / length, j / length, k / length

    def add_row(self, point: tuple[float, float, float], axis: tuple[float, float, float], kind: int, feed: float,
                source: int) -> None:
        self.tip.extend(point)
        self.axis.extend(axis)
        self.kind.append(kind)
        self.feed.append(feed)
        self.source.append(source)
        self.frame_of.append(len(self.frames) - 1)
        self.rows += 1
        self.position = point

    def add_rows(self, tip: FloatArray, axis: tuple[float, float, float] | FloatArray, kind: int | np.ndarray,
                 feed: float | np.ndarray, source: int | np.ndarray) -> None:
        tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
        n = len(tip)
        self.tip.frombytes(tip.tobytes())
        self.axis.frombytes(np.broadcast_to(np.asarray(axis, dtype=np.float64), (n, 3)).tobytes())
        self.kind.frombytes(np.broadcast_to(np.asarray(kind, dtype=np.int64), (n,)).tobytes())
        self.feed.frombytes(np.broadcast_to(np.asarray(feed, dtype=np.float64), (n,)).tobytes())
        self.source.frombytes(np.broadcast_to(np.asarray(source, dtype=np.int64), (n,)).tobytes())
        self.frame_of.frombytes(np.full(n, len(self.frames) - 1, dtype=np.int64).tobytes())
        self.rows += n
        x, y, z = tip[-1].tolist()
        self.position = (x, y, z)

    def event(self, kind: EventKind, value: float = 0.0, text: str = "") -> None:
        self.events.append(Event(before=self.rows - self.chunk_start, kind=kind, value=value, text=text))

    def current_feed(self) -> float:
        """mm/min of a feed move now."""
        if self.feed_value is None:
            raise self.error("feed move before any FEDRAT/: the feed rate is unknown (give FEDRAT/ first, or "
                             "RAPID before the move)")
        if not self.per_rev:
            return self.feed_value
        if not (self.spindle_on and self.spindle_rpm > 0):
            raise self.error("feed per revolution (MMPR/IPR) while the spindle is off: the feed rate is unknown "
                             "(give SPINDL/ with a speed first, or a feed per minute)")
        return self.feed_per_minute(self.feed_value * self.spindle_rpm,
                                    f"the feed per revolution at {self.spindle_rpm:g} rpm")

    def feed_per_minute(self, feed: float, what: str) -> float:
        """``feed`` (mm/min) if within :data:`FEED_RANGE_MM_MIN`, else the error naming ``what`` made it."""
        if not MIN_FEED_MM_MIN <= feed <= MAX_FEED_MM_MIN:
            raise self.error(f"{what} is {feed:.6g} mm/min (allowed: "
                             f"{MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} mm/min)")
        return feed

    # ---- dispatch
    def record(self, record: Record) -> None:
        self.line = record.line
        self.records += 1
        word = record.word
        if self.finished and not TRAILER.match(record.text):
            raise self.error(f"{quote(record.text)} after FINI: FINI ends the CL data")
        if word != "$$" and record.comment is not None:
            self.comments += 1
            self.event(EventKind.COMMENT, text=record.comment)
        if self.arc is not None and word not in ("GOTO", "$$", "PPRINT") and word not in DISPLAY_WORDS:
            raise self.error(f"CIRCLE/ at line {self.arc.line} must be followed by its end GOTO/, found "
                             f"{quote(record.text)}")
        handler = _HANDLERS.get(word)
        if handler is not None:
            self.by_word[word] += 1
            self.after_end = False
            handler(self, record)
        elif word in DISPLAY_WORDS or word in self.ignore:
            self.by_word[word] += 1
            self.skipped[word] += 1
        elif TRAILER.match(record.text):
            if not self.after_end:
                raise self.error(f"listing trailer {quote(record.text)} before END-OF-PATH/FINI: not CL data")
            self.by_word[LISTING_TRAILER] += 1
            self.skipped[LISTING_TRAILER] += 1
        else:
            raise self.error(
                f"unknown major word {word[:40]!r} in {quote(record.text)} (understood: {', '.join(KNOWN_WORDS)}; "
                f"display-only, skipped: {', '.join(sorted(DISPLAY_WORDS))}; other words can be ignored on purpose "
                "by listing them as words to ignore)")

    # ---- motion
    def goto(self, record: Record) -> None:
        values = self.numbers(record)
        if len(values) not in (3, 6):
            raise self.error(f"{record.word}/ has {len(values)} values: expected 3 (x,y,z) or 6 (x,y,z,i,j,k); "
                             f"found {quote(record.text)}")
        if len(values) == 6 and self.multax_on is False:
            raise self.error(f"{record.word}/ with i,j,k under MULTAX/OFF: give x,y,z only, or MULTAX/ON first")
        self.lengths(record, values, range(3))
        scale = self.scale
        point = (values[0] * scale, values[1] * scale, values[2] * scale)
        if len(values) == 6:
            axis = self.unit_axis(values[3:], f"{record.word}/")
        else:
            axis = self.tool_axis
        if record.word == "GOTO":
            self.gotos += 1
            self.gotos_with_axis += len(values) == 6
        rapid = self.rapid_next or record.word != "GOTO"
        self.rapid_next = False                        # RAPID applies to the next motion record only
        if self.arc is not None:
            self.end_arc(point, axis, len(values) == 6)
            return
        self.tool_axis = axis
        if self.cycle is not None and record.word == "GOTO":
            self.hole(point, axis)
            return
        if self.cycle is not None:
            raise self.error(f"{record.word}/ inside the CYCLE/ of line {self.cycle.line}: close it with CYCLE/OFF "
                             "first")
        self.moves += 1
        if rapid:
            self.add_row(point, axis, RAPID, 0.0, record.line)
        else:
            self.add_row(point, axis, FEED, self.current_feed(), record.line)

    def rapid(self, record: Record) -> None:
        if record.args:
            raise self.error(f"RAPID takes no values; found {quote(record.text)}")
        self.rapid_next = True

    def circle(self, record: Record) -> None:
        values = self.numbers(record)
        if len(values) < 7:
            raise self.error(f"CIRCLE/ has {len(values)} values: expected at least 7 (xc,yc,zc,i,j,k,r); found "
                             f"{quote(record.text)}")
        self.lengths(record, values, (0, 1, 2, 6))
        if self.cycle is not None:
            raise self.error(f"CIRCLE/ inside the CYCLE/ of line {self.cycle.line}: close it with CYCLE/OFF first")
        if self.rapid_next:
            raise self.error("CIRCLE/ after RAPID: an arc is cut at the feed rate (put RAPID before a GOTO/ only)")
        if self.position is None:
            raise self.error("CIRCLE/ before any move: the arc has no start point")
        normal = np.array(values[3:6])
        length = float(np.linalg.norm(normal))
        if not length > 0:
            raise self.error("CIRCLE/ axis i,j,k is the zero vector: it must give the circle's axis direction")
        radius = values[6] * self.scale
        if not radius > 0:
            raise self.error(f"CIRCLE/ radius must be > 0, got {values[6]:g}")
        self.current_feed()
        self.arc = _Arc(record.line, np.array(values[:3]) * self.scale, normal / length, radius, record.text)

    def end_arc(self, end_point: tuple[float, float, float], axis: tuple[float, float, float], has_axis: bool) -> None:
        arc = self.arc
        assert arc is not None and self.position is not None  # only called with an arc pending
        if has_axis and math.dist(axis, self.tool_axis) > 1e-9:
            raise self.error(f"the end GOTO/ of the CIRCLE/ at line {arc.line} changes the tool axis: an arc is "
                             "cut with a constant tool axis (give the end point without i,j,k, or the same i,j,k)")
        start, end = np.array(self.position), np.array(end_point)
        for name, point in (("start", start), ("end", end)):
            offset = point - arc.centre
            height = float(offset @ arc.axis)
            radial = float(np.linalg.norm(offset - height * arc.axis))
            off_circle = radial - arc.radius
            if radial == 0.0:
                raise self.error(f"arc {name} point lies on the axis of CIRCLE/ at line {arc.line}, where an arc has "
                                 "no direction; start and end must lie on the circle")
            if abs(off_circle) > self.circle_tolerance:
                shown = ", ".join(f"{v / self.scale:.4f}" for v in point)
                raise self.error(
                    f"arc {name} point ({shown}) is {abs(off_circle):.4f} mm "
                    f"{'outside' if off_circle > 0 else 'inside'} "
                    f"the circle of CIRCLE/ at line {arc.line} (radius {arc.radius / self.scale:g}); start and end "
                    f"must lie on the circle within {self.circle_tolerance:g} mm")
            if name == "start":
                start_height = height
            elif abs(height - start_height) > self.circle_tolerance:
                raise self.error(
                    f"arc end point is {abs(height - start_height):.4f} mm off the plane of the arc's start, along "
                    f"the axis of CIRCLE/ at line {arc.line}; start and end must lie on one circle within "
                    f"{self.circle_tolerance:g} mm")
        sweep = arc_sweep(arc.centre, -arc.axis, start, end)
        count = arc_segment_count(max(float(np.linalg.norm(start - arc.centre)), arc.radius), sweep,
                                  tolerance=self.tolerance)
        if count > MAX_ARC_SEGMENTS:
            raise self.error(f"the arc of CIRCLE/ at line {arc.line} (radius {arc.radius / self.scale:g}) needs "
                             f"{count:,} segments within {self.tolerance:g} mm, more than {MAX_ARC_SEGMENTS:,}: "
                             "the circle is far larger than any part")
        # The corpus convention: the tool moves clockwise about (i, j, k), i.e. counter-clockwise about −(i, j, k).
        points = arc_points_3d(arc.centre, -arc.axis, start, end, tolerance=self.tolerance)[1:]
        source = np.full(len(points), arc.line, dtype=np.int64)
        source[-1] = self.line
        self.add_rows(points, self.tool_axis, int(MoveKind.FEED), self.current_feed(), source)
        self.arcs += 1
        self.arc_segments += len(points)
        self.arc = None

    def hole(self, point: tuple[float, float, float], axis: tuple[float, float, float]) -> None:
        assert self.cycle is not None  # only called inside a cycle
        tip, kind, bottom = drill_rows(np.array([point]), np.array([axis]), self.cycle.cycle)
        feed = np.where(kind == int(MoveKind.FEED), self.cycle.cycle.feed, 0.0)
        first = self.rows
        self.add_rows(tip, axis, kind, feed, self.line)
        if self.cycle.cycle.dwell > 0:
            self.events.append(Event(before=first - self.chunk_start + int(bottom[0]) + 1,
                                     kind=EventKind.DWELL, value=self.cycle.cycle.dwell))
        self.cycle.holes += 1
        self.cycle_holes += 1
        self.cycle_rows += len(tip)

    # ---- modal state
    def fedrat(self, record: Record) -> None:
        unit: str | None = None
        values: list[str] = []
        for arg in record.args:
            if arg.upper() in FEED_UNITS:
                if unit is not None:
                    raise self.error(f"FEDRAT/ with two units ({unit}, {arg.upper()}): give one")
                unit = arg.upper()
            else:
                values.append(arg)
        if len(values) != 1:
            raise self.error(f"FEDRAT/ expects one value and an optional unit (MMPM, IPM, MMPR, IPR) before or after "
                             f"it; found {quote(record.text)}")
        (value,) = self.numbers(record, tuple(values))
        if not value > 0:
            raise self.error(f"FEDRAT/ must be > 0, got {values[0]}")
        if unit is None:
            self.feed_value, self.per_rev = value * self.scale, False
        else:
            factor, per_rev = FEED_UNITS[unit]
            self.feed_value, self.per_rev = value * factor, per_rev
        if not self.per_rev and self.feed_value > MAX_FEED_MM_MIN:
            raise self.error(f"FEDRAT/ {values[0]} is {self.feed_value:.6g} mm/min, "
                             f"more than {MAX_FEED_MM_MIN:g} mm/min")
        if not self.per_rev and self.feed_value < MIN_FEED_MM_MIN:
            raise self.error(f"FEDRAT/ {values[0]} is {self.feed_value:.6g} mm/min, less than {MIN_FEED_MM_MIN:g} "
                             f"mm/min (allowed: {MIN_FEED_MM_MIN:g} to {MAX_FEED_MM_MIN:g} mm/min)")

    def multax(self, record: Record) -> None:
        setting = record.args[0].upper() if record.args else "ON"
        if len(record.args) > 1 or setting not in ("ON", "OFF"):
            raise self.error(f"MULTAX expects nothing, ON or OFF; found {quote(record.text)}")
        self.multax_on = setting == "ON"

    def tlaxis(self, record: Record) -> None:
        values = self.numbers(record)
        if len(values) != 3:
            raise self.error(f"TLAXIS/ has {len(values)} values: expected 3 (i,j,k); found {quote(record.text)}")
        self.tool_axis = self.unit_axis(values, "TLAXIS/")

    def msys(self, record: Record) -> None:
        values = self.numbers(record)
        if len(values) != 9:
            raise self.error(f"MSYS/ has {len(values)} values: expected 9 (origin x,y,z, x axis i,j,k, y axis i,j,k); "
                             f"found {quote(record.text)}")
        x_axis, y_axis = np.array(values[3:6]), np.array(values[6:9])
        x_len, y_len, dot = float(np.linalg.norm(x_axis)), float(np.linalg.norm(y_axis)), float(x_axis @ y_axis)
        if abs(x_len - 1) > FRAME_TOLERANCE or abs(y_len - 1) > FRAME_TOLERANCE or abs(dot) > FRAME_TOLERANCE:
            raise self.error(
                f"MSYS/ axes are not orthogonal unit vectors: x axis ({', '.join(f'{v:g}' for v in values[3:6])}), "
                f"y axis ({', '.join(f'{v:g}' for v in values[6:9])}) have |x| = {x_len:.6g}, |y| = {y_len:.6g}, "
                f"x·y = {dot:.6g} (valid: |x| = |y| = 1 and x·y = 0 within {FRAME_TOLERANCE:g})")
        self.lengths(record, values, range(3))
        x_axis = x_axis / x_len
        y_axis = y_axis - (y_axis @ x_axis) * x_axis
        y_axis = y_axis / np.linalg.norm(y_axis)
        rotation = np.column_stack([x_axis, y_axis, np.cross(x_axis, y_axis)])
        self.frames.append(ClFrame(record.line, np.array(values[:3]) * self.scale, rotation))
        if not self.apply_msys:             # points stay as written: the frame is only recorded
            return
        previous = self.frames[-2]
        if self.position is not None:       # the same place, now seen from the new frame
            x, y, z = self.frames[-1].to_local(previous.to_part(np.array(self.position)))[0].tolist()
            self.position = (x, y, z)
        i, j, k = (rotation.T @ (previous.rotation @ np.array(self.tool_axis))).tolist()
        self.tool_axis = (i, j, k)

    def units(self, record: Record) -> None:
        """Checked and applied to the whole file before the records are read (see _file_units)."""

    def tool_change(self, record: Record) -> None:
        args = record.args
        if record.word == "LOAD" or record.word == "SELECT":
            if not args or args[0].upper() != "TOOL":
                raise self.error(f"{record.word}/ expects TOOL,n; found {quote(record.text)}")
            args = args[1:]
        if not args:
            raise self.error(f"{record.word}/ without a tool number; found {quote(record.text)}")
        (number,) = self.numbers(record, args[:1])
        if number < 0 or number != int(number):
            raise self.error(f"{record.word}/ tool number must be a whole number ≥ 0, got {args[0]}")
        if number > self.tool_number_max:
            limit = self.tool_number_max
            raise self.error(f"{record.word}/ tool number {args[0]} is out of range (allowed: whole numbers 0 to "
                             f"{limit}{DIALECT_TOOLS if limit < TOOL_NUMBER_LIMIT else ''})")
        if record.word != "SELECT":
            shape = f": TLDATA/{','.join(self.tool_data[-1].words)}" if self.tool_data else ""
            self.event(EventKind.TOOL_CHANGE, value=float(number), text=f"tool {int(number)}{shape}")

    def tldata(self, record: Record) -> None:
        """The cutter's shape: words (MILL, DRILL), then numbers, the first the diameter; a NaN or a diameter
        ≤ 0 is refused (it would shrink the tool the rapids are checked with to nothing)."""
        diameter = True
        for index, arg in enumerate(record.args, start=1):
            text = arg.strip()
            word = not NUMBER.match(text) and any(c.isalpha() for c in text)
            if word and text.lstrip("+-").upper() not in _NOT_FINITE:     # MILL, DRILL; not NaN, -inf
                continue
            value = parse_number(text, f"TLDATA/ value {index}")
            if isinstance(value, str):
                raise self.error(value)
            if diameter and not value > 0:
                raise self.error(f"TLDATA/ value {index}: the tool diameter must be above 0, got {text}")
            diameter = False
        self.tool_data.append(ClToolData(record.line, record.args))

    def spindl(self, record: Record) -> None:
        words = [arg.upper() for arg in record.args]
        if words in (["OFF"],):
            self.spindle_on = False
            self.event(EventKind.SPINDLE_OFF)
            return
        if words == ["ON"]:
            if not self.spindle_rpm > 0:
                raise self.error("SPINDL/ON before any spindle speed: give SPINDL/RPM,s,CLW first")
            self.spindle_on = True
            self.event(self.spindle_kind, value=self.spindle_rpm)
            return
        direction = "CLW"
        speed: list[str] = []
        for arg, upper in zip(record.args, words, strict=True):
            if upper in ("CLW", "CCLW"):
                direction = upper
            elif upper == "RPM":
                continue
            elif NUMBER.match(arg) or not upper.isalpha():
                speed.append(arg)
            else:
                raise self.error(f"SPINDL/ word {arg!r} is not understood (valid: RPM, a speed, CLW, CCLW; or ON, "
                                 "OFF alone)")
        if len(speed) != 1:
            raise self.error(f"SPINDL/ expects one speed in rpm; found {quote(record.text)}")
        (rpm,) = self.numbers(record, tuple(speed))
        if not rpm > 0:
            raise self.error(f"SPINDL/ speed must be > 0 rpm, got {speed[0]}")
        if rpm < MIN_SPINDLE_RPM:                      # it would print as S0
            raise self.error(f"SPINDL/ speed {speed[0]} is less than {MIN_SPINDLE_RPM:g} rpm (allowed: "
                             f"{MIN_SPINDLE_RPM:g} to {MAX_SPINDLE_RPM:g} rpm)")
        if rpm > MAX_SPINDLE_RPM:
            raise self.error(f"SPINDL/ speed {speed[0]} is more than {MAX_SPINDLE_RPM:g} rpm (allowed: "
                             f"{MIN_SPINDLE_RPM:g} to {MAX_SPINDLE_RPM:g} rpm)")
        self.spindle_rpm, self.spindle_on = rpm, True
        self.spindle_kind = EventKind.SPINDLE_ON_CCW if direction == "CCLW" else EventKind.SPINDLE_ON
        self.event(self.spindle_kind, value=rpm)

    def coolnt(self, record: Record) -> None:
        words = {arg.upper() for arg in record.args}
        if words == {"OFF"}:
            self.event(EventKind.COOLANT_OFF)
        elif words and words <= {"ON", "FLOOD"}:
            self.event(EventKind.COOLANT_ON, text=Coolant.FLOOD.value)
        elif words in ({"MIST"}, {"MIST", "ON"}):
            self.event(EventKind.COOLANT_ON, text=Coolant.MIST.value)
        else:
            raise self.error(f"COOLNT/ expects ON, FLOOD, MIST or OFF; found {quote(record.text)}")

    def cycle_record(self, record: Record) -> None:
        words = [arg.upper() for arg in record.args]
        if words == ["OFF"]:
            if self.cycle is None:
                raise self.error("CYCLE/OFF without an active CYCLE/")
            active = self.cycle
            self.cycles.append(ClCycle(active.line, active.words, active.cycle, active.holes))
            self.cycle = None
            return
        if self.cycle is not None:
            raise self.error(f"CYCLE/ while the CYCLE/ of line {self.cycle.line} is active: close it with CYCLE/OFF")
        self.cycle = _ActiveCycle(record.line, record.args, self.parse_cycle(record, words))

    def parse_cycle(self, record: Record, words: list[str]) -> DrillCycle:
        pecking: Pecking | None = None
        params: dict[str, float] = {}
        feed: float | None = None
        index = 0
        while index < len(words):
            word = words[index]
            if word in _CYCLE_KINDS:
                kind = _CYCLE_KINDS[word]
                if pecking is not None and kind is not Pecking.NONE and pecking is not Pecking.NONE:
                    raise self.error(f"CYCLE/ with two kinds of pecking; found {quote(record.text)}")
                pecking = kind if pecking in (None, Pecking.NONE) else pecking
                index += 1
                continue
            if word in ("RAPTO", "FEDTO", "RTRCTO", "STEP", "DWELL", *FEED_UNITS):
                if index + 1 >= len(words):
                    raise self.error(f"truncated record {quote(record.text)}: {word} without its value")
                (value,) = self.numbers(record, (record.args[index + 1],))
                if word in FEED_UNITS:
                    factor, per_rev = FEED_UNITS[word]
                    feed = value * factor * (self.spindle_rpm if per_rev else 1.0)
                    if per_rev and not self.spindle_rpm > 0:
                        raise self.error(f"CYCLE/ feed in {word} before any spindle speed: give SPINDL/ first")
                else:
                    if word != "DWELL" and not abs(value) * self.scale <= MAX_COORDINATE_MM:
                        raise self.error(self.length_message(record.args[index + 1], f"CYCLE/ {word}"))
                    params[word] = value
                index += 2
                continue
            raise self.error(f"CYCLE/ word {record.args[index]!r} is not understood (valid: DRILL, DEEP, BRKCHP, "
                             "RAPTO, FEDTO, RTRCTO, STEP, DWELL, MMPM, IPM, MMPR, IPR with their values; OFF)")
        if pecking is None:
            raise self.error(f"CYCLE/ without a kind (DRILL, DEEP or BRKCHP); found {quote(record.text)}")
        for needed in ("RAPTO", "FEDTO"):
            if needed not in params:
                raise self.error(f"CYCLE/ without {needed}: the cycle needs RAPTO (clearance) and FEDTO (depth); "
                                 f"found {quote(record.text)}")
        if params["RAPTO"] < 0 or params.get("RTRCTO", 0.0) < 0:
            raise self.error("CYCLE/ RAPTO and RTRCTO are heights above the hole point and must be ≥ 0")
        if feed is None:
            feed = self.current_feed()
        if not feed > 0:
            raise self.error("CYCLE/ feed must be > 0")
        feed = self.feed_per_minute(feed, "CYCLE/ feed")
        peck = params.get("STEP", 0.0) * self.scale
        if pecking is not Pecking.NONE and "STEP" in params and not peck > 0:
            raise self.error(f"CYCLE/ STEP must be > 0, got {params['STEP']:g}")
        if peck > 0 and (count := peck_count(abs(params["FEDTO"]) * self.scale, peck)) > MAX_PECKS:
            raise self.error(f"CYCLE/ STEP {params['STEP']:g} would drill FEDTO {abs(params['FEDTO']):g} in "
                             f"{count:,} pecks, more than {MAX_PECKS:,}: use a larger STEP")
        if params.get("DWELL", 0.0) < 0:
            raise self.error(f"CYCLE/ DWELL must be ≥ 0 s, got {params['DWELL']:g}")
        return DrillCycle(
            depth=abs(params["FEDTO"]) * self.scale, clearance=params["RAPTO"] * self.scale,
            retract=params.get("RTRCTO", params["RAPTO"]) * self.scale, feed=feed,
            pecking=pecking if peck > 0 else Pecking.NONE, peck=peck, dwell=params.get("DWELL", 0.0))

    def comment_record(self, record: Record) -> None:
        self.comments += 1
        self.event(EventKind.COMMENT, text=(record.comment if record.word == "$$" else record.rest) or "")

    def stop(self, record: Record) -> None:
        if record.args:
            raise self.error(f"{record.word} takes no values; found {quote(record.text)}")
        self.event(EventKind.OPTIONAL_STOP if record.word == "OPSTOP" else EventKind.STOP)

    def end(self, record: Record) -> None:
        if record.args:
            raise self.error(f"{record.word} takes no values; found {quote(record.text)}")
        if self.cycle is not None:
            raise self.error(f"{record.word} while the CYCLE/ of line {self.cycle.line} is active: close it with "
                             "CYCLE/OFF first")
        self.end_lines.append(record.line)
        self.after_end = True
        self.finished = record.word == "FINI"

    # ---- result

    def close(self) -> None:
        """The end of the file: nothing may be left open."""
        self.assembler.close()
        if self.records == 0:
            raise InputError("not a CL file: no records (the file is empty)", path=self.path)
        if self.arc is not None:
            self.line = self.arc.line
            raise self.error("CIRCLE/ at the end of the file: its end GOTO/ is missing")
        if self.cycle is not None:
            self.line = self.cycle.line
            raise self.error("CYCLE/ is not closed with CYCLE/OFF before the end of the file")

    def take(self) -> Toolpath:
        """The rows and events since the last take, in the PART frame (events count from the chunk's start)."""
        local = np.frombuffer(self.tip, dtype=np.float64).reshape(-1, 3)
        axis_local = np.frombuffer(self.axis, dtype=np.float64).reshape(-1, 3)
        frame = np.frombuffer(self.frame_of, dtype=np.int64)
        if self.apply_msys and len(frame) and frame[0] == frame[-1] and (frame == frame[0]).all():   # one MSYS
            one = self.frames[int(frame[0])]
            tip, axis = _turned(local, one.rotation, one.origin), _turned(axis_local, one.rotation, None)
        else:
            tip, axis = local.copy(), axis_local.copy()
            for index in np.unique(frame) if self.apply_msys else ():   # one transform per MSYS, its rows at once
                rows = frame == index
                tip[rows] = _turned(local[rows], self.frames[index].rotation, self.frames[index].origin)
                axis[rows] = _turned(axis_local[rows], self.frames[index].rotation, None)
        events = tuple(self.events)                    # counted from the chunk's start already
        chunk = Toolpath(kind=np.frombuffer(self.kind, dtype=np.int64), tip=tip, axis=axis,
                         feed=np.frombuffer(self.feed, dtype=np.float64),
                         source=np.frombuffer(self.source, dtype=np.int64), events=events,
                         source_file=self.path)
        self.tip, self.axis, self.kind = array("d"), array("d"), array("q")
        self.feed, self.source, self.frame_of = array("d"), array("q"), array("q")
        self.events = []
        self.chunk_start = self.rows
        return chunk

    def summary(self, units: str) -> ClFile:
        """Everything but the rows (an empty toolpath): units, counts, frames, cycles, tool data, ends."""
        counts = ClCounts(
            records=self.records, gotos=self.gotos, gotos_with_axis=self.gotos_with_axis, moves=self.moves,
            arcs=self.arcs, arc_segments=self.arc_segments, cycles=len(self.cycles), cycle_holes=self.cycle_holes,
            cycle_rows=self.cycle_rows, comments=self.comments, skipped=tuple(sorted(self.skipped.items())),
            by_word=tuple(sorted(self.by_word.items())), rows=self.rows)
        return ClFile(path=self.path, units=units, toolpath=join_toolpaths([]), counts=counts,
                      frames=tuple(self.frames[1:]), cycles=tuple(self.cycles), tool_data=tuple(self.tool_data),
                      end_lines=tuple(self.end_lines))


def _turned(rows: FloatArray, rotation: FloatArray, origin: FloatArray | None) -> FloatArray:
    """(N, 3) ``rotate_rows(rows, rotation)`` (+ ``origin``): in C where it was built (the same bits, one pass)."""
    from prs3_post.core import native  # ctypes: loaded only where rows are read

    turned = native.rows_to_part(rows, rotation, origin)
    if turned is not None:
        return turned
    return rotate_rows(rows, rotation) if origin is None else rotate_rows(rows, rotation) + origin


_HANDLERS = {
    "GOTO": Records.goto, "FROM": Records.goto, "GOHOME": Records.goto, "RAPID": Records.rapid,
    "CIRCLE": Records.circle, "FEDRAT": Records.fedrat, "MULTAX": Records.multax, "TLAXIS": Records.tlaxis,
    "MSYS": Records.msys, "UNITS": Records.units, "LOADTL": Records.tool_change, "LOAD": Records.tool_change,
    "SELECT": Records.tool_change, "TLDATA": Records.tldata, "SPINDL": Records.spindl, "COOLNT": Records.coolnt,
    "CYCLE": Records.cycle_record, "PPRINT": Records.comment_record, "$$": Records.comment_record,
    "STOP": Records.stop, "OPSTOP": Records.stop, "END-OF-PATH": Records.end, "FINI": Records.end,
}
