"""The main job as one plain-data request, whether it comes from the command line or a job file.

Both front ends build the same dictionary, shaped like a job file (top-level settings, ``setup``,
a list of ``operation`` tables; keys as a job file spells them), and :func:`job_request` checks it
into a :class:`JobRequest`; :func:`job_specs` turns that into the :class:`~prs3_post.app.job.JobSpec`
of each operation (the machine, dialect and tool table loaded, the domain's defaults applied). A
value that is wrong raises :class:`~prs3_post.core.errors.FieldError` naming its key; the front end
words it (``--depth`` on the command line, ``operation[1].depth`` in a job file).

The defaults live here, once: :data:`OPERATION_FIELDS` and :data:`SETTING_FIELDS` (the command
line shows them in its ``--help``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.app.values import (
    ANGLE,
    FEED,
    LENGTH,
    SPEED,
    SPINDLE_LOW,
    TIME,
    ChoiceKind,
    DecimalKind,
    FlagKind,
    IntegerKind,
    Kind,
    NumbersKind,
    ValueProblem,
    checked,
)
from prs3_post.core.defaults import DEFAULT_CLEARANCE_MIN, DEFAULT_TOLERANCE, FEED_RANGE_MM_MIN
from prs3_post.core.errors import FeatureError, FieldError, InputError, UnusedFields, quoted
from prs3_post.core.numbers import exact_text
from prs3_post.core.toolpath import Coolant
from prs3_post.machine.loading import DEFAULT_DIALECT, DEFAULT_MACHINE, Dialect, Machine, load_dialect, load_machine
from prs3_post.part.setup_transform import AUTO, UP_ROTATION, Setup, SetupError
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE
from prs3_post.toolpaths.profiles import Direction, Entry, Side
from prs3_post.toolpaths.work import Operation

if TYPE_CHECKING:
    from prs3_post.app.job import JobSpec
    from prs3_post.readers.tooltable import ToolTable

__all__ = [
    "AUTO",
    "OPERATION_FIELDS",
    "SETTING_FIELDS",
    "UP_ROTATION",
    "Field",
    "JobRequest",
    "choices",
    "job_request",
    "job_specs",
    "resolve_setup",
    "used_by",
]


@dataclass(frozen=True, slots=True)
class FaceKind(Kind):
    """A face: ``auto`` or an index (text on the command line, a string or a whole number in a job file)."""

    def check(self, value: Any) -> str:
        if not isinstance(value, str | int):
            raise ValueProblem(f'expected "auto" or a face index, got {quoted(value)}')
        return str(value)


@dataclass(frozen=True, slots=True)
class Field:
    """One key of the request: its kind, its default and (for an operation's key) the profiles that use it.

    Attributes
    ----------
    kind : Kind — how a value is checked
    default : Any — the value when the key is not given (None: decided where it is used, or none)
    profiles : tuple of str — the profiles that use the key (empty: every profile)
    points : bool — a list of points of ``kind`` (``at``, ``at_xyz``)
    """

    kind: Kind
    default: Any = None
    profiles: tuple[str, ...] = ()
    points: bool = False


_HOLE = ("hole",)
_PROFILES = ("square", "round")
_LENGTH = DecimalKind(LENGTH)
_FEED = DecimalKind(FEED, low=FEED_RANGE_MM_MIN[0])

#: An operation's keys (a job file's ``[[operation]]``; the main job's options), in the order they are checked.
OPERATION_FIELDS: dict[str, Field] = {
    "profile": Field(ChoiceKind(tuple(o.value for o in Operation))),
    "face": Field(FaceKind(), "auto"),
    "at": Field(NumbersKind("U,V"), (), points=True),
    "at_xyz": Field(NumbersKind("X,Y,Z"), (), points=True),
    "depth": Field(_LENGTH, None),                   # by profile: DEFAULT_DEPTH
    "peck": Field(_LENGTH, 0.0, _HOLE),
    "reapproach_gap": Field(_LENGTH, 0.5, _HOLE),
    "dwell": Field(DecimalKind(TIME), 0.0, _HOLE),
    "size": Field(_LENGTH, 30.0, ("square",)),
    "corner_radius": Field(_LENGTH, 0.0, ("square",)),
    "rotation": Field(DecimalKind(ANGLE), 0.0, ("square",)),
    "diameter": Field(_LENGTH, 30.0, ("round",)),
    "side": Field(ChoiceKind(tuple(s.value for s in Side)), "on", _PROFILES),
    "step_down": Field(_LENGTH, 1.0, _PROFILES),
    "direction": Field(ChoiceKind(tuple(d.value for d in Direction)), "climb", _PROFILES),
    "entry": Field(ChoiceKind(tuple(e.value for e in Entry)), "ramp", _PROFILES),
    "ramp_angle": Field(DecimalKind(ANGLE), 3.0, _PROFILES),
    "clearance": Field(_LENGTH, 2.0),
    "retract": Field(_LENGTH, 10.0),
    "tool_diameter": Field(_LENGTH, None),           # the tool table's, else DEFAULT_TOOL_DIAMETER
    "tool": Field(IntegerKind(), 1),
    "feed": Field(_FEED, 300.0),
    "plunge_feed": Field(_FEED, 100.0),
    "spindle": Field(DecimalKind(SPEED, low=SPINDLE_LOW), 3000.0),
    "coolant": Field(ChoiceKind(tuple(c.value for c in Coolant)), Coolant.FLOOD.value),
}

#: The job's settings (a job file's top-level keys and ``[setup]``; the main job's other options).
SETTING_FIELDS: dict[str, Field] = {
    "units": Field(ChoiceKind(("mm", "inch")), "mm"),
    "up": Field(ChoiceKind(tuple(UP_ROTATION)), "z"),
    "machine": Field(Kind(), DEFAULT_MACHINE),
    "dialect": Field(Kind(), DEFAULT_DIALECT),
    "tool_table": Field(Kind(), None),
    "tolerance": Field(_LENGTH, DEFAULT_TOLERANCE),
    "line_numbers": Field(FlagKind(), None),
    "line_start": Field(IntegerKind(0, 99999), None),
    "line_step": Field(IntegerKind(1, 1000), None),
    "clamp": Field(FlagKind(), True),
    "collision_check": Field(FlagKind(), True),
    "clearance_min": Field(DecimalKind(LENGTH, low=0.0), DEFAULT_CLEARANCE_MIN),
}

#: The depth of an operation that gives none, mm: a hole's, a profile's.
DEFAULT_DEPTH = {Operation.HOLE: 5.0, Operation.SQUARE: 2.0, Operation.ROUND: 2.0}

#: The tool diameter of an operation that gives none and whose tool the tool table lacks, mm.
DEFAULT_TOOL_DIAMETER = 6.0

#: The settings whose value is taken as given (a name or path, a flag): the loader or the job checks it.
_TAKEN_AS_GIVEN = ("machine", "dialect", "tool_table", "line_numbers", "clamp", "collision_check")


def choices(key: str) -> tuple[str, ...]:
    """The words an operation's or a setting's key takes (``side``: on, inside, outside)."""
    kind = {**SETTING_FIELDS, **OPERATION_FIELDS}[key].kind
    if not isinstance(kind, ChoiceKind):
        raise ValueError(f"{key} takes no fixed words")
    return kind.choices


def used_by(profile: str, key: str) -> bool:
    """Whether an operation of ``profile`` uses ``key`` (``diameter``: only a round one)."""
    profiles = OPERATION_FIELDS[key].profiles
    return not profiles or profile in profiles


@dataclass(frozen=True, slots=True)
class JobRequest:
    """The main job, checked: one part, its settings, one or more operations (plain values, a job file's keys).

    Attributes
    ----------
    part : str — the STL's path
    settings : dict — every key of :data:`SETTING_FIELDS`, given or default
    part_origin : (3,) float | str | None — mm, ``"auto"`` (chosen), or None (the machine's default)
    part_rotation_deg : float | str | None — degrees, ``"auto"``, or None (0)
    operations : tuple of dict — each operation's keys of :data:`OPERATION_FIELDS` that its profile uses,
        given or default (``depth`` None: the profile's :data:`DEFAULT_DEPTH`)
    """

    part: str
    settings: Mapping[str, Any]
    part_origin: tuple[float, ...] | str | None
    part_rotation_deg: float | str | None
    operations: tuple[Mapping[str, Any], ...]


def _value(fields: dict[str, Field], key: str, value: Any, operation: int | None) -> Any:
    """A given value of ``key``, checked by its kind."""
    field = fields[key]
    if fields is SETTING_FIELDS and key in _TAKEN_AS_GIVEN:
        return value
    try:
        return checked(field.kind, value, points=field.points)
    except ValueProblem as problem:
        raise FieldError(str(problem), field=key, operation=operation) from problem


def job_request(data: Mapping[str, Any]) -> JobRequest:
    """Check a job's values, shaped as a job file (``part``, settings, ``setup``, ``operation`` list).

    Settings are checked first, then each operation in order: its profile, the keys its profile
    does not use, then each key's value as given.

    Raises
    ------
    FieldError
        A value of the wrong type or out of range, naming its key (and operation).
    UnusedFields
        An operation's keys that its profile does not use.
    """
    settings = {key: field.default for key, field in SETTING_FIELDS.items()}
    for key in SETTING_FIELDS:
        if data.get(key) is not None:
            settings[key] = _value(SETTING_FIELDS, key, data[key], None)
    setup = data.get("setup", {})
    operations = []
    for number, given in enumerate(data["operation"], start=1):
        profile = _value(OPERATION_FIELDS, "profile", given["profile"], number)
        unused = tuple((key, OPERATION_FIELDS[key].profiles) for key in given if not used_by(profile, key))
        if unused:
            raise UnusedFields(profile, unused, operation=number)
        values = {key: field.default for key, field in OPERATION_FIELDS.items() if used_by(profile, key)}
        values |= {key: _value(OPERATION_FIELDS, key, value, number) for key, value in given.items()}
        operations.append(values)
    return JobRequest(part=data["part"], settings=settings, part_origin=setup.get("part_origin"),
                      part_rotation_deg=setup.get("part_rotation_deg"), operations=tuple(operations))


def _face_index(choice: str | int, number: int) -> int | None:
    """``auto`` → None, ``7`` → 7 (ASCII digits only: ``²`` is a digit to Python, not to us)."""
    text = str(choice)
    if text == "auto":
        return None
    if text.isascii() and text.isdigit():
        return int(text)
    raise FieldError(f"expected auto or a face index, got {quoted(text)}", field="face", operation=number)


def _setup(request: JobRequest, machine: Machine) -> Setup:
    return resolve_setup(machine, request.part_origin, request.part_rotation_deg)


def resolve_setup(machine: Machine, origin: tuple[float, ...] | str | None, rotation: float | str | None) -> Setup:
    """The setup a job starts from: the machine's default, with the part origin and rotation given
    (None: the default's; ``auto``: the default's until the job chooses it).

    Raises
    ------
    FieldError
        A value out of range, naming ``setup.part_origin`` or ``setup.part_rotation_deg``.
    """
    try:
        return Setup.resolve(machine, None if origin == AUTO else origin,  # type: ignore[arg-type]
                             None if rotation == AUTO else rotation)  # type: ignore[arg-type]
    except SetupError as error:
        key = "setup.part_rotation_deg" if error.field == "rotation" else "setup.part_origin"
        raise FieldError(str(error), field=key) from error


def job_specs(request: JobRequest, *, table: ToolTable | None = None) -> tuple[JobSpec, ...]:
    """The :class:`~prs3_post.app.job.JobSpec` of each operation of a request.

    Parameters
    ----------
    request : JobRequest
    table : ToolTable | None — the tool table, read already (None: read from the ``tool_table`` setting,
        if any); an operation without ``tool_diameter`` takes its tool's diameter from it

    Raises
    ------
    FieldError
        A face that is no index, a tool number the dialect does not take, block numbers that would
        repeat, a setup out of range (naming the key).
    InputError, ConfigError
        A tool table, machine or dialect that cannot be read, or a table's diameter out of range.
    FeatureError
        An operation's values that do not make an operation (a depth ≤ 0 ...).
    """
    from prs3_post.readers.tooltable import read_tool_table

    settings = request.settings
    if table is None and settings["tool_table"]:
        table = read_tool_table(settings["tool_table"])
    dialect = load_dialect(settings["dialect"])
    specs = []
    for number, values in enumerate(request.operations, start=1):
        try:
            specs.append(_spec(request, number, values, dialect, table))
        except FeatureError as error:                # which operation: the front end says it
            if error.operation is not None:
                raise
            raise FeatureError(error.args[0], key=error.key, operation=number) from error
    return tuple(specs)


def _spec(request: JobRequest, number: int, values: Mapping[str, Any], dialect: Dialect,
          table: ToolTable | None) -> JobSpec:
    """The JobSpec of operation ``number`` (as :func:`job_specs`)."""
    from prs3_post.app.job import JobSpec
    from prs3_post.toolpaths import Cutting, HoleParams, ProfileParams, RoundShape, SquareShape
    from prs3_post.toolpaths.work import HoleJob, ProfileJob

    settings = request.settings
    operation = Operation(values["profile"])
    face = _face_index(values["face"], number)
    tool_diameter = values["tool_diameter"]
    if tool_diameter is None:
        tool_diameter = DEFAULT_TOOL_DIAMETER if table is None else _table_diameter(table, values)
    if not 1 <= values["tool"] <= dialect.tool_number_max:       # both bounds, one message
        raise FieldError(f"must be 1..{dialect.tool_number_max} with dialect {dialect.name} (its "
                         f"words.tool_number_max), got {values['tool']}", field="tool", operation=number)
    _check_resolution(values, dialect, number)
    cutting = Cutting(tool_diameter=tool_diameter, feed=values["feed"], plunge_feed=values["plunge_feed"],
                      spindle_rpm=values["spindle"], coolant=Coolant(values["coolant"]), tool_number=values["tool"])
    depth = DEFAULT_DEPTH[operation] if values["depth"] is None else values["depth"]
    work: HoleJob | ProfileJob
    if operation is Operation.HOLE:
        work = HoleJob(HoleParams(depth=depth, peck=values["peck"], dwell=values["dwell"],
                                  clearance=values["clearance"], retract=values["retract"],
                                  reapproach_gap=values["reapproach_gap"]))
    else:
        shape: SquareShape | RoundShape
        if operation is Operation.SQUARE:
            shape = SquareShape(size=values["size"], corner_radius=values["corner_radius"],
                                rotation=math.radians(values["rotation"]))
        else:
            shape = RoundShape(diameter=values["diameter"])
        work = ProfileJob(shape, ProfileParams(
            side=Side(values["side"]), depth=depth, step_down=values["step_down"],
            direction=Direction(values["direction"]), entry=Entry(values["entry"]),
            ramp_angle=math.radians(values["ramp_angle"]), clearance=values["clearance"],
            retract=values["retract"]))
    _check_line_numbers(settings, dialect)
    machine = load_machine(settings["machine"])
    return JobSpec(
        part=request.part, units=settings["units"], face=face, work=work,
        at_uv=np.array(values["at"], dtype=np.float64).reshape(-1, 2),
        at_xyz=np.array(values["at_xyz"], dtype=np.float64).reshape(-1, 3),
        cutting=cutting, machine=machine, dialect=dialect, setup=_setup(request, machine),
        tolerance=settings["tolerance"], line_numbers=settings["line_numbers"],
        line_start=settings["line_start"], line_step=settings["line_step"], up=settings["up"],
        auto_origin=request.part_origin == AUTO, auto_rotation=request.part_rotation_deg == AUTO,
        tool_table=table, clamp=settings["clamp"], collision_check=settings["collision_check"],
        clearance_min=settings["clearance_min"])


#: The operation's lengths the program writes (a depth, a size, a height over the face), and what 0
#: means for those that may be 0 (None: it must be more).
_DIMENSIONS: dict[str, str | None] = {
    "depth": None, "size": None, "diameter": None, "step_down": None, "clearance": None, "retract": None,
    "peck": "no pecking", "reapproach_gap": "feed resumes at the previous peck's bottom",
    "corner_radius": "sharp corners",
}


def _check_resolution(values: Mapping[str, Any], dialect: Dialect, number: int) -> None:
    """One rule for every length of an operation: more than 0 but less than the program's resolution (one
    unit of the last digit the dialect writes) is refused, whatever it is: the program could not show
    it (a depth of 1e-300 mm drilled a hole of depth 0).

    Raises
    ------
    FieldError
        ``1e-300 mm is below the program's resolution ...``, naming the key.
    """
    from prs3_post.post.visible_moves import length_resolution

    decimals = dialect.decimals.length
    resolution = length_resolution(decimals)
    for key, zero in _DIMENSIONS.items():
        value = values.get(key)
        if value is not None and 0.0 < value < resolution:
            smallest = exact_text(resolution, decimals)
            also = "" if zero is None else f" (or 0: {zero})"
            raise FieldError(f"{value:g} mm is below the program's resolution, {smallest} mm (dialect {dialect.name} "
                             f"writes lengths to {decimals} decimals), so the program could not show it: give at "
                             f"least {smallest} mm{also}", field=key, operation=number)


def _table_diameter(table: ToolTable, values: Mapping[str, Any]) -> float:
    """The diameter of the operation's tool in the table (:data:`DEFAULT_TOOL_DIAMETER` if it lacks the tool)."""
    tool = table.find(values["tool"])
    if tool is None:
        return DEFAULT_TOOL_DIAMETER
    low, high = TOOL_DIAMETER_RANGE                  # its line, not the operation's tool_diameter (not given)
    if not low <= tool.diameter <= high:
        raise InputError(f"T{tool.number} has diameter {tool.diameter:g} mm in the tool table: a job takes a "
                         f"diameter from {low:g} to {high:g} mm (or give tool_diameter in the operation)",
                         path=table.path, line=tool.line)
    return tool.diameter


def _check_line_numbers(settings: Mapping[str, Any], dialect: Any) -> None:
    """Block numbers that would all be the same (a start plus a step beyond the dialect's largest) are refused."""
    wrap = dialect.line_numbers.wrap_after
    start = dialect.line_numbers.start if settings["line_start"] is None else settings["line_start"]
    step = dialect.line_numbers.step if settings["line_step"] is None else settings["line_step"]
    if start + step > wrap:
        raise FieldError(f"{{line_start}} {start} + {{line_step}} {step} passes dialect {dialect.name}'s largest "
                         f"block number {wrap}: every block would get the same number", field="line_start")
