"""The main job and job files as use cases: a request in, a checked program (and its picture) out.

:func:`check_request` runs a :class:`~prs3_post.app.requests.JobRequest` (one operation or several);
:func:`job_preview` draws the program it made; :func:`post_part` and :func:`run_job_file` are the
library's one-call faces of ``prs3-post PART.stl ...`` and ``prs3-post job JOB.toml``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from prs3_post.app.requests import JobRequest, job_request, job_specs
from prs3_post.core.defaults import NOMINAL_RAPID_RATE

if TYPE_CHECKING:
    from prs3_post.app.job import JobProgram, JobSpec
    from prs3_post.readers.jobfile import JobFile

__all__ = ["check_request", "check_specs", "job_json", "job_preview", "post_part", "read_job", "run_job_file"]


def read_job(path: str) -> JobFile:
    """A job file, its structure checked (:func:`~prs3_post.readers.jobfile.read_job_file`; its values are
    the request's to check: :meth:`~prs3_post.readers.jobfile.JobFile.as_data`)."""
    from prs3_post.readers.jobfile import read_job_file

    return read_job_file(path)


def check_request(request: JobRequest) -> tuple[tuple[JobSpec, ...], JobProgram]:
    """Each operation's JobSpec, and the job they make, checked (every row against every limit, the
    collision check) and ready to be written (:meth:`~prs3_post.app.job.JobProgram.chunks`).

    Raises
    ------
    FieldError, UnusedFields, FeatureError, InputError, ConfigError
        As :func:`~prs3_post.app.requests.job_specs` and the job (a feature that does not fit).
    LimitError, ReachError
        A point outside a limit or out of reach (with the placement's suggestion, :mod:`prs3_post.check.placement`).
    """
    specs = job_specs(request)
    return specs, check_specs(specs)


def check_specs(specs: tuple[JobSpec, ...], *,
                placement_hint: Callable[[tuple[str, str, str] | None], str] | None = None,
                margins: bool = False) -> JobProgram:
    """The job of these operations, checked (:func:`~prs3_post.app.job.check_operations`; ``margins``:
    with each limit's closest approach, for :func:`job_json`).

    ``placement_hint`` words, for a job that does not fit its setup, what to do about it: the front
    end's way to give the part origin that works (its argument; None: no translation of the part
    does); the error's message then ends with it. An error whose message says what to change instead
    (a collision no setup avoids: ``blocked``) is left as it is.
    """
    from prs3_post.app.job import check_job, check_operations
    from prs3_post.check.placement import Placement

    try:
        return check_job(specs[0], margins=margins) if len(specs) == 1 else check_operations(specs, margins=margins)
    except Placement as error:
        if placement_hint is None or error.blocked:
            raise
        origin = error.suggested_origin
        raise type(error)(f"{error}: {placement_hint(origin)}", setup=error.setup, suggested_origin=origin) from error


def job_json(job: JobProgram, specs: tuple[JobSpec, ...], path: str, text: str) -> str:
    """What a checked job wrote to ``path`` (its program ``text``), as one line of JSON
    (:func:`~prs3_post.app.run_report.job_record`); each row's program line is read from the text, as
    the preview names its lines."""
    import json

    from prs3_post.app.run_report import Written, job_record
    from prs3_post.readers.program import read_program

    first = specs[0]
    moves = read_program(text, first.dialect, path=path, stage=first.machine.stage.present,
                         kinematics=job.kinematics).moves
    written = Written(path=path, lines=text.count("\n"), bytes=len(text.encode("utf-8")))
    return json.dumps(job_record(job, specs, written, moves.source), allow_nan=False)


def job_preview(job: JobProgram, specs: tuple[JobSpec, ...], fmt: str, *, text: str, path: str, title: str) -> bytes:
    """The picture of a checked job's program (``text``, read back as the controller reads it) on its
    part and each operation's face, as ``png`` or ``svg`` bytes (:func:`~prs3_post.app.preview.preview_bytes`)."""
    from prs3_post.app.preview import preview_bytes
    from prs3_post.emit.header_read import header_comments, parse_header
    from prs3_post.readers.program import read_program

    first = specs[0]
    program = read_program(text, first.dialect, path=path, stage=first.machine.stage.present)
    style = first.dialect.comments
    head = text[:65536]                                # the header's lines: its operations, tools, the setup
    header = parse_header(header_comments(head[:head.rfind("\n") + 1], open_=style.open, close=style.close), path=path)
    lengths = (None if first.tool_table is None
               else {spec.cutting.tool_number: length for spec, length in zip(specs, job.tool_lengths, strict=True)})
    return preview_bytes(program, first.machine, job.setup, fmt, tolerance=first.tolerance, tool_lengths=lengths,
                         mesh=job.triangles, faces=job.faces, title=title, dialect=first.dialect, closest=job.closest,
                         header=header, rapid_rate=NOMINAL_RAPID_RATE)


def post_part(part: str, *, profile: str, operation: Mapping[str, Any] | None = None, **settings: Any) -> str:
    """The main job on a part's inclined face: a hole, square or round profile, as G-code text.

    Parameters
    ----------
    part : str — the STL file
    profile : str — ``hole``, ``square`` or ``round``
    operation : mapping, optional — the operation's other keys, as a job file's ``[[operation]]``
        (``depth``, ``at``, ``tool_diameter``, ...; :data:`~prs3_post.app.requests.OPERATION_FIELDS`)
    **settings — the job's settings, as a job file's top-level keys (``machine``, ``dialect``, ``units``,
        ``tolerance``, ...; :data:`~prs3_post.app.requests.SETTING_FIELDS`) and ``setup``
        (``{"part_origin": [x, y, z], "part_rotation_deg": θ}``)

    Returns
    -------
    str — the program, checked against every limit of the machine

    Raises
    ------
    FieldError
        A value that is wrong, naming its key.
    FeatureError, LimitError, ReachError, InputError, ConfigError
        As the main job.
    """
    data = {"part": part, **settings, "operation": [{"profile": profile, **(operation or {})}]}
    _, job = check_request(job_request(data))
    return "".join(job.chunks())


def run_job_file(path: str, **overrides: Any) -> str:
    """A job file's program (several operations on one part), as G-code text.

    Parameters
    ----------
    path : str — the job file (TOML; the format is in :mod:`prs3_post.readers.jobfile`)
    **overrides — settings that replace the file's (``machine``, ``dialect``, ``collision_check``,
        ``setup={"part_origin": ...}``), as a job file spells them

    Raises
    ------
    InputError
        A job file that cannot be read or has a key it does not know.
    FieldError, FeatureError, LimitError, ReachError, ConfigError
        As :func:`post_part`.
    """
    data = read_job(path).as_data()
    setup = {**data.get("setup", {}), **overrides.pop("setup", {})}
    _, job = check_request(job_request({**data, **overrides, "setup": setup}))
    return "".join(job.chunks())

