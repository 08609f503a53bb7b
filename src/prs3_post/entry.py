"""The console script ``prs3-post``: the CLI, loaded so that Ctrl-C while it loads is no traceback.

Importing :mod:`prs3_post.cli` (numpy, click and the package) takes a few tenths of a second; a
Ctrl-C then raised KeyboardInterrupt outside click, which reports one later as ``Aborted!`` with exit
status 1. The same is reported here.

OpenBLAS runs on one thread unless ``OPENBLAS_NUM_THREADS`` says otherwise: its thread pool, started
when numpy is imported, spent some 0.09 CPU s of every start on the 2-core machine, and nothing here
needs it (the products are (N, 3) by (3, 3); the kinematics and the conversions use their own threads
and processes, processes × threads ≤ cores).
"""

from __future__ import annotations

import os
import sys

#: What the console script sets, unless already set, before numpy is imported (see above).
BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1"}


def configure_blas() -> None:
    """:data:`BLAS_THREADS`, where the environment does not set them (before numpy is imported)."""
    for name, value in BLAS_THREADS.items():
        os.environ.setdefault(name, value)


def main() -> None:
    """Load the CLI and run it; Ctrl-C while it loads: ``Aborted!`` on standard error, exit 1."""
    configure_blas()
    try:
        from prs3_post.cli import main as cli
    except KeyboardInterrupt:
        sys.stderr.write("\nAborted!\n")
        sys.exit(1)
    cli()
