"""The G-code the 3+2 reader reads: its codes and their modal groups, the letters, what a word is for, and
one line's words sorted by kind (see :mod:`prs3_post.readers.gcode.reader`)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from prs3_post.core.toolpath import MoveKind
from prs3_post.core.types import FloatArray
from prs3_post.toolpaths.cycles import Pecking

#: mm, how far above the previous depth a peck's rapid stops (G83), or how far G73 lifts: LinuxCNC's
#: ``delta`` of 0.010 inch.
PECK_GAP_MM = 0.254
#: FANUC's G68.2 P3: the x direction and the normal must be 85° to 95° apart.
P3_MAX_COSINE = math.cos(math.radians(85.0))
RAPID, FEED = int(MoveKind.RAPID), int(MoveKind.FEED)

# G codes by modal group (the value as a float: G68.2 is 68.2)
G_GROUPS: dict[float, str] = {
    0: "motion", 1: "motion", 2: "motion", 3: "motion", 80: "motion", 81: "motion", 82: "motion",
    83: "motion", 73: "motion", 4: "dwell", 17: "plane", 18: "plane", 19: "plane", 20: "units", 21: "units",
    90: "distance", 91: "distance", 93: "feed mode", 94: "feed mode", 98: "return", 99: "return",
    68.2: "tilt", 69: "tilt", 53.1: "tilt", 40: "compensation", 43: "length offset", 49: "length offset",
    54: "coordinate system", 91.1: "arc distance",
}
M_GROUPS: dict[float, str] = {
    0: "stop", 1: "stop", 2: "stop", 30: "stop", 3: "spindle", 4: "spindle", 5: "spindle", 6: "tool change",
    7: "coolant", 8: "coolant", 9: "coolant",
}
CODES_READ = ("G0 G1 G2 G3 G4 G17 G18 G19 G20 G21 G40 G43 G49 G53.1 G54 G68.2 G69 G73 G80 G81 G82 G83 G90 "
               "G91 G91.1 G93 G94 G98 G99; M0 M1 M2 M3 M4 M5 M6 M7 M8 M9 M30")
#: Why some codes CAM posts write are not read (the message says it before the codes that are).
HINTS = {
    **dict.fromkeys(("G28", "G30"), "a return to the machine's reference point is no position on the part; "
                    "leave it out (the converted program starts and ends at the machine's safe position)"),
    "G53": "machine coordinates are no position on the part",
    **dict.fromkeys(("G43.4", "G43.5", "G234", "M428"), "tool centre point control belongs to 5-axis programs"),
    **dict.fromkeys(("G41", "G42"), "cutter compensation: have the CAM system write the tool centre path"),
    **dict.fromkeys(("G10", "G52", "G92"), "an offset set by the program; put the coordinates in the work plane"),
    "G95": "feed per revolution: have the CAM system write a feed per minute (G94)",
    "G90.1": "absolute arc centres: have the CAM system write I J K relative to the start (G91.1)",
}
VALUE_LETTERS = "XYZIJKRPQFSTH"
WORDS_READ = "G M N X Y Z I J K R P Q F S T H; O alone on its line"
CYCLES = {81.0: Pecking.NONE, 82.0: Pecking.NONE, 83.0: Pecking.FULL_RETRACT, 73.0: Pecking.CHIP_BREAK}
#: The letters of the bulk path, in the order a regular motion line writes them.
BULK_LETTERS = "NGXYZF"
#: A blank line, or one with only comments (closed, not nested), which the bulk path passes as events.
QUIET = re.compile(r"[ \t]*(?:\([^()]*\)[ \t]*)*(?:;.*)?")
#: A line that is one comment in parentheses, nothing else: its text (what split_comments reads there).
ONE_COMMENT = re.compile(r"\(([^()]*)\)")
#: A rotary word (A, B, C and a number) somewhere in a line: a 5-axis program (checked on the code
#: without comments).
ROTARY = re.compile(r"(?<![A-Za-z_<\[#])([ABCabc])[ \t]*(-?[ \t]*[0-9.][0-9. \t]*)")
ROTARY_HINT = re.compile(r"[ABCabc][ \t]*-?[ \t]*[0-9.]")
# the plane of G17, G18, G19: (first, second, normal) axis indexes, right-handed (first × second = normal)
PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
AXES = "XYZ"
OFFSETS = "IJK"


# --------------------------------------------------------------------------------------------
# Interpretation
# --------------------------------------------------------------------------------------------
@dataclass(slots=True)
class Block:
    """One line's words, sorted by kind (value: as written, text: for messages)."""

    g: dict[str, tuple[float, str]] = field(default_factory=dict)      # group → (code value, text)
    m: dict[str, tuple[float, str]] = field(default_factory=dict)
    values: dict[str, tuple[float, str]] = field(default_factory=dict)  # letter → (value, text)
    used: set[str] = field(default_factory=set)

    def take(self, letter: str) -> float | None:
        """The value of ``letter``'s word (None without one), marked as used."""
        word = self.values.get(letter)
        if word is None:
            return None
        self.used.add(letter)
        return word[0]


@dataclass(slots=True)
class Cycle:
    """The active canned cycle: its code, sticky words (program units as written) and where it began."""

    code: float
    line: int
    initial_z: float                  # mm, plane coordinates: the level where the cycle began (G98)
    fresh: bool = True                # after G80 or another motion code (not another cycle code): the
                                      # first hole starts by going up to R if below it
    z: float | None = None            # the sticky words, as written
    r: float | None = None
    q: float | None = None
    p: float | None = None
    holes: int = 0


@dataclass(slots=True)
class PendingP3:
    line: int
    text: str
    origin: FloatArray                # mm, outer plane
    x_direction: FloatArray


#: What each value word is for, for the message about a word no code on its line uses.
USES = {
    "X": "X Y Z go with a motion code or G68.2", "Y": "X Y Z go with a motion code or G68.2",
    "Z": "X Y Z go with a motion code or G68.2", "I": "I J K go with G2/G3 or G68.2",
    "J": "I J K go with G2/G3 or G68.2", "K": "I J K go with G2/G3 or G68.2",
    "R": "R goes with G2/G3 or a canned cycle", "P": "P goes with G4, G82, G2/G3 (turns) or G68.2",
    "Q": "Q goes with G83/G73 or G68.2 P3", "H": "H goes with G43",
}
