"""The `export` job: a program's tool path back in the part frame, for CAM-side viewers and simulators.

    PROGRAM ──► header (machine, dialect, setup, tool lengths) ──► read ──► FK of every line's joint
    words ──► part frame (the setup's inverse) ──► APT CL file (GOTO/x,y,z,i,j,k) or CSV (one row a line)

The tip of each motion line is where the machine puts it at the line's end point: forward kinematics
of its joint words (stage X, Y and the joints; the machine's kinematics, ideal or as built), the tool
length of the tool in the spindle (a job's tool table, or a converted program's one tool length),
turned into the part frame by the setup (p_part = Rz(−θ)·(p_machine − origin)). Between two lines the
machine moves straight in joint space; the tip curves a little (within the program's tolerance:
`verify` checks that) and the export writes only the end points, as a CL file does.

The feed of a G1 line is the tip's chord over the move's time: F (G93 inverse time, 1/min) × chord
(mm) = mm/min. A program's first G1 has no known start point; its feed is the next G1's. Time: G1
1/F min, G0 the machine's [dynamics] (else the longest joint travel at the nominal rapid rate),
as `verify` counts it.

Everything the program was made for comes from its header (a program without one is refused: its
machine, setup and tool length would be guesses); each can be given instead, which then wins.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from prs3_post.app.requests import resolve_setup
from prs3_post.app.verify import load_recorded, tool_lengths_of
from prs3_post.check.verify import NOMINAL_RAPID_RATE, move_durations
from prs3_post.core.errors import InputError, LexError, ReachError
from prs3_post.core.input_files import open_input
from prs3_post.core.lexer import decode
from prs3_post.core.numbers import fixed, fixed_column
from prs3_post.core.toolpath import Event, EventKind, MoveKind
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.emit.header import ProgramHeader, SourceHeader
from prs3_post.emit.header_read import read_header
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.kinematics.replay import expand, forward_parts, head_shift, joints_of, shift_keys
from prs3_post.machine.loading import DEFAULT_DIALECT, Dialect, load_dialect, load_machine
from prs3_post.machine.model import Machine
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.program import ProgramFile, load_program

__all__ = ["EXPORT_FORMATS", "Exported", "cl_text", "csv_text", "export_program", "exported_path"]

#: What `export` writes.
EXPORT_FORMATS = ("cl", "csv")
#: Decimals of a tip coordinate (mm) and of a unit axis component: the IK of the rounded pose gives the
#: program's joint words again to well within their 0.0001 mm (an axis off by 5e-10 moves a point a
#: tool length away by 1e-7 mm).
TIP_DECIMALS = 6
AXIS_DECIMALS = 9
#: Decimals of a feed (mm/min) and of a time (s).
FEED_DECIMALS = 4
TIME_DECIMALS = 4
#: The CSV's columns.
CSV_COLUMNS = ("line", "x", "y", "z", "i", "j", "k", "feed_mm_min", "time_s")
#: How much of a file without a header is checked for being text.
_TEXT_CHECK_BYTES = 1 << 16


@dataclass(frozen=True, slots=True)
class Exported:
    """A program's tool path in the part frame, one row per motion line.

    Attributes
    ----------
    program : ProgramFile
    header : ProgramHeader | SourceHeader
    machine : Machine — with the tool length the tips are computed with before any tool change
    dialect : Dialect
    setup : Setup
    tool_lengths : dict of int to float | None — mm, "TL" of each tool (None: every row has the machine's)
    tip : (N, 3) float — mm, part frame
    axis : (N, 3) float — unit tool axis (tip → spindle), part frame
    feed : (N,) float — mm/min, the tip's feed of G1 lines (NaN for G0)
    duration : (N,) float — s, each line's move time (row 0: 0)
    """

    program: ProgramFile
    header: ProgramHeader | SourceHeader
    machine: Machine
    dialect: Dialect
    setup: Setup
    tool_lengths: dict[int, float] | None
    tip: FloatArray
    axis: FloatArray
    feed: FloatArray
    duration: FloatArray

    @property
    def lines(self) -> IntArray:
        """(N,) int — the program line of each row."""
        return np.asarray(self.program.moves.source)


def export_program(path: str, *, machine: str | None = None, dialect: str | None = None,
                   origin: tuple[float, ...] | None = None, rotation_deg: float | None = None,
                   tool_length: float | None = None) -> Exported:
    """Read a program and put its tool path in the part frame (module docstring).

    Parameters
    ----------
    path : str — the program (it must have a prs3-post header)
    machine, dialect : str | None — a shipped name or TOML path instead of the header's
    origin : (3,) mm | None, rotation_deg : float | None — the setup instead of the header's
    tool_length : float | None — mm, one tool length "TL" for every line instead of the header's

    Raises
    ------
    InputError
        No header, an unreadable header or line (``path:line: ...``), no motion lines.
    ReachError
        A line whose joint words the head cannot take (FK finds no pose).
    FieldError
        A setup out of range.
    """
    given_dialect = load_dialect(dialect) if dialect is not None else None
    style = (given_dialect or load_dialect(DEFAULT_DIALECT)).comments
    header = read_header(path, open_=style.open, close=style.close)
    if header is None:
        _refuse_non_text(path)
        raise InputError("no prs3-post header (the '(program: prs3-post ...)' comments at its top): export needs the "
                         "machine, setup and tool length the program was made for; export a program made by "
                         "prs3-post (run, job or convert)", path=path, line=1)
    chosen = load_machine(machine) if machine is not None else load_recorded(header, "machine", load_machine)
    words = given_dialect or load_recorded(header, "dialect", load_dialect)
    setup = resolve_setup(chosen, header.setup.origin if origin is None else origin,
                          header.setup.rotation_deg if rotation_deg is None else rotation_deg)
    lengths = None
    if tool_length is not None:
        chosen = chosen.with_tool_length(tool_length)
    elif isinstance(header, SourceHeader):
        chosen = chosen.with_tool_length(header.tool_length)
    else:
        lengths = tool_lengths_of(header)
    program = load_program(path, words, stage=chosen.stage.present, kinematics=kinematics_of(chosen))
    moves = program.moves
    if not len(moves):
        raise InputError("no moves (G0/G1 lines) in the program: nothing to export", path=path)
    joints = joints_of(moves)
    direction = head_shift(chosen)
    canonical, index = shift_keys(joints[:, 2:], shift=direction is not None)
    (fk,) = forward_parts(chosen, [canonical])
    poses = expand(fk, None, index, joints, direction)
    if not poses.converged.all():
        r = int(np.flatnonzero(~poses.converged)[0])
        words_at = ", ".join(f"{v:.4f}" for v in joints[r, 2:])
        raise ReachError(f"{path}:{int(moves.source[r])}: the head does not assemble at these joint words "
                         f"({words_at} mm) on machine {chosen.name}: no tool pose to export")
    tip = poses.tip
    if lengths:
        row_lengths = _row_tool_lengths(moves.events, len(moves), lengths, chosen.geometry.tool_length)
        tip = tip + (chosen.geometry.tool_length - row_lengths)[:, None] * poses.axis
    tip_part = setup.points_to_part(tip)
    axis_part = setup.axes_to_part(poses.axis)
    return Exported(program=program, header=header, machine=chosen, dialect=words, setup=setup, tool_lengths=lengths,
                    tip=tip_part, axis=axis_part, feed=_feeds(tip_part, moves.kind, moves.inverse_time),
                    duration=60.0 * move_durations(moves, rapid_rate=NOMINAL_RAPID_RATE, dynamics=chosen.dynamics))


def _refuse_non_text(path: str) -> None:
    """What the program reader says first about a file that is no G-code text (empty, a byte-order
    mark, binary data), where no header was found: a missing header would hide it (a mark is invisible)."""
    with open_input(path, "a G-code program") as stream:
        head = stream.read(_TEXT_CHECK_BYTES)
    if len(head) == _TEXT_CHECK_BYTES:
        head = head[:head.rfind(b"\n") + 1] or head    # whole lines: no character cut in two
    try:
        decode(head)
    except LexError as exc:
        raise InputError(str(exc), path=path) from exc


def _row_tool_lengths(events: tuple[Event, ...], n: int, lengths: dict[int, float], default: float) -> FloatArray:
    """(N,) mm, the tool length of the tool in the spindle at each row (a tool change before row k
    counts from row k; a tool the header does not list: the machine's)."""
    out = np.full(n, default)
    for event in sorted((e for e in events if e.kind is EventKind.TOOL_CHANGE), key=lambda e: e.before):
        out[event.before:] = lengths.get(int(event.value), default)
    return out


def _feeds(tip: FloatArray, kind: IntArray, inverse_time: FloatArray) -> FloatArray:
    """(N,) mm/min, chord × F of each G1 row (NaN for G0; a first G1 takes the next G1's)."""
    chord = np.zeros(len(tip))
    chord[1:] = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    feed_row = kind == MoveKind.FEED
    feed = np.where(feed_row, chord * inverse_time, np.nan)
    if len(feed) and feed_row[0]:
        later = np.flatnonzero(feed_row[1:] & (chord[1:] > 0.0))
        feed[0] = feed[later[0] + 1] if len(later) else np.nan
    return feed


def exported_path(exported: Exported, fmt: str) -> Iterator[str]:
    """The text of ``fmt`` (``cl`` or ``csv``), in chunks."""
    return cl_text(exported) if fmt == "cl" else csv_text(exported)


# ----------------------------------------------------------------------------- CL

#: CL records of the events (the CL reader reads them back as the same events).
def _event_records(event: Event) -> list[str]:
    kind = event.kind
    if kind is EventKind.TOOL_CHANGE:
        return [f"LOADTL/{int(event.value)}"]
    if kind in (EventKind.SPINDLE_ON, EventKind.SPINDLE_ON_CCW):
        turn = "CLW" if kind is EventKind.SPINDLE_ON else "CCLW"
        return [f"SPINDL/RPM,{fixed(event.value, 1)},{turn}"]
    if kind is EventKind.SPINDLE_OFF:
        return ["SPINDL/OFF"]
    if kind is EventKind.COOLANT_ON:
        return [f"COOLNT/{event.coolant.value.upper()}"]
    if kind is EventKind.COOLANT_OFF:
        return ["COOLNT/OFF"]
    if kind is EventKind.STOP:
        return ["STOP"]
    if kind is EventKind.OPTIONAL_STOP:
        return ["OPSTOP"]
    if kind is EventKind.DWELL:                        # no CL word the CL readers share: a comment
        return [f"$$ dwell {fixed(event.value, 3)} s"]
    return [f"PPRINT/{_printable(event.text)}"] if event.text else []


def _printable(text: str) -> str:
    """A comment's text as one CL record: no line break, no continuation ``$`` at its end."""
    return " ".join(text.split()).rstrip("$ ")[:66]


def cl_text(exported: Exported, *, chunk_rows: int = 20000) -> Iterator[str]:
    """An APT CL file of the tool path: ``UNITS/MM``, ``MULTAX``, then per motion line its events,
    ``RAPID`` or a ``FEDRAT/MMPM,f`` when the feed changes, and ``GOTO/x,y,z,i,j,k``; ``FINI`` at the end."""
    program, header, setup = exported.program, exported.header, exported.setup
    moves = program.moves
    n = len(moves)
    made = (f"converted from {header.source_name}" if isinstance(header, SourceHeader)
            else f"made from {header.part_name}")
    yield (f"$$ prs3-post export of {program.path.rsplit('/', 1)[-1]} ({made}): tool tip and axis in the part "
           "frame, mm\n")
    yield (f"$$ machine {exported.machine.name}, setup {setup.describe()}, tool length "
           f"{_lengths_text(exported)}\n")
    yield "UNITS/MM\nMULTAX\n"
    events: dict[int, list[Event]] = {}
    for event in moves.events:
        events.setdefault(min(event.before, n), []).append(event)
    valid = np.isfinite(exported.feed) & (exported.feed > 0.0)
    current = ""
    for lo in range(0, n, chunk_rows):              # a block at a time: memory does not grow with the program
        hi = min(n, lo + chunk_rows)
        tips = [fixed_column(exported.tip[lo:hi, j], TIP_DECIMALS) for j in range(3)]
        axes = [fixed_column(exported.axis[lo:hi, j], AXIS_DECIMALS) for j in range(3)]
        gotos = [f"GOTO/{x},{y},{z},{i},{j},{k}\n" for x, y, z, i, j, k in zip(*tips, *axes, strict=True)]
        feeds = fixed_column(np.where(valid[lo:hi], exported.feed[lo:hi], 0.0), FEED_DECIMALS)
        rapid = (moves.kind[lo:hi] == MoveKind.RAPID).tolist()
        valid_rows = valid[lo:hi].tolist()
        out: list[str] = []
        for r in range(hi - lo):
            if r + lo in events:
                for event in events[r + lo]:
                    out += [f"{record}\n" for record in _event_records(event)]
            if rapid[r]:
                out.append("RAPID\n")
            elif valid_rows[r] and feeds[r] != current:
                current = feeds[r]
                out.append(f"FEDRAT/MMPM,{current}\n")
            out.append(gotos[r])
        yield "".join(out)
    out = []
    for event in events.get(n, ()):
        out += [f"{record}\n" for record in _event_records(event)]
    out.append("FINI\n")
    yield "".join(out)


def _lengths_text(exported: Exported) -> str:
    if not exported.tool_lengths:
        return f"{fixed(exported.machine.geometry.tool_length, 3)} mm"
    return ", ".join(f"T{number} {fixed(length, 3)} mm" for number, length in sorted(exported.tool_lengths.items()))


# ----------------------------------------------------------------------------- CSV

def csv_text(exported: Exported, *, chunk_rows: int = 50000) -> Iterator[str]:
    """One CSV row per motion line: its program line, the tip (mm) and axis in the part frame, the tip
    feed (mm/min; empty for G0) and the program time at its end (s)."""
    yield ",".join(CSV_COLUMNS) + "\n"
    n = len(exported.tip)
    elapsed = np.cumsum(exported.duration)
    for lo in range(0, n, chunk_rows):
        hi = min(n, lo + chunk_rows)
        columns = [[str(v) for v in exported.lines[lo:hi].tolist()]]
        columns += [fixed_column(exported.tip[lo:hi, j], TIP_DECIMALS) for j in range(3)]
        columns += [fixed_column(exported.axis[lo:hi, j], AXIS_DECIMALS) for j in range(3)]
        feed = exported.feed[lo:hi]
        texts = fixed_column(np.nan_to_num(feed, nan=0.0), FEED_DECIMALS)
        columns.append([t if math.isfinite(f) else "" for t, f in zip(texts, feed.tolist(), strict=True)])
        columns.append(fixed_column(elapsed[lo:hi], TIME_DECIMALS))
        yield "".join(",".join(row) + "\n" for row in zip(*columns, strict=True))
