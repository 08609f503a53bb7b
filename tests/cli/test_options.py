"""The CLI's shared option names (issue 20 §2): one name per concept on every command, the old
spellings kept as hidden aliases that say so on standard error.

- the STL's unit is ``--part-units`` on every command that reads an STL (old: ``--units``);
- convert's CL-file unit is ``--cl-units`` (old: ``--units``);
- verify's part is ``--part PART.stl`` (old: ``--against PART.stl``); ``--against`` keeps POSES.csv and CAM input.
"""

from __future__ import annotations

import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
WEDGE = str(REPO / "fixtures" / "parts" / "wedge.stl")
TINY = str(REPO / "fixtures" / "bad" / "tiny.stl")
DEMO_PART = str(REPO / "postproc" / "parts" / "patel2020-wedge.stl")

PART_UNITS_NOTE = "prs3-post: note: --units is deprecated: use --part-units (it means the same)\n"
CL_UNITS_NOTE = "prs3-post: note: --units is deprecated: use --cl-units (it means the same)\n"
AGAINST_NOTE = "prs3-post: note: --against PART.stl is deprecated: use --part PART.stl (it means the same)\n"
#: A part under 1 mm: the error names the option that sets the STL's unit (the message's {units} key).
TINY_ERROR = ("part is only 0.1 x 0.1 x 0.325 mm (largest extent under 1 mm): if the file is in inches, use "
              "--part-units inch (2.54 x 2.54 x 8.25 mm); if it is in metres, scale it by 1000 (100 x 100 x 325 mm)")
#: A small CL file (mm) that `--part-origin auto` places in inches too.
CL_TEXT = ("FROM/0.0,0.0,2.0\nFEDRAT/20.0,MMPM\nGOTO/0.0,0.0,0.5,0.0,0.0,1.0\nGOTO/1.0,0.0,0.0,0.0,0.0,1.0\n"
           "GOTO/1.0,1.0,0.0,0.0,0.0,1.0\nFINI\n")


def invoke(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="prs3-post")


def _context(command: str) -> click.Context:
    """A command's context under the group's, as the command line makes it: click keeps the first help
    option a command is asked for, and one made without the group's -h would stay in the command
    reference (tests/docs) after these tests."""
    return click.Context(main.commands[command], info_name=command,
                         parent=click.Context(main, info_name="prs3-post", **main.context_settings))


def _help_options(command: str) -> set[str]:
    """Every option name that `prs3-post COMMAND --help` shows."""
    ctx = _context(command)
    return {name for param in main.commands[command].get_params(ctx) if isinstance(param, click.Option)
            for name in (*param.opts, *param.secondary_opts)}


@pytest.mark.parametrize("command", ["run", "demo", "faces", "verify", "preview", "job"])
def test_the_stl_unit_is_part_units_everywhere_and_units_is_not_shown(command):
    names = _help_options(command)
    assert "--part-units" in names and "--units" not in names
    assert "--units" not in invoke(command, "--help").stdout


def test_convert_names_the_cl_unit_and_the_part_unit_apart():
    names = _help_options("convert")
    assert {"--cl-units", "--part-units"} <= names and "--units" not in names
    text = invoke("convert", "--help").stdout
    assert "--units" not in text
    assert "Length unit of the --part and --work-plane STL (--cl-units is the CL files')." in " ".join(text.split())


@pytest.mark.parametrize("args", [["run", TINY, "--profile", "hole"], ["demo", "--profile", "hole"],
                                  ["faces", TINY]], ids=["run", "demo", "faces"])
def test_units_is_a_deprecated_alias_of_part_units(args):
    new = invoke(*args, "--part-units", "inch")
    old = invoke(*args, "--units", "inch")
    glued = invoke(*args, "--units=inch")
    assert (old.exit_code, old.stdout) == (glued.exit_code, glued.stdout) == (new.exit_code, new.stdout)
    assert old.stderr == glued.stderr == PART_UNITS_NOTE + new.stderr
    assert PART_UNITS_NOTE not in new.stderr


def test_the_alias_and_the_new_name_together_are_one_option_given_twice():
    result = invoke("faces", WEDGE, "--units", "mm", "--part-units", "inch")
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == "Error: --part-units given twice ('mm' and 'inch'): give it once"


