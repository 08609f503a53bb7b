"""Source conventions: how a 5-axis G-code program written for another machine gives its tool axis.

The types are loaded from ``postproc/sources/*.toml`` by :func:`prs3_post.machine.loading.load_source`.
Under tool-centre-point control (TCP) X Y Z are the tool tip in the part frame, and the tool's
orientation comes either from the rotary words (A, B, C) through the source machine's chain of
rotary axes, or from a tool vector on every motion block (I J K). Either way the tool axis in the
part frame is a pure function of the words (:meth:`SourceConvention.axes_from_rotary`): the
source machine's pivot offsets do not enter, because under TCP the controller compensates them.

Frames and the rotary chain
---------------------------
The source machine's frame: at every rotary's zero the part frame and the machine frame are
parallel, and the tool points down, its axis (tip → spindle) is +z. Each rotary turns about a
fixed direction ``axis`` given in that all-zero configuration. A word value ``w`` turns the rotary
by ``θ = sign · (w − zero_deg)``, right-handed about ``axis``:

- tables (the part moves), listed from the bed outwards (the first is mounted on the bed, the last
  carries the part): a part direction ``d`` is ``T1(θ1)·T2(θ2)··· d`` in the machine frame;
- heads (the tool moves), listed from the ram to the spindle: the tool axis in the machine frame
  is ``H1(φ1)·H2(φ2)··· z``;

so that the tool axis in the part frame is ``(T1·T2···)ᵀ · H1·H2··· · z``.

ISO 841 names the positive direction of A, B, C by the tool's motion relative to the part
(right-handed about +X, +Y, +Z). A head that follows it has ``sign = 1``; a table that follows it
turns itself the other way, ``sign = -1`` (the Haas UMC-750's trunnion and platter, proven against
its CL source in tests/test_fiveaxis.py). LinuxCNC's ``xyzac-trt-kins`` turns its tables
right-handed (``sign = 1``).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import FloatArray

__all__ = ["NOT_QUIET", "NOT_QUIET_SHOWN", "Orientation", "Rotary", "SourceConvention", "rotations"]


#: Codes a source may not list as clamps or inert codes (``codes.clamps``, ``codes.inert``), with what
#: each is. The reader drops such codes from their blocks: a motion code would leave the moves it
#: starts in the previous motion (every cut a rapid), a feed mode would leave the feeds misread, a
#: program end would be lost (and what follows it read).
NOT_QUIET: dict[str, str] = {
    **dict.fromkeys(("G0", "G1", "G2", "G3", "G73", *(f"G{n}" for n in range(80, 90))), "a motion code"),
    **dict.fromkeys(("G93", "G94", "G95"), "a feed mode"),
    **dict.fromkeys(("M2", "M30"), "a program end"),
}
#: :data:`NOT_QUIET` as messages list it.
NOT_QUIET_SHOWN = "no motion code G0-G3, G73, G80-G89, no feed mode G93-G95, no program end M2, M30"


class Orientation(enum.Enum):
    """Where a program's tool orientation comes from."""

    ROTARY = "rotary"
    """Rotary words (A, B, C) through the source machine's chain of rotary axes."""
    VECTOR = "vector"
    """A tool vector (tip → spindle) on the motion blocks, e.g. I J K."""


@dataclass(frozen=True, slots=True)
class Rotary:
    """One rotary axis of the source machine.

    Attributes
    ----------
    word : str — its letter, ``A``, ``B`` or ``C``
    table : bool — True: it turns the part (a table); False: it turns the tool (a head)
    axis : (3,) tuple — unit direction it turns about, machine frame at every rotary's zero
    sign : int — 1: a growing word turns it right-handed about ``axis``; -1: left-handed
    zero_deg : float — the word value at which it is at its zero
    """

    word: str
    table: bool
    axis: tuple[float, float, float]
    sign: int
    zero_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.word not in ("A", "B", "C"):
            raise ValueError(f"Rotary: word must be A, B or C, got {self.word!r}")
        if self.sign not in (1, -1):
            raise ValueError(f"Rotary: sign must be 1 or -1, got {self.sign!r}")
        if abs(math.hypot(*self.axis) - 1.0) > 1e-12:
            raise ValueError(f"Rotary: axis must be a unit vector, got {self.axis!r}")


