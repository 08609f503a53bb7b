"""Pose tables (CSV) for ``prs3-post ik --batch``: one pose per line, keeping its line number."""

from __future__ import annotations

import csv
from dataclasses import dataclass

import numpy as np

from prs3_post.errors import InputError
from prs3_post.readers.files import read_input
from prs3_post.types import FloatArray, IntArray

POSE_COLUMNS = ("tip_x", "tip_y", "tip_z", "axis_x", "axis_y", "axis_z")


@dataclass(frozen=True, slots=True)
class PoseTable:
    """Poses read from a CSV file.

    Attributes
    ----------
    tip : (N, 3) float — mm
    axis : (N, 3) float — as written (not yet unit length)
    line : (N,) int — 1-based line number of each pose in the file
    """

    tip: FloatArray
    axis: FloatArray
    line: IntArray


def read_poses(path: str) -> PoseTable:
    """Read a CSV with the header ``tip_x,tip_y,tip_z,axis_x,axis_y,axis_z`` (that order, mm).

    Blank lines are ignored; anything else that is not six numbers is an error naming the line.

    Raises
    ------
    InputError
    """
    try:
        text = read_input(path, "a CSV file").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text: {exc.reason} at byte {exc.start}", path=path) from exc
    lines = text.splitlines()
    fast = _parse_fast(lines)
    if fast is not None:
        return fast
    rows = csv.reader(lines)
    header = next(rows, None)
    expected = ",".join(POSE_COLUMNS)
    if header is None or [h.strip() for h in header] != list(POSE_COLUMNS):
        got = "an empty file" if header is None else repr(",".join(header))
        raise InputError(f"expected the header {expected}, got {got}", path=path, line=1)
    values: list[list[float]] = []
    line_numbers: list[int] = []
    for number, row in enumerate(rows, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        if len(row) != len(POSE_COLUMNS):
            raise InputError(f"expected 6 values ({expected}), got {len(row)}", path=path, line=number)
        try:
            values.append([float(cell) for cell in row])
        except ValueError as exc:
            raise InputError(f"not a number: {exc}".replace("could not convert string to float: ", ""), path=path, line=number) from exc
        line_numbers.append(number)
    table = np.array(values, dtype=np.float64).reshape(-1, 6)
    return PoseTable(tip=table[:, :3], axis=table[:, 3:], line=np.array(line_numbers, dtype=np.int64))


def _parse_fast(lines: list[str]) -> PoseTable | None:
    """numpy's C parser for a well-formed table; None whenever anything is off (the careful
    line-by-line reader then finds the first problem and names its line)."""
    if not lines or lines[0].replace(" ", "") != ",".join(POSE_COLUMNS):
        return None
    numbers = [i + 1 for i, line in enumerate(lines) if line.strip()][1:]       # 1-based, header dropped
    body = [lines[n - 1] for n in numbers]
    try:
        table = np.loadtxt(body, delimiter=",", dtype=np.float64, ndmin=2, comments=None) if body else np.zeros((0, 6))
    except ValueError:
        return None
    if table.shape[1] != 6:
        return None
    return PoseTable(tip=table[:, :3], axis=table[:, 3:], line=np.array(numbers, dtype=np.int64))
