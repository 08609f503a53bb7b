"""A machine as the text of a machine TOML file (the inverse of :func:`prs3_post.machine.loading.load_machine`).

Every number is written so that it reads back as the same float (angles: the degrees whose radians
are the model's), so that ``load_machine`` of the text gives the same machine. Pure text: the
caller writes the file.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable

from prs3_post.core.numbers import degrees_text, exact_list, exact_text, fixed
from prs3_post.machine.model import Calibration, GeneralGeometry, Machine

__all__ = ["machine_toml"]

#: Decimals at least: mm and degrees to a tenth of a micrometre, unit vectors to 1e-12.
_MM, _UNIT = 4, 12


def _string(text: str) -> str:
    """A TOML basic string (JSON's escapes are TOML's)."""
    return json.dumps(text, ensure_ascii=False)


def _comments(lines: Iterable[str]) -> list[str]:
    return [f"# {line}".rstrip() for line in lines]


def _degrees_list(values: Iterable[float]) -> str:
    return "[" + ", ".join(degrees_text(v, _MM) for v in values) + "]"


def machine_toml(machine: Machine, *, comment: Iterable[str] = ()) -> str:
    """The machine file of ``machine``, with ``comment`` lines at its top.

    Parameters
    ----------
    machine : Machine
    comment : lines of text (without ``#``) for the comment block that opens the file

    Returns
    -------
    str — TOML, ``\\n`` line ends
    """
    g, lim, stage = machine.geometry, machine.limits, machine.stage
    out = _comments(comment)
    out += ["", f"description = {_string(machine.description)}", f"kinematics = {_string(machine.kinematics)}", "",
            "[geometry]",
            "# The head's nominal numbers: where its kinematics start, and the ideal head when no [[legs]] are given.",
            f"leg_azimuth_deg = {_degrees_list(g.leg_azimuth)}",
            f"guide_radius_mm = {exact_text(g.guide_radius, _MM)}",
            f"link_length_mm = {exact_text(g.link_length, _MM)}",
            f"platform_circumradius_mm = {exact_text(g.platform_radius, _MM)}",
            f"tool_length_mm = {exact_text(g.tool_length, _MM)}",
            f"gauge_offset_mm = {exact_text(g.gauge_offset, _MM)}"]
    if g.general is not None:
        out += _general(g.general)
    out += ["", "[limits]",
            f"stroke_mm = {exact_list(lim.stroke, _MM)}",
            f"link_angle_deg = {_degrees_list(lim.link_angle)}",
            f"max_tilt_deg = {degrees_text(lim.max_tilt, _MM)}",
            f"max_condition = {exact_text(lim.max_condition, _MM)}",
            "", "[stage]", f"present = {'true' if stage.present else 'false'}"]
    if stage.present:
        out += [f"travel_x_mm = {exact_list(stage.travel_x, _MM)}", f"travel_y_mm = {exact_list(stage.travel_y, _MM)}"]
    out += ["", "[setup]", f"part_origin_mm = {exact_list(machine.part_origin, _MM)}"]
    if machine.dynamics is not None:
        d = machine.dynamics
        out += ["", "[dynamics]", f"stroke_speed_mm_min = {exact_text(d.stroke_speed, _MM)}",
                f"stroke_accel_mm_s2 = {exact_text(d.stroke_accel, _MM)}",
                f"stage_speed_mm_min = {exact_text(d.stage_speed, _MM)}",
                f"stage_accel_mm_s2 = {exact_text(d.stage_accel, _MM)}"]
    if machine.holder is not None:
        h = machine.holder
        out += ["", "[holder]", f"holder_diameter_mm = {exact_text(h.holder_diameter, _MM)}",
                f"holder_length_mm = {exact_text(h.holder_length, _MM)}",
                f"nose_diameter_mm = {exact_text(h.nose_diameter, _MM)}",
                f"nose_length_mm = {exact_text(h.nose_length, _MM)}"]
    if machine.calibration is not None:
        out += _calibration(machine.calibration)
    return "\n".join(out) + "\n"


def _general(general: GeneralGeometry) -> list[str]:
    """The ``[[legs]]`` tables and the ``[platform]`` table (the tool) of a general head."""
    out = []
    for number, leg in enumerate(general.legs, start=1):
        out += ["", "[[legs]]", f"# leg {number}: machine frame at stroke 0, mm; directions unit",
                f"rail_point_mm = {exact_list(leg.rail_point, _MM)}",
                f"rail_direction = {exact_list(leg.rail_direction, _UNIT)}",
                f"revolute_axis = {exact_list(leg.revolute_axis, _UNIT)}",
                f"link_length_mm = {exact_text(leg.link_length, _MM)}",
                f"platform_joint_mm = {exact_list(leg.platform_joint, _MM)}",
                f"stroke_offset_mm = {exact_text(leg.stroke_offset, _MM)}"]
    out += ["", "[platform]",
            "# The tool in the platform frame, with the tool of geometry.tool_length_mm: its tip, mm, and",
            "# its axis (unit, tip toward the spindle).",
            f"tool_tip_mm = {exact_list(general.tool_tip, _MM)}",
            f"tool_axis = {exact_list(general.tool_axis, _UNIT)}"]
    return out


def _calibration(calibration: Calibration) -> list[str]:
    """The ``[calibration]`` table: the identified parameters' uncertainties."""
    rows = ",\n".join("    [" + ", ".join(fixed(v if math.isfinite(v) else 0.0, 4) for v in row) + "]"
                      for row in calibration.correlation)
    return ["", "[calibration]",
            "# What the calibration determined: each identified parameter's standard deviation (mm for lengths,",
            "# degrees for angles) and their correlations; `prs3-post accuracy` and the program header use them.",
            f"noise_mm = {exact_text(calibration.noise, 6)}",
            "parameters = [" + ", ".join(_string(p) for p in calibration.parameters) + "]",
            "std = [" + ", ".join(exact_text(s, 6) for s in calibration.std) + "]",
            "correlation = [\n" + rows + ",\n]" if calibration.correlation else "correlation = []"]
