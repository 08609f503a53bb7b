"""The kinds of value a request takes, and their checks: shared by the command line's option types
and the job file, so that both accept and refuse the same values with the same words.

Each kind's :meth:`~Kind.check` takes a value as the user wrote it (text from the command line, a
TOML value from a job file) and returns it converted, or raises :class:`ValueProblem` saying what
was found and what is valid; it keeps out what no machine means (``1e308``, ``nan``, ``1_0``), the
library checks what a value means (a depth > 0).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from prs3_post.core.defaults import FEED_RANGE_MM_MIN, MAX_SPINDLE_RPM, MIN_SPINDLE_RPM
from prs3_post.core.errors import quoted

#: The magnitudes a value may have (physically meaningful, with room to spare): (limit, unit).
LENGTH = (1e6, "mm")            # a kilometre
ANGLE = (3600.0, "degrees")     # ten turns
FEED = (FEED_RANGE_MM_MIN[1], "mm/min")  # a kilometre a minute
SPEED = (MAX_SPINDLE_RPM, "rpm")  # spindles reach some 100,000 rpm
TIME = (1e4, "s")               # almost three hours
RATIO = (1e6, "")               # direction components (normalized later)
#: A spindle speed: at least :data:`~prs3_post.core.defaults.MIN_SPINDLE_RPM` (less prints as S0).
SPINDLE_LOW = MIN_SPINDLE_RPM

#: Plain decimal numbers only: ``-12.5``, ``.5``, ``5.``, ``1e-3``; not ``1_0``, ``nan``, ``inf``, ``0x1p3``,
#: ``٣`` or surrounding spaces, which Python's float() would take.
_PLAIN_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_PLAIN_INTEGER = re.compile(r"[+-]?[0-9]+")
_INTEGER_LIMIT = 10**30 - 1


class ValueProblem(ValueError):
    """A value that is not of its kind; the message says what was found and what is valid (no field named)."""


def compact(value: float) -> str:
    """A number for a message: at most 6 significant digits, ``1e+308`` rather than 309 digits."""
    return f"{value:.6g}"


def plain_decimal(text: str) -> float | None:
    """``text`` as a float if it is a plain decimal number, else None."""
    return float(text) if _PLAIN_DECIMAL.fullmatch(text) else None


class Kind:
    """A kind of value: ``name`` as a message calls it, :meth:`check` converts and checks one."""

    name = "text"

    def check(self, value: Any) -> Any:
        return value


@dataclass(frozen=True, slots=True)
class DecimalKind(Kind):
    """A plain, finite decimal number within ``[low, magnitude]`` (default ``low``: ``-magnitude``);
    ``low_open`` excludes ``low`` itself."""

    magnitude: tuple[float, str]
    low: float | None = None
    low_open: bool = False
    name = "number"

    def check(self, value: Any) -> float:
        number = float(value) if isinstance(value, int | float) else plain_decimal(str(value))
        if number is None:
            raise ValueProblem(f"expected a plain decimal number (like 12.5 or -0.25), got {quoted(str(value))}")
        limit, unit = self.magnitude
        low = -limit if self.low is None else self.low
        too_low = number <= low if self.low_open else number < low
        if too_low or not number <= limit:          # `not <=`: also NaN from a default
            unit = f" {unit}" if unit else ""
            allowed = (f"> {compact(low)} and ≤ {compact(limit)}" if self.low_open
                       else f"{compact(low)} to {compact(limit)}")
            raise ValueProblem(f"{compact(number)}{unit} is out of range (allowed: {allowed}{unit})")
        return number


@dataclass(frozen=True, slots=True)
class IntegerKind(Kind):
    """A plain whole number (``12``, ``-3``; not ``1_0``, ``1e3``, ``٣`` or ``+ 1``) within ``[low, high]``.

    Without bounds only a count of digits no controller takes is refused (more than 30), so that no
    message prints a 300-digit number; what the value means is checked where it is used."""

    low: int | None = None
    high: int | None = None
    name = "integer"

    def check(self, value: Any) -> int:
        if isinstance(value, int):
            number = value
        elif _PLAIN_INTEGER.fullmatch(str(value)):
            number = int(str(value))
        else:
            raise ValueProblem(f"expected a whole number (like 12), got {quoted(str(value))}")
        low = -_INTEGER_LIMIT if self.low is None else self.low
        high = _INTEGER_LIMIT if self.high is None else self.high
        if not low <= number <= high:
            shown = str(number) if abs(number) < 10**12 else compact(float(number))
            allowed = f"{low} to {high}" if self.low is not None or self.high is not None else "at most 30 digits"
            raise ValueProblem(f"{shown} is out of range (allowed: {allowed})")
        return number


@dataclass(frozen=True, slots=True)
class NumbersKind(Kind):
    """``X,Y,Z``-style values: a fixed count of comma-separated plain decimal numbers, each within
    ``±magnitude`` (``names`` names them, and the kind)."""

    names: str
    magnitude: tuple[float, str] = LENGTH

    @property
    def name(self) -> str:  # type: ignore[override]
        return self.names

    def check(self, value: Any) -> tuple[float, ...]:
        if isinstance(value, tuple):
            return value
        names = self.names.split(",")
        parts = [plain_decimal(p) for p in str(value).split(",")]
        if len(parts) != len(names) or None in parts:
            raise ValueProblem(f"expected {len(names)} plain decimal numbers {self.names}, got {quoted(str(value))}")
        numbers = tuple(float(p) for p in parts if p is not None)
        limit, unit = self.magnitude
        for name, number in zip(names, numbers, strict=True):
            if not abs(number) <= limit:
                unit = f" {unit}" if unit else ""
                raise ValueProblem(f"{name} = {compact(number)}{unit} is out of range (allowed: within "
                                   f"±{compact(limit)}{unit})")
        return numbers


@dataclass(frozen=True, slots=True)
class ChoiceKind(Kind):
    """One of a few words."""

    choices: tuple[str, ...]
    name = "choice"

    def check(self, value: Any) -> str:
        if value not in self.choices:
            raise ValueProblem(f"expected one of {', '.join(self.choices)}, got {quoted(value)}")
        return str(value)


@dataclass(frozen=True, slots=True)
class FlagKind(Kind):
    """True or false."""

    name = "boolean"


def checked(kind: Kind, value: Any, *, points: bool = False) -> Any:
    """A value as a job file gives it (TOML: a number, a string, a list), checked as the option's own
    value is; ``points``: a list of points of ``kind`` (``at = [[1.0, 2.0]]``).

    Raises
    ------
    ValueProblem
        A value of the wrong TOML type, or one its kind refuses.
    """
    if isinstance(value, bool) and not isinstance(kind, FlagKind):
        raise ValueProblem(f"expected {kind.name}, got {str(value).lower()}")
    if points:                                       # at, at_xyz: a list of points
        if not (isinstance(value, list) and value and all(isinstance(v, list) for v in value)):   # [] is no point
            like = "[[1.0, 2.0, 3.0]]" if kind.name == "X,Y,Z" else "[[1.0, 2.0]]"
            raise ValueProblem(f"expected a list of points like {like}, got {quoted(value)}")
        return tuple(kind.check(",".join(str(x) for x in point)) for point in value)
    if isinstance(kind, DecimalKind | IntegerKind) and isinstance(value, str):
        raise ValueProblem(f"expected a number, got {quoted(value)}")
    return kind.check(value)
