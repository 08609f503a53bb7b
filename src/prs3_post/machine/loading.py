"""Machine and dialect files: the only code that parses TOML.

The types they load into are defined in :mod:`prs3_post.machine.model` and :mod:`prs3_post.machine.dialect`
(re-exported here), so that code that only uses them (the kinematics, the emitter) does not
depend on the TOML reader.

Loading is strict: an unknown or missing key, a wrong type or an out-of-range value is a
:class:`ConfigError` that names the file and the dotted key, e.g.
``machines/patel2020.toml: limits.stroke_mm: expected [min, max] in mm``.

Shipped files live in ``postproc/`` (``machines/*.toml``, ``dialects/*.toml``); they are found in
a checkout (``<repo>/postproc``) and in an installed wheel (``prs3_post/postproc``). A user may
pass a path to a file of their own wherever a shipped name is accepted.
"""

from __future__ import annotations

import math
import re
import stat
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.core.errors import ConfigError, FieldError, InputError, quoted, shortened
from prs3_post.core.input_files import read_text
from prs3_post.core.lexer import code_name
from prs3_post.machine.controller_rules import block_problem
from prs3_post.machine.dialect import (
    AXIS_LETTERS,
    COMMENT_CONTINUATION,
    DWELL_UNITS,
    END_CODES,
    LINE_ENDINGS,
    TOOL_NUMBER_LIMIT,
    AxisLetters,
    CommentStyle,
    Decimals,
    Dialect,
    LineNumbers,
)
from prs3_post.machine.model import (
    DEFAULT_KINEMATICS,
    GENERAL_KINEMATICS,
    KINEMATICS_NAMES,
    Calibration,
    Dynamics,
    GeneralGeometry,
    Geometry,
    Holder,
    LegGeometry,
    Limits,
    Machine,
    Stage,
    general_from_ideal,
)

# The five-axis source conventions (only `convert` and a converted program's check need them) load in load_source.
if TYPE_CHECKING:
    from prs3_post.machine.cam_conventions import Rotary, SourceConvention

__all__ = [
    "AXIS_LETTERS",
    "DEFAULT_DIALECT",
    "DEFAULT_MACHINE",
    "TOOL_NUMBER_LIMIT",
    "AxisLetters",
    "CommentStyle",
    "Decimals",
    "Dialect",
    "Dynamics",
    "Geometry",
    "Holder",
    "Limits",
    "LineNumbers",
    "Machine",
    "Stage",
    "load_dialect",
    "load_machine",
    "load_source",
    "postproc_dir",
    "read_toml",
    "resolve",
    "shipped_names",
]

# ----------------------------------------------------------------------------- shipped files

#: The machine a command uses when none is given (``--machine``; a program without a header is read for it).
DEFAULT_MACHINE = "patel2020"
#: The dialect a command uses when none is given (``--dialect``; a program without a header is read in it).
DEFAULT_DIALECT = "linuxcnc"


def postproc_dir() -> Path:
    """The folder holding the shipped ``machines/`` and ``dialects/`` (wheel or checkout)."""
    installed = Path(__file__).resolve().parents[1] / "postproc"
    if installed.is_dir():
        return installed
    return Path(__file__).resolve().parents[3] / "postproc"


def shipped_names(kind: str) -> tuple[str, ...]:
    """Names of the shipped ``kind`` files (``machines`` or ``dialects``), sorted."""
    return tuple(sorted(p.stem for p in (postproc_dir() / kind).glob("*.toml")))


def resolve(kind: str, name_or_path: str) -> Path:
    """A shipped name (``patel2020``) or a path to a TOML file → the file's path.

    Raises
    ------
    ConfigError
        When it is neither a shipped name nor an existing file (a folder or a FIFO is named as such);
        the message lists the shipped names.
    FieldError
        An empty name (or only spaces), as the value of the key ``kind`` names (``machine``, ``dialect``,
        ``source``): it names no file (a path of the current folder, which is no TOML file).
    """
    if not name_or_path.strip():
        names = ", ".join(shipped_names(kind)) or "none"
        raise FieldError(f"{'empty' if not name_or_path else 'blank'} name (valid: a shipped {kind[:-1]} name: "
                         f"{names}; or the path of a {kind[:-1]} TOML file)", field=kind[:-1])
    shipped = postproc_dir() / kind / f"{name_or_path}.toml"
    if stat.S_ISREG(_mode(shipped, name_or_path)):
        return shipped
    path = Path(name_or_path)
    mode = _mode(path, name_or_path)
    if stat.S_ISREG(mode):
        return path
    names = ", ".join(shipped_names(kind)) or "none"
    if mode:
        what = f"a folder, not a {kind[:-1]} file" if stat.S_ISDIR(mode) else "not a regular file"
        raise ConfigError(f"is {what}: give a {kind[:-1]} TOML file or a shipped name (shipped: {names})",
                          path=name_or_path)
    raise ConfigError(f"no such {kind[:-1]} file or shipped name (shipped: {names})", path=name_or_path)


