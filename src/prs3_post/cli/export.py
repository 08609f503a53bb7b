"""`export`: a program's tool path back in the part frame, as an APT CL file or a CSV table."""

from __future__ import annotations

from pathlib import Path

import click

from prs3_post.app.values import LENGTH
from prs3_post.cli.options import (
    Command,
    Decimal,
    OutputPath,
    detail,
    part_origin_option,
    part_rotation_option,
    run_reported,
    say,
    timed,
    verbosity_options,
)
from prs3_post.core.output_files import is_stdout, write_atomic


@click.command(cls=Command)
@click.argument("program_path", type=click.Path(dir_okay=False), metavar="PROGRAM.ngc")
@click.option("--format", "fmt", type=click.Choice(["cl", "csv"]), default=None,
              help="cl: an APT CL file (UNITS/MM, MULTAX, LOADTL, SPINDL, COOLNT, RAPID, FEDRAT/MMPM, "
                   "GOTO/x,y,z,i,j,k, FINI); csv: one row per motion line (line, x, y, z, i, j, k, "
                   "feed_mm_min, time_s).  [default: csv for an output ending in .csv, else cl]")
@click.option("-o", "--output", "out_path", type=OutputPath(), required=True, metavar="FILE|-",
              help="The file to write (a temp file, then renamed; '-': standard output).")
@click.option("--machine", "machine_name", default=None, metavar="NAME|PATH",
              help="Shipped machine name or machine TOML file.  [default: the program header's]")
@click.option("--dialect", "dialect_name", default=None, metavar="NAME|PATH",
              help="G-code dialect of the program: linuxcnc, fanuc, or a dialect TOML file.  "
                   "[default: the program header's]")
@part_origin_option
@part_rotation_option
@click.option("--tool-length", type=Decimal(LENGTH, low=0.0, low_open=True), default=None, metavar="MM",
              help="Platform centre to tool tip for every line, mm.  [default: the header's: each tool's IK length, "
                   "or the converted program's tool length, or the machine's]")
@verbosity_options
def export(program_path: str, fmt: str | None, out_path: str, machine_name: str | None, dialect_name: str | None,
           part_origin: tuple[float, ...] | None, part_rotation: float | None, tool_length: float | None) -> None:
    """Export a program's tool path to CAM: the tool tip and axis of every motion line in the part frame.

    Each line's joint words go through the machine's forward kinematics (ideal or as built), with the
    tool length of the tool in the spindle, and the setup's inverse puts them in the part frame: what
    a CAM-side viewer or simulator (Vericut, NX's CL viewer) shows, and what `prs3-post convert`
    reads back. The feed of a G1 line is its tip chord × F (G93 inverse time), in mm/min. The
    machine, dialect, setup and tool lengths come from the program's header (a program without one
    is refused); an option given here replaces the header's value. Only the lines' end points are
    written: between them the machine moves straight in joint space (`verify` checks that the tip
    stays within the tolerance of the straight line).

    \b
    Examples:
      prs3-post demo --profile square -o sq.ngc
      prs3-post export sq.ngc -o sq.cls
      prs3-post export sq.ngc --format csv -o -
    """
    from prs3_post.app.export import export_program, exported_path

    def body() -> int:
        chosen = fmt or ("csv" if not is_stdout(out_path) and Path(out_path).suffix.lower() == ".csv" else "cl")
        with timed("read and forward kinematics"):
            exported = export_program(program_path, machine=machine_name, dialect=dialect_name, origin=part_origin,
                                      rotation_deg=part_rotation, tool_length=tool_length)
        detail(f"machine {exported.machine.name} ({exported.machine.source}), dialect {exported.dialect.name}, "
               f"setup {exported.setup.describe()}")
        with timed("write"):
            write_atomic(out_path, exported_path(exported, chosen))
        if not is_stdout(out_path):
            say(f"wrote {out_path}: {len(exported.tip)} motion lines as {chosen.upper()}")
        return 0

    run_reported(body)
