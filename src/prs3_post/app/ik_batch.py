"""``ik --batch``: inverse kinematics of a pose table, streamed from the CSV to the CSV.

The table is read, solved, checked and written a chunk of lines at a time
(:func:`~prs3_post.readers.poses_bulk.iter_poses_bulk`, :func:`~prs3_post.kinematics.inverse`,
:func:`~prs3_post.post.limits.check_limits`, :func:`~prs3_post.app.pose_tables.ik_csv_rows`), so memory stays
flat whatever the table's length; the writer (:mod:`prs3_post.core.output_files`) puts the chunks into a temp
file and renames it only when the last one is written, so a bad line anywhere leaves no output file.
A large table is read by pyarrow's CSV parser where it is installed (the optional extra
``prs3-post[fast-csv]``), else by the numpy reader: the same output (:mod:`prs3_post.readers.poses_bulk`).
"""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from prs3_post.app.pose_tables import ik_csv_header, ik_csv_rows
from prs3_post.core.errors import InputError, PoseError
from prs3_post.core.types import FloatArray
from prs3_post.kinematics import IKModel, unit_axes
from prs3_post.kinematics.prs3.exact import IKResult
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import Machine
from prs3_post.post.limits import LimitReport, check_limits
from prs3_post.readers.poses import PoseTable
from prs3_post.readers.poses_bulk import iter_poses_bulk

#: Lines of the input solved together: large enough for the kernels' speed, small enough for memory.
CHUNK_LINES = 65536
#: Lines named in the summary of poses outside limits.
SHOWN_LINES = 10


class IKBatch:
    """The IK of every pose of a CSV table, as CSV chunks; counts what is outside the limits.

    Parameters
    ----------
    machine : Machine
    path : str — the pose table (see :func:`~prs3_post.readers.poses.read_poses`)
    model : IKModel
    chunk_lines : int — input lines per chunk

    Attributes (complete once :meth:`chunks` is exhausted)
    ----------
    poses : int — poses read
    outside : int — poses unreachable or outside a limit (``ok`` false)
    outside_lines : list of int — the input lines of the first SHOWN_LINES of them
    """

    def __init__(self, machine: Machine, path: str, *, model: IKModel = IKModel.EXACT,
                 chunk_lines: int = CHUNK_LINES) -> None:
        self.machine, self.path, self.model, self.chunk_lines = machine, path, model, chunk_lines
        self.poses = 0
        self.outside = 0
        self.outside_lines: list[int] = []

    def chunks(self) -> Iterator[bytes]:
        """The output CSV: its header line, then the lines of each chunk of poses.

        Raises
        ------
        InputError
            From the reader (naming the line), or for poses whose axis is zero, NaN or points
            away from the spindle (naming their lines, within the chunk where the first one is).
        """
        tables = iter_poses_bulk(self.path, chunk_lines=self.chunk_lines)
        first = next(tables, None)                     # a file that cannot be read writes nothing at all
        solved = None if first is None else self._solve(first)
        yield ik_csv_header(kinematics_of(self.machine).joint_names)
        if solved is None:
            return
        # a chunk's lines are formatted on a second thread while the next chunk is read and solved (numpy
        # and pyarrow release the GIL): the same bytes in the same order, at most two chunks formatted ahead
        with ThreadPoolExecutor(max_workers=1) as formatter:
            pending = formatter.submit(ik_csv_rows, *solved)
            for table in tables:
                solved = self._solve(table)
                lines = pending.result()
                pending = formatter.submit(ik_csv_rows, *solved)
                yield lines
            yield pending.result()

    def _solve(self, table: PoseTable) -> tuple[FloatArray, FloatArray, IKResult, LimitReport]:
        try:
            unit = unit_axes(table.tip, table.axis, row_name="line", row_numbers=table.line)
        except PoseError as error:
            raise InputError(str(error), path=self.path) from error
        result = kinematics_of(self.machine).inverse(table.tip, unit, model=self.model)
        report = check_limits(self.machine, result, unit)
        outside = np.flatnonzero(~report.ok)
        room = SHOWN_LINES - len(self.outside_lines)
        self.outside_lines += table.line[outside[:room]].tolist() if room > 0 else []
        self.outside += len(outside)
        self.poses += len(table.line)
        return table.tip, unit, result, report

    def summary(self) -> str | None:
        """``1 of 3 poses unreachable or outside limits (lines 5); see the ok column``, or None when all are ok."""
        if not self.outside:
            return None
        shown = ", ".join(map(str, self.outside_lines)) + (", ..." if self.outside > len(self.outside_lines) else "")
        return (f"{self.outside} of {self.poses} poses unreachable or outside limits (lines {shown}); "
                "see the ok column")
