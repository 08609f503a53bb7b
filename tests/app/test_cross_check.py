"""`verify --cross-check`: every golden program read by pygcode as we read it, and hand-made programs where
pygcode reads (or refuses) a line otherwise, each reported with its exact message."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.app.cross_check import CrossCheck, cross_check
from prs3_post.app.verify import open_program, open_setting
from prs3_post.cli.main import main
from prs3_post.kinematics.registry import kinematics_of

REPO = Path(__file__).resolve().parents[2]
GOLDEN = sorted((REPO / "fixtures" / "golden").iterdir())


def _checked(path: Path) -> CrossCheck:
    setting = open_setting(str(path))
    return cross_check(str(path), setting.dialect, stage=setting.machine.stage.present,
                       kinematics=kinematics_of(setting.machine))


@pytest.mark.parametrize("path", GOLDEN, ids=lambda p: p.name)
def test_every_golden_program_cross_checks_clean(path: Path) -> None:
    found = _checked(path)
    lines = path.read_text().splitlines()
    assert (found.count, found.shown) == (0, ())
    assert found.lines == sum(1 for line in lines if line.strip() != "%")
    assert found.moves == len(open_program(str(path)).program.moves) > 0
    assert found.text() == f"cross-check: {found.lines} lines read by pygcode, 0 disagreements\n"


#: The demo hole (linuxcnc dialect): line 27 is its one G1, line 28 the G0 back up.
G1_LINE = "G1 X-23.9737 U31.2100 V165.3741 W83.9375 F14.2857"


@pytest.fixture(scope="module")
def hole(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    path = tmp_path_factory.mktemp("hole") / "hole.ngc"
    made = CliRunner().invoke(main, ["demo", "--profile", "hole", "-o", str(path)])
    assert made.exit_code == 0, made.output
    lines = path.read_text().split("\n")
    assert lines[26] == G1_LINE and lines[27] == "G0 X-20.8432 U24.9490 V159.1131 W77.6765"
    return lines


def _edited(tmp_path: Path, lines: list[str], edits: dict[int, str]) -> Path:
    path = tmp_path / "prog.ngc"
    path.write_text("\n".join(edits.get(n, line) for n, line in enumerate(lines, start=1)))
    return path


@pytest.mark.parametrize(("edits", "messages"), [
    # pygcode reads a number up to a space and skips what it cannot read up to the next letter
    ({27: "G1 X-23.9737 U31 . 2100 V165.3741 W83.9375 F14.2857"}, ["27: U: ours 31.21, pygcode 31"]),
    # ... and the modal value it keeps then differs on the next line that does not set U
    ({27: "G1 X-23.9737 U31 . 2100 V165.3741 W83.9375 F14.2857", 28: "G0 X-20.8432 V159.1131 W77.6765"},
     ["27: U: ours 31.21, pygcode 31", "28: U (modal): ours 31.21, pygcode 31"]),
    # an N word is a whole number for pygcode: it reads N1 and skips ".5"; it refuses N-5
    ({27: "N1.5 " + G1_LINE}, ["27: N: ours 1.5, pygcode 1"]),
    ({27: "N-5 " + G1_LINE}, ["27: line: ours N-5 G1 X-23.9737 U31.21 V165.3741 W83.9375 F14.2857, pygcode refused "
                              "(GCodeWordStrError: word 'N' value invalid)"]),
    # a space after the sign: LinuxCNC and our reader ignore it, pygcode refuses the line
    ({27: "G1 X- 23.9737 U31.2100 V165.3741 W83.9375 F14.2857"},
     ["27: line: ours G1 X-23.9737 U31.21 V165.3741 W83.9375 F14.2857, pygcode refused "
      "(GCodeWordStrError: word 'X' value invalid)"]),
    # a ';' comment: not in the linuxcnc dialect's delimiters, so our reader refuses the line; pygcode reads it
    ({27: G1_LINE + " ; plunge"},
     ["27: line: ours refused (column 51: cannot read '; plunge' as words (a letter and a plain decimal number, "
      "e.g. G1 X-1.5)), pygcode G1 X-23.9737 U31.21 V165.3741 W83.9375 F14.2857"]),
])
def test_where_pygcode_reads_otherwise(tmp_path: Path, hole: list[str], edits: dict[int, str],
                                       messages: list[str]) -> None:
    path = _edited(tmp_path, hole, edits)
    found = _checked(path)
    assert [d.message(str(path)) for d in found.shown] == [f"{path}:{m}" for m in messages]
    assert found.count == len(messages)


@pytest.mark.parametrize("edits", [
    {27: "g1 x-23.9737 u31.2100 v165.3741 w83.9375 f14.2857"},                    # lower case
    {27: "G1 X-23.9737 (plunge) U31.2100 V165.3741 W83.9375 F14.2857"},          # an inline comment
    {27: "G01X-23.9737U31.2100V165.3741W83.9375F14.2857"},                       # no spaces, G01
    {27: "N10 " + G1_LINE, 22: "M8 (100% coolant)"},                              # N word; % inside a comment
    {28: "X-20.8432 U24.9490 V159.1131 W77.6765 F20", 27: "F14.2857 G93 G1 X-23.9737 U31. V165.3741 W83.9375"},
])
def test_where_pygcode_reads_the_same(tmp_path: Path, hole: list[str], edits: dict[int, str]) -> None:
    """Spellings both read alike (line 28 without G0: a modal G1 in both)."""
    found = _checked(_edited(tmp_path, hole, edits))
    assert (found.count, found.moves) == (0, 5)


def test_verify_cross_check_on_the_command_line(tmp_path: Path, hole: list[str]) -> None:
    clean = _edited(tmp_path, hole, {})
    done = CliRunner().invoke(main, ["verify", str(clean), "--cross-check"])
    assert done.exit_code == 0, done.output
    assert done.output.split("\n")[0] == "cross-check: 33 lines read by pygcode, 0 disagreements"
    plain = CliRunner().invoke(main, ["verify", str(clean)])
    assert "cross-check" not in plain.output                   # off by default
    path = _edited(tmp_path, hole, {27: "N1.5 " + G1_LINE})
    done = CliRunner().invoke(main, ["verify", str(path), "--cross-check"])
    lines = done.output.split("\n")
    assert done.exit_code == 1
    assert lines[:2] == ["cross-check: 33 lines read by pygcode, 1 disagreement",
                         f"  {path}:27: N: ours 1.5, pygcode 1"]
    assert lines[-3:] == ["OK: within every limit and tolerance",
                          "FAIL: cross-check: 1 disagreement with pygcode (listed above)", ""]
    done = CliRunner().invoke(main, ["verify", str(path), "--cross-check", "--json"])
    record = json.loads(done.output)
    assert done.exit_code == 1 and record["ok"] is False
    assert record["cross_check"] == {"reader": "pygcode", "lines": 33, "moves": 5, "disagreements": 1,
                                     "shown": [{"line": 27, "what": "N", "ours": "1.5", "pygcode": "1"}]}
    assert json.loads(CliRunner().invoke(main, ["verify", str(clean), "--json"]).output)["cross_check"] is None


def test_a_line_our_reader_refuses_is_cross_checked_before_the_refusal(tmp_path: Path, hole: list[str]) -> None:
    path = _edited(tmp_path, hole, {27: G1_LINE + " ; plunge"})
    done = CliRunner().invoke(main, ["verify", str(path), "--cross-check"])
    assert done.exit_code == 2
    assert done.stdout.split("\n")[:2] == ["cross-check: 33 lines read by pygcode, 1 disagreement",
                                           f"  {path}:27: line: ours refused (column 51: cannot read '; plunge' as "
                                           "words (a letter and a plain decimal number, e.g. G1 X-1.5)), pygcode "
                                           "G1 X-23.9737 U31.21 V165.3741 W83.9375 F14.2857"]
    assert done.stderr == (f"prs3-post: error: {path}:27: not G-code: cannot read 'G1 X-23.9737 U31.2100 V165.3741 "
                           "W83.9375...' as words (a letter and a number each, e.g. G1 X-1.5)\n")


def test_disagreements_beyond_those_shown_are_counted(tmp_path: Path, hole: list[str]) -> None:
    path = _edited(tmp_path, hole, {n: f"N{n}.5 {hole[n - 1]}" for n in range(20, 30)})
    setting = open_setting(str(path))
    found = cross_check(str(path), setting.dialect, stage=True, kinematics=kinematics_of(setting.machine), shown=3)
    assert (found.count, len(found.shown)) == (10, 3)
    assert found.text().split("\n")[-2:] == ["  ... and 7 more", ""]
