"""IK and FK results as records, CSV and text: pure formatting for the ``ik`` and ``fk`` commands.

CSV columns and JSON keys are the same names; the CSV writes CSV_DECIMALS fixed decimals (1e-9 mm),
JSON full float precision.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from prs3_post.core.numbers import REPORT_DECIMALS, ChoiceColumn, Column, render_rows, scale_column
from prs3_post.core.numbers import fixed_or_na as fixed
from prs3_post.core.types import FloatArray
from prs3_post.kinematics import FKResult, IKResult
from prs3_post.kinematics.prs3.kinematics import Prs3Kinematics
from prs3_post.post.limits import LimitReport
from prs3_post.readers.poses import POSE_COLUMNS


def ik_columns(joints: tuple[str, ...] | None = None, angles: int = 3) -> tuple[str, ...]:
    """The IK table's columns after the pose: stage ``X``, ``Y``, each joint (``joints``: the
    kinematics' :attr:`~prs3_post.kinematics.protocol.Kinematics.joint_names`; None: the 3-PRS
    head's), each link angle ``theta1_deg`` ..., ``cond`` and ``ok``."""
    names = Prs3Kinematics.joint_names if joints is None else joints
    return ("X", "Y", *names, *(f"theta{i + 1}_deg" for i in range(angles)), "cond", "ok")


FK_COLUMNS = (
    "tip_x", "tip_y", "tip_z", "axis_x", "axis_y", "axis_z",
    "theta1_deg", "theta2_deg", "theta3_deg", "tilt_deg", "converged", "iterations", "residual_mm",
)


def _number(value: float) -> float | None:
    """A JSON-safe float: NaN (unreachable) becomes null."""
    return None if math.isnan(value) else float(value)


def ik_records(tip: FloatArray, axis: FloatArray, ik: IKResult, report: LimitReport,
               joints: tuple[str, ...] | None = None) -> list[dict[str, Any]]:
    """One record per pose: the pose, :func:`ik_columns`, and ``violations`` (limit, value, margin).

    Angles in the records are degrees, as their names say; margins are in each limit's unit.
    """
    values = np.column_stack([
        tip, axis, ik.stage, ik.strokes, np.degrees(ik.link_angle), ik.condition,
    ])
    names = POSE_COLUMNS + ik_columns(joints, ik.link_angle.shape[1])[:-1]
    records = []
    for row in range(len(values)):
        record: dict[str, Any] = {name: _number(v) for name, v in zip(names, values[row].tolist(), strict=True)}
        record["ok"] = bool(report.ok[row])
        record["reachable"] = bool(ik.reachable[row])
        record["violations"] = _violations(report, row)
        records.append(record)
    return records


def _violations(report: LimitReport, row: int) -> list[dict[str, Any]]:
    """The limits ``row`` breaks: name, value, margin (negative) and unit."""
    return [
        {
            "limit": report.names[col],
            "value": _number(_shown(report, row, col, report.value)),
            "margin": _number(_shown(report, row, col, report.margin)),
            "unit": report.units[col],
        }
        for col in range(len(report.names))
        if not report.margin[row, col] >= 0.0
    ]


def _limit_lines(record: dict[str, Any]) -> list[str]:
    """``ok: within every limit``, or one ``LIMIT`` line per violation."""
    lines = ["ok: within every limit"] if record["ok"] else []
    for v in record["violations"]:
        unit = f" {v['unit']}" if v["unit"] else ""
        lines.append(f"LIMIT {v['limit']}: {fixed(v['value'])}{unit} (margin {fixed(v['margin'])}{unit})")
    return lines


def _shown(report: LimitReport, row: int, col: int, table: FloatArray) -> float:
    value = float(table[row, col])
    return math.degrees(value) if report.units[col] == "deg" else value


#: Digits after the point in the batch CSV: 1e-9 mm for lengths (far below any machine's resolution),
#: 1e-9 for the unit axes and the condition number, 1e-9° for angles. Fixed decimals, not ``repr``:
#: a whole column is written at once (:mod:`prs3_post.core.numbers`), several times faster.
CSV_DECIMALS = 9


