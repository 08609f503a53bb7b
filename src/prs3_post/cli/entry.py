"""The console script ``prs3-post``: the CLI, loaded so that Ctrl-C while it loads is no traceback.

Importing :mod:`prs3_post.cli.main` (numpy, click and the package) takes a few tenths of a second; a
Ctrl-C then raised KeyboardInterrupt outside click, which reports one later as ``Aborted!`` with exit
status 1. The same is reported here.

OpenBLAS runs on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise: its thread pool, started
when numpy is imported, spent some 0.09 CPU s of every start on the 2-core machine, and nothing here
needs it (the products are (N, 3) by (3, 3); the kinematics and the conversions use their own threads
and processes, processes × threads ≤ cores).

glibc's malloc keeps blocks up to 4 MB on its heap and 8 MB of freed heap before returning it
(:data:`MALLOC_OPTIONS`), unless ``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_`` or
``GLIBC_TUNABLES`` say otherwise: the numpy temporaries of a chunk (10,000 rows: 80 KB to 1 MB
each) were otherwise mapped and unmapped one by one, and every page of every one faulted in again:
85,000 page faults and about 0.3 CPU s (half of it in the kernel) in a million-line conversion.
"""

from __future__ import annotations

import os
import sys

#: What the console script sets, unless already set, before numpy is imported (see above).
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1"}

#: glibc ``mallopt`` settings (see above): M_MMAP_THRESHOLD (-3) 4 MB, M_TRIM_THRESHOLD (-1) 8 MB.
MALLOC_OPTIONS = {-3: 4 << 20, -1: 8 << 20}
_MALLOC_VARIABLES = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")


def configure_blas() -> None:
    """:data:`BLAS_THREADS`, where the environment does not set them (before numpy is imported)."""
    for name, value in BLAS_THREADS.items():
        os.environ.setdefault(name, value)


def configure_malloc() -> bool:
    """:data:`MALLOC_OPTIONS`, with glibc's malloc and where the environment sets none of its own;
    True if set."""
    if not sys.platform.startswith("linux") or any(name in os.environ for name in _MALLOC_VARIABLES):
        return False
    import ctypes

    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # noqa: B018  # glibc (musl's mallopt does nothing)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    return all(mallopt(option, value) == 1 for option, value in MALLOC_OPTIONS.items())


def main() -> None:
    """Load the CLI and run it; Ctrl-C while it loads: ``Aborted!`` on standard error, exit 1."""
    configure_blas()
    configure_malloc()
    try:
        from prs3_post.cli.main import main as cli
    except KeyboardInterrupt:
        sys.stderr.write("\nAborted!\n")
        sys.exit(1)
    cli()
