"""Which reader a CAM file needs, from its first bytes: APT / CL records, or G-code words.

A CL record is a major word and a slash (``GOTO/1,2,3``, ``TOOL PATH/...``), a bare CL word
(``RAPID``, ``FINI``, ``END-OF-PATH``), or a ``$$`` comment; a G-code line starts with ``%``, a
comment (``(`` or ``;``), or a letter and a number (``N10``, ``G0``, ``x1``). A slash never follows
a word in G-code (``/`` there is block delete, at the start of a line). The first line that is
either decides; a file where none is (empty, unreadable) is sent to the G-code reader, whose
messages say what is wrong with it.
"""

from __future__ import annotations

import re

__all__ = ["DETECT_BYTES", "FORMATS", "detect_format"]

#: Input formats: ``auto`` decides by content (:func:`detect_format`).
FORMATS = ("auto", "cl", "gcode")

#: Bytes of a file's start that :func:`detect_format` needs at most (callers read this many).
DETECT_BYTES = 65_536

_CL_RECORD = re.compile(r"[A-Za-z][A-Za-z0-9 _-]*/|(?:RAPID|FINI|END-OF-PATH|STOP|OPSTOP|MULTAX)\s*\Z|\$\$",
                        re.IGNORECASE)
_GCODE_LINE = re.compile(r"[%(;]|/?\s*[A-Za-z]\s*[-.0-9]")


def detect_format(first_bytes: bytes) -> str:
    """``"cl"`` or ``"gcode"``: the format of a file that starts with ``first_bytes`` (module docstring).

    >>> detect_format(b"TOOL PATH/DRILL\\nGOTO/1,2,3\\n"), detect_format(b"%\\nG0 X1\\n")
    ('cl', 'gcode')
    """
    text = first_bytes.decode("utf-8", errors="replace").removeprefix("\ufeff")
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        if _CL_RECORD.match(line):
            return "cl"
        if _GCODE_LINE.match(line):
            return "gcode"
    return "gcode"
