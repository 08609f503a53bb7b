"""`prs3-post linuxcnc-config`: the options reach the configuration; bad inputs write nothing."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "fixtures" / "jobs" / "tools.tbl"


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def test_it_writes_the_folder_and_says_how_to_start_it(tmp_path: Path) -> None:
    out = tmp_path / "sim"
    result = invoke("linuxcnc-config", "--machine", "patel2020", "--tool-table", str(TOOLS), "-o", str(out),
                    "--max-feed-override", "4", "--display", "gmoccapy")
    assert result.exit_code == 0, result.output
    assert result.stderr == (f"prs3-post: wrote {out}: LinuxCNC configuration of patel2020, joints XYUVW; "
                             f"start it with: linuxcnc {out}/patel2020.ini\n")
    ini = (out / "patel2020.ini").read_text()
    assert "\nDISPLAY = gmoccapy\n" in ini and "\nMAX_FEED_OVERRIDE = 4.000\n" in ini
    assert (out / "tool.tbl").read_text().splitlines()[1] == "T2 P2 D8.000 Z71.250 ;8 mm end mill"
    assert (out / "prs3_vismach.py").is_file() and "\nHALFILE = vismach.hal\n" in ini


def test_quiet_says_nothing(tmp_path: Path) -> None:
    result = invoke("linuxcnc-config", "-q", "-o", str(tmp_path / "sim"))
    assert (result.exit_code, result.stderr, result.stdout) == (0, "", "")


@pytest.mark.parametrize(("args", "message"), [
    (["--machine", "nope"], "prs3-post: error: nope: no such machine file or shipped name (shipped: patel2020, "
                            "patel2020-head)"),
    (["--machine", "{bad}"], "prs3-post: error: {bad}: geometry: cannot assemble: |guide_radius_mm - "
                             "platform_circumradius_mm| = 218.808 mm must be < link_length_mm = 200 mm"),
    (["--tool-table", "{missing}"], "prs3-post: error: {missing}: file not found"),
    (["--tool-table", "{dup}"], "prs3-post: error: {dup}:4: T2 appears twice (first on line 3): each tool number "
                                "once"),
    (["--max-feed-override", "0"], "Error: Invalid value for '--max-feed-override': expected 1 to 100 (1 = 100 %), "
                                   "got 0.0"),
    (["--display", " "], "Error: Invalid value for '--display': give the display program on one line, printable (like "
                         "'axis'), got ' '"),
])
def test_bad_inputs_write_nothing(tmp_path: Path, args: list[str], message: str) -> None:
    names = {"bad": str(REPO / "fixtures" / "bad" / "machines" / "cannot_assemble.toml"),
             "missing": str(tmp_path / "missing.tbl"),
             "dup": str(REPO / "fixtures" / "bad" / "tooltables" / "duplicate.tbl")}
    args = [arg.format(**names) for arg in args]
    result = invoke("linuxcnc-config", *args, "-o", str(tmp_path / "sim"))
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == message.format(**names)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_the_folder_cannot_be_an_input_or_a_file(tmp_path: Path) -> None:
    machine = tmp_path / "m.toml"
    shutil.copy(REPO / "postproc" / "machines" / "patel2020.toml", machine)
    result = invoke("linuxcnc-config", "--machine", str(machine), "-o", str(machine))
    assert result.exit_code == 2
    assert result.stderr == (f"prs3-post: error: {machine}: is also the input --machine: writing --output would "
                             "destroy it (choose another file)\n")
    result = invoke("linuxcnc-config", "-o", str(machine))
    assert result.stderr == f"prs3-post: error: {machine}: is not a folder: give a new or empty folder for the files\n"
    result = invoke("linuxcnc-config", "-o", str(machine / "sim"))
    assert result.exit_code == 2
    assert result.stderr == f"prs3-post: error: {machine / 'sim'}: cannot write the folder here: Not a directory\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml"]


def test_force_replaces_a_full_folder(tmp_path: Path) -> None:
    out = tmp_path / "sim"
    out.mkdir()
    (out / "old.ini").write_text("old")
    result = invoke("linuxcnc-config", "-o", str(out))
    assert result.exit_code == 2
    assert result.stderr == (f"prs3-post: error: {out}: exists and is not empty: give a new or empty folder, or "
                             "--force to replace it\n")
    result = invoke("linuxcnc-config", "-o", str(out), "--force", "--no-vismach")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == ["patel2020.hal", "patel2020.ini", "prs3.var", "tool.tbl"]


def test_the_folder_is_not_standard_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = invoke("linuxcnc-config", "-o", "-")
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr == ("prs3-post: error: '-': standard output cannot take a folder of files: give the folder "
                             "to write (e.g. -o config)\n")
    assert list(tmp_path.iterdir()) == []                       # no folder named '-'
