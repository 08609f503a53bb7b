"""What the main job and a job file wrote, for scripts (``--json``): one JSON object made from the
checked job's own results (its header's setup and faces, the closest approach to each limit tallied
as the rows were posted, the collision check's closest body, the cycle time and the feeds slowed),
nothing computed again."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.core.errors import shown_path

if TYPE_CHECKING:
    from prs3_post.app.job import JobProgram, JobSpec
    from prs3_post.core.types import IntArray

__all__ = ["Written", "job_record"]


@dataclass(frozen=True, slots=True)
class Written:
    """A program as written: where, and its size.

    Attributes
    ----------
    path : str — as given (``-``: standard output)
    lines : int
    bytes : int — UTF-8
    """

    path: str
    lines: int
    bytes: int


def job_record(job: JobProgram, specs: tuple[JobSpec, ...], written: Written, row_lines: IntArray) -> dict[str, Any]:
    """The checked job as JSON-ready data.

    Parameters
    ----------
    job : JobProgram — checked with ``margins`` (:func:`~prs3_post.app.job.check_operations`)
    specs : the job's operations
    written : Written — the program file
    row_lines : (N,) int — the program line of each of its N motion rows (as a reader numbers them)
    """
    first = specs[0]
    record: dict[str, Any] = {
        "program": {"path": shown_path(written.path), "lines": written.lines, "bytes": written.bytes,
                    "moves": len(job.program)},
        "machine": first.machine.name,
        "dialect": first.dialect.name,
        "part": {"path": first.part, "units": first.units, "up": first.up},
        "setup": {"part_origin_mm": [float(v) for v in job.setup.origin],
                  "part_rotation_deg": float(job.setup.rotation_deg),
                  "chosen": None if job.placement is None else job.placement.describe()},
        "faces": [_face_record(face, spec, note=job.face_note if k == 0 else None)
                  for k, (face, spec) in enumerate(zip(job.faces, specs, strict=True))],
        "margins": _margins(job, row_lines),
        "collision": _collision(job, specs, row_lines),
        "cycle_time": None if job.cycle_minutes is None else {"minutes": job.cycle_minutes,
                                                              "seconds": job.cycle_minutes * 60.0},
        "slowed_moves": job.slowed_moves,
        "header": {"dynamics": job.dynamics, "collision": dict(job.header).get("collision")},
    }
    return record


def _face_record(face: Any, spec: JobSpec, *, note: str | None) -> dict[str, Any]:
    return {"index": int(face.index), "asked": "auto" if spec.face is None else spec.face,
            "inclination_deg": math.degrees(face.inclination), "normal": [float(v) for v in face.normal],
            "origin_mm": [float(v) for v in face.origin], "area_mm2": float(face.area),
            **({"choice": note} if note is not None else {})}


def _line(row_lines: IntArray, row: int) -> int | None:
    return int(row_lines[row]) if 0 <= row < len(row_lines) else None


def _margins(job: JobProgram, row_lines: IntArray) -> list[dict[str, Any]]:
    """Each limit's closest approach: as `verify --json` lists its ``limits`` (degrees where the unit is)."""
    tally = job.limits
    if tally is None or not tally.names:
        return []
    from prs3_post.check.verify import margin_fraction

    spread = margin_fraction(tally.closest())
    out = []
    for col, name in enumerate(tally.names):
        scale = math.degrees(1.0) if tally.units[col] == "deg" else 1.0
        margin = float(tally.margin[col])
        out.append({"limit": name, "unit": tally.units[col], "min": _number(tally.low[col] * scale),
                    "max": _number(tally.high[col] * scale), "value": _number(tally.value[col] * scale),
                    "margin": _number(margin * scale), "margin_fraction": _number(margin / float(spread[col])),
                    "line": _line(row_lines, int(tally.row[col]))})
    return out


def _collision(job: JobProgram, specs: tuple[JobSpec, ...], row_lines: IntArray) -> dict[str, Any]:
    """Whether the tool, holder and nose were checked, against what clearance, and the closest body."""
    checked = any(spec.collision_check for spec in specs)
    closest = job.closest
    found = None
    if closest is not None:
        from prs3_post.check.collision_bodies import BODY_NAMES

        found = {"body": BODY_NAMES[closest.body], "clearance_mm": float(closest.distance),
                 "exact": bool(closest.exact), "line": _line(row_lines, int(closest.row))}
    return {"checked": checked, "clearance_min_mm": float(min(s.clearance_min for s in specs)), "closest": found}


def _number(value: float | np.floating[Any]) -> float | None:
    """A finite number, or None (JSON has no infinity: a one-sided limit's other bound)."""
    number = float(value)
    return number if math.isfinite(number) else None
