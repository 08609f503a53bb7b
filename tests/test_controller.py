"""Never write a program the controller rejects (issue 7 section 4).

* Tool numbers are bounded by the dialect (``words.tool_number_max``); LinuxCNC reads T2147483648
  and above as "Negative tool id", and the float of a tool-change event garbles far larger ones.
* Every G1 moves at least one axis by at least one output unit: points and depth passes closer
  than what the output can show are merged, so there is no G1 without an axis word, no duplicate
  lap, no 1e-5 mm plunge printed as a sideways move; and every G1's F still gives the requested tip feed.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli import main

REPO = Path(__file__).resolve().parents[1]


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


# ----------------------------------------------------------------------------- tool numbers


def _dialect_with_tool_max(tmp_path: Path, top: int) -> Path:
    text = (REPO / "postproc" / "dialects" / "linuxcnc.toml").read_text(encoding="utf-8")
    assert text.count("tool_number_max = 99999\n") == 1
    path = tmp_path / "small-tools.toml"
    path.write_text(text.replace("tool_number_max = 99999\n", f"tool_number_max = {top}\n"), encoding="utf-8")
    return path


@pytest.mark.parametrize(("extra", "message"), [
    ([], "must be 1..99999 with dialect linuxcnc (its words.tool_number_max), got 100000000000000000000"),
    (["--dialect", "fanuc"], "must be 1..99999 with dialect fanuc (its words.tool_number_max), "
                             "got 100000000000000000000"),
])
def test_a_tool_number_beyond_the_dialect_is_a_usage_error(tmp_path, extra, message):
    out = tmp_path / "p.ngc"
    result = invoke("demo", "--profile", "hole", "--tool-number", "100000000000000000000", *extra, "-o", str(out))
    assert result.exit_code == 2
    assert result.stderr.splitlines()[-1] == f"Error: Invalid value for '--tool-number': {message}"
    assert list(tmp_path.iterdir()) == []


def test_the_dialect_sets_the_largest_tool_number(tmp_path):
    dialect = _dialect_with_tool_max(tmp_path, 9)
    out = tmp_path / "p.ngc"
    refused = invoke("demo", "--profile", "hole", "--tool-number", "10", "--dialect", str(dialect), "-o", str(out))
    assert (refused.exit_code, refused.stderr.splitlines()[-1]) == (
        2, "Error: Invalid value for '--tool-number': must be 1..9 with dialect small-tools (its "
           "words.tool_number_max), got 10")
    assert not out.exists()
    accepted = invoke("demo", "--profile", "hole", "--tool-number", "9", "--dialect", str(dialect), "-o", str(out))
    assert accepted.exit_code == 0, accepted.stderr
    assert [line for line in out.read_text().splitlines() if line.endswith("M6")] == ["T9 M6"]


def test_the_largest_tool_number_passes_linuxcnc(tmp_path, rs274_check):
    out = tmp_path / "p.ngc"
    assert invoke("demo", "--profile", "hole", "--tool-number", "99999", "-o", str(out)).exit_code == 0
    assert [line for line in out.read_text().splitlines() if line.endswith("M6")] == ["T99999 M6"]
    table = tmp_path / "tools.tbl"
    table.write_text("T99999 P1 D6 ;\n", encoding="ascii")
    code, report = rs274_check(out, "--tool-table", str(table))
    assert code == 0, report
