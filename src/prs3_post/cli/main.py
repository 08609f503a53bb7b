"""Command line: click options → library calls → atomic writes. No math here.

The group `prs3-post` and its commands (each command lives in the module of its topic).
"""

from __future__ import annotations

import difflib
import os
import sys
from pathlib import Path
from typing import Any

import click

from prs3_post.cli.calibrate import accuracy, calibrate
from prs3_post.cli.convert import convert
from prs3_post.cli.exits import report_interrupted
from prs3_post.cli.export import export
from prs3_post.cli.info import faces, machines, sources
from prs3_post.cli.kinematics import fk, ik
from prs3_post.cli.linuxcnc import linuxcnc_config
from prs3_post.cli.options import Command
from prs3_post.cli.run import demo, job, run
from prs3_post.cli.sim import sim
from prs3_post.cli.verify import preview, verify
from prs3_post.core.errors import OutputClosed, quoted
from prs3_post.core.output_files import (
    guard_closed_stdout,
    stdout_error,
)
from prs3_post.core.version import __version__


class _MainGroup(click.Group):
    """A group whose first argument may be a part file: ``prs3-post PART.stl ...`` means ``run``."""

    command_class = Command

    def main(self, *args: Any, **kwargs: Any) -> Any:
        """click's main; a standard output that cannot take what click itself prints (``--help``,
        ``--version``, usage errors go to standard error) is reported as the commands report it; so
        is a closed one (``>&-``)."""
        guard_closed_stdout()
        try:
            return super().main(*args, **kwargs)
        except OSError as exc:
            failed = stdout_error(exc)
            if failed is None:
                raise
            if not isinstance(failed, OutputClosed):    # its reader went away: nothing to say
                click.echo(f"prs3-post: error: {failed}", err=True)
            sys.exit(failed.exit_code)

    def make_context(self, *args: Any, **kwargs: Any) -> click.Context:
        """click's, with Ctrl-C and a reader of standard output gone while the options are read (``--help``,
        ``--version``) as when the command runs (:meth:`invoke`)."""
        try:
            return super().make_context(*args, **kwargs)
        except KeyboardInterrupt:
            raise click.exceptions.Exit(report_interrupted()) from None
        except OSError as exc:
            raise _quiet_exit(exc) from None

    def invoke(self, ctx: click.Context) -> Any:
        """The command; Ctrl-C (SIGINT) is ``prs3-post: interrupted`` and exit status 130, not click's
        ``Aborted!`` and 1 (the status of a limit violation). Outputs under way are whole or absent (temp
        files removed) and convert's workers are stopped before it gets here. A reader of standard output
        that went away (``| head``) ends it quietly with 141 (click says nothing either, but exits 1)."""
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            raise click.exceptions.Exit(report_interrupted()) from None
        except OSError as exc:
            raise _quiet_exit(exc) from None

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if args and (not args[0].startswith("-") or args[0] == "-") and args[0] not in self.commands:   # '-': run's
            first = args[0]
            if not (Path(first).suffix or os.sep in first or os.path.lexists(first) or first == "-"):   # a word
                near = difflib.get_close_matches(first, list(self.commands), n=1)
                hint = f"did you mean '{near[0]}'? " if near else ""
                ctx.fail(f"no such command or file {quoted(first)} ({hint}commands: {', '.join(sorted(self.commands))};"
                         " or a part file: prs3-post PART.stl --profile ...)")
            args = ["run", *args]
        return super().parse_args(ctx, args)


def _quiet_exit(exc: OSError) -> BaseException:
    """``click.exceptions.Exit(141)`` when ``exc`` is standard output's reader gone, else ``exc`` itself."""
    failed = stdout_error(exc)
    return click.exceptions.Exit(failed.exit_code) if isinstance(failed, OutputClosed) else exc


@click.group(cls=_MainGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "-V", "--version", prog_name="prs3-post")
def main() -> None:
    """prs3-post: the post-processor for 3-PRS parallel-kinematic machines.

    Drills and grooves inclined faces with the tool normal to the face: reads an STL part, finds
    its inclined face, plans the operation and writes a G-code program in actuator space
    (stage X, Y and strokes T1, T2, T3 as U, V, W), checked against every machine limit.

    Every command takes -q (errors only on standard error) and -v (what was used, and the time of
    each stage). The part is PART.stl where it is the command's subject (run, faces) and --part
    PART.stl where it is an extra input (convert, verify, preview); --part-units is its unit.

    \b
    Examples:
      prs3-post demo --profile square -o demo.ngc        (the paper's wedge, bundled)
      prs3-post part.stl --profile hole --depth 8 --peck 2 -o part.ngc
      prs3-post part.stl --part-units inch --up y --profile hole -o part.ngc
      prs3-post faces part.stl
      prs3-post verify part.ngc --part part.stl
      prs3-post ik --tip -81.0264,21.2132,-679.4865 --axis 0.447214,0,0.894427
      prs3-post fk --strokes 36.2244,170.3886,88.9519 --xy -2.7640,12.0703

    \b
    Exit status (every command):
      0    done
      1    a machine limit, the workspace, a collision or a verify check failed (nothing written)
      2    bad input or usage, or a missing optional dependency (the message gives the install command)
      130  interrupted (Ctrl-C); outputs under way are not written
      141  standard output's reader went away (prs3-post machines | head -1); files are whole
    """


for _command in (accuracy, calibrate, convert, demo, export, faces, fk, ik, job, linuxcnc_config, machines, preview,
                 run, sim, sources, verify):
    main.add_command(_command)


if __name__ == "__main__":
    main()