@pytest.mark.parametrize("args", [["run", TINY, "--profile", "hole"], ["faces", TINY]], ids=["run", "faces"])
def test_the_stl_size_error_names_part_units(args):
    result = invoke(*args)
    assert (result.exit_code, result.stdout, result.stderr) == (2, "", f"prs3-post: error: {TINY}: {TINY_ERROR}\n")


def test_the_size_warning_names_part_units(tmp_path):
    result = invoke("faces", WEDGE, "--part-units", "inch")
    assert result.exit_code == 0
    assert result.stderr == (f"prs3-post: warning: {WEDGE}: part is 2540 x 2540 x 8260 mm (largest extent over 2 m): "
                             "is this STL in mm? use --part-units mm (100 x 100 x 325 mm)\n")


def test_convert_names_part_units_for_its_part_not_the_cl_files_unit(tmp_path):
    """The STL size error used to say --units, which in convert is the CL file's unit."""
    source = tmp_path / "tiny.cls"
    source.write_text(CL_TEXT)
    result = invoke("convert", source, "-d", tmp_path / "out", "--part-origin", "auto", "--part", TINY)
    assert result.exit_code == 2
    assert result.stdout == f"failed\t{source}\t-\t{TINY}: {TINY_ERROR}\n"


def test_convert_work_plane_stl_errors_name_part_units(tmp_path):
    """The work plane's STL is read with --part-units: its size error named the bare key ('use units inch')."""
    program = tmp_path / "a.ngc"
    program.write_text("G21 G90 G17\nG0 X1 Y1 Z10\nG1 Z5 F100\nM30\n")
    result = invoke("convert", program, "-d", tmp_path / "out", "--work-plane", f"{TINY}:0")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == f"Error: Invalid value for '--work-plane': {TINY}: {TINY_ERROR}"


