"""Read a job file: one part, one setup, a tool table and a list of operations, in TOML.

::

    part = "../parts/twofaces.stl"     # relative to the job file
    units = "mm"                       # optional: mm | inch (the STL's unit)
    up = "z"                           # optional: the STL's up axis
    machine = "patel2020"              # optional: shipped name or TOML path (relative to the job file)
    dialect = "linuxcnc"               # optional: likewise
    tool_table = "tools.tbl"           # optional: LinuxCNC tool table (relative to the job file)
    tolerance = 0.002                  # optional, mm

    [setup]                            # optional
    part_origin = [-100.0, -200.0, -970.0]   # machine coordinates, mm, or "auto" (chosen for the largest margins)
    part_rotation_deg = 0.0                  # about the machine z axis, or "auto" (chosen with the origin)

    [[operation]]                      # one table per operation, in program order
    profile = "hole"                   # hole | square | round
    face = 5                           # a face index, or "auto"
    tool = 1                           # tool number (its diameter comes from the tool table)
    at = [[5.0, 5.0]]                  # and every option of the main job, with _ for -

Loading is strict, like the machine files: an unknown key, a missing one or a value of the wrong
TOML type is an error naming the file, the table and the key
(``job.toml: operation[2].step_dwon: unknown key``). The values' ranges are checked where the
main job's options are (the caller converts them as it converts those options).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from prs3_post.core.errors import InputError, quoted, shortened
from prs3_post.machine.loading import read_toml as _read_toml
from prs3_post.part.setup_transform import AUTO

#: The keys of an ``[[operation]]`` table: the main job's option names with ``_`` for ``-``
#: (``face`` for ``--face``, ``tool`` for ``--tool-number``, ``at`` for ``--at``).
OPERATION_KEYS = (
    "profile", "face", "at", "at_xyz", "depth", "peck", "reapproach_gap", "dwell", "size", "corner_radius", "rotation",
    "diameter", "side", "step_down", "direction", "entry", "ramp_angle", "clearance", "retract", "tool",
    "tool_diameter", "feed", "plunge_feed", "spindle", "coolant",
)
#: The keys of the top level, with the TOML type each takes.
TOP_KEYS = {"part": str, "units": str, "up": str, "machine": str, "dialect": str, "tool_table": str,
            "tolerance": float, "line_numbers": bool, "line_start": int, "line_step": int, "setup": dict,
            "operation": list}
#: Largest number of operations in one job.
MAX_OPERATIONS = 999


@dataclass(frozen=True, slots=True)
class JobFile:
    """A job file's content, its paths resolved against the file's folder.

    Attributes
    ----------
    path : str — the job file, as given
    part : str — the STL's path
    settings : dict — the top-level keys given other than ``part``, ``setup`` and ``operation``
        (``units``, ``up``, ``machine``, ``dialect``, ``tool_table``, ``tolerance``, ``line_*``;
        ``machine``, ``dialect`` and ``tool_table`` paths resolved)
    part_origin : (3,) float | str | None — mm, or ``"auto"`` (None: the machine's default)
    part_rotation_deg : float | str | None — degrees, or ``"auto"`` (None: 0)
    operations : tuple of dict — each ``[[operation]]`` table's keys and values as TOML gave them
    """

    path: str
    part: str
    settings: dict[str, Any]
    part_origin: tuple[float, float, float] | str | None
    part_rotation_deg: float | str | None
    operations: tuple[dict[str, Any], ...]

    def as_data(self) -> dict[str, Any]:
        """The job as the plain data a job request is built from (:func:`prs3_post.app.requests.job_request`):
        the top-level keys, ``setup`` and the ``operation`` list, paths resolved."""
        setup = {key: value for key, value in (("part_origin", self.part_origin),
                                                ("part_rotation_deg", self.part_rotation_deg)) if value is not None}
        return {"part": self.part, **self.settings, "setup": setup, "operation": [dict(o) for o in self.operations]}


def _kind(value: Any, wanted: type) -> bool:
    if wanted is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if wanted is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, wanted)


_NAMES = {str: "a string", float: "a number", int: "a whole number", bool: "true or false", dict: "a table",
          list: "an array of tables ([[operation]])"}


def _relative(base: Path, value: str) -> str:
    """``value`` as a path relative to the job file's folder (absolute paths stay as they are)."""
    return str(base / value) if not Path(value).is_absolute() else value


def read_job_file(path: str) -> JobFile:
    """Read and check a job file's structure (keys and TOML types; the values' ranges are the caller's).

    Raises
    ------
    InputError
        ``path: KEY: problem`` for an unknown, missing or mistyped key; ``not valid TOML: ...``.
    """
    data = _read_toml(Path(path))
    base = Path(path).parent

    def bad(key: str, problem: str) -> InputError:
        return InputError(f"{key}: {problem}", path=path)

    for key, value in data.items():
        if key not in TOP_KEYS:
            raise bad(shortened(key), f"unknown key (a job file has {', '.join(TOP_KEYS)})")
        if not _kind(value, TOP_KEYS[key]):
            raise bad(key, f"expected {_NAMES[TOP_KEYS[key]]}, got {quoted(value)}")
    for key in ("part", "operation"):
        if key not in data:
            raise bad(key, "missing" + (" (at least one [[operation]] table)" if key == "operation" else ""))
    settings = {k: v for k, v in data.items() if k not in ("part", "setup", "operation")}
    if "tolerance" in settings and not math.isfinite(settings["tolerance"]):
        raise bad("tolerance", f"expected a finite number in mm, got {quoted(settings['tolerance'])}")
    for key in ("machine", "dialect"):
        if key in settings and settings[key].endswith(".toml"):       # a file, not a shipped name
            settings[key] = _relative(base, settings[key])
    if "tool_table" in settings:
        settings["tool_table"] = _relative(base, settings["tool_table"])
    origin, rotation = _setup(data.get("setup", {}), bad)
    operations = data["operation"]
    if not 1 <= len(operations) <= MAX_OPERATIONS:
        raise bad("operation", f"expected 1 to {MAX_OPERATIONS} [[operation]] tables, got {len(operations)}")
    for number, table in enumerate(operations, start=1):
        where = f"operation[{number}]"
        if not isinstance(table, dict):
            raise bad(where, f"expected a table ([[operation]]), got {quoted(table)}")
        for key in table:
            if key not in OPERATION_KEYS:
                raise bad(f"{where}.{shortened(key)}", f"unknown key (an operation has {', '.join(OPERATION_KEYS)})")
        if "profile" not in table:
            raise bad(f"{where}.profile", "missing (hole, square or round)")
    return JobFile(path=path, part=_relative(base, data["part"]), settings=settings, part_origin=origin,
                   part_rotation_deg=rotation, operations=tuple(dict(t) for t in operations))


def _setup(table: dict[str, Any], bad: Any) -> tuple[tuple[float, float, float] | str | None, float | str | None]:
    """``[setup]``: the part origin and rotation (None where not given, ``"auto"`` where asked for)."""
    for key in table:
        if key not in ("part_origin", "part_rotation_deg"):
            raise bad(f"setup.{shortened(key)}", "unknown key (the setup has part_origin, part_rotation_deg)")
    origin = table.get("part_origin")
    rotation = table.get("part_rotation_deg")
    if origin not in (None, AUTO) and not (isinstance(origin, list) and len(origin) == 3
                                           and all(_kind(v, float) and math.isfinite(v) for v in origin)):
        raise bad("setup.part_origin", f'expected [x, y, z] in mm or "auto", got {quoted(origin)}')
    if rotation not in (None, AUTO) and not (_kind(rotation, float) and math.isfinite(rotation)):
        raise bad("setup.part_rotation_deg", f'expected a number of degrees or "auto", got {quoted(rotation)}')
    return (origin if origin in (None, AUTO) else (float(origin[0]), float(origin[1]), float(origin[2])),
            rotation if rotation in (None, AUTO) else float(rotation))