def _mode(path: Path, given: str) -> int:
    """``st_mode`` of ``path`` (0 when nothing is there); a name the system cannot look up is a ConfigError."""
    try:
        return path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        return 0
    except OSError as exc:                             # a name too long, a loop of symlinks, no permission
        raise ConfigError(f"cannot read the file: {exc.strerror or exc}", path=given) from exc


#: The shortest ``program.max_line_length`` of a dialect: a header line must hold its fixed fields' words
#: whole (verify reads them back), and a motion block its five axis words and F.
MIN_LINE_LENGTH = 80
#: Hex digits of a SHA-256, the longest word of a header's fixed fields.
SHA256_DIGITS = 64


# ----------------------------------------------------------------------------- strict reading


#: The largest magnitude a number in a machine, dialect or source file may have (mm, degrees, mm/min,
#: rpm ...): physically meaningful with room to spare, as for the command line's options.
MAX_MAGNITUDE = 1e6


class _Table:
    """A TOML table read strictly: every key must be taken once, and unknown keys are errors."""

    def __init__(self, data: dict[str, Any], path: str, prefix: str = ""):
        self._data, self._path, self._prefix = data, path, prefix
        self._taken: set[str] = set()

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
            raise self._error(key, f"expected a string, got {quoted(value)}")
        return value

    def boolean(self, key: str, default: Any = ...) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self._error(key, f"expected true or false, got {quoted(value)}")
        return value

    def integer(self, key: str, default: Any = ..., *, minimum: int | None = None) -> int:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self._error(key, f"expected an integer, got {quoted(value)}")
        if minimum is not None and value < minimum:
            raise self._error(key, f"must be ≥ {minimum}, got {value}")
        return value

    def number(self, key: str, default: Any = ..., *, unit: str = "", positive: bool = False,
               within: tuple[float, float] | None = None) -> float:
        """A finite number within ±:data:`MAX_MAGNITUDE`; ``positive``: > 0; ``within``: also in ``[low, high]``."""
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise self._error(key, f"expected a number{' in ' + unit if unit else ''}, got {quoted(value)}")
        if abs(value) > MAX_MAGNITUDE:
            raise self._error(key, f"{value:.6g}{' ' + unit if unit else ''} is out of range "
                                   f"(allowed: within ±{MAX_MAGNITUDE:.6g}{' ' + unit if unit else ''})")
        if positive and value <= 0:
            raise self._error(key, f"must be > 0{' ' + unit if unit else ''}, got {value}")
        if within is not None and not within[0] <= value <= within[1]:
            raise self._error(key, f"{value:.6g}{' ' + unit if unit else ''} is out of range "
                                   f"(allowed: {within[0]:g} to {within[1]:g}{' ' + unit if unit else ''})")
        return float(value)

    def numbers(self, key: str, count: int, what: str, default: Any = ...) -> tuple[float, ...]:
        value = self._get(key, default)
        ok = isinstance(value, list) and len(value) == count and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
        )
        if not ok:
            raise self._error(key, f"expected {what}, got {quoted(value)}")
        for v in value:
            if abs(v) > MAX_MAGNITUDE:
                raise self._error(key, f"{v:.6g} is out of range (allowed: within ±{MAX_MAGNITUDE:.6g})")
        return tuple(float(v) for v in value)

    def range(self, key: str, unit: str) -> tuple[float, float]:
        low, high = self.numbers(key, 2, f"[min, max] in {unit}")
        if not low < high:
            raise self._error(key, f"min must be < max, got [{low:g}, {high:g}]")
        return low, high

    def strings(self, key: str, default: Any = ...) -> tuple[str, ...]:
        value = self._get(key, default)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self._error(key, f"expected a list of strings, got {quoted(value)}")
        return tuple(value)

    def optional_table(self, key: str) -> _Table | None:
        """The table ``key``, or None when the file has none (a table added after files were written)."""
        if key not in self._data:
            self._taken.add(key)
            return None
        return self.table(key)

    def finish(self) -> None:
        """Raise on the first key nobody asked for (a typo must not be ignored)."""
        unknown = sorted(set(self._data) - self._taken)
        if unknown:
            raise self._error(shortened(unknown[0]), "unknown key")


