"""Convert CAM output files into programs for a machine given by name: the library's face of ``convert``."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from prs3_post.app.kinematics import machine_of
from prs3_post.app.requests import AUTO, resolve_setup
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.errors import ConfigError, FeatureError, FieldError, InputError
from prs3_post.machine.loading import (
    DEFAULT_DIALECT,
    DEFAULT_MACHINE,
    Dialect,
    Machine,
    load_dialect,
    load_machine,
    load_source,
)
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.detect import FORMATS
from prs3_post.toolpaths.common import TOOL_DIAMETER_RANGE, require_tolerance

# The conversion itself (worker processes, the readers) loads when a conversion runs.
if TYPE_CHECKING:
    from prs3_post.app.batch import BatchResult
    from prs3_post.app.convert import ConvertSettings

#: The input formats `convert` takes (``auto``: by content).
INPUT_FORMATS = tuple(FORMATS)

__all__ = ["INPUT_FORMATS", "convert_files", "convert_settings"]


def convert_files(inputs: Sequence[str], outdir: str, *, machine: Machine | str = DEFAULT_MACHINE,
                  dialect: Dialect | str = DEFAULT_DIALECT, setup: Setup | None = None,
                  tolerance: float = DEFAULT_TOLERANCE, jobs: int = 1, force: bool = False) -> BatchResult:
    """Convert APT CL files and 3+2 G-code programs into programs for the machine, one per input.

    Parameters
    ----------
    inputs : sequence of str — files, directories (searched recursively for CAM files) or glob patterns
    outdir : str — the folder for the programs, ``OUTDIR/<input stem><dialect extension>`` (created if missing)
    machine : Machine | str — a loaded machine, a shipped machine's name or a machine TOML path
    dialect : Dialect | str — a loaded dialect, a shipped dialect's name or a dialect TOML path
    setup : Setup | None — where the part sits on the machine (None: the machine file's default setup)
    tolerance : float — mm, chordal tolerance of arcs and of moves that turn the tool axis
    jobs : int — files converted at a time, in worker processes
    force : bool — replace programs that exist already (False: keep them; that file fails)

    Returns
    -------
    BatchResult — every file's outcome in input order (a failing file does not stop the others)
    """
    from prs3_post.app.batch import collect_inputs, convert_batch
    from prs3_post.app.convert import ConvertSettings

    loaded = machine_of(machine)
    words = load_dialect(dialect) if isinstance(dialect, str) else dialect
    settings = ConvertSettings(machine=loaded, dialect=words,
                               setup=Setup.resolve(loaded) if setup is None else setup, tolerance=tolerance)
    files = collect_inputs(inputs, exclude=outdir, exclude_suffix=words.extension)
    return convert_batch(files, outdir, settings, jobs=jobs, force=force)


def convert_settings(*, machine: str, dialect: str, part_origin: tuple[float, ...] | str | None,
                     part_rotation: float | str | None, tolerance: float, angle_tolerance_deg: float,
                     tool_length: float | None, input_format: str, units: str | None, ignore: tuple[str, ...],
                     work_plane: str | None, part: str | None, part_units: str, part_up: str, source: str | None,
                     tcp_on: tuple[str, ...] | None, tcp_off: tuple[str, ...] | None, line_numbers: bool | None,
                     line_start: int | None, line_step: int | None, collision_check: bool, clearance_min: float,
                     tool_diameter: float | None, clamp: bool = True) -> ConvertSettings:
    """The settings of a conversion (``prs3-post convert``), from names and plain values: the machine,
    dialect and source loaded, the work plane read (``PART.stl[:FACE]`` or numbers), the setup resolved.

    Raises
    ------
    FieldError
        A tool diameter out of range (``tool_diameter``), a work plane that cannot be read
        (``work_plane``), a setup out of range, TCP codes the source cannot take (``tcp_on``/``tcp_off``).
    ConfigError, InputError
        A machine, dialect or source file that is wrong.
    """
    from prs3_post.app.convert import ConvertSettings
    from prs3_post.app.work_plane import WorkPlaneError, work_plane_from_text

    require_tolerance(tolerance)
    low, high = TOOL_DIAMETER_RANGE
    if tool_diameter is not None and not low <= tool_diameter <= high:
        raise FieldError(f"must be from {low:g} to {high:g} mm (got {tool_diameter:g})", field="tool_diameter")
    loaded = load_machine(machine)
    words = load_dialect(dialect)
    try:
        plane = work_plane_from_text(work_plane, units=part_units, up=part_up)[0] if work_plane is not None else None
    except (WorkPlaneError, InputError, FeatureError) as error:
        # the keys the STL's messages name ({units}: its unit) stay keys, for the front end to word
        problem = FieldError(error.carried() if error.names_keys else str(error), field="work_plane")
        problem.names_keys = error.names_keys        # only those: the rest (a path's braces) is as written
        raise problem from error
    convention = None if source is None else load_source(source)
    try:
        return ConvertSettings(
            machine=loaded, dialect=words, setup=resolve_setup(loaded, part_origin, part_rotation),
            tolerance=tolerance, angle_tolerance_deg=angle_tolerance_deg, tool_length=tool_length,
            input_format=input_format, units=units, ignore=tuple(w.upper() for w in ignore),
            work_plane=plane, source=convention, tcp_on=tcp_on, tcp_off=tcp_off,
            line_numbers=line_numbers, line_start=line_start, line_step=line_step,
            auto_origin=part_origin == AUTO, auto_rotation=part_rotation == AUTO, part=part,
            part_units=part_units, part_up=part_up, collision_check=collision_check, clearance_min=clearance_min,
            tool_diameter=tool_diameter, clamp=clamp)
    except ConfigError as error:                     # the TCP codes given do not work with the source
        given = tuple(key for key, codes in (("tcp_on", tcp_on), ("tcp_off", tcp_off)) if codes)
        if convention is None or not given:
            raise
        raise FieldError(f"{error.args[0]} (source {convention.name})", field=given[0], also=given[1:]) from error
