"""The console script ``prs3-post``: the CLI, loaded so that Ctrl-C while it loads is no traceback.

Importing :mod:`prs3_post.cli.main` (numpy, click and the package) takes a few tenths of a second; a
Ctrl-C then raised KeyboardInterrupt outside click. It is reported here as at any later moment
(:func:`report_interrupted`): ``prs3-post: interrupted`` and exit status 130.

OpenBLAS runs on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise: its thread pool, started
when numpy is imported, spent some 0.09 CPU s of every start on the 2-core machine, and nothing here
needs it (the products are (N, 3) by (3, 3); the kinematics and the conversions use their own threads
and processes, processes × threads ≤ cores).

glibc's malloc is tuned here, once, for every command (:data:`MALLOC_OPTIONS`), unless
``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_`` or ``GLIBC_TUNABLES`` say otherwise: blocks up
to 64 MB come from the heap, which keeps up to 256 MB free (and grows 16 MB at a time) before it is
returned. The streamed commands make and free the same numpy temporaries for every chunk (80 KB to a
few MB each); by default each is mapped and unmapped on its own, or the heap is trimmed and grown
again, and every page faults in again: 85,000 page faults and about 0.3 CPU s (half of it in the
kernel) in a million-line conversion.

Measured (/usr/bin/time -v, user + system CPU s and peak RSS, medians of 3-4 runs alternated on the
shared 2-core machine at a load of 4-6, main job ``demo --profile round --diameter 36 --depth 10
--step-down 0.01 --tolerance 0.0001`` = 947,620 lines, then ``verify`` of its program):

    malloc settings               main job               verify
    none                          1.71-1.74 s, 210 MB    2.19 s (0.4-0.6 s of it system), 224 MB
    4 MB / 8 MB (the entry's)     1.59-1.95 s, 217 MB    1.88-1.90 s, 227 MB
    64 MB / 256 MB / 16 MB        1.69-1.78 s, 205 MB    1.69-1.84 s (0.1-0.2 s system), 222 MB

The last is what verify set for itself from inside the library (over the entry's); it is verify's
best by 10-25 %, and the main job cannot tell it from the entry's 4 MB / 8 MB within the machine's
noise, so it is the one setting for all (peak memory unchanged). A 1,000,000-line 3+2 conversion
(bench/bench_convert.py's input, ``--jobs 1``) takes 0.72-0.75 CPU s and 59-60 MB with each of the three.

The cyclic garbage collector is off while the CLI loads, and what it loaded (modules, classes,
functions: they live as long as the process) is then frozen (:func:`gc.freeze`), so that no collection
scans it again. Loading makes some hundred thousand objects and no garbage, and the collections it
triggered were about 7 % of the CPU time of ``ik`` on one pose and of ``verify`` of a short program
(0.128 → 0.119 s and 0.160 → 0.153 s, medians of 12 runs alternated). Only switching it off while
loading is no gain: the first collection after it then scans everything once, in a full collection.
"""

from __future__ import annotations

import gc
import os
import sys

from prs3_post.cli.exits import report_interrupted

#: What the console script sets, unless already set, before numpy is imported (see above).
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1"}

#: glibc ``mallopt`` settings (malloc.h; see above): M_MMAP_THRESHOLD (-3) 64 MB, M_TRIM_THRESHOLD (-1)
#: 256 MB, M_TOP_PAD (-2) 16 MB.
MALLOC_OPTIONS = {-3: 64 << 20, -1: 256 << 20, -2: 16 << 20}
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
    """Load the CLI and run it; Ctrl-C while it loads: as later (:func:`report_interrupted`)."""
    configure_blas()
    configure_malloc()
    gc.disable()                                     # while the CLI loads, then frozen (see above)
    try:
        from prs3_post.cli.main import main as cli
    except KeyboardInterrupt:
        sys.exit(report_interrupted())
    finally:
        gc.freeze()
        gc.enable()
    cli()