def read_toml(path: Path) -> dict[str, Any]:
    """The TOML file at ``path`` (UTF-8, a regular file of at most 1 MB) as a dict: the one place the
    package parses TOML (machine, dialect and source-convention files here; job files in
    :mod:`prs3_post.readers.jobfile`). Only the syntax is checked; what the keys mean is the caller's.

    Raises
    ------
    ConfigError
        ``not valid TOML: <reason>``; arrays nested too deeply; the reading errors of
        :func:`~prs3_post.core.input_files.read_text` (``line 3: not UTF-8 text (byte 0xe9): save the file as
        UTF-8``) as ConfigError too.
    """
    try:
        text = read_text(str(path), "a TOML file")
    except InputError as exc:
        raise ConfigError(exc.args[0], path=exc.path, line=exc.line) from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=str(path)) from exc
    except RecursionError as exc:                 # tomllib recurses once per nested array or inline table
        raise ConfigError("not valid TOML here: arrays or inline tables nested too deeply", path=str(path)) from exc


def _display(path: Path) -> str:
    """``machines/patel2020.toml`` for shipped files, the path as given otherwise."""
    try:
        return str(path.resolve().relative_to(postproc_dir().resolve()))
    except ValueError:
        return str(path)


# ----------------------------------------------------------------------------- machines


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
    top = _Table(read_toml(path), shown)
    description = top.text("description")
    kinematics = top.text("kinematics", DEFAULT_KINEMATICS)
    if kinematics not in KINEMATICS_NAMES:
        raise top._error("kinematics", f"unknown kinematics {quoted(kinematics)} (known: "
                                       f"{', '.join(sorted(KINEMATICS_NAMES))})")

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
    gauge_offset = geo.number("gauge_offset_mm", unit="mm", positive=True)
    if not gauge_offset < tool_length:
        raise ConfigError(f"geometry.gauge_offset_mm: the gauge line must be between the platform centre and the "
                          f"tool tip: expected < tool_length_mm = {tool_length:g} mm, got {gauge_offset:g}", path=shown)
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
        gauge_offset=gauge_offset,
    )
    geometry = _general(top, geometry, kinematics)

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
    dynamics = _dynamics(top.optional_table("dynamics"))
    holder = _holder(top.optional_table("holder"))
    calibration = _calibration(top.optional_table("calibration"), shown)
    top.finish()
    return Machine(
        name=path.stem,
        description=description,
        source=shown,
        geometry=geometry,
        limits=limits,
        stage=stage,
        part_origin=part_origin,  # type: ignore[arg-type]
        dynamics=dynamics,
        holder=holder,
        kinematics=kinematics,
        calibration=calibration,
    )


#: How far a ``[[legs]]`` or ``[platform]`` direction may be from unit length and still be taken (and
#: scaled to it): rounded components, not a different vector.
UNIT_LENGTH_SLACK = 1e-3
#: The most a rail may leave its link's plane, |rail_direction · revolute_axis| = sin 30°.
MAX_RAIL_TILT = 0.5


def _unit(table: _Table, key: str, default: tuple[float, ...]) -> tuple[float, float, float]:
    """A direction [x, y, z] of unit length (within :data:`UNIT_LENGTH_SLACK`, then scaled to it)."""
    vector = table.numbers(key, 3, "a unit vector [x, y, z]", list(default))
    length = math.sqrt(sum(v * v for v in vector))
    if abs(length - 1.0) > UNIT_LENGTH_SLACK:
        raise table._error(key, f"expected a unit vector [x, y, z], got {list(vector)} (length {length:.6g})")
    return (vector[0] / length, vector[1] / length, vector[2] / length)


