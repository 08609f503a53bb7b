"""`sim`: a program run in LinuxCNC's own motion controller, headless."""

from __future__ import annotations

import click

from prs3_post.app.values import RATIO
from prs3_post.cli.options import (
    Command,
    Decimal,
    OutputPath,
    detail,
    image_format,
    run_reported,
    say,
    timed,
    verbosity_options,
)


@click.command(cls=Command)
@click.argument("program_path", type=click.Path(dir_okay=False), metavar="PROGRAM.ngc")
@click.option("--machine", "machine_name", default=None, metavar="NAME|PATH",
              help="Shipped machine name or machine TOML file.  [default: the program header's]")
@click.option("--feed-override", type=Decimal(RATIO), default=1.0,
              show_default=True, metavar="K",
              help="The feed override the program runs at, 1 = 100 % (up to 100): G1 feeds × K, up to the "
                   "axes' top speeds; rapids run at the axes' top speeds whatever K.")
@click.option("--screenshot", type=OutputPath(), default=None, metavar="FILE.png",
              help="Write a PNG of the vismach model of the machine at the end of the run (needs xvfb-run).")
@click.option("--keep", is_flag=True,
              help="Keep the run's temporary folder (the configuration, LinuxCNC's output, the display's "
                   "result) and say where it is.")
@verbosity_options
def sim(program_path: str, machine_name: str | None, feed_override: float, screenshot: str | None,
        keep: bool) -> None:
    """Run a program in LinuxCNC's motion controller, headless, and check what it did.

    The program runs in LinuxCNC's own interpreter, task and motion controller (milltask and motmod,
    non-realtime, no X display) with the configuration `prs3-post linuxcnc-config` writes for the
    machine the header names, in a temporary folder, with every joint homing at the program's first
    point. A small display program does what an operator would: E-stop reset, machine on, home, feed
    override, auto mode, cycle start; it reads the controller's error channel until the program ends.

    It passes when the program runs to its end with no controller error and every joint stops within
    0.001 mm of the last motion line's words (exit 0); a controller error names its line (exit 1).
    The controller's run time (the motion's) is shown beside the header's cycle-time estimate,
    worked out again at the feed override. Motion runs in real time: a program takes as long as on
    the machine (at the override). LinuxCNC runs one instance per host; runs of sim wait for each
    other. Needs LinuxCNC (apt-get install linuxcnc-uspace).

    \b
    Examples:
      prs3-post demo --profile hole -o demo.ngc
      prs3-post sim demo.ngc --feed-override 10
      prs3-post sim demo.ngc --screenshot end.png
    """
    from prs3_post.app.sim import report_lines, simulate, steps_text  # only when it is asked for

    def body() -> int:
        if screenshot is not None:                     # a PNG file (standard output has the report)
            image_format(screenshot, "'--screenshot'", (".png",), what="screenshot")
        with timed("run in LinuxCNC"):
            report = simulate(program_path, machine=machine_name, feed_override=feed_override,
                              screenshot=screenshot, keep=keep, progress=detail)
        detail(steps_text(report))
        for line in report_lines(report):
            click.echo(line)
        if report.screenshot is not None:
            say(f"wrote {report.screenshot}")
        return 0 if report.passed else 1

    run_reported(body)
