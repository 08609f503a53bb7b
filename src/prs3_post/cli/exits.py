"""How a command stopped by Ctrl-C ends, for the console script while the CLI loads and for the CLI
after (one small module: the console script imports it before anything heavy)."""

from __future__ import annotations

import sys

#: The exit status of a command stopped by Ctrl-C (SIGINT): 128 + 2, as a shell reports a process the
#: signal ended (1 is a limit's, 2 bad input's).
EXIT_INTERRUPTED = 130
#: What a command stopped by Ctrl-C says (every output is whole or absent: temp files are removed).
INTERRUPTED = "prs3-post: interrupted"


def report_interrupted() -> int:
    """Say :data:`INTERRUPTED` on standard error (after the terminal's ``^C``, on a line of its own) and
    return :data:`EXIT_INTERRUPTED`."""
    try:
        sys.stderr.write(("\n" if sys.stderr.isatty() else "") + INTERRUPTED + "\n")
        sys.stderr.flush()
    except (OSError, ValueError):                    # no standard error to say it on: the status says it
        pass
    return EXIT_INTERRUPTED
