"""Read a tool table in LinuxCNC's ``tool.tbl`` format: each tool's number, pocket, diameter and length.

One tool per line, words separated by blanks, in any order and either case, then an optional
comment after ``;``::

    T1 P1 D6.000 Z52.300 ;6 mm drill
    T2 P2 D8.000 Z+71.250 ;8 mm end mill

What LinuxCNC writes and reads there (its ``tooldata`` format): ``T`` tool number, ``P`` pocket,
``X Y Z A B C U V W`` offsets, ``D`` diameter, ``I J`` front and back angle and ``Q`` orientation
(lathe tools). This reader takes all of them, and refuses what makes no sense on a 3-PRS head:

- ``Z`` is the tool's own length, mm, from the spindle's gauge line to the tip; the inverse
  kinematics puts the tip at the machine's gauge offset plus this length from the platform centre.
  It must be given and > 0 (a negative length, or an offset from a master tool, is not a length).
- ``D`` (diameter, mm, ≥ 0) must be given: the job checks it against each operation's tool.
- An offset on ``X Y A B C U V W`` other than 0 is refused: the tip is on the spindle axis here,
  and U, V, W are this machine's actuators.
- ``T0`` is refused: it means "no tool" to LinuxCNC, and a job's tool numbers start at 1.
- ``I J Q`` (lathe tool angles and orientation) are range-checked (±360°, 0 to 9) and ignored.
- Numbers may have an exponent (``Z5.23e1``). Each value must lie in its range (a length or a
  diameter at most 10 m, a tool or pocket number at most 99999999); a word is at most 32 characters.

Blank lines and lines with only a comment are skipped. Lengths are in mm (the programs are G21).
Every problem is an :class:`~prs3_post.core.errors.InputError` naming ``file:line``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from prs3_post.core.errors import InputError
from prs3_post.core.input_files import open_input

#: Letters of LinuxCNC's tool table, in the order of its documentation.
LETTERS = "TPXYZABCUVWDIJQ"
#: Offsets that must be 0 here (the tip is on the spindle axis; U, V, W are the actuators).
ZERO_OFFSETS = "XYABCUVW"
#: Largest tool number (LinuxCNC's T words, as the dialects' words.tool_number_max).
MAX_TOOL_NUMBER = 99_999_999
#: mm, the largest length or diameter read (a metre is already no tool).
MAX_LENGTH_MM = 1e4
#: Degrees, the largest front or back angle (``I``, ``J``) of a lathe tool.
MAX_ANGLE_DEG = 360.0
#: The largest orientation ``Q`` (LinuxCNC's lathe tool orientations are 0 to 9).
MAX_ORIENTATION = 9
#: Characters in the longest word read (a letter and its number): no value a tool table means needs more.
MAX_WORD = 32

#: A decimal number as LinuxCNC's reader takes it, with an optional exponent (``52.3``, ``+.5``, ``1e2``).
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")


@dataclass(frozen=True, slots=True)
class Tool:
    """One line of a tool table.

    Attributes
    ----------
    number : int — ``T``, ≥ 1
    pocket : int | None — ``P`` (None: not given)
    diameter : float — mm, ``D``
    length : float — mm, ``Z``: gauge line to tip
    comment : str — the text after ``;``, stripped
    line : int — 1-based line in the file
    """

    number: int
    pocket: int | None
    diameter: float
    length: float
    comment: str = ""
    line: int = 0


@dataclass(frozen=True, slots=True)
class ToolTable:
    """A tool table's tools, in file order.

    Attributes
    ----------
    path : str — the file, as given (or the program whose header recorded the tools)
    tools : tuple of Tool
    """

    path: str
    tools: tuple[Tool, ...]

    def find(self, number: int) -> Tool | None:
        """The tool numbered ``number``, or None."""
        return next((tool for tool in self.tools if tool.number == number), None)


def read_tool_table(path: str) -> ToolTable:
    """Read and check a tool table file (the module docstring gives the format).

    Raises
    ------
    InputError
        ``file:line: what is wrong`` for an unknown letter, a word that is not a number, a word
        given twice, a missing ``T``, ``D`` or ``Z``, a negative or zero length, a nonzero
        X Y A B C U V W offset, ``T0``, or a tool number that appears twice.
    """
    with open_input(path, "a tool table") as stream:
        try:
            data = stream.read()
        except OSError as exc:
            raise InputError(f"cannot read the file: {exc.strerror or exc}", path=path) from exc
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a text file (byte {exc.start} is not UTF-8): give a LinuxCNC tool table",
                         path=path) from exc
    return parse_tool_table(text, path=path)


def parse_tool_table(text: str, *, path: str) -> ToolTable:
    """The tools of a tool table's text (see :func:`read_tool_table`)."""
    tools: list[Tool] = []
    first: dict[int, int] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        code, _, comment = raw.partition(";")
        if not code.strip():
            continue
        tool = _tool(code, comment.strip(), path, number)
        if tool.number in first:
            raise InputError(f"T{tool.number} appears twice (first on line {first[tool.number]}): each tool "
                             "number once", path=path, line=number)
        first[tool.number] = number
        tools.append(tool)
    if not tools:
        raise InputError("no tools (a LinuxCNC tool table has lines like 'T1 P1 D6.0 Z52.3 ;6 mm drill')", path=path)
    return ToolTable(path=path, tools=tuple(tools))


