"""A verify report as text (short, for people) and as JSON-ready data (complete).

Pure formatting of a :class:`~prs3_post.check.verify.VerifyReport`; the numbers are computed in
:mod:`prs3_post.check.verify`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from prs3_post.check.verify import NOMINAL_RAPID_RATE, VerifyReport, row_times
from prs3_post.core.errors import shown_path
from prs3_post.core.numbers import fixed_or_na as fixed
from prs3_post.core.toolpath import EventKind, MoveKind
from prs3_post.core.types import FloatArray, IntArray
from prs3_post.kinematics.replay import MAX_INTERVALS, PROBE_INTERVALS, joints_of

__all__ = ["against_summary", "clearance_record", "report_record", "report_text", "summary"]

if TYPE_CHECKING:
    from prs3_post.app.verify import PartClearance

#: Rows of the text report's problem list.
SHOWN_PROBLEMS = 10


def _num(value: float) -> float | None:
    """A JSON-safe float (NaN and infinities become null)."""
    value = float(value)
    return value if math.isfinite(value) else None


def _nums(values: FloatArray) -> list[Any]:
    """Nested lists of JSON-safe floats."""
    array = np.asarray(values, dtype=np.float64)
    return [_nums(v) for v in array] if array.ndim > 1 else [_num(v) for v in array.tolist()]


def _kind_name(kind: int) -> str:
    return "feed" if kind == MoveKind.FEED else "rapid"


def _worst(values: FloatArray, rows: IntArray, lines: IntArray) -> tuple[float | None, int | None, int | None]:
    """Max of ``values`` (NaN ignored): value, program line, sample index."""
    if not np.isfinite(values).any():
        return None, None, None
    i = int(np.nanargmax(values))
    return float(values[i]), int(lines[rows[i]]), i


def summary(report: VerifyReport, *, rapid_rate: float) -> dict[str, Any]:
    """Headline numbers shared by the text and JSON reports (from the per-move values: no samples needed)."""
    program = report.program
    feed_row = program.kind == MoveKind.FEED
    known = report.duration is not None and (report.dynamics is not None or rapid_rate == NOMINAL_RAPID_RATE)
    start, end = row_times(program, rapid_rate=rapid_rate, dynamics=report.dynamics,
                           durations=report.duration if known else None)
    durations = end - start
    dwell = sum(e.value for e in program.events if e.kind is EventKind.DWELL) / 60.0
    straight, straight_line, _ = _worst(report.straightness, np.arange(len(program)), program.source)
    implied = report.implied_feed[np.isfinite(report.implied_feed)]
    return {
        "moves": len(program), "feed_moves": int(feed_row.sum()), "rapid_moves": int((~feed_row).sum()),
        "samples": report.samples,
        "intervals_min": int(report.intervals[1:].min()) if len(program) > 1 else 0,
        "intervals_max": int(report.intervals[1:].max()) if len(program) > 1 else 0,
        "sampling_bound_mm": float(report.bound.max()) if len(program) else 0.0,
        "straightness_mm": straight, "straightness_line": straight_line,
        "implied_feed_min": float(implied.min()) if len(implied) else None,
        "implied_feed_max": float(implied.max()) if len(implied) else None,
        "time_feed_min": float(durations[feed_row].sum()), "time_rapid_min": float(durations[~feed_row].sum()),
        "time_dwell_min": float(dwell), "time_total_min": float(end[-1]) if len(end) else 0.0,
        "time_model": "trapezoid" if report.dynamics is not None else "nominal rapid rate",
        "axis_speed_max_fraction": report.fastest[0] if report.dynamics is not None else None,
        "axis_speed_max_line": report.fastest[1] if report.dynamics is not None else None,
        "axis_speed_max_axis": report.fastest[2] if report.dynamics is not None else None,
    }


def against_summary(report: VerifyReport) -> dict[str, Any] | None:
    """The deviation from the intended path in a few numbers (None without ``--against``).

    Max and mean of the tip deviation (mm) and of the axis deviation (degrees), with the line of
    each maximum: the ``against`` entry of the JSON report and the text report's ``against`` line.
    Reductions over the samples only: no per-sample lists (the text report calls it).
    """
    a = report.against
    if a is None:
        return None
    rep, lines = report.samples_kept, report.program.source
    tip = np.linalg.norm(a.tip_deviation, axis=1)
    tip_max, tip_line, tip_i = _worst(tip, rep.row, lines)
    axis_max, axis_line, _ = _worst(a.axis_deviation, rep.row, lines)
    return {
        "label": a.label, "compared_samples": int(a.compared.sum()),
        "tip_max_mm": tip_max, "tip_max_line": tip_line,
        "tip_max_at": None if tip_i is None else float(rep.fraction[tip_i]),
        "tip_max_vector_mm": None if tip_i is None else _nums(a.tip_deviation[tip_i]),
        "tip_mean_mm": _num(np.nanmean(tip)) if np.isfinite(tip).any() else None,
        "axis_max_deg": None if axis_max is None else math.degrees(axis_max), "axis_max_line": axis_line,
        "axis_mean_deg": _num(math.degrees(np.nanmean(a.axis_deviation)))
        if np.isfinite(a.axis_deviation).any() else None,
    }


def clearance_record(clearance: PartClearance | str | None) -> dict[str, Any] | None:
    """The clearance of the tool, holder and spindle nose from the part (``verify --against PART.stl``):
    each body's minimum (mm, negative: a penetration's depth), its line, the fraction along that move,
    the job's step, the body's point there (part frame), whether it is exact or a lower bound, the
    clearance min it was held to; ``closest``: the body nearest its clearance min. A text: why it was
    not measured. None: not asked (no part)."""
    if clearance is None:
        return None
    if isinstance(clearance, str):
        return {"measured": False, "note": clearance}
    from prs3_post.check.collision import BODY_NAMES  # measured: the collision module is loaded already
    bodies = [
        {"body": name, "rapids_only": b == 0 and clearance.tool_in_rapids,
         **({"rapids_tool": clearance.rapids_tool} if b == 0 and clearance.tool_in_rapids else {}),
         "distance_mm": _num(clearance.distance[b]), "exact": bool(clearance.exact[b]),
         "line": int(clearance.line[b]) or None, "at": _num(clearance.at[b]) if clearance.line[b] else None,
         "step": clearance.step[b] or None,
         "point_part_mm": _nums(clearance.point[b]) if clearance.line[b] else None,
         "clearance_min_mm": float(clearance.clearance_min[b]),
         "ok": not clearance.distance[b] < clearance.clearance_min[b]}
        for b, name in enumerate(BODY_NAMES)]
    return {"measured": True, "allowance": clearance.allowance, "bodies": bodies,
            "closest": BODY_NAMES[clearance.worst()]}


def _clearance_lines(clearance: PartClearance | str | None) -> list[str]:
    """The text report's lines on the clearance from the part."""
    if clearance is None:
        return []
    if isinstance(clearance, str):
        return [f"  clearance from the part: {clearance}"]
    from prs3_post.check.collision import BODY_NAMES  # measured: the collision module is loaded already
    held = clearance.clearance_min[1:] if clearance.tool_in_rapids else clearance.clearance_min
    asked = sorted(set(held.tolist()))
    out = [f"  clearance from the part (min {', '.join(f'{v:.3f}' for v in asked)} mm; not counted: "
           f"{clearance.allowance}):"]
    for b, name in enumerate(BODY_NAMES):
        if b == 0 and clearance.tool_in_rapids:         # a converted program's tool: held out of the part in rapids
            name = "tool, rapids"
            if not clearance.line[b]:
                out.append(f"    {name:<12}  none to check (a retract along the tool axis is not; "
                           f"{clearance.rapids_tool})")
                continue
        if not clearance.line[b]:
            out.append(f"    {name:<12}  not measured at any pose")
            continue
        d = float(clearance.distance[b])
        shown = f"{'over ' if not clearance.exact[b] else ''}{d:.3f} mm"
        step = f" ({clearance.step[b]})" if clearance.step[b] else ""
        tool = f" ({clearance.rapids_tool})" if b == 0 and clearance.tool_in_rapids else ""
        out.append(f"    {name:<12}  {shown:>14}  line {clearance.line[b]}{step}{tool}")
    return out