def _general(top: _Table, geometry: Geometry, kinematics: str) -> Geometry:
    """``geometry`` with the head as built from the ``[[legs]]`` array and the ``[platform]`` table
    (machines of kinematics ``3-prs-general`` only); every key not given is the ideal head's value.

    Each of the three ``[[legs]]`` (legs 1, 2, 3 in order; machine frame, stroke 0):
    ``rail_point_mm`` [x, y, z] mm, the revolute joint's centre at commanded stroke 0;
    ``rail_direction`` unit [x, y, z], the way it moves as the stroke grows;
    ``revolute_axis`` unit [x, y, z], the revolute joint's axis (the link moves in the plane normal to it);
    ``link_length_mm`` mm, revolute centre to spherical centre;
    ``platform_joint_mm`` [x, y, z] mm, the spherical joint's centre in the platform frame;
    ``stroke_offset_mm`` mm, the encoder zero (physical stroke = commanded + offset).
    ``[platform]``: ``tool_tip_mm`` [x, y, z] mm, the tool tip in the platform frame with the tool of
    ``geometry.tool_length_mm``; ``tool_axis`` unit [x, y, z], the tool axis there (tip → spindle).
    """
    legs_given = top._get("legs", None)
    platform = top.optional_table("platform")
    if kinematics != GENERAL_KINEMATICS:
        if legs_given is not None or platform is not None:
            key = "legs" if legs_given is not None else "platform"
            raise top._error(key, f"a head described leg by leg needs kinematics = {quoted(GENERAL_KINEMATICS)}, "
                                  f"this file's is {quoted(kinematics)}")
        return geometry
    ideal = general_from_ideal(geometry)
    if legs_given is None:
        legs_given = [{}, {}, {}]
    if not isinstance(legs_given, list) or len(legs_given) != 3 or not all(isinstance(t, dict) for t in legs_given):
        raise top._error("legs", "expected three [[legs]] tables (legs 1, 2, 3 in order)")
    legs = []
    for number, (data, nominal) in enumerate(zip(legs_given, ideal.legs, strict=True), start=1):
        table = _Table(data, top._path, f"legs[{number}].")
        direction = _unit(table, "rail_direction", nominal.rail_direction)
        axis = _unit(table, "revolute_axis", nominal.revolute_axis)
        tilt = abs(sum(d * r for d, r in zip(direction, axis, strict=True)))
        if tilt > MAX_RAIL_TILT:
            raise table._error("rail_direction", f"the rail is {math.degrees(math.asin(min(tilt, 1.0))):.3g}° out of "
                                                 "the link's plane (the plane normal to revolute_axis); at most "
                                                 f"{math.degrees(math.asin(MAX_RAIL_TILT)):.3g}° is allowed")
        legs.append(LegGeometry(
            rail_point=table.numbers("rail_point_mm", 3, "[x, y, z] in mm", list(nominal.rail_point)),  # type: ignore[arg-type]
            rail_direction=direction,
            revolute_axis=axis,
            link_length=table.number("link_length_mm", nominal.link_length, unit="mm", positive=True),
            platform_joint=table.numbers("platform_joint_mm", 3, "[x, y, z] in mm",  # type: ignore[arg-type]
                                         list(nominal.platform_joint)),
            stroke_offset=table.number("stroke_offset_mm", 0.0, unit="mm"),
        ))
        table.finish()
    tool_tip, tool_axis = ideal.tool_tip, ideal.tool_axis
    if platform is not None:
        tool_tip = platform.numbers("tool_tip_mm", 3, "[x, y, z] in mm", list(tool_tip))  # type: ignore[assignment]
        tool_axis = _unit(platform, "tool_axis", tool_axis)
        platform.finish()
    if not tool_axis[2] > 0.0:
        raise ConfigError(f"platform.tool_axis: must point toward the platform frame's +z (from the tip toward "
                          f"the spindle), got {list(tool_axis)}", path=top._path)
    general = GeneralGeometry(legs=(legs[0], legs[1], legs[2]), tool_tip=tool_tip, tool_axis=tool_axis)
    return Geometry(leg_azimuth=geometry.leg_azimuth, guide_radius=geometry.guide_radius,
                    link_length=geometry.link_length, platform_radius=geometry.platform_radius,
                    tool_length=geometry.tool_length, gauge_offset=geometry.gauge_offset, general=general)


#: The values a machine's drives and tool holder may have: physically meaningful, with room to spare
#: (the shipped machine files' comments state them).
AXIS_SPEED_RANGE = (1.0, 200_000.0)
"""mm/min, ``[dynamics]`` top speeds: 1 mm/min to 200 m/min (a linear motor reaches some 120 m/min)."""
AXIS_ACCEL_RANGE = (1.0, 100_000.0)
"""mm/s², ``[dynamics]`` accelerations: up to some 10 g."""
HOLDER_SIZE_RANGE = (1.0, 1000.0)
"""mm, ``[holder]`` diameters and lengths."""


def _dynamics(table: _Table | None) -> Dynamics | None:
    """The ``[dynamics]`` table (all four keys, each within its range), or None without one."""
    if table is None:
        return None
    out = Dynamics(
        stroke_speed=table.number("stroke_speed_mm_min", unit="mm/min", positive=True, within=AXIS_SPEED_RANGE),
        stroke_accel=table.number("stroke_accel_mm_s2", unit="mm/s²", positive=True, within=AXIS_ACCEL_RANGE),
        stage_speed=table.number("stage_speed_mm_min", unit="mm/min", positive=True, within=AXIS_SPEED_RANGE),
        stage_accel=table.number("stage_accel_mm_s2", unit="mm/s²", positive=True, within=AXIS_ACCEL_RANGE),
    )
    table.finish()
    return out