@dataclass(frozen=True, slots=True)
class SourceConvention:
    """A source machine's 5-axis convention (see the module docstring).

    Attributes
    ----------
    name : str — the file's stem (``haas-umc750``)
    description : str — one line
    source : str — the file as shown in messages (``sources/haas-umc750.toml``)
    orientation : Orientation
    tables : tuple of Rotary — from the bed outwards (ROTARY only)
    heads : tuple of Rotary — from the ram to the spindle (ROTARY only)
    vector_words : tuple of str — the letters of the tool vector's x, y, z (VECTOR only)
    tcp_on, tcp_off : tuple of str — the codes that switch TCP on and off (``G43.4``, ``M428``)
    clamps : tuple of str — axis clamp and unclamp codes (nothing to do on a 3-PRS machine)
    inert : tuple of str — other codes read and counted that change nothing in a conversion
    """

    name: str
    description: str
    source: str
    orientation: Orientation
    tables: tuple[Rotary, ...]
    heads: tuple[Rotary, ...]
    vector_words: tuple[str, ...]
    tcp_on: tuple[str, ...]
    tcp_off: tuple[str, ...]
    clamps: tuple[str, ...] = ()
    inert: tuple[str, ...] = ()

    @property
    def words(self) -> str:
        """The rotary letters, tables then heads in chain order (``BC``); empty for a vector source."""
        return "".join(r.word for r in (*self.tables, *self.heads))

    def axes_from_rotary(self, values_deg: FloatArray) -> FloatArray:
        """The tool axis in the part frame for rotary word values.

        Parameters
        ----------
        values_deg : (N, k) float — degrees, one column per letter of :attr:`words`, as written

        Returns
        -------
        axis : (N, 3) float — unit, tip → spindle, part frame

        >>> from prs3_post.machine.cam_conventions import Rotary, SourceConvention, Orientation
        >>> b = Rotary("B", True, (0.0, 1.0, 0.0), -1)
        >>> c = Rotary("C", True, (0.0, 0.0, 1.0), -1)
        >>> s = SourceConvention("t", "", "", Orientation.ROTARY, (b, c), (), (), ("G234",), ("G49",))
        >>> s.axes_from_rotary(np.array([[90.0, 90.0]])).round(12).tolist()
        [[0.0, 1.0, 0.0]]
        """
        values = np.asarray(values_deg, dtype=np.float64).reshape(len(values_deg), -1)
        chain = (*self.tables, *self.heads)
        if values.shape[1] != len(chain):
            raise ValueError(f"axes_from_rotary: expected {len(chain)} columns ({self.words}), got {values.shape[1]}")
        n = len(values)
        table = np.broadcast_to(np.eye(3), (n, 3, 3))
        head = np.broadcast_to(np.eye(3), (n, 3, 3))
        for column, rotary in enumerate(chain):
            turn = rotations(rotary.axis, rotary.sign * np.radians(values[:, column] - rotary.zero_deg))
            if rotary.table:
                table = table @ turn
            else:
                head = head @ turn
        tool = head[:, :, 2]                                        # H1·H2···z, machine frame
        return np.einsum("nji,nj->ni", table, tool)                 # (T1·T2···)ᵀ applied


def rotations(axis: tuple[float, float, float], angle: FloatArray) -> FloatArray:
    """Rotation matrices about a unit ``axis`` by ``angle`` (N,) rad, right-handed (Rodrigues).

    Returns
    -------
    (N, 3, 3) float

    >>> rotations((0.0, 0.0, 1.0), np.array([np.pi / 2]))[0].round(12).tolist()
    [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    """
    u = np.asarray(axis, dtype=np.float64)
    cross = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    angle = np.asarray(angle, dtype=np.float64).reshape(-1)
    sin, cos = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + sin * cross + (1.0 - cos) * (cross @ cross)