def report_record(report: VerifyReport, *, path: str = "", dialect: str = "", rapid_rate: float,
                  clearance: PartClearance | str | None = None) -> dict[str, Any]:
    """The complete report as JSON-ready data (angles in degrees where the key says ``_deg``);
    ``clearance``: :func:`clearance_record`."""
    program, rep = report.program, report.samples_kept
    head = summary(report, rapid_rate=rapid_rate)
    lines = program.source
    tip_part = report.tip_part
    rows = []
    joints = joints_of(program)
    for r in range(len(program)):
        e = int(rep.end[r])
        record: dict[str, Any] = {
            "line": int(lines[r]), "kind": _kind_name(int(program.kind[r])),
            "X": _num(joints[r, 0]), "Y": _num(joints[r, 1]),
            **{name: _num(joints[r, 2 + j]) for j, name in enumerate(report.joint_names)},
            "F": _num(program.inverse_time[r]) if program.kind[r] == MoveKind.FEED else None,
            "tip_part": _nums(tip_part[e]), "axis": _nums(rep.axis[e]),
            "intervals": int(report.intervals[r]), "sampling_bound_mm": _num(report.bound[r]),
            "rounding_mm": _num(report.rounding[r]), "chord_mm": _num(report.chord[r]),
            "straightness_mm": _num(report.straightness[r]),
            "implied_feed_mm_per_min": _num(report.implied_feed[r]),
        }
        if report.against is not None:
            a = report.against
            record["tip_deviation_mm"] = _nums(a.tip_deviation[e])
            record["tip_deviation_norm_mm"] = _num(float(np.linalg.norm(a.tip_deviation[e])))
            record["axis_deviation_deg"] = _num(math.degrees(a.axis_deviation[e]))
        rows.append(record)
    return {
        "program": shown_path(path), "dialect": dialect, "machine": report.machine, "ok": report.ok,
        "part_origin_mm": list(report.setup.origin), "part_rotation_deg": report.setup.rotation_deg,
        "tolerance_mm": report.tolerance,
        "axis_tolerance_deg": math.degrees(report.axis_tolerance),
        **head,
        "sampling": {
            "rule": "n = max(8, ceil(sqrt(M / (8 eps)))) intervals per move, M = 2 max|f''| from second "
                    "differences of the tip and of link length x link angle, eps = tolerance / 20; "
                    "bound = M / (8 n^2)",
            "epsilon_mm": report.epsilon, "probe_intervals": PROBE_INTERVALS, "max_intervals": MAX_INTERVALS,
        },
        "rapid_rate_mm_per_min": rapid_rate,
        "limits": [
            {"limit": c.name, "unit": c.unit, "min": _num(c.low), "max": _num(c.high), "value": _num(c.value),
             "margin": _num(c.margin), "margin_fraction": _num(c.fraction_of_range), "line": c.line, "at": c.at}
            for c in report.closest
        ],
        "feeds": {
            "mode": "G93 inverse time: F = 1/min of each G1; implied tip feed = chord x F",
            "groups": [{"feed_mm_per_min": g.feed, "moves": len(g.lines), "lines": g.lines.tolist()}
                       for g in report.feed_groups],
        },
        "against": against_summary(report),
        "clearance": clearance_record(clearance),
        "problems": [{"line": p.line, "kind": p.kind, "message": p.message} for p in report.problems],
        "warnings": [{"line": p.line, "kind": p.kind, "message": p.message} for p in report.warnings],
        "moves_detail": rows,
        "path": {
            "line": [int(v) for v in lines[rep.row].tolist()], "fraction": rep.fraction.tolist(),
            "kind": [_kind_name(int(k)) for k in program.kind[rep.row].tolist()],
            "tip_part": _nums(tip_part), "axis": _nums(rep.axis),
        },
    }