def _holder(table: _Table | None) -> Holder | None:
    """The ``[holder]`` table (all four keys, each within :data:`HOLDER_SIZE_RANGE`), or None without one."""
    if table is None:
        return None
    out = Holder(**{key: table.number(f"{key}_mm", unit="mm", positive=True, within=HOLDER_SIZE_RANGE) for key in (
        "holder_diameter", "holder_length", "nose_diameter", "nose_length")})
    table.finish()
    return out


def _calibration(table: _Table | None, shown: str) -> Calibration | None:
    """The ``[calibration]`` table a calibration writes (the identified parameters' names, standard
    deviations, correlations and the noise), or None without one."""
    if table is None:
        return None
    noise = table.number("noise_mm", unit="mm")
    names = table.strings("parameters")
    count = len(names)
    std = table.numbers("std", count, f"{count} standard deviations (one per parameter)")
    value = table._get("correlation")
    ok = isinstance(value, list) and len(value) == count and all(
        isinstance(row, list) and len(row) == count and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) and abs(v) <= 1.0 for v in row)
        for row in value)
    if not ok:
        raise ConfigError(f"calibration.correlation: expected a {count}×{count} array of numbers within ±1 "
                          "(one row per parameter)", path=shown)
    table.finish()
    try:
        return Calibration(parameters=names, std=std, correlation=tuple(tuple(float(v) for v in row) for row in value),
                           noise=noise)
    except ValueError as exc:
        raise ConfigError(str(exc), path=shown) from exc


# =============================================================================================
# ----------------------------------------------------------------------------- dialects
# (G-code dialects for the emitter. Owned separately from the machine part above; it only reuses
# the strict-reading helpers `_Table`, `read_toml`, `resolve` and `_display`.)

def _printable(text: str) -> bool:
    """Only printable ASCII (space to ``~``)."""
    return all(" " <= c <= "~" for c in text)


def _decimals(table: _Table, key: str, minimum: int) -> int:
    value = table.integer(key)
    if not minimum <= value <= 8:
        raise table._error(key, f"must be {minimum}..8 digits after the point, got {value}")
    return value


def _letter(table: _Table, key: str) -> str:
    value = table.text(key)
    if len(value) != 1 or not "A" <= value <= "Z":
        raise table._error(key, f"expected one upper-case letter A-Z, got {quoted(value)}")
    return value


def _blocks(table: _Table, key: str, room: int, comment: tuple[str, str], tool_number_max: int) -> tuple[str, ...]:
    """A list of literal blocks: each one line of printable ASCII, no ``%``, short enough to number,
    and nothing the controller rejects or that would change what the moves mean (see
    :func:`~prs3_post.machine.controller_rules.block_problem`: no motion, no program end, closed comments)."""
    lines = table.strings(key)
    for i, line in enumerate(lines):
        problem = ""
        if not line.strip():
            problem = "is empty (remove it)"
        elif not _printable(line):
            problem = f"must be one line of printable ASCII, got {quoted(line)}"
        elif "%" in line:
            problem = f"must not contain '%' (the program start/end is program.percent), got {quoted(line)}"
        elif line != line.strip():
            problem = f"has leading or trailing spaces, got {quoted(line)}"
        elif len(line) > room:
            problem = f"is {len(line)} characters, at most {room} fit on a numbered line"
        elif (wrong := block_problem(line, comment, tool_number_max=tool_number_max)) is not None:
            problem = f"{wrong}, got {quoted(line)}"
        if problem:
            raise table._error(f"{key}[{i}]", problem)
    return lines


