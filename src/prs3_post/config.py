"""Machine and dialect definitions: the only code that parses TOML.

Loading is strict: an unknown or missing key, a wrong type or an out-of-range value is a
:class:`ConfigError` that names the file and the dotted key, e.g.
``machines/patel2020.toml: limits.stroke_mm: expected [min, max] in mm``.

Shipped files live in ``postproc/`` (``machines/*.toml``, ``dialects/*.toml``); they are found in
a checkout (``<repo>/postproc``) and in an installed wheel (``prs3_post/postproc``). A user may
pass a path to a file of their own wherever a shipped name is accepted.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from prs3_post.errors import ConfigError

# ----------------------------------------------------------------------------- shipped files


def postproc_dir() -> Path:
    """The folder holding the shipped ``machines/`` and ``dialects/`` (wheel or checkout)."""
    installed = Path(__file__).resolve().parent / "postproc"
    if installed.is_dir():
        return installed
    return Path(__file__).resolve().parents[2] / "postproc"


def shipped_names(kind: str) -> tuple[str, ...]:
    """Names of the shipped ``kind`` files (``machines`` or ``dialects``), sorted."""
    return tuple(sorted(p.stem for p in (postproc_dir() / kind).glob("*.toml")))


def resolve(kind: str, name_or_path: str) -> Path:
    """A shipped name (``patel2020``) or a path to a TOML file → the file's path.

    Raises
    ------
    ConfigError
        When it is neither a shipped name nor an existing file; the message lists the shipped names.
    """
    shipped = postproc_dir() / kind / f"{name_or_path}.toml"
    if shipped.is_file():
        return shipped
    path = Path(name_or_path)
    if path.is_file():
        return path
    names = ", ".join(shipped_names(kind)) or "none"
    raise ConfigError(f"no such {kind[:-1]} file or shipped name (shipped: {names})", path=name_or_path)


# ----------------------------------------------------------------------------- strict reading


class _Table:
    """A TOML table read strictly: every key must be taken once, and unknown keys are errors."""

    def __init__(self, data: dict[str, Any], path: str, prefix: str = ""):
        self._data, self._path, self._prefix, self._taken = data, path, prefix, set()

    def _error(self, key: str, problem: str) -> ConfigError:
        return ConfigError(f"{self._prefix}{key}: {problem}", path=self._path)

    def _get(self, key: str, default: Any = ...) -> Any:
        self._taken.add(key)
        if key not in self._data:
            if default is ...:
                raise self._error(key, "missing")
            return default
        return self._data[key]

    def table(self, key: str) -> _Table:
        value = self._get(key)
        if not isinstance(value, dict):
            raise self._error(key, "expected a table")
        return _Table(value, self._path, f"{self._prefix}{key}.")

    def text(self, key: str, default: Any = ...) -> str:
        value = self._get(key, default)
        if not isinstance(value, str):
            raise self._error(key, f"expected a string, got {value!r}")
        return value

    def boolean(self, key: str, default: Any = ...) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self._error(key, f"expected true or false, got {value!r}")
        return value

    def integer(self, key: str, default: Any = ..., *, minimum: int | None = None) -> int:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self._error(key, f"expected an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise self._error(key, f"must be ≥ {minimum}, got {value}")
        return value

    def number(self, key: str, default: Any = ..., *, unit: str = "", positive: bool = False) -> float:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self._error(key, f"expected a number{' in ' + unit if unit else ''}, got {value!r}")
        if positive and value <= 0:
            raise self._error(key, f"must be > 0{' ' + unit if unit else ''}, got {value}")
        return float(value)

    def numbers(self, key: str, count: int, what: str, default: Any = ...) -> tuple[float, ...]:
        value = self._get(key, default)
        ok = isinstance(value, list) and len(value) == count and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
        )
        if not ok:
            raise self._error(key, f"expected {what}, got {value!r}")
        return tuple(float(v) for v in value)

    def range(self, key: str, unit: str) -> tuple[float, float]:
        low, high = self.numbers(key, 2, f"[min, max] in {unit}")
        if not low < high:
            raise self._error(key, f"min must be < max, got [{low:g}, {high:g}]")
        return low, high

    def strings(self, key: str, default: Any = ...) -> tuple[str, ...]:
        value = self._get(key, default)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self._error(key, f"expected a list of strings, got {value!r}")
        return tuple(value)

    def finish(self) -> None:
        """Raise on the first key nobody asked for (a typo must not be ignored)."""
        unknown = sorted(set(self._data) - self._taken)
        if unknown:
            raise self._error(unknown[0], "unknown key")


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as stream:
            return tomllib.load(stream)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=str(path)) from exc
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror}", path=str(path)) from exc


def _display(path: Path) -> str:
    """``machines/patel2020.toml`` for shipped files, the path as given otherwise."""
    try:
        return str(path.resolve().relative_to(postproc_dir().resolve()))
    except ValueError:
        return str(path)


# ----------------------------------------------------------------------------- machines


@dataclass(frozen=True, slots=True)
class Geometry:
    """The head's dimensions (mm, rad). Symbols from the paper in quotes.

    Attributes
    ----------
    leg_azimuth : (3,) tuple — rad, azimuth α of legs 1, 2, 3, 120° apart, counter-clockwise
    guide_radius : float — mm, "K": horizontal distance from the base centre to each revolute axis
    link_length : float — mm, "U": revolute-to-spherical link length
    platform_radius : float — mm, "r_p = q/√3": circumradius of the spherical-joint triangle
    tool_length : float — mm, "TL": platform centre to tool tip along the tool axis
    """

    leg_azimuth: tuple[float, float, float]
    guide_radius: float
    link_length: float
    platform_radius: float
    tool_length: float

    def __post_init__(self) -> None:
        for name in ("guide_radius", "link_length", "platform_radius", "tool_length"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")

    @property
    def layout_offset(self) -> float:
        """rad, how far the leg layout is turned from the reference 210°/330°/90° (legs 1, 2, 3)."""
        return self.leg_azimuth[0] - math.radians(210.0)


@dataclass(frozen=True, slots=True)
class Limits:
    """Per-point limits, checked on every emitted point (mm, rad).

    Attributes
    ----------
    stroke : (min, max) mm — each actuator stroke T_i
    link_angle : (min, max) rad — each link's angle θ_i from horizontal
    max_tilt : float — rad, tool-axis angle from vertical
    max_condition : float — actuator-Jacobian 2-norm condition number (distance to singularity)
    """

    stroke: tuple[float, float]
    link_angle: tuple[float, float]
    max_tilt: float
    max_condition: float


@dataclass(frozen=True, slots=True)
class Stage:
    """The XY stage under the part (absent on a pure head).

    Attributes
    ----------
    present : bool — the machine has an XY stage
    travel_x, travel_y : (min, max) mm — stage travel (only when present)
    """

    present: bool
    travel_x: tuple[float, float] = (0.0, 0.0)
    travel_y: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Machine:
    """A whole machine file: head geometry, limits, stage and default setup.

    Attributes
    ----------
    name : str — the file's stem (``patel2020``)
    description : str — one line for ``prs3-post machines``
    source : str — where it was loaded from, as shown in messages
    geometry, limits, stage : see their classes
    part_origin : (3,) tuple — mm, machine coordinates of the part origin in the default setup
    """

    name: str
    description: str
    source: str
    geometry: Geometry
    limits: Limits
    stage: Stage
    part_origin: tuple[float, float, float]


def load_machine(name_or_path: str) -> Machine:
    """Load a shipped machine by name or a machine TOML file by path, strictly.

    Raises
    ------
    ConfigError
        ``file: dotted.key: problem`` for anything missing, unknown, mistyped or out of range,
        and for a geometry that cannot assemble.
    """
    path = resolve("machines", name_or_path)
    shown = _display(path)
    top = _Table(_read_toml(path), shown)
    description = top.text("description")

    geo = top.table("geometry")
    azimuth_deg = geo.numbers("leg_azimuth_deg", 3, "[α1, α2, α3] in degrees")
    spacing = [(azimuth_deg[(i + 1) % 3] - azimuth_deg[i]) % 360.0 for i in range(3)]
    if not all(abs(s - 120.0) < 1e-9 for s in spacing):
        raise ConfigError(
            "geometry.leg_azimuth_deg: legs must be 120° apart and counter-clockwise in order 1, 2, 3 "
            f"(e.g. [210, 330, 90]), got {list(azimuth_deg)}",
            path=shown,
        )
    guide_radius = geo.number("guide_radius_mm", unit="mm", positive=True)
    link_length = geo.number("link_length_mm", unit="mm", positive=True)
    platform_radius = geo.number("platform_circumradius_mm", unit="mm", positive=True)
    tool_length = geo.number("tool_length_mm", unit="mm", positive=True)
    geo.finish()
    if abs(guide_radius - platform_radius) >= link_length:
        raise ConfigError(
            "geometry: cannot assemble: |guide_radius_mm - platform_circumradius_mm| = "
            f"{abs(guide_radius - platform_radius):g} mm must be < link_length_mm = {link_length:g} mm",
            path=shown,
        )
    geometry = Geometry(
        leg_azimuth=tuple(math.radians(a) for a in azimuth_deg),  # type: ignore[arg-type]
        guide_radius=guide_radius,
        link_length=link_length,
        platform_radius=platform_radius,
        tool_length=tool_length,
    )

    lim = top.table("limits")
    stroke = lim.range("stroke_mm", "mm")
    link_angle_deg = lim.range("link_angle_deg", "degrees")
    if not (0.0 < link_angle_deg[0] and link_angle_deg[1] < 90.0):
        raise ConfigError(
            f"limits.link_angle_deg: must lie inside (0, 90) degrees, got {list(link_angle_deg)}", path=shown
        )
    max_tilt_deg = lim.number("max_tilt_deg", unit="degrees", positive=True)
    if max_tilt_deg >= 90.0:
        raise ConfigError(f"limits.max_tilt_deg: must be < 90 degrees, got {max_tilt_deg:g}", path=shown)
    max_condition = lim.number("max_condition")
    if max_condition < 1.0:
        raise ConfigError(f"limits.max_condition: must be ≥ 1, got {max_condition:g}", path=shown)
    lim.finish()
    limits = Limits(
        stroke=stroke,
        link_angle=(math.radians(link_angle_deg[0]), math.radians(link_angle_deg[1])),
        max_tilt=math.radians(max_tilt_deg),
        max_condition=max_condition,
    )

    stg = top.table("stage")
    if stg.boolean("present"):
        stage = Stage(True, stg.range("travel_x_mm", "mm"), stg.range("travel_y_mm", "mm"))
    else:
        stage = Stage(False)
    stg.finish()

    setup = top.table("setup")
    part_origin = setup.numbers("part_origin_mm", 3, "[x, y, z] in mm")
    setup.finish()
    top.finish()
    return Machine(
        name=path.stem,
        description=description,
        source=shown,
        geometry=geometry,
        limits=limits,
        stage=stage,
        part_origin=part_origin,  # type: ignore[arg-type]
    )