def test_job_takes_part_units_and_its_size_warning_names_it(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text((REPO / "fixtures" / "jobs" / "example.toml").read_text()
                   .replace('"../parts/twofaces.stl"', repr(str(REPO / "fixtures" / "parts" / "twofaces.stl")))
                   .replace('"tools.tbl"', repr(str(REPO / "fixtures" / "jobs" / "tools.tbl")))
                   .replace('units = "mm"', 'units = "inch"'))
    inch = invoke("job", job, "-o", tmp_path / "inch.ngc")
    assert inch.exit_code == 1
    assert inch.stderr.splitlines()[0] == (
        f"prs3-post: warning: {REPO / 'fixtures' / 'parts' / 'twofaces.stl'}: part is 3050 x 2540 x 7620 mm (largest "
        "extent over 2 m): is this STL in mm? use --part-units mm (120 x 100 x 300 mm)")
    replaced = invoke("job", job, "-o", tmp_path / "mm.ngc", "--part-units", "mm")
    assert replaced.exit_code == 0, replaced.stderr
    assert "(part: twofaces.stl, units mm, up z, sha256 " in (tmp_path / "mm.ngc").read_text()


def test_convert_units_is_a_deprecated_alias_of_cl_units(tmp_path):
    source = tmp_path / "tiny.cls"
    source.write_text(CL_TEXT)
    new = invoke("convert", source, "-d", tmp_path / "new", "--part-origin", "auto", "--cl-units", "inch")
    old = invoke("convert", source, "-d", tmp_path / "old", "--part-origin", "auto", "--units", "inch")
    assert (new.exit_code, old.exit_code) == (0, 0), new.stderr
    assert old.stderr.startswith(CL_UNITS_NOTE) and CL_UNITS_NOTE not in new.stderr
    made = (tmp_path / "new" / "tiny.ngc").read_text()
    assert made == (tmp_path / "old" / "tiny.ngc").read_text()
    assert "(source: tiny.cls, format cl, units inch, sha256 " in made


def test_verify_takes_the_part_as_part_and_against_part_stl_still_works(tmp_path):
    program = tmp_path / "sq.ngc"
    assert invoke("demo", "--profile", "square", "-o", program).exit_code == 0
    new = invoke("verify", program, "--part", DEMO_PART)
    old = invoke("verify", program, "--against", DEMO_PART)
    assert (new.exit_code, old.exit_code) == (0, 0)
    assert new.stdout == old.stdout and new.stdout.splitlines()[-1] == "OK: within every limit and tolerance"
    assert "clearance from the part" in new.stdout
    assert (new.stderr, old.stderr) == ("", AGAINST_NOTE)


def test_verify_against_part_stl_with_part_is_the_part_given_twice(tmp_path):
    program = tmp_path / "sq.ngc"
    assert invoke("demo", "--profile", "square", "-o", program).exit_code == 0
    result = invoke("verify", program, "--part", DEMO_PART, "--against", WEDGE)
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == (f"Error: --against {WEDGE} is the old spelling of --part, and --part "
                                              f"{DEMO_PART} is given: give the part once, as --part")


def test_verify_part_and_poses_together_are_refused(tmp_path):
    result = invoke("verify", REPO / "fixtures" / "verify" / "paper_2a_2b.ngc", "--part", DEMO_PART,
                    "--against", REPO / "fixtures" / "verify" / "paper_2a_2b.csv")
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == (
        f"Error: --part {DEMO_PART} rebuilds the path the program was made for; --against "
        f"{REPO / 'fixtures' / 'verify' / 'paper_2a_2b.csv'} gives another: give one of them (both only for a "
        "program converted from CAM output)")


def test_verify_help_names_part_and_against_apart():
    text = " ".join(invoke("verify", "--help").stdout.split())
    assert "--part PART.stl The part the program was made from:" in text
    assert "--against POSES.csv|INPUT The intended path: POSES.csv" in text
    assert "PART.stl|POSES.csv" not in text


# ----------------------------------------------------------------------------- -q / -v

QUIET_HELP = ("Errors only on standard error: no summaries (wrote ...), notes or warnings. What the command prints "
              "on standard output is unchanged.")
VERBOSE_HELP = "Say more on standard error: the setup, face, files and settings used, and the time of each stage."
#: The time line -v ends every command with: each stage's, then the whole command's.
TIME_LINE = r"prs3-post: time: (?:[a-z ,]+ [0-9]+\.[0-9]{3} s, )*total [0-9]+\.[0-9]{3} s"


@pytest.mark.parametrize("command", sorted(main.commands))
def test_every_command_takes_quiet_and_verbose(command):
    ctx = _context(command)
    options = {param.name: param for param in main.commands[command].get_params(ctx) if isinstance(param, click.Option)}
    assert (options["quiet"].opts, options["quiet"].help) == (["-q", "--quiet"], QUIET_HELP)
    assert (options["verbose"].opts, options["verbose"].help) == (["-v", "--verbose"], VERBOSE_HELP)


@pytest.mark.parametrize("flags", [["-q", "-v"], ["-qv"], ["--verbose", "--quiet"]])
def test_quiet_and_verbose_together_are_refused(flags):
    result = invoke("machines", *flags)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == "Error: -q/--quiet and -v/--verbose: give one of them"


def test_quiet_says_nothing_but_errors_and_leaves_standard_output_alone(tmp_path):
    out = tmp_path / "sq.ngc"
    loud = invoke("demo", "--profile", "square", "-o", out)
    assert loud.stderr.startswith(f"prs3-post: wrote {out}: 49 lines, 20 moves; ")
    quiet = invoke("demo", "--profile", "square", "-o", out, "-q")
    assert (quiet.exit_code, quiet.stdout, quiet.stderr) == (0, "", "")
    to_stdout = invoke("demo", "--profile", "square", "--quiet")
    assert (to_stdout.exit_code, to_stdout.stdout, to_stdout.stderr) == (0, out.read_text(), "")
    warned = invoke("faces", WEDGE, "--part-units", "inch", "-q")                  # a warning: not said
    assert (warned.exit_code, warned.stderr) == (0, "")
    assert warned.stdout == invoke("faces", WEDGE, "--part-units", "inch").stdout
    noted = invoke("faces", WEDGE, "--units", "mm", "-q")                          # an old spelling's note: not said
    assert (noted.exit_code, noted.stderr) == (0, "")
    failed = invoke("run", TINY, "--profile", "hole", "-q")                        # an error: said
    assert (failed.exit_code, failed.stderr) == (2, f"prs3-post: error: {TINY}: {TINY_ERROR}\n")


def test_verbose_says_what_the_main_job_was_made_with_and_the_time_of_each_stage(tmp_path):
    out = tmp_path / "sq.ngc"
    result = invoke("demo", "--profile", "square", "-o", out, "-v")
    assert result.exit_code == 0
    lines = result.stderr.splitlines()
    assert lines[:-3] == [
        "prs3-post: machine: patel2020 [Patel 2020 3-PRS head over an XY stage (the paper's numbers, assumed limits)]",
        "prs3-post: part: patel2020-wedge.stl, units mm, up z, sha256 "
        "2e6933ec5ebd47f6b894d89f5b6cd77bf2854fed2465f0679a3f148e80163537",
        "prs3-post: face: 4, chosen automatically: inclination 26.5651 deg, normal [0.447214, 0.000000, 0.894427], "
        "origin [0.0000, 200.0000, 300.0000] mm",
        "prs3-post: setup: part origin at machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z",
        "prs3-post: tool: T1 diameter 6.000 mm, feed 300.0 mm/min, plunge 100.0 mm/min, spindle 3000 rpm, "
        "coolant flood",
        "prs3-post: tolerance: 0.002 mm",
        "prs3-post: collision: clear of the part by at least 1.000 mm: tool over 11.000 mm, holder over 11.000 mm, "
        "spindle nose over 11.000 mm",
        "prs3-post: tool length (platform centre to tip, for the IK): T1 175.000 mm"]
    assert lines[-3].startswith(f"prs3-post: wrote {out}: 49 lines, 20 moves; ")
    assert re.fullmatch(r"prs3-post: time: options, machine and dialect [0-9.]+ s, post and check [0-9.]+ s, "
                        r"write [0-9.]+ s, total [0-9.]+ s", lines[-1])
    assert re.fullmatch(TIME_LINE, lines[-1])


def test_verbose_verify_says_what_the_program_was_read_with(tmp_path):
    program = tmp_path / "sq.ngc"
    assert invoke("demo", "--profile", "square", "-o", program).exit_code == 0
    result = invoke("verify", program, "-v")
    assert result.exit_code == 0
    assert result.stdout == invoke("verify", program).stdout
    lines = result.stderr.splitlines()
    assert lines[0] == ("prs3-post: read with machine patel2020, dialect linuxcnc (as the program's header states "
                        "them); setup: part origin at machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 "
                        "deg about z")
    assert re.fullmatch(r"prs3-post: time: read and replay [0-9.]+ s, total [0-9.]+ s", lines[1]) and len(lines) == 2


@pytest.mark.parametrize(("args", "first"), [
    (["fk", "--strokes", "36.2244,170.3886,88.9519"], "prs3-post: machine patel2020: machines/patel2020.toml"),
    (["machines"], "prs3-post: patel2020: machines/patel2020.toml"),
    (["sources"], "prs3-post: haas-umc750: sources/haas-umc750.toml"),
    (["faces", WEDGE], None),
], ids=["fk", "machines", "sources", "faces"])
def test_verbose_ends_every_command_with_its_time(args, first):
    result = invoke(*args, "-v")
    assert result.exit_code == 0
    assert result.stdout == invoke(*args).stdout
    lines = result.stderr.splitlines()
    assert re.fullmatch(TIME_LINE, lines[-1])
    assert first is None or lines[0] == first


def test_convert_quiet_keeps_the_failures_and_verbose_lists_every_file(tmp_path):
    source = tmp_path / "tiny.cls"
    source.write_text(CL_TEXT)
    out = tmp_path / "out"
    loud = invoke("convert", source, "-d", out, "--part-origin", "auto", "-v")
    assert loud.exit_code == 0, loud.stderr
    lines = loud.stderr.splitlines()
    assert lines[0] == ("prs3-post: 1 file, 1 at a time; machine patel2020, dialect linuxcnc, setup chosen for each "
                        "file (auto), tolerance 0.002 mm, axis tolerance 0.01 deg")
    assert re.fullmatch(rf"prs3-post: ok  {re.escape(str(source))}  {re.escape(str(out / 'tiny.ngc'))}  4 moves, "
                        r"0 arcs, 0 holes in; 4 program moves, 0 subdivisions; [0-9.]+ s", lines[1])
    assert lines[2].startswith("prs3-post: converted 1 of 1 files, 4 input moves, arcs and holes in ")
    assert re.fullmatch(TIME_LINE, lines[3]) and len(lines) == 4
    kept = invoke("convert", source, "-d", out, "--part-origin", "auto", "-q")   # the program exists: kept
    assert kept.exit_code == 2
    assert kept.stderr == f"prs3-post: 1 failed:\n  {out / 'tiny.ngc'}: exists already: kept (convert with --force " \
                          "to replace it)\n"
    assert kept.stdout == f"failed\t{source}\t-\t{out / 'tiny.ngc'}: exists already: kept (convert with --force to " \
                          "replace it)\n"


# ----------------------------------------------------------------------------- convert: -o FILE, -d DIR


def _cl(tmp_path: Path, *names: str) -> list[Path]:
    paths = [tmp_path / name for name in names]
    for path in paths:
        path.write_text(CL_TEXT)
    return paths


def test_convert_writes_one_program_with_o_and_a_folder_with_d(tmp_path):
    (source,) = _cl(tmp_path, "tiny.cls")
    one = invoke("convert", source, "-o", tmp_path / "one.ngc", "--part-origin", "auto")
    assert (one.exit_code, one.stdout) == (0, f"ok\t{source}\t{tmp_path / 'one.ngc'}\t4 moves, 0 arcs, 0 holes in; "
                                              f"4 program moves, 0 subdivisions; {one.stdout.split('; ')[-1]}")
    folder = invoke("convert", source, "-d", tmp_path / "out", "--part-origin", "auto")
    assert folder.exit_code == 0
    assert (tmp_path / "one.ngc").read_text() == (tmp_path / "out" / "tiny.ngc").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.ngc", "out", "tiny.cls"]


def test_convert_o_with_several_inputs_is_refused(tmp_path):
    sources = _cl(tmp_path, "a.cls", "b.cls")
    result = invoke("convert", *sources, "-o", tmp_path / "x.ngc", "--part-origin", "auto")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == ("Error: -o FILE writes the program of one input, and 2 files are given: "
                                              "convert them into a folder with -d DIR")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.cls", "b.cls"]


@pytest.mark.parametrize("trailing", ["", "/"], ids=["existing", "slash"])
def test_convert_o_onto_a_folder_still_writes_into_it_with_a_note(tmp_path, trailing):
    sources = _cl(tmp_path, "a.cls", "b.cls")
    out = tmp_path / "out"
    if not trailing:
        out.mkdir()
    result = invoke("convert", *sources, "-o", f"{out}{trailing}", "--part-origin", "auto")
    assert result.exit_code == 0, result.stderr
    assert result.stderr.splitlines()[0] == (f"prs3-post: note: -o {out}{trailing} (a folder) is deprecated: use -d "
                                             f"{out}{trailing} (it means the same)")
    assert sorted(p.name for p in out.iterdir()) == ["a.ngc", "b.ngc"]


@pytest.mark.parametrize(("args", "message"), [
    ([], "Error: give -d DIR (a folder for the programs) or, for a single input, -o FILE (its program)"),
    (["-o", "x.ngc", "-d", "out"], "Error: -o FILE (the program of one input) and -d DIR (a folder of programs): give "
                                   "one of them"),
], ids=["neither", "both"])
def test_convert_needs_one_of_o_and_d(tmp_path, args, message):
    (source,) = _cl(tmp_path, "tiny.cls")
    result = invoke("convert", source, *args)
    assert (result.exit_code, result.stderr.splitlines()[-1]) == (2, message)


def test_convert_help_says_which_is_which():
    text = " ".join(invoke("convert", "--help").stdout.split())
    assert ("-d, --output-dir DIR Folder for the programs, one per input: DIR/<input stem><dialect extension> "
            "(created if missing).") in text
    assert "-o, --output FILE The program of a single INPUT, as one file (several inputs: -d DIR)." in text