def load_dialect(name_or_path: str) -> Dialect:
    """Load a shipped dialect by name or a dialect TOML file by path, strictly.

    Parameters
    ----------
    name_or_path : str
        A shipped name (``linuxcnc``, ``fanuc``) or the path of a dialect TOML file.

    Returns
    -------
    Dialect

    Raises
    ------
    ConfigError
        ``file: dotted.key: problem`` for anything missing, unknown, mistyped or out of range: axis
        letters that are not distinct axis letters, decimals outside their range, a comment style that
        a text could break out of, blocks that are not one line of printable ASCII, ...
    """
    path = resolve("dialects", name_or_path)
    shown = _display(path)
    top = _Table(read_toml(path), shown)
    description = top.text("description")

    # Tables are read in the order their checks depend on: program (line length) before blocks.
    ax = top.table("axes")
    letters: dict[str, str] = {}
    for key in ("x", "y", "t1", "t2", "t3"):
        letter = _letter(ax, key)
        if letter not in AXIS_LETTERS:
            raise ax._error(key, f"{quoted(letter)} is not an axis letter (use one of {' '.join(AXIS_LETTERS)})")
        for other, used in letters.items():
            if used == letter:
                raise ax._error(key, f"{quoted(letter)} is already the letter of axes.{other}")
        letters[key] = letter
    ax.finish()
    axes = AxisLetters(**letters)

    dec = top.table("decimals")
    decimals = Decimals(
        length=_decimals(dec, "length", 1),
        inverse_time=_decimals(dec, "inverse_time", 1),
        spindle=_decimals(dec, "spindle", 0),
        dwell=_decimals(dec, "dwell", 0),
    )
    dec.finish()

    num = top.table("line_numbers")
    enabled = num.boolean("enabled")
    n_letter = num.text("letter")
    if n_letter != "N":
        # Every other letter is an axis letter or a word of its own (G M F S T P O D E H I J K L Q R).
        raise num._error("letter", f"RS-274 block numbers are written with 'N', got {quoted(n_letter)}")
    start = num.integer("start", minimum=0)
    step = num.integer("step", minimum=1)
    wrap_after = num.integer("wrap_after", minimum=1)
    if wrap_after < start:
        raise num._error("wrap_after", f"must be ≥ line_numbers.start = {start}, got {wrap_after}")
    num.finish()
    line_numbers = LineNumbers(enabled, n_letter, start, step, wrap_after)

    com = top.table("comments")
    c_open = com.text("open")
    c_close = com.text("close")
    for key, value in (("open", c_open), ("close", c_close)):
        if not _printable(value) or value != value.strip():
            raise com._error(key, f"must be printable ASCII without spaces, got {quoted(value)}")
    if not c_open:
        raise com._error("open", "must not be empty")
    if set(c_open) & set(c_close):              # '(' ... '(' is a nested comment, not a closed one
        raise com._error("close", f"must not share a character with comments.open = {quoted(c_open)}, "
                                  f"got {quoted(c_close)}")
    uppercase = com.boolean("uppercase")
    control = com.text("control")
    non_ascii = com.text("non_ascii")
    for key, value in (("control", control), ("non_ascii", non_ascii)):
        if not _printable(value):
            raise com._error(key, f"must be printable ASCII, got {quoted(value)}")
    rep = com.table("replace")
    replace: list[tuple[str, str]] = []
    # The keys of this table are data (characters), not a fixed schema: walk them all. Each is
    # taken through rep.text(), so rep.finish() below still has nothing left to reject.
    for char in sorted(rep._data):
        full_key = f"replace.{char}" if char.isalnum() else f'replace."{char}"'
        if len(char) != 1:
            raise com._error(full_key, "keys must be single characters")
        value = rep.text(char)
        if not _printable(value):
            raise com._error(full_key, f"must be printable ASCII, got {quoted(value)}")
        replace.append((char, value))
    rep.finish()
    replaced = dict(replace)
    # The text must never be able to end (or, for LinuxCNC, nest) its comment: every delimiter
    # character is replaced, and no replacement brings one back.
    delimiters = sorted(set(c_open + c_close))
    for char in delimiters:
        if char not in replaced:
            raise com._error("replace", f"must replace {quoted(char)} (a comment delimiter character)")
    for key, value in (*((f'replace."{c}"', v) for c, v in replace), ("control", control), ("non_ascii", non_ascii)):
        bad = sorted(set(value) & set(delimiters))
        if bad:
            raise com._error(key, f"must not contain the comment delimiter {quoted(bad[0])}, got {quoted(value)}")
    active_words = com.strings("active_words", default=[])
    for word in active_words:
        if not (word.isascii() and word.isalpha()):
            raise com._error("active_words", f"expected words of letters A-Z, got {quoted(word)}")
    com.finish()
    comments = CommentStyle(c_open, c_close, uppercase, tuple(replace), control, non_ascii,
                            tuple(w.upper() for w in active_words))

    prog = top.table("program")
    percent = prog.boolean("percent")
    program_number = prog.integer("number", minimum=0)
    if program_number > 99999999:
        raise prog._error("number", f"must be 0 (no O line) or 1..99999999, got {program_number}")
    program_name = prog.text("name")
    if not _printable(program_name) or set(program_name) & set(c_open + c_close):
        raise prog._error("name", f"must be printable ASCII without {quoted(c_open)} or {quoted(c_close)}, "
                                  f"got {quoted(program_name)}")
    if program_name and not program_number:
        raise prog._error("name", "needs program.number > 0 (the name is a comment on the O line)")
    end_code = prog.text("end_code")
    if end_code not in END_CODES:
        raise prog._error("end_code", f"expected one of {', '.join(END_CODES)}, got {quoted(end_code)}")
    line_ending = prog.text("line_ending")
    if line_ending not in LINE_ENDINGS:
        raise prog._error("line_ending", f'expected "\\n" or "\\r\\n", got {quoted(line_ending)}')
    max_line_length = prog.integer("max_line_length")
    if not MIN_LINE_LENGTH <= max_line_length <= 252:
        raise prog._error("max_line_length", f"must be {MIN_LINE_LENGTH}..252 ({MIN_LINE_LENGTH}: a header line holds "
                                             f"a SHA-256 whole; 252: LinuxCNC's limit), got {max_line_length}")
    # A header's fixed fields are read back by verify: a wrapped comment breaks only at spaces, unless a word
    # is longer than a line, so the longest fixed word (a SHA-256, 64 hex digits) must fit a continuation line.
    sha_room = (max_line_length - (len(line_ending) - 1) - len(c_open) - len(c_close) - len(COMMENT_CONTINUATION))
    if sha_room < SHA256_DIGITS:
        raise prog._error("max_line_length", f"{max_line_length} leaves {sha_room} characters for a wrapped header "
                                             f"comment line with comments.open {quoted(c_open)} and close "
                                             f"{quoted(c_close)}: the header's SHA-256 needs {SHA256_DIGITS}")
    extension = prog.text("extension")
    if not re.fullmatch(r"\.[A-Za-z0-9]{1,8}", extension):
        raise prog._error("extension", f"expected a dot and 1 to 8 letters or digits (\".ngc\"), "
                                       f"got {quoted(extension)}")
    prog.finish()

    # A literal block must fit behind the longest block number, e.g. "N99999 ", whether or not
    # numbers are enabled here (the CLI may switch them on).
    room = max_line_length - (len(line_ending) - 1) - len(f"{n_letter}{wrap_after} ")
    o_line = f"O{program_number} {c_open}{program_name}{c_close}" if program_name else f"O{program_number}"
    if program_number and len(o_line) > room:
        raise ConfigError(f"program.name: the O line would be {len(o_line)} characters, at most {room} fit", path=shown)

    words = top.table("words")                         # before the blocks: their T words need tool_number_max
    modal_motion = words.boolean("modal_motion")
    dwell_unit = words.text("dwell_unit")
    if dwell_unit not in DWELL_UNITS:
        raise words._error("dwell_unit", f"expected one of {', '.join(DWELL_UNITS)}, got {quoted(dwell_unit)}")
    tool_number_max = words.integer("tool_number_max", minimum=1)
    if tool_number_max > TOOL_NUMBER_LIMIT:
        raise words._error("tool_number_max", f"must be 1..{TOOL_NUMBER_LIMIT}, got {tool_number_max}")
    words.finish()

    blk = top.table("blocks")
    safe_start = _blocks(blk, "safe_start", room, (c_open, c_close), tool_number_max)
    preamble = _blocks(blk, "preamble", room, (c_open, c_close), tool_number_max)
    postamble = _blocks(blk, "postamble", room, (c_open, c_close), tool_number_max)
    blk.finish()
    top.finish()

    return Dialect(
        name=path.stem,
        description=description,
        source=shown,
        axes=axes,
        decimals=decimals,
        line_numbers=line_numbers,
        comments=comments,
        percent=percent,
        program_number=program_number,
        program_name=program_name,
        end_code=end_code,
        line_ending=line_ending,
        max_line_length=max_line_length,
        safe_start=safe_start,
        preamble=preamble,
        postamble=postamble,
        modal_motion=modal_motion,
        dwell_unit=dwell_unit,
        tool_number_max=tool_number_max,
        extension=extension,
    )


