"""`linuxcnc-config`: a LinuxCNC simulation configuration for a machine."""

from __future__ import annotations

import os

import click

from prs3_post.app.values import RATIO
from prs3_post.cli.options import (
    Command,
    Decimal,
    OutputPath,
    detail,
    dialect_option,
    machine_option,
    run_reported,
    say,
    timed,
    verbosity_options,
)


@click.command("linuxcnc-config", cls=Command)
@machine_option
@click.option("--tool-table", "tool_table", type=click.Path(dir_okay=False), metavar="TOOL.tbl",
              help="LinuxCNC tool table (T P D Z ;comment) the programs change tools from.  [default: the "
                   "machine's tool as T1, tool_length_mm - gauge_offset_mm long]")
@dialect_option
@click.option("-o", "--output", "out_dir", type=OutputPath(dir_okay=True), required=True, metavar="DIR",
              help="The folder to write (new or empty; written whole, or not at all).")
@click.option("--force", is_flag=True, help="Replace DIR when it has files in it (its files are lost).")
@click.option("--display", default=None, metavar="PROGRAM",
              help="LinuxCNC's display program, [DISPLAY] DISPLAY (axis, gmoccapy, a script).  [default: axis]")
@click.option("--max-feed-override", "max_feed_override", type=Decimal(RATIO), default=None, metavar="K",
              help="The largest feed override the display offers, [DISPLAY] MAX_FEED_OVERRIDE (1 = 100 %; 1 to "
                   "100).  [default: 2]")
@click.option("--vismach/--no-vismach", default=True, show_default=True,
              help="Load the vismach model of the machine: a window with the machine drawn at the joints' positions "
                   "(needs an X display; without it LinuxCNC runs headless with a display script).")
@verbosity_options
def linuxcnc_config(machine_name: str, tool_table: str | None, dialect_name: str, out_dir: str, force: bool,
                    display: str | None, max_feed_override: float | None, vismach: bool) -> None:
    """Write a LinuxCNC configuration that runs the programs in LinuxCNC's own motion controller.

    One joint per program axis with trivial kinematics (stage X, Y and the strokes T1, T2, T3 under
    the dialect's letters: X Y U V W), each joint's and axis's limits from the machine file (stroke
    range, stage travel), speeds and accelerations from its [dynamics], simulated drives (no
    hardware), homing without switches, the tool table, and a vismach model of the 3-PRS machine
    (rails, sliders, links, platform, spindle, the XY stage) placed by prs3-post's own forward
    kinematics. Start it with `linuxcnc DIR/MACHINE.ini`, then machine on, home all, and open a
    program.

    \b
    Examples:
      prs3-post linuxcnc-config --machine patel2020 -o patel2020-sim
      prs3-post linuxcnc-config --tool-table tools.tbl -o sim --force
      linuxcnc patel2020-sim/patel2020.ini
    """
    from prs3_post.app.linuxcnc_config import DEFAULT_MAX_FEED_OVERRIDE, write_config

    def body() -> int:
        override = DEFAULT_MAX_FEED_OVERRIDE if max_feed_override is None else max_feed_override
        with timed("write"):
            config = write_config(machine_name, out_dir, tool_table=tool_table, dialect=dialect_name,
                                  display=display, max_feed_override=override, vismach=vismach, force=force)
        letters = "".join(axis.letter for axis in config.axes)
        detail(f"machine {config.machine.name} ({config.machine.source}), joints {letters}, "
               f"{len(config.tools)} tool(s), files: {', '.join(config.files)}")
        say(f"wrote {out_dir}: LinuxCNC configuration of {config.machine.name}, joints {letters}; "
            f"start it with: linuxcnc {os.path.join(out_dir, config.ini.name)}")
        return 0

    run_reported(body)