#: A valid value of each letter, for messages.
_EXAMPLE = {"T": "1", "P": "1", "D": "6.0", "Z": "6.0", "I": "95.0", "J": "155.0", "Q": "1"} | dict.fromkeys(
    ZERO_OFFSETS, "0")
#: The lathe letters' ranges (low, high, what), read only to be checked.
_LATHE_RANGES = {"I": (-MAX_ANGLE_DEG, MAX_ANGLE_DEG, "front angle in degrees"),
                 "J": (-MAX_ANGLE_DEG, MAX_ANGLE_DEG, "back angle in degrees"),
                 "Q": (0.0, float(MAX_ORIENTATION), "orientation")}


def _cut(word: str) -> str:
    """A word for a message: at most 24 characters (``Z100000000000000000000…``)."""
    return word if len(word) <= 24 else word[:23] + "…"


def _tool(code: str, comment: str, path: str, line: int) -> Tool:
    words: dict[str, str] = {}
    for word in code.split():
        letter, value = word[0].upper(), word[1:]
        if letter not in LETTERS:
            raise InputError(f"unknown letter {word[0]!r} in {_cut(word)!r} (allowed: {' '.join(LETTERS)}, and ; "
                             "before a comment)", path=path, line=line)
        if len(word) > MAX_WORD:
            raise InputError(f"{_cut(word)!r} ({len(word)} characters): a tool table's word is at most {MAX_WORD} "
                             f"characters (like {letter}{_EXAMPLE[letter]})", path=path, line=line)
        if letter in words:
            raise InputError(f"{letter} given twice ({letter}{words[letter]} and {word})", path=path, line=line)
        integer = letter in "TP"
        if not (_INTEGER if integer else _NUMBER).fullmatch(value):
            raise InputError(f"{word!r}: expected {letter} and {'a whole number' if integer else 'a number'} "
                             f"(like {letter}{_EXAMPLE[letter]})", path=path, line=line)
        words[letter] = value
    for letter, what in (("T", "tool number"), ("D", "diameter"), ("Z", "length")):
        if letter not in words:
            raise InputError(f"no {letter} ({what}): every tool needs T, D and Z (like 'T1 P1 D6.0 Z52.3')",
                             path=path, line=line)
    tool = int(words["T"])
    if not 1 <= tool <= MAX_TOOL_NUMBER:
        raise InputError(f"T{words['T']}: tool numbers are 1 to {MAX_TOOL_NUMBER} (T0 is LinuxCNC's 'no tool')",
                         path=path, line=line)
    pocket = int(words["P"]) if "P" in words else None
    if pocket is not None and not 0 <= pocket <= MAX_TOOL_NUMBER:
        raise InputError(f"P{words['P']}: pocket numbers are 0 to {MAX_TOOL_NUMBER}", path=path, line=line)
    diameter, length = float(words["D"]), float(words["Z"])
    if not 0.0 <= diameter <= MAX_LENGTH_MM:
        raise InputError(f"D{words['D']}: the diameter must be 0 to {MAX_LENGTH_MM:g} mm", path=path, line=line)
    if length < 0.0:
        raise InputError(f"Z{words['Z']}: negative tool length (Z is the tool's length from the spindle's gauge "
                         "line to its tip, > 0 mm)", path=path, line=line)
    if not 0.0 < length <= MAX_LENGTH_MM:
        raise InputError(f"Z{words['Z']}: the tool length must be > 0 and ≤ {MAX_LENGTH_MM:g} mm", path=path,
                         line=line)
    for letter in ZERO_OFFSETS:
        if letter in words and float(words[letter]) != 0.0:
            raise InputError(f"{letter}{words[letter]}: a tool offset on {letter} makes no sense on a 3-PRS head "
                             f"(the tip is on the spindle axis; U, V, W are its actuators): only Z may be nonzero",
                             path=path, line=line)
    for letter, (low, high, what) in _LATHE_RANGES.items():
        if letter in words and not low <= float(words[letter]) <= high:
            raise InputError(f"{letter}{words[letter]}: the {what} must be {low:g} to {high:g} (read and ignored "
                             "here, but no tool has such a value)", path=path, line=line)
    return Tool(number=tool, pocket=pocket, diameter=diameter, length=length, comment=comment, line=line)