# =============================================================================================
# ----------------------------------------------------------------------------- source conventions
# (5-axis G-code sources, postproc/sources/*.toml, for readers/fivex.py. Owned separately; it
# only reuses the strict-reading helpers above.)

_CODE = re.compile(r"([GM])([0-9]+(?:\.[0-9]+)?)")
_VECTOR_LETTERS = "ABCIJKUVW"


def _codes(table: _Table, key: str, letters: str = "GM") -> tuple[str, ...]:
    """A list of G/M codes (``"G43.4"``, ``"M428"``), each as :func:`~prs3_post.core.lexer.code_name`
    writes it (``G00`` → ``G0``)."""
    out = []
    for i, text in enumerate(table.strings(key)):
        match = _CODE.fullmatch(text.strip().upper())
        if match is None or match[1] not in letters:
            raise table._error(f"{key}[{i}]", f"expected a {' or '.join(letters)} code such as "
                               f"{'G43.4' if 'G' in letters else 'M10'}, got {quoted(text)}")
        out.append(code_name(match[1], float(match[2])))
    return tuple(out)


def _rotary(table: _Table, is_table: bool) -> Rotary:
    from prs3_post.machine.cam_conventions import Rotary

    word = table.text("word")
    if word not in ("A", "B", "C"):
        raise table._error("word", f"must be A, B or C, got {quoted(word)}")
    axis = np.array(table.numbers("axis", 3, "[x, y, z], a unit vector"))
    length = float(np.linalg.norm(axis))
    if abs(length - 1.0) > 1e-6:
        raise table._error("axis", f"must be a unit vector, got {axis.tolist()} (length {length:.6g})")
    sign = table.integer("sign")
    if sign not in (1, -1):
        raise table._error("sign", f"must be 1 or -1, got {sign}")
    zero_deg = table.number("zero_deg", unit="degrees")
    table.finish()
    unit = axis / length
    return Rotary(word, is_table, (float(unit[0]), float(unit[1]), float(unit[2])), sign, zero_deg)


