"""The CAM input formats by name: each a :class:`~prs3_post.readers.protocol.Reader`, registered once.

The shipped formats are APT CL (``cl``, :mod:`prs3_post.readers.cl`) and G-code (``gcode``,
:mod:`prs3_post.readers.gcode`: 3+2, or 5-axis under TCP with a source convention); a new format is a
package with a reader, added with :func:`register`. Registration order is the order in which
:func:`~prs3_post.readers.detect.detect_format` asks the readers about a line, and in which their file
name endings are listed.
"""

from __future__ import annotations

from prs3_post.readers.cl.format import CL
from prs3_post.readers.gcode.format import GCODE
from prs3_post.readers.protocol import Reader

__all__ = ["FALLBACK", "reader_named", "readers", "register", "suffixes", "unregister"]

_READERS: dict[str, Reader] = {}

#: The format of a file no reader claims: the G-code reader's messages say what is wrong with it.
FALLBACK = GCODE.name


def register(reader: Reader) -> Reader:
    """Add ``reader`` under its name (after those registered before it); returns it.

    Raises
    ------
    ValueError
        Its name is taken, or is ``auto`` (which asks for detection by content).
    """
    if reader.name == "auto" or reader.name in _READERS:
        raise ValueError(f"a reader named {reader.name!r} is registered already (or the name is reserved)")
    _READERS[reader.name] = reader
    return reader


def unregister(name: str) -> None:
    """Remove the reader registered as ``name`` (a test's own format, once the test is done)."""
    del _READERS[name]


def readers() -> tuple[Reader, ...]:
    """The registered readers, in registration order."""
    return tuple(_READERS.values())


def reader_named(name: str) -> Reader:
    """The reader registered as ``name``.

    Raises
    ------
    ValueError
        No reader has that name (the names that exist are listed).
    """
    try:
        return _READERS[name]
    except KeyError:
        raise ValueError(f"no input format {name!r} (formats: {', '.join(_READERS)})") from None


def suffixes() -> tuple[str, ...]:
    """File name endings of every registered format, in registration order."""
    return tuple(suffix for reader in _READERS.values() for suffix in reader.suffixes)


register(CL)
register(GCODE)
