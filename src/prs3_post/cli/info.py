"""The listing commands: `machines`, `sources` (shipped configuration) and `faces` (a part's faces)."""

from __future__ import annotations

import click

from prs3_post.cli.options import (
    PART_UNITS_ALIAS,
    Command,
    detail,
    flag_of,
    part_units_option,
    run_reported,
    timed,
    up_option,
    verbosity_options,
)


@click.command(cls=Command)
@verbosity_options
@click.option("--json", "as_json", is_flag=True,
              help="Print the list as JSON: each machine's geometry, limits, stage travel, dynamics and holder.")
def machines(as_json: bool) -> None:
    """List the shipped machines (use a name or a TOML path with --machine).

    Each line: name, whether it has an XY stage, and its description. The files live in
    postproc/machines/ (every key commented); copy one to describe your own machine.

    \b
    Example:
      prs3-post machines
      prs3-post ik --tip 0,200,-680 --axis 0,0,1 --machine my-machine.toml
    """

    def body() -> int:
        from prs3_post.app.listings import machines_json, shipped_machines

        if as_json:
            click.echo(machines_json())
            return 0
        for name, machine in shipped_machines():
            stage = "XY stage" if machine.stage.present else "no stage"
            click.echo(f"{name:<18} {stage:<9} {machine.description}")
            detail(f"{name}: {machine.source}")
        return 0

    run_reported(body)


@click.command(cls=Command)
@verbosity_options
@click.option("--json", "as_json", is_flag=True, help="Print the list as JSON: each source's words and TCP codes.")
def sources(as_json: bool) -> None:
    """List the shipped 5-axis source conventions (how a program for another machine gives its tool axis).

    Each line: name, the rotary words (or the vector words), the TCP on/off codes and the
    description. The files live in postproc/sources/ (every key commented); copy one to describe
    another machine.

    \b
    Example:
      prs3-post sources
    """

    def body() -> int:
        from prs3_post.app.listings import shipped_sources, sources_json

        if as_json:
            click.echo(sources_json())
            return 0
        for name, source in shipped_sources():
            words = " ".join(source.words or source.vector_words)
            tcp = f"{'/'.join(source.tcp_on)} {'/'.join(source.tcp_off)}"
            click.echo(f"{name:<14} {words:<6} {tcp:<12} {source.description}")
            detail(f"{name}: {source.source}")
        return 0

    run_reported(body)


@click.command(cls=Command, aliases=PART_UNITS_ALIAS)
@click.argument("part", type=click.Path(dir_okay=False), metavar="PART.stl")
@part_units_option()
@up_option
@click.option("--json", "as_json", is_flag=True, help="Print the table as JSON.")
@verbosity_options
def faces(part: str, units: str, up: str, as_json: bool) -> None:
    """List a part's faces: index, area, width, inclination, normal, origin, kind; and the automatic choice.

    Each face says whether automatic selection may take it and why not: it must face up, be inclined
    between 1° and 89°, be a planar face of the design (not a strip of a tessellated curved surface:
    a fillet, a hole wall) and be at least 3 mm wide (the main job: as wide as its tool). A Y-up export needs
    --up y; a part that loads with a size warning probably needs --part-units inch.

    \b
    Examples:
      prs3-post faces part.stl --json
      prs3-post faces angle_block.STL --part-units inch --up y
    """
    def body() -> int:
        from prs3_post.app.listings import faces_json, faces_text

        with timed("load and find the faces"):
            table = (faces_json(part, units=units, up=up) if as_json
                     else faces_text(part, units=units, up=up, spell=flag_of))
        click.echo(table, nl=as_json)
        return 0

    run_reported(body)