def report_text(report: VerifyReport, *, path: str = "", dialect: str = "", rapid_rate: float,
                clearance: PartClearance | str | None = None, all_listed: str = "") -> str:
    """A short readable report: headline, limits, feeds, deviation, clearance from the part, result.

    ``all_listed``: what lists every warning and problem when some are left out (the command line's
    ``--json lists all``), said after the count of those left out; empty: nothing said."""
    hint = f" ({all_listed})" if all_listed else ""
    head = summary(report, rapid_rate=rapid_rate)
    out = [
        f"{shown_path(path)}: {head['moves']} moves ({head['feed_moves']} G1, {head['rapid_moves']} G0), "
        f"dialect {dialect}, machine {report.machine}",
        f"  replay: {head['samples']} FK samples, {head['intervals_min']}..{head['intervals_max']} intervals per move, "
        f"sampling error ≤ {head['sampling_bound_mm']:.1e} mm",
    ]
    if head["straightness_mm"] is not None:
        out.append(f"  straightness: G1 tips within {head['straightness_mm']:.6f} mm of their chords "
                   f"(tolerance {report.tolerance:g} mm; worst line {head['straightness_line']})")
    out.append("  limits, closest approach:")
    width = max((len(c.name) for c in report.closest), default=0)
    for c in report.closest:
        unit = f" {c.unit}" if c.unit else ""
        bounds = (f"{fixed(c.low, 1)}..{fixed(c.high, 1)}" if math.isfinite(c.low) and math.isfinite(c.high)
                  else f"≤ {fixed(c.high, 1)}")
        out.append(f"    {c.name:<{width}}  {fixed(c.value):>9}{unit:<4} margin {fixed(c.margin):>9}{unit:<4}"
                   f" ({100 * c.fraction_of_range:5.1f} % of {bounds}{unit}) line {c.line}")
    if head["implied_feed_min"] is not None:
        groups = ", ".join(f"{g.feed:.1f} ×{len(g.lines)}" for g in report.feed_groups[:6])
        more = f", ... ({len(report.feed_groups)} groups)" if len(report.feed_groups) > 6 else ""
        out.append(f"  feeds (G93, chord × F): {head['implied_feed_min']:.1f}..{head['implied_feed_max']:.1f} mm/min; "
                   f"{groups}{more}")
    if report.dynamics is None:
        out.append(f"  time: {head['time_total_min']:.3f} min (G1 {head['time_feed_min']:.3f}, G0 "
                   f"{head['time_rapid_min']:.3f} at {rapid_rate:g} mm/min, dwell {head['time_dwell_min']:.3f})")
    else:
        out.append(f"  cycle time: {head['time_total_min']:.3f} min (G1 {head['time_feed_min']:.3f}, G0 "
                   f"{head['time_rapid_min']:.3f}, dwell {head['time_dwell_min']:.3f}; trapezoidal profile of the "
                   "slowest axis, the machine's speeds and accelerations)")
        fastest, line, axis = report.fastest
        if line:
            out.append(f"  axis speeds: G1 at most {100 * fastest:.1f} % of the top speed ({axis}, line {line})")
    rec = against_summary(report)
    if rec is not None:
        out.append(f"  against {rec['label']}: tip max {fixed(rec['tip_max_mm'], 6)} mm at line {rec['tip_max_line']}"
                   f" (mean {fixed(rec['tip_mean_mm'], 6)}), axis max {fixed(rec['axis_max_deg'])}° at line "
                   f"{rec['axis_max_line']} (mean {fixed(rec['axis_mean_deg'])}°)")
    out += _clearance_lines(clearance)
    for w in report.warnings[:SHOWN_PROBLEMS]:
        out.append(f"  warning: {w.message}")
    if len(report.warnings) > SHOWN_PROBLEMS:
        out.append(f"  ... and {len(report.warnings) - SHOWN_PROBLEMS} more warnings{hint}")
    if report.ok:
        out.append("OK: within every limit and tolerance")
    else:
        out.append(f"FAIL: {len(report.problems)} problem{'s' if len(report.problems) > 1 else ''}")
        out += [f"  {p.message}" for p in report.problems[:SHOWN_PROBLEMS]]
        if len(report.problems) > SHOWN_PROBLEMS:
            out.append(f"  ... and {len(report.problems) - SHOWN_PROBLEMS} more{hint}")
    return "\n".join(out) + "\n"
