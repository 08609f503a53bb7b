"""APT CL as a registered input format (:mod:`prs3_post.readers.registry`): its name, file name endings,
how its records look, and its stream (:class:`~prs3_post.readers.cl.reader.ClStream`)."""

from __future__ import annotations

import re
from dataclasses import dataclass

from prs3_post.readers.protocol import CamStream, ReadOptions

__all__ = ["CL", "ClReader"]

#: A CL record: a major word and a slash, a bare CL word, or a ``$$`` comment.
_CL_RECORD = re.compile(r"[A-Za-z][A-Za-z0-9 _-]*/|(?:RAPID|FINI|END-OF-PATH|STOP|OPSTOP|MULTAX)\s*\Z|\$\$",
                        re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class ClReader:
    """The APT CL reader (:mod:`prs3_post.readers.cl.reader`)."""

    name: str = "cl"
    suffixes: tuple[str, ...] = (".cls", ".clsf", ".cl", ".apt", ".aptsource", ".cldata")
    first_move: str = "start with FROM/x,y,z, or RAPID and a GOTO/ to the start point, before the first feed"

    def claims(self, line: str) -> bool:
        """A major word and a slash (``GOTO/1,2,3``), a bare CL word (``RAPID``) or a ``$$`` comment."""
        return _CL_RECORD.match(line) is not None

    def check(self, options: ReadOptions) -> None:
        """Nothing to refuse before a file is read (words to ignore are checked as each file is opened)."""

    def open(self, path: str, options: ReadOptions) -> CamStream:
        """A :class:`~prs3_post.readers.cl.reader.ClStream` with the options' tolerance, units and ignored words."""
        from prs3_post.readers.cl.reader import ClStream  # numpy: loaded where a file is read (test_startup)

        stream = ClStream(path, tolerance=options.tolerance, units=options.units, ignore=options.ignore,
                          circle_tolerance=options.circle_tolerance)
        stream.tool_number_max = options.tool_number_max
        return stream


#: The registered APT CL reader.
CL = ClReader()
