"""The listing use cases: the shipped machines and source conventions, the bundled demo part, a part's faces."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from prs3_post.core.errors import FeatureError
from prs3_post.machine.loading import Machine, load_machine, load_source, postproc_dir, shipped_names

if TYPE_CHECKING:
    from prs3_post.machine.cam_conventions import SourceConvention

__all__ = ["demo_part", "faces_json", "faces_text", "machines_json", "shipped_machines", "shipped_sources",
           "sources_json"]


def shipped_machines() -> list[tuple[str, Machine]]:
    """Every shipped machine, by name (``postproc/machines``), loaded."""
    return [(name, load_machine(name)) for name in shipped_names("machines")]


def shipped_sources() -> list[tuple[str, SourceConvention]]:
    """Every shipped 5-axis source convention, by name (``postproc/sources``), loaded."""
    return [(name, load_source(name)) for name in shipped_names("sources")]


def machine_record(name: str, machine: Machine) -> dict[str, Any]:
    """A machine's key facts as JSON-ready data (mm and degrees, as its TOML file gives them)."""
    geometry, limits, stage = machine.geometry, machine.limits, machine.stage
    dynamics = machine.dynamics
    holder = machine.holder
    return {
        "name": name, "description": machine.description, "file": machine.source, "kinematics": machine.kinematics,
        "stage": stage.present,
        "stage_travel_mm": {"x": list(stage.travel_x), "y": list(stage.travel_y)} if stage.present else None,
        "geometry": {"leg_azimuth_deg": [math.degrees(a) for a in geometry.leg_azimuth],
                     "guide_radius_mm": geometry.guide_radius, "link_length_mm": geometry.link_length,
                     "platform_radius_mm": geometry.platform_radius, "tool_length_mm": geometry.tool_length,
                     "gauge_offset_mm": geometry.gauge_offset},
        "limits": {"stroke_mm": list(limits.stroke), "link_angle_deg": [math.degrees(a) for a in limits.link_angle],
                   "max_tilt_deg": math.degrees(limits.max_tilt), "max_condition": limits.max_condition},
        "part_origin_mm": list(machine.part_origin),
        "dynamics": None if dynamics is None else {
            "stroke_speed_mm_per_min": dynamics.stroke_speed, "stroke_accel_mm_per_s2": dynamics.stroke_accel,
            "stage_speed_mm_per_min": dynamics.stage_speed, "stage_accel_mm_per_s2": dynamics.stage_accel},
        "holder": None if holder is None else {
            "holder_diameter_mm": holder.holder_diameter, "holder_length_mm": holder.holder_length,
            "nose_diameter_mm": holder.nose_diameter, "nose_length_mm": holder.nose_length},
    }


def machines_json() -> str:
    """The shipped machines (:func:`machine_record`) as a JSON list, by name."""
    return json.dumps([machine_record(name, machine) for name, machine in shipped_machines()], indent=2,
                      allow_nan=False)


def sources_json() -> str:
    """The shipped 5-axis source conventions as a JSON list, by name: their rotary words (tables then
    heads) or vector words, and TCP codes."""
    return json.dumps([{"name": name, "description": source.description, "file": source.source,
                        "words": source.words, "vector_words": "".join(source.vector_words),
                        "tcp_on": list(source.tcp_on), "tcp_off": list(source.tcp_off)}
                       for name, source in shipped_sources()], indent=2, allow_nan=False)


def demo_part() -> Path:
    """The bundled demo part: the paper's wedge."""
    return postproc_dir() / "parts" / "patel2020-wedge.stl"


def faces_json(part: str, *, units: str, up: str) -> str:
    """A part's faces as JSON (:func:`~prs3_post.part.faces.face_table`)."""
    from prs3_post.part.faces import face_table, find_faces
    from prs3_post.part.stl import load_part

    return json.dumps(face_table(find_faces(load_part(part, units=units, up=up))), indent=2, allow_nan=False)


def faces_text(part: str, *, units: str, up: str, spell: Callable[[str], str] = str) -> str:
    """A part's faces as a table, and the automatic choice (or why there is none) on the last line (the
    keys it names as ``spell`` words them: the command line's flags)."""
    from prs3_post.part.faces import find_faces, format_face_table, select_face
    from prs3_post.part.stl import load_part

    found = find_faces(load_part(part, units=units, up=up))
    try:
        choice = select_face(found, None)[1]
    except FeatureError as error:
        choice = f"auto: {error.worded(spell)}"
    return format_face_table(found) + choice + "\n"
