"""Run a per-block kernel over row blocks of N points, on up to two threads.

NumPy releases the GIL inside its element-wise loops, so blocks of a few ten thousand rows run
concurrently on the machine's cores; a block's temporaries also stay in the CPU cache. Results do
not depend on the block size or the number of threads (each row is computed independently).

Measured against one whole-array pass (``block_rows = N``, one thread), side by side in one process,
alternately, 1M poses of ``bench/bench_kinematics.py``'s workspace on the shared 2-core machine
(median of 5-7 rounds): exact IK 2.7× (load 0.5: 6.69 vs 2.46 M poses/s) to 3.1× (load 7: 0.93 vs
2.91 s), FK 2.8× (1.35 vs 0.49 M poses/s) to 3.5× (4.05 vs 14.3 s). Most of it is the cache: one
thread on blocks is already 2.3-3.9× the whole-array pass; the second thread adds 1.0-1.4× on a
loaded machine. A whole-array kernel's temporaries (each 8 MB a column at 1M rows) do not fit.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

#: Rows per block (measured best on the 2-core CI machine: 64k rows, 8 M exact IK poses/s).
BLOCK_ROWS = 65536


#: Environment variable that caps the threads (a batch of conversions in N processes sets it so
#: that processes × threads ≤ cores).
THREADS_VARIABLE = "PRS3_POST_THREADS"


def default_workers() -> int:
    """Threads to use: the CPUs this process may run on, at most 2 (more gains nothing here), at most
    :data:`THREADS_VARIABLE` when that is set to a positive integer."""
    cap = os.environ.get(THREADS_VARIABLE, "")
    if cap.isdigit() and int(cap) > 0:
        return max(1, min(2, int(cap)))
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(2, cpus))


def run_blocks(
    kernel: Callable[[slice], None], n: int, *, block_rows: int = BLOCK_ROWS, workers: int | None = None
) -> None:
    """Call ``kernel(rows)`` for consecutive row slices covering ``range(n)``.

    Parameters
    ----------
    kernel : callable — writes its slice's results into preallocated outputs; must not share
        writable state between slices
    n : int — number of rows
    block_rows : int — rows per slice (> 0)
    workers : int, optional — threads (default :func:`default_workers`); 1 runs inline
    """
    if block_rows <= 0:
        raise ValueError("block_rows must be > 0")
    slices = [slice(start, min(start + block_rows, n)) for start in range(0, n, block_rows)]
    workers = default_workers() if workers is None else workers
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if workers <= 1 or len(slices) <= 1:
            for rows in slices:
                kernel(rows)
            return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        list(pool.map(_quiet(kernel), slices))


def _quiet(kernel: Callable[[slice], None]) -> Callable[[slice], None]:
    """``kernel`` with floating-point warnings off (errstate is per thread)."""

    def call(rows: slice) -> None:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            kernel(rows)

    return call
