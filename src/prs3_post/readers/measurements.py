"""Calibration measurements (CSV) for ``prs3-post calibrate``: one measured pose per line, keeping its line number.

The header names the columns, in any order: ``t1,t2,t3`` the commanded strokes (mm, the zero and
sign of the U V W words), optional ``x,y`` the stage (mm, default 0), ``px,py,pz`` the measured tool
tip in the machine frame with the stage applied (what ``prs3-post fk --strokes ... --xy x,y``
reports), optional ``ax,ay,az`` the measured tool axis (unit, tip → spindle), optional
``tool_length_mm`` when several tools were measured (default: the machine file's tool length).

``calibrate plan`` writes the same header with the measured cells empty: a cell left empty is
refused, naming its line, except that the axis columns may be empty on every line (the axis was
not measured).
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from prs3_post.core.errors import InputError, quoted
from prs3_post.core.input_files import read_text
from prs3_post.core.types import FloatArray, IntArray

__all__ = ["MEASURED_COLUMNS", "MEASUREMENT_COLUMNS", "Measurements", "read_measurements"]

#: Every column a measurement file may have, in the order ``calibrate plan`` writes them.
MEASUREMENT_COLUMNS = ("t1", "t2", "t3", "x", "y", "px", "py", "pz", "ax", "ay", "az", "tool_length_mm")
#: The columns a measuring instrument fills in (``calibrate plan`` leaves them empty).
MEASURED_COLUMNS = ("px", "py", "pz", "ax", "ay", "az")
_REQUIRED = ("t1", "t2", "t3", "px", "py", "pz")
_AXIS = ("ax", "ay", "az")
#: The magnitude a value may have (mm; an axis component is at most 1 after normalizing, a little
#: more as measured): beyond it a value is a typo or a unit error.
VALUE_LIMIT = 1e6
#: How far a measured axis's length may be from 1 (it is normalized, but a length of 0.5 is a wrong column).
AXIS_LENGTH_TOLERANCE = 0.02
#: A plain decimal number (``float()`` also takes ``1_0``, ``١`` and ``nan``: not here).
_PLAIN_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


@dataclass(frozen=True, slots=True)
class Measurements:
    """Measured poses read from a CSV file.

    Attributes
    ----------
    path : str — the file, as given (for messages)
    strokes : (N, 3) float — mm, commanded strokes T1..T3
    stage : (N, 2) float — mm, stage X, Y (0 where the file has no ``x,y``)
    tip : (N, 3) float — mm, measured tool tip, machine frame, stage applied
    axis : (N, 3) float — unit, measured tool axis (tip → spindle); NaN when ``has_axis`` is False
    tool_length : (N,) float — mm, the tool length "TL" of each row; NaN where the file gives none
    line : (N,) int — 1-based line number of each row in the file
    has_axis : bool — the file gives the tool axis
    """

    path: str
    strokes: FloatArray
    stage: FloatArray
    tip: FloatArray
    axis: FloatArray
    tool_length: FloatArray
    line: IntArray
    has_axis: bool

    def rows(self, index: IntArray) -> Measurements:
        """The rows ``index`` (an array of row indices or a mask) of this table."""
        return Measurements(path=self.path, strokes=self.strokes[index], stage=self.stage[index], tip=self.tip[index],
                            axis=self.axis[index], tool_length=self.tool_length[index], line=self.line[index],
                            has_axis=self.has_axis)


def _csv_rows(rows: Iterator[list[str]], path: str) -> Iterator[list[str]]:
    """The csv reader's rows, one a line; its own error (a field over its 131072-character limit) as an
    InputError naming the line."""
    number = 0
    try:
        for row in rows:
            number += 1
            yield row
    except csv.Error as exc:
        raise InputError(f"cannot read the line as CSV: {exc}", path=path, line=number + 1) from exc


def read_measurements(path: str) -> Measurements:
    """Read a measurement CSV (see the module's docstring).

    Blank lines are skipped; a value that is not a plain decimal number within ±1e6, a missing
    measured value, an axis of length far from 1 are errors naming the line and the column.

    Raises
    ------
    InputError
        ``meas.csv:7: pz is empty: fill in the measured tool tip (px, py, pz)``, an unknown or repeated
        column, a missing required column, no rows.
    """
    lines = read_text(path, "a CSV file").splitlines()
    rows = _csv_rows(csv.reader(lines), path)
    header = next(rows, None)
    if header is None or not any(cell.strip() for cell in header):
        raise InputError(f"expected a header naming the columns ({','.join(MEASUREMENT_COLUMNS)}), got an empty "
                         "line", path=path, line=1)
    names = [cell.strip() for cell in header]
    columns = _columns(names, path)
    values: list[list[float]] = []
    line_numbers: list[int] = []
    axis_given: list[bool] = []
    for number, row in enumerate(rows, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(names):
            raise InputError(f"expected {len(names)} values ({','.join(names)}), got {len(row)}", path=path,
                             line=number)
        record = [math.nan] * len(MEASUREMENT_COLUMNS)
        for name, cell in zip(names, row, strict=True):
            text = cell.strip()
            if not text:
                continue
            if not _PLAIN_NUMBER.fullmatch(text):
                raise InputError(f"{name} is not a number: {quoted(cell)}", path=path, line=number)
            value = float(text)
            if not abs(value) <= VALUE_LIMIT:
                raise InputError(f"{name} = {value:.6g} is out of range (allowed: within ±{VALUE_LIMIT:.6g})",
                                 path=path, line=number)
            record[MEASUREMENT_COLUMNS.index(name)] = value
        _check_row(record, columns, number, path)
        values.append(record)
        line_numbers.append(number)
        axis_given.append(all(not math.isnan(record[MEASUREMENT_COLUMNS.index(a)]) for a in _AXIS))
    if not values:
        raise InputError("no measured poses: the file has a header and no rows", path=path, line=1)
    has_axis = any(axis_given)
    if has_axis and not all(axis_given):
        at = line_numbers[axis_given.index(False)]
        raise InputError("the tool axis (ax, ay, az) is empty here but given on other lines: measure it on every "
                         "line or on none", path=path, line=at)
    table = np.array(values, dtype=np.float64)
    line = np.array(line_numbers, dtype=np.int64)

    def take(*keys: str) -> FloatArray:
        return np.ascontiguousarray(table[:, [MEASUREMENT_COLUMNS.index(k) for k in keys]])

    stage = np.nan_to_num(take("x", "y"), nan=0.0)
    axis = take(*_AXIS)
    if has_axis:
        length = np.sqrt(np.sum(axis * axis, axis=1))
        bad = np.flatnonzero(~(np.abs(length - 1.0) <= AXIS_LENGTH_TOLERANCE) | ~(axis[:, 2] > 0.0))
        if len(bad):
            at = int(bad[0])
            raise InputError(
                f"the measured axis ({', '.join(f'{v:.6g}' for v in axis[at])}) has length {length[at]:.6g} "
                f"and z {axis[at, 2]:.6g}: expected a unit vector (length within {AXIS_LENGTH_TOLERANCE:g} of 1) "
                "pointing from the tip toward the spindle (az > 0)", path=path, line=int(line[at]))
        axis = axis / length[:, None]
    tool_length = take("tool_length_mm")[:, 0]
    with np.errstate(invalid="ignore"):
        bad_tool = np.flatnonzero(tool_length <= 0.0)
    if len(bad_tool):
        at = int(bad_tool[0])
        raise InputError(f"tool_length_mm must be > 0, got {tool_length[at]:.6g}", path=path, line=int(line[at]))
    return Measurements(path=path, strokes=take("t1", "t2", "t3"), stage=stage, tip=take("px", "py", "pz"),
                        axis=axis, tool_length=np.ascontiguousarray(tool_length), line=line, has_axis=has_axis)


def _columns(names: list[str], path: str) -> set[str]:
    """The header's columns, checked: known, once each, the required ones there, ``x,y`` and the axis whole."""
    seen: set[str] = set()
    for name in names:
        if name not in MEASUREMENT_COLUMNS:
            raise InputError(f"unknown column {quoted(name)} (columns: {','.join(MEASUREMENT_COLUMNS)}; required: "
                             f"{','.join(_REQUIRED)})", path=path, line=1)
        if name in seen:
            raise InputError(f"column {name} appears twice", path=path, line=1)
        seen.add(name)
    missing = [name for name in _REQUIRED if name not in seen]
    if missing:
        raise InputError(f"missing column{'s' if len(missing) > 1 else ''} {','.join(missing)} (required: "
                         f"{','.join(_REQUIRED)})", path=path, line=1)
    for group in (("x", "y"), _AXIS):
        given = [name for name in group if name in seen]
        if given and len(given) != len(group):
            raise InputError(f"columns {','.join(group)} go together: the header has only {','.join(given)}",
                             path=path, line=1)
    return seen


def _check_row(record: list[float], columns: set[str], number: int, path: str) -> None:
    """Every required value of a row is there; the axis is whole or empty (an empty ``tool_length_mm``:
    the machine file's tool)."""
    for name in ("t1", "t2", "t3", "x", "y"):
        if name in columns and math.isnan(record[MEASUREMENT_COLUMNS.index(name)]):
            raise InputError(f"{name} is empty: every row needs the commanded strokes (t1, t2, t3) and the stage "
                             "(x, y) it was measured at", path=path, line=number)
    for name in ("px", "py", "pz"):
        if math.isnan(record[MEASUREMENT_COLUMNS.index(name)]):
            raise InputError(f"{name} is empty: fill in the measured tool tip (px, py, pz) of this pose", path=path,
                             line=number)
    axis = [math.isnan(record[MEASUREMENT_COLUMNS.index(name)]) for name in _AXIS]
    if any(axis) and not all(axis):
        empty = ", ".join(name for name, gone in zip(_AXIS, axis, strict=True) if gone)
        raise InputError(f"{empty} empty: give the whole measured axis (ax, ay, az) or none of it", path=path,
                         line=number)
