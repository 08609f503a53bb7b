"""Which reader a CAM file needs, from its first bytes.

Each registered reader (:mod:`prs3_post.readers.registry`) says whether a line is one of its records:
a CL record is a major word and a slash (``GOTO/1,2,3``, ``TOOL PATH/...``), a bare CL word (``RAPID``,
``FINI``, ``END-OF-PATH``), or a ``$$`` comment; a G-code line starts with ``%``, a comment (``(`` or
``;``), or a letter and a number (``N10``, ``G0``, ``x1``). The first line that is not blank decides,
asking the readers in their registration order; a file where none is claimed (empty, unreadable) is
sent to the G-code reader (:data:`~prs3_post.readers.registry.FALLBACK`), whose messages say what is
wrong with it.
"""

from __future__ import annotations

from prs3_post.readers.registry import FALLBACK, readers

__all__ = ["DETECT_BYTES", "FORMATS", "detect_format", "formats"]

#: Bytes of a file's start that :func:`detect_format` needs at most (callers read this many).
DETECT_BYTES = 65_536


def formats() -> tuple[str, ...]:
    """Input formats: ``auto`` (decided by content, :func:`detect_format`), then the registered readers'."""
    return ("auto", *(reader.name for reader in readers()))


#: The shipped input formats (:func:`formats`, as registered when this module is first imported).
FORMATS = formats()


def detect_format(first_bytes: bytes) -> str:
    """The name of the reader of a file that starts with ``first_bytes`` (module docstring).

    >>> detect_format(b"TOOL PATH/DRILL\\nGOTO/1,2,3\\n"), detect_format(b"%\\nG0 X1\\n")
    ('cl', 'gcode')
    """
    text = first_bytes.decode("utf-8", errors="replace").removeprefix("\ufeff")
    known = readers()
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        for reader in known:
            if reader.claims(line):
                return reader.name
    return FALLBACK