def load_source(name_or_path: str) -> SourceConvention:
    """Load a shipped source convention by name or a source TOML file by path, strictly.

    Raises
    ------
    ConfigError
        ``file: dotted.key: problem`` for anything missing, unknown, mistyped or out of range.
    """
    from prs3_post.machine.cam_conventions import NOT_QUIET, NOT_QUIET_SHOWN, Orientation, SourceConvention

    path = resolve("sources", name_or_path)
    shown = _display(path)
    data = read_toml(path)
    top = _Table(data, shown)
    description = top.text("description")
    kind = top.text("orientation")
    if kind not in ("rotary", "vector"):
        raise top._error("orientation", f"expected \"rotary\" or \"vector\", got {quoted(kind)}")
    orientation = Orientation(kind)
    tcp = top.table("tcp")
    tcp_on, tcp_off = _codes(tcp, "on"), _codes(tcp, "off")
    tcp.finish()
    for key, given in (("on", tcp_on), ("off", tcp_off)):
        if not given:
            raise tcp._error(key, "give at least one code")
    both = sorted(set(tcp_on) & set(tcp_off))
    if both:
        raise tcp._error("off", f"{both[0]} is also in tcp.on")
    extra = top.table("codes")
    clamps, inert = _codes(extra, "clamps"), _codes(extra, "inert")
    extra.finish()
    for key, codes, role in (("clamps", clamps, "a clamp"), ("inert", inert, "inert")):
        for i, code in enumerate(codes):
            if code in NOT_QUIET:
                raise extra._error(f"{key}[{i}]", f"{code} is {NOT_QUIET[code]}, it cannot be {role} (inert and "
                                   f"clamp codes must change nothing in a conversion: {NOT_QUIET_SHOWN})")
    rotaries: dict[str, list[Rotary]] = {"table": [], "head": []}
    for key in ("table", "head"):
        entries = top._get(key, [])
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            raise top._error(key, f"expected [[{key}]] tables")
        for i, entry in enumerate(entries):
            rotaries[key].append(_rotary(_Table(entry, shown, f"{key}[{i}]."), key == "table"))
    vector_words: tuple[str, ...] = ()
    chain = rotaries["table"] + rotaries["head"]
    if orientation is Orientation.VECTOR:
        if chain:
            raise top._error("table" if rotaries["table"] else "head",
                             "a vector source has no rotary chain (orientation = \"vector\")")
        vec = top.table("vector")
        vector_words = tuple(w.upper() for w in vec.strings("words"))
        vec.finish()
        if (len(vector_words) != 3 or len(set(vector_words)) != 3
                or not all(len(w) == 1 and w in _VECTOR_LETTERS for w in vector_words)):
            raise vec._error("words", f"expected three distinct letters of {' '.join(_VECTOR_LETTERS)}, got "
                             f"{list(vector_words)}")
    else:
        if "vector" in data:
            top._get("vector")
            raise top._error("vector", "only a vector source (orientation = \"vector\") has [vector]")
        if not 1 <= len(chain) <= 3:
            raise top._error("table", f"a rotary source needs 1 to 3 [[table]]/[[head]] entries, got {len(chain)}")
        words = [r.word for r in chain]
        twice = sorted({w for w in words if words.count(w) > 1})
        if twice:
            raise top._error("table", f"rotary word {twice[0]} appears twice in the chain")
    top.finish()
    return SourceConvention(name=path.stem, description=description, source=shown, orientation=orientation,
                            tables=tuple(rotaries["table"]), heads=tuple(rotaries["head"]),
                            vector_words=vector_words, tcp_on=tcp_on, tcp_off=tcp_off, clamps=clamps, inert=inert)


def file_given(source: str, kind: str, name: str) -> str | None:
    """The path a machine or dialect was given by, or None for a shipped one (``machines/NAME.toml``)."""
    return None if source == f"{kind}/{name}.toml" else source
