"""The console script ``prs3-post``: the CLI, loaded so that Ctrl-C while it loads is no traceback.

Importing :mod:`prs3_post.cli` (numpy, click and the package) takes a few tenths of a second; a
Ctrl-C then raised KeyboardInterrupt outside click, which reports one later as ``Aborted!`` with exit
status 1. The same is reported here.
"""

from __future__ import annotations

import sys


def main() -> None:
    """Load the CLI and run it; Ctrl-C while it loads: ``Aborted!`` on standard error, exit 1."""
    try:
        from prs3_post.cli import main as cli
    except KeyboardInterrupt:
        sys.stderr.write("\nAborted!\n")
        sys.exit(1)
    cli()
