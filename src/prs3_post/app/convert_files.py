"""Convert CAM output files into programs for a machine given by name: the library's face of ``convert``."""

from __future__ import annotations

from collections.abc import Sequence

from prs3_post.app.batch import BatchResult, collect_inputs, convert_batch
from prs3_post.app.convert import ConvertSettings
from prs3_post.app.kinematics import machine_of
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.machine.loading import DEFAULT_DIALECT, DEFAULT_MACHINE, Dialect, Machine, load_dialect
from prs3_post.part.setup_transform import Setup

__all__ = ["convert_files"]


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
    loaded = machine_of(machine)
    words = load_dialect(dialect) if isinstance(dialect, str) else dialect
    settings = ConvertSettings(machine=loaded, dialect=words,
                               setup=Setup.resolve(loaded) if setup is None else setup, tolerance=tolerance)
    files = collect_inputs(inputs, exclude=outdir, exclude_suffix=words.extension)
    return convert_batch(files, outdir, settings, jobs=jobs, force=force)
