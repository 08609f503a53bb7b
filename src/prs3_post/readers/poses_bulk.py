"""Large pose tables read by pyarrow's CSV parser (compiled, multi-threaded, correctly rounded).

:func:`iter_poses_bulk` yields what :func:`~prs3_post.readers.poses.iter_poses` yields — the same
tables, cut at the same lines — four to five times faster on a plain table (a million poses of 17
digits: 0.6 to 0.75 CPU s with pyarrow's import, against 3.0 s, at a load average near 5). It
reads only the plain case: ASCII numbers separated by commas, ``\n`` or ``\r\n`` line ends, no
blank line, and every value finite and within POSE_LIMITS. Anything else — a parse error, a wrong
column count, a quote, a lone ``\r``, a blank line, a NaN or an infinity, a value out of range —
hands the table, from the chunk where it was found, to :func:`~prs3_post.readers.poses.iter_poses`,
so that every message (and every value it accepts) is exactly that reader's. That reader reads the
chunks before again to skip them: a table irregular only near its end costs its numpy reading and
the bulk one.

pyarrow is optional (the extra ``prs3-post[fast-csv]``: 170 MB of a 307 MB install): without it every
table is read by the numpy reader, with the same output. It is imported only here, and only for a
table of at least :data:`BULK_BYTES`: its import costs about 0.035 CPU s and 27 MB, more than the numpy
reader spends on a small table (at 4 MB, 33,000 poses, the bulk reading with the import takes 0.055 CPU s,
the numpy reader 0.09 to 0.15).
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from typing import BinaryIO

import numpy as np

from prs3_post.core.errors import STDIN_PATH, InputError
from prs3_post.core.input_files import open_input
from prs3_post.core.types import FloatArray
from prs3_post.readers.poses import CHUNK_LINES, POSE_COLUMNS, PoseTable, check_header, check_range, iter_poses

#: Bytes: the smallest table read by pyarrow (about 33,000 poses of 17 digits); below, numpy's reader.
BULK_BYTES = 4_000_000
#: Bytes of the file pyarrow parses at a time (its blocks are parsed on both cores).
BLOCK_BYTES = 1 << 20


def _line_ends_plain(stream: BinaryIO) -> bool:
    """Whether the rest of ``stream`` has no lone ``\r`` (one not before ``\n``), read in blocks.

    A lone ``\r`` is a line end for pyarrow and for the numpy reader, but that reader cuts its
    chunks at ``\n`` only, so it would move the chunks (and the lines a message names with them).
    ``\r\n`` (a spreadsheet's CSV) is one line end for both. (Checked before pyarrow reads the
    file, not by handing pyarrow a Python file object that checks each block: pyarrow's threads
    would then need the interpreter's lock, and one left waiting can hang the process at exit.)
    """
    cr_before = False                               # the block before ended with \r
    while block := stream.read(BLOCK_BYTES):
        if cr_before and not block.startswith(b"\n"):
            return False
        cr_before = block.endswith(b"\r")           # its \n is the next block's first byte
        if b"\r" in block and block.count(b"\r") != block.count(b"\r\n") + cr_before:
            return False
    return not cr_before


def iter_poses_bulk(path: str, *, chunk_lines: int = CHUNK_LINES, min_bytes: int = BULK_BYTES) -> Iterator[PoseTable]:
    """The poses of a CSV, as :func:`~prs3_post.readers.poses.iter_poses` yields them (same tables,
    same line numbers, same chunks, same errors), read by pyarrow when the file has at least
    ``min_bytes`` and is plain.

    Raises
    ------
    InputError
        From :func:`~prs3_post.readers.poses.iter_poses` (the bulk reader raises none of its own).
    """
    done = 0                                        # chunks yielded by the bulk reader
    with open_input(path, "a CSV file") as stream:
        # standard input (``-``) is read by the numpy reader: pyarrow opens files by name
        bulk = chunk_lines > 1 and path != STDIN_PATH and os.fstat(stream.fileno()).st_size >= min_bytes
        if bulk:
            first = stream.readline()
            try:
                check_header(first, path)
            except InputError:
                bulk = False                        # the numpy reader says what is wrong with it
            else:
                bulk = _line_ends_plain(stream)
    if bulk:
        for table in _bulk_chunks(path, len(first), chunk_lines):
            if table is None:
                break
            yield table
            done += 1
        else:
            return
    yield from itertools.islice(iter_poses(path, chunk_lines=chunk_lines), done, None)


def _bulk_chunks(path: str, offset: int, chunk_lines: int) -> Iterator[PoseTable | None]:
    """The chunks of the file after its header (line 1, ``offset`` bytes), then None if a chunk is
    not plain.

    The first chunk holds ``chunk_lines - 1`` poses (the header is the chunk's first line), the
    others ``chunk_lines``, as in :func:`~prs3_post.readers.poses.iter_poses`. None also for a
    table without a pose (that reader's empty chunk).
    """
    try:
        import pyarrow as pa
        import pyarrow.csv as pa_csv
    except ImportError:                             # not installed (the optional fast-csv extra): slower, same
        yield None
        return
    columns = list(POSE_COLUMNS)
    try:
        source = pa.OSFile(path)                    # read by pyarrow's own threads, without Python
        source.seek(offset)
        reader = pa_csv.open_csv(
            source,
            read_options=pa_csv.ReadOptions(column_names=columns, block_size=BLOCK_BYTES),
            parse_options=pa_csv.ParseOptions(delimiter=",", quote_char=False, double_quote=False, escape_char=False,
                                              newlines_in_values=False, ignore_empty_lines=False),
            convert_options=pa_csv.ConvertOptions(
                column_types=dict.fromkeys(columns, pa.float64()), null_values=[], true_values=[],
                false_values=[], strings_can_be_null=False, quoted_strings_can_be_null=False),
        )
    except (pa.ArrowException, OSError):            # an empty body, a bad first block, a file gone
        yield None
        return
    number = 1                                      # lines before the chunk being filled
    size = chunk_lines - 1
    values = np.zeros((size, len(columns)))
    filled = 0
    while True:
        try:
            batch = reader.read_next_batch()
        except StopIteration:
            break
        except pa.ArrowException:
            yield None
            return
        start = 0
        while start < batch.num_rows:
            take = min(size - filled, batch.num_rows - start)
            for j in range(len(columns)):
                values[filled:filled + take, j] = batch.column(j).to_numpy()[start:start + take]
            filled, start = filled + take, start + take
            if filled == size:
                table = _plain_table(values, number, path)
                if table is None:
                    yield None
                    return
                yield table
                number, size = number + size, chunk_lines
                values, filled = np.zeros((size, len(columns))), 0
    if filled:
        yield _plain_table(values[:filled], number, path)
    elif number == 1:
        yield None                                  # no pose at all


def _plain_table(values: FloatArray, before: int, path: str) -> PoseTable | None:
    """The chunk's ``(n, 6)`` values as a table (``before`` lines of the file come first), or None
    when one is NaN, infinite or out of range (the numpy reader's message names it)."""
    table = PoseTable(tip=values[:, :3], axis=values[:, 3:],
                      line=np.arange(before + 1, before + 1 + len(values), dtype=np.int64))
    try:
        check_range(table, path)
    except InputError:
        return None
    return table
