"""What a CAM input format gives a conversion: the :class:`Reader` protocol and its :class:`CamStream`.

A format is one package under ``readers/`` (``cl/``, ``gcode/``...) with one :class:`Reader`, registered
by name (:func:`prs3_post.readers.registry.register`). A conversion asks the registry which reader a
file's first lines belong to (:func:`prs3_post.readers.detect.detect_format`), opens a
:class:`CamStream` with :meth:`Reader.open`, and from then on asks the stream only: its chunks (part
frame, mm), its summary once through, and the few things in which formats differ (what the program's
header says of the source, a tool diameter, records skipped, whether a thread may read ahead). So
``convert`` names no format, and a new format is a new package and one :func:`register` call.

:class:`StreamDefaults` gives a stream the common answers; :class:`ReadCounts` and :class:`ReadFile`
are a summary a small format can use as it is.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from prs3_post.core.toolpath import Toolpath
from prs3_post.core.types import Progress
from prs3_post.machine.dialect import TOOL_NUMBER_LIMIT

if TYPE_CHECKING:
    from prs3_post.machine.cam_conventions import SourceConvention
    from prs3_post.part.workplane import WorkPlane

__all__ = ["CamStream", "ReadCounts", "ReadFile", "ReadOptions", "Reader", "SourceNotes", "StreamDefaults",
           "Summary", "SummaryCounts"]


@dataclass(frozen=True, slots=True)
class ReadOptions:
    """How a conversion asks for its inputs to be read (each format takes what concerns it).

    Attributes
    ----------
    tolerance : float — mm, chordal tolerance of expanded arcs
    circle_tolerance : float — mm, how far an arc's ends may be from its circle
    units : str | None — a CL file's length unit when it states none (None: from its feeds)
    ignore : tuple of str — CL major words skipped (and counted) instead of refused
    work_plane : WorkPlane | None — where a G-code program's X, Y, Z are in the part (None: the part frame)
    source : SourceConvention | None — G-code is a 5-axis program of this source machine (None: 3+2)
    tcp_on, tcp_off : tuple of str | None — the codes that switch its TCP on and off (None: the source's)
    tool_number_max : int — the largest tool number the output takes (the dialect's ``words.tool_number_max``):
        a tool change beyond it is refused at its line
    """

    tolerance: float
    circle_tolerance: float
    units: str | None = None
    ignore: tuple[str, ...] = ()
    work_plane: WorkPlane | None = None
    source: SourceConvention | None = None
    tcp_on: tuple[str, ...] | None = None
    tcp_off: tuple[str, ...] | None = None
    tool_number_max: int = TOOL_NUMBER_LIMIT


@dataclass(frozen=True, slots=True)
class SourceNotes:
    """What a converted program's header says of how its source was read (beyond its name and format).

    Attributes
    ----------
    units : str — the length unit the file was read in when one was given, else ``auto``
    ignore : tuple of str — words skipped on purpose
    work_plane : WorkPlane | None — where the program's X, Y, Z were put in the part
    five_axis : str — a 5-axis program's source convention (shipped name or file; "": not one)
    tcp_on, tcp_off : tuple of str — the codes that switched its TCP on and off
    """

    units: str = "auto"
    ignore: tuple[str, ...] = ()
    work_plane: WorkPlane | None = None
    five_axis: str = ""
    tcp_on: tuple[str, ...] = ()
    tcp_off: tuple[str, ...] = ()


class SummaryCounts(Protocol):
    """The accounting a conversion reports of any format (field names as :class:`ReadCounts`)."""

    @property
    def records(self) -> int: ...
    @property
    def by_word(self) -> tuple[tuple[str, int], ...]: ...
    @property
    def moves(self) -> int: ...
    @property
    def arcs(self) -> int: ...
    @property
    def arc_segments(self) -> int: ...
    @property
    def cycles(self) -> int: ...
    @property
    def cycle_holes(self) -> int: ...
    @property
    def cycle_rows(self) -> int: ...
    @property
    def comments(self) -> int: ...
    @property
    def skipped(self) -> tuple[tuple[str, int], ...]: ...


class Summary(Protocol):
    """A file read: its length unit, its counts and (from :meth:`CamStream.whole`) its toolpath."""

    @property
    def path(self) -> str: ...
    @property
    def units(self) -> str: ...
    @property
    def toolpath(self) -> Toolpath: ...
    @property
    def counts(self) -> SummaryCounts: ...


@dataclass(frozen=True, slots=True)
class ReadCounts:
    """What a file held, for a format without counts of its own.

    Attributes
    ----------
    records : int — records read
    by_word : tuple of (str, int) — records by kind, sorted
    moves : int — records that became one row each
    arcs, arc_segments : int — arcs expanded and the rows they became
    cycles, cycle_holes, cycle_rows : int — drilling cycles, their holes and the rows those became
    comments : int — comments carried into the program
    skipped : tuple of (str, int) — records skipped on purpose, by kind
    """

    records: int = 0
    by_word: tuple[tuple[str, int], ...] = ()
    moves: int = 0
    arcs: int = 0
    arc_segments: int = 0
    cycles: int = 0
    cycle_holes: int = 0
    cycle_rows: int = 0
    comments: int = 0
    skipped: tuple[tuple[str, int], ...] = ()


@dataclass(frozen=True, slots=True)
class ReadFile:
    """A file read, for a format without a summary of its own (``toolpath``: PART frame, mm)."""

    path: str
    units: str
    toolpath: Toolpath
    counts: ReadCounts


class CamStream(Protocol):
    """A CAM file read in chunks (what :meth:`Reader.open` gives).

    Iterate it for one :class:`~prs3_post.core.toolpath.Toolpath` per chunk (PART frame, mm; ``source``
    the file's line numbers; events count rows from the chunk's start); once through, :attr:`summary`
    is set (with an empty toolpath) and :attr:`sha256` is the hash of the bytes read. Errors are
    :class:`~prs3_post.core.errors.InputError` naming the file and line.
    """

    @property
    def path(self) -> str: ...
    @property
    def sha256(self) -> str | None: ...
    @property
    def summary(self) -> Summary | None: ...
    @property
    def reads_ahead(self) -> bool:
        """Whether a thread may read the next chunk while this one is used (False: the stream's state
        is read between chunks)."""
    @property
    def refuses_tilt(self) -> bool:
        """Whether the tool axes are the program's own orientations, which no setup changes: one beyond
        the machine's tilt is refused at once, naming the share of the rows beyond it."""
    @property
    def read_as(self) -> str:
        """What the file is read as, where that needs saying (the report and the program's first
        comment; "": nothing to say)."""

    progress: Progress | None
    """Told the bytes read and the file's size as the iteration reads the file (the front end's
    progress; None: nobody asked), set before iterating."""

    def __iter__(self) -> Iterator[Toolpath]: ...

    def whole(self) -> Summary:
        """All chunks joined: the whole file's summary."""

    def skipped(self) -> tuple[tuple[str, int], ...]:
        """Records skipped on purpose, by kind, once through (the report's and the header's)."""

    def tool_diameter(self) -> float:
        """mm: the smallest tool diameter the file states, once through (0: none stated)."""

    def notes(self) -> SourceNotes:
        """What the program's header says of how the file was read."""


class StreamDefaults:
    """The common answers of a :class:`CamStream` (a stream class derives from this and overrides)."""

    summary: Summary | None
    reads_ahead = True
    refuses_tilt = False
    #: The largest tool number a tool change may have (:attr:`ReadOptions.tool_number_max`; the reader sets it).
    tool_number_max = TOOL_NUMBER_LIMIT
    progress: Progress | None = None

    @property
    def read_as(self) -> str:
        """Nothing to say."""
        return ""

    def skipped(self) -> tuple[tuple[str, int], ...]:
        """The summary's own skipped counts."""
        assert self.summary is not None  # set when the iteration ends
        return self.summary.counts.skipped

    def tool_diameter(self) -> float:
        """None stated: the tool is checked as its axis."""
        return 0.0

    def notes(self) -> SourceNotes:
        """Nothing beyond the name and format."""
        return SourceNotes()


class Reader(Protocol):
    """One CAM input format.

    Attributes
    ----------
    name : str — how it is asked for (``--format``), and the program header's and report's name for it
    suffixes : tuple of str — file name endings (lower case) taken from a folder searched for inputs
    first_move : str — what a file must do instead of starting with a feed move (the message's advice)
    """

    @property
    def name(self) -> str: ...
    @property
    def suffixes(self) -> tuple[str, ...]: ...
    @property
    def first_move(self) -> str: ...

    def claims(self, line: str) -> bool:
        """Whether ``line`` (a file's first line that is not blank, stripped) is a record of this format."""

    def check(self, options: ReadOptions) -> None:
        """Refuse ``options`` this format cannot read with, once, before any file is read (ConfigError)."""

    def open(self, path: str, options: ReadOptions) -> CamStream:
        """The stream of the file at ``path`` (nothing is read until it is iterated)."""