def ik_csv_header(joints: tuple[str, ...] | None = None) -> bytes:
    """The batch output's header line: the input columns, then :func:`ik_columns`."""
    return (",".join(POSE_COLUMNS + ik_columns(joints)) + "\n").encode("ascii")


def ik_csv_rows(tip: FloatArray, axis: FloatArray, ik: IKResult, report: LimitReport) -> bytes:
    """The batch output's lines for N poses (ASCII, ``\n`` endings): the pose, :func:`ik_columns` with
    CSV_DECIMALS decimals (``nan`` where a pose is unreachable), ``ok`` as ``true``/``false``."""
    values = np.column_stack([tip, axis, ik.stage, ik.strokes, np.degrees(ik.link_angle), ik.condition])
    columns: list[Column] = [(b"", scale_column(values[:, j], CSV_DECIMALS)) for j in range(values.shape[1])]
    columns.append(ChoiceColumn(report.ok.astype(np.int64), (b"false", b"true")))
    buffer, _ = render_rows(columns, np.ones((len(values), len(columns)), dtype=bool), separator=b",")
    return buffer.tobytes()


def ik_text(record: dict[str, Any]) -> str:
    """A short human-readable report of one IK record."""
    def show(key: str, decimals: int = REPORT_DECIMALS) -> str:
        return fixed(record[key], decimals)

    keys = list(record)
    joints = keys[keys.index("Y") + 1:keys.index("theta1_deg")]      # the kinematics' joints, in order
    angles = [key for key in keys if key.startswith("theta")]
    lines = [
        f"tip   {show('tip_x')} {show('tip_y')} {show('tip_z')} mm   axis {show('axis_x', 6)} "
        f"{show('axis_y', 6)} {show('axis_z', 6)}",
        f"stage X {show('X')}  Y {show('Y')} mm",
        "strokes " + "  ".join(f"{name} {show(name)}" for name in joints) + " mm",
        "link angles " + "  ".join(show(name) for name in angles) + " deg",
        f"condition number {show('cond', 3)}",
    ]
    return "\n".join(lines + _limit_lines(record)) + "\n"


def fk_records(fk: FKResult, report: LimitReport) -> list[dict[str, Any]]:
    """One record per actuator setting, keys FK_COLUMNS (angles in degrees), ``ok`` and ``violations``
    (limit, value, margin) from ``report``, the limits checked at the same setting (as :func:`ik_records`)."""
    tilt = np.degrees(np.arccos(np.clip(fk.axis[:, 2], -1.0, 1.0)))   # clip: rounding past 1
    values = np.column_stack([fk.tip, fk.axis, np.degrees(fk.link_angle), tilt])
    records = []
    for row in range(len(values)):
        record: dict[str, Any] = {
            name: _number(v) for name, v in zip(FK_COLUMNS[:10], values[row].tolist(), strict=True)
        }
        record["converged"] = bool(fk.converged[row])
        record["iterations"] = int(fk.iterations[row])
        record["residual_mm"] = float(fk.residual[row])
        record["ok"] = bool(report.ok[row])
        record["violations"] = _violations(report, row)
        records.append(record)
    return records


def fk_text(record: dict[str, Any]) -> str:
    """A short human-readable report of one FK record."""
    r = {key: fixed(value, 6 if key.startswith("axis") else 4) if isinstance(value, float) else value
         for key, value in record.items()}
    return (
        f"tip   {r['tip_x']} {r['tip_y']} {r['tip_z']} mm\n"
        f"axis  {r['axis_x']} {r['axis_y']} {r['axis_z']}   tilt {r['tilt_deg']} deg\n"
        f"link angles {r['theta1_deg']}  {r['theta2_deg']}  {r['theta3_deg']} deg\n"
        f"converged in {record['iterations']} Newton steps, residual {record['residual_mm']:.1e} mm\n"
    ) + "".join(line + "\n" for line in _limit_lines(record))
