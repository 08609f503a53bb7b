"""G-code as a registered input format (:mod:`prs3_post.readers.registry`): its name, file name endings,
how its lines look, and its stream: 3+2 (:class:`~prs3_post.readers.gcode.reader.GcodeStream`), or
5-axis under TCP where a source convention is given (:class:`~prs3_post.readers.fivex.reader.FivexStream`)."""

from __future__ import annotations

import re
from dataclasses import dataclass

from prs3_post.core.errors import InputError
from prs3_post.readers.protocol import CamStream, ReadOptions

__all__ = ["GCODE", "GcodeReader"]

#: A G-code line: ``%``, a comment, or a letter and a number (``/`` before it: block delete).
_GCODE_LINE = re.compile(r"[%(;]|/?\s*[A-Za-z]\s*[-.0-9]")


@dataclass(frozen=True, slots=True)
class GcodeReader:
    """The G-code reader: 3+2 (:mod:`prs3_post.readers.gcode.reader`), or 5-axis with a source
    convention (:mod:`prs3_post.readers.fivex.reader`)."""

    name: str = "gcode"
    suffixes: tuple[str, ...] = (".nc", ".ngc", ".gcode", ".tap", ".cnc", ".iso", ".mpf", ".eia")
    first_move: str = "move to the start point with G0 before the first G1"

    def claims(self, line: str) -> bool:
        """``%``, a comment (``(`` or ``;``), or a letter and a number (``N10``, ``G0``, ``x1``)."""
        return _GCODE_LINE.match(line) is not None

    def check(self, options: ReadOptions) -> None:
        """A source convention's TCP, clamp and inert codes (:func:`~prs3_post.readers.fivex.reader.check_tcp_codes`,
        :func:`~prs3_post.readers.fivex.reader.check_quiet_codes`)."""
        source = options.source
        if source is not None:
            from prs3_post.readers.fivex.reader import check_quiet_codes, check_tcp_codes  # only 5-axis needs them

            check_tcp_codes(source, source.tcp_on if options.tcp_on is None else options.tcp_on,
                            source.tcp_off if options.tcp_off is None else options.tcp_off)
            check_quiet_codes(source)

    def open(self, path: str, options: ReadOptions) -> CamStream:
        """A 3+2 stream on the options' work plane, or with a source convention a 5-axis one.

        Raises
        ------
        InputError
            A work plane and a source convention both (under TCP the program's X Y Z are the part frame).
        """
        if options.source is not None:
            if options.work_plane is not None:
                raise InputError("a work plane and a 5-axis source: under TCP the program's X Y Z are the part "
                                 "frame itself (its work offset), so there is no work plane to put them on",
                                 path=path)
            from prs3_post.readers.fivex.reader import FivexStream  # only a 5-axis program needs it

            five = FivexStream(path, options.source, tolerance=options.tolerance, tcp_on=options.tcp_on,
                               tcp_off=options.tcp_off, circle_tolerance=options.circle_tolerance)
            five.tool_number_max = options.tool_number_max
            return five
        from prs3_post.readers.gcode.reader import GcodeStream  # numpy: loaded where a file is read

        stream = GcodeStream(path, tolerance=options.tolerance, work_plane=options.work_plane,
                             circle_tolerance=options.circle_tolerance)
        stream.tool_number_max = options.tool_number_max
        return stream


#: The registered G-code reader.
GCODE = GcodeReader()
