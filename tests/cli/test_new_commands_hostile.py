"""The session's new commands (calibrate, accuracy, export) under the hostile inputs every command meets."""

from __future__ import annotations

import sys
from pathlib import Path

from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
MEASURED = REPO / "fixtures" / "calibration" / "measured.csv"
NO_MATPLOTLIB = "prs3-post: error: {} needs matplotlib: pip install 'prs3-post[plot]'\n"


def run(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args])


def test_pictures_without_matplotlib_exit_2_and_write_nothing(tmp_path, monkeypatch):
    # A missing optional dependency is exit status 2 on every command (issue 20), as preview's is.
    for name in [n for n in sys.modules if n.split(".")[0] in ("matplotlib", "mpl_toolkits")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    result = run("calibrate", MEASURED, "--machine", "patel2020", "-o", tmp_path / "c.toml",
                 "--preview", tmp_path / "r.png")
    assert (result.exit_code, result.output) == (2, NO_MATPLOTLIB.format("calibrate --preview"))
    result = run("accuracy", "--machine", "patel2020", "--preview", tmp_path / "a.png")
    assert (result.exit_code, result.output) == (2, NO_MATPLOTLIB.format("accuracy --preview"))
    assert list(tmp_path.iterdir()) == []


def test_calibrate_takes_its_group_options_before_the_subcommand(tmp_path):
    # `calibrate --help` lists -q/-v: given before `plan` or `identify` (or the CSV) they must not
    # turn the subcommand into a stray argument of `identify`.
    for args in (("-q", "plan"), ("--verbose", "plan")):
        out = tmp_path / f"{len(args)}{args[0]}.csv"
        result = run("calibrate", *args, "--poses", "3", "-o", out)
        assert result.exit_code == 0, result.output
        assert out.read_text().startswith("t1,t2,t3,")
    for args in (("-q", "identify", MEASURED), ("-q", MEASURED)):
        out = tmp_path / f"c{len(args)}.toml"
        result = run("calibrate", *args, "--machine", "patel2020", "-o", out)
        assert result.exit_code == 0, result.output
        assert out.read_text().startswith("# Machine patel2020 as calibrated")


def test_export_names_what_is_wrong_with_a_file_that_is_no_text(tmp_path):
    # A byte-order mark, an empty file or binary data: the reader's own words, not "no prs3-post header"
    # (the mark is invisible, and the header is right there after it).
    program = tmp_path / "sq.ngc"
    assert run("demo", "--profile", "square", "-o", program).exit_code == 0
    text = program.read_bytes()
    cases = {"bom.ngc": (b"\xef\xbb\xbf" + text, "starts with a UTF-8 byte-order mark, which LinuxCNC rejects "
                                                  "('Bad character')"),
             "empty.ngc": (b"\n \n", "not a G-code program: the file is empty"),
             "binary.ngc": (b"\x01\x02GIF", "not a G-code program: binary data (byte 0x01 at offset 0)")}
    for name, (data, message) in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        result = run("export", path, "-o", tmp_path / "out.cls")
        assert (result.exit_code, result.output) == (2, f"prs3-post: error: {path}: {message}\n")
    assert not (tmp_path / "out.cls").exists()


def test_a_value_over_the_csv_modules_limit_is_named_not_a_traceback(tmp_path):
    # csv.reader raises its own csv.Error on a field of more than 131072 characters.
    poses = tmp_path / "poses.csv"
    poses.write_text("tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n0,0,-680,0,0,1\n" + "1" * 200_000 + "\n")
    result = run("ik", "--batch", poses)
    assert (result.exit_code, result.output) == (
        2, f"prs3-post: error: {poses}:3: cannot read the line as CSV: field larger than field limit (131072)\n")
    rows = MEASURED.read_text().splitlines()
    measured = tmp_path / "measured.csv"
    measured.write_text("\n".join([*rows[:3], rows[3] + "1" * 200_000, *rows[4:]]) + "\n")
    out = tmp_path / "c.toml"
    result = run("calibrate", measured, "--machine", "patel2020", "-o", out)
    assert (result.exit_code, result.output) == (
        2, f"prs3-post: error: {measured}:4: cannot read the line as CSV: field larger than field limit (131072)\n")
    assert not out.exists()


def test_a_cl_line_of_sixty_thousand_digits_is_refused_at_once(tmp_path):
    # The plain-GOTO pattern split a run of digits two ways per number: 4e4 digits took 7 s, 1e5 minutes.
    import time

    cl = tmp_path / "long.cls"
    cl.write_text("GOTO/" + "1" * 60_000 + "\n")
    started = time.perf_counter()
    result = run("convert", cl, "-o", tmp_path / "long.ngc", "--part-origin", "auto")
    assert time.perf_counter() - started < 5
    assert result.exit_code == 2
    assert "long.cls:1: GOTO/ value 1: '1111111111111111111111111111111111111111...' is too large to be a finite " \
           "number" in result.output
    assert not (tmp_path / "long.ngc").exists()
