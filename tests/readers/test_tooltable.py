"""Tool tables (LinuxCNC's tool.tbl format) and the machine's gauge offset."""

from pathlib import Path

import pytest

from prs3_post.core.errors import ConfigError, InputError
from prs3_post.machine.loading import load_machine
from prs3_post.readers.tooltable import Tool, parse_tool_table, read_tool_table

ROOT = Path(__file__).resolve().parents[2]
BAD = ROOT / "fixtures" / "bad"
BAD_TABLES = sorted((BAD / "tooltables").glob("*.tbl"))


def test_example_table_reads_every_column():
    table = read_tool_table(str(ROOT / "fixtures" / "jobs" / "tools.tbl"))
    assert table.tools == (
        Tool(number=1, pocket=1, diameter=6.0, length=52.3, comment="6 mm drill", line=3),
        Tool(number=2, pocket=2, diameter=8.0, length=71.25, comment="8 mm end mill", line=4),
        Tool(number=7, pocket=7, diameter=10.0, length=80.0, comment="10 mm end mill, not used by the example",
             line=5),
    )
    assert table.find(2) == table.tools[1] and table.find(3) is None


def test_any_order_and_case_and_what_linuxcnc_writes():
    text = "t3 z+12.5 d2 p0 x0.0 y0 a0 b0 c0 u0 v0 w0 i10 j20 q3;probe\n   \n;x\nT4 D1 Z1\n"
    table = parse_tool_table(text, path="t.tbl")
    assert table.tools == (Tool(3, 0, 2.0, 12.5, "probe", 1), Tool(4, None, 1.0, 1.0, "", 4))


@pytest.mark.parametrize("path", BAD_TABLES, ids=lambda p: p.stem)
def test_bad_table_message(path, monkeypatch):
    expected = path.read_text(encoding="utf-8").splitlines()[0].removeprefix("; expect: ")
    monkeypatch.chdir(BAD)
    with pytest.raises(InputError) as caught:
        read_tool_table(f"tooltables/{path.name}")
    assert str(caught.value) == expected


def test_gauge_offset_loaded_and_with_tool():
    geometry = load_machine("patel2020").geometry
    assert (geometry.gauge_offset, geometry.tool_length) == (120.0, 175.0)
    assert geometry.with_tool(52.3).tool_length == pytest.approx(172.3, abs=1e-12)
    assert geometry.with_tool(55.0) == geometry


def test_gauge_offset_beyond_the_tool_is_refused(tmp_path):
    text = (ROOT / "postproc" / "machines" / "patel2020.toml").read_text(encoding="utf-8")
    bad = tmp_path / "m.toml"
    bad.write_text(text.replace("gauge_offset_mm = 120.0", "gauge_offset_mm = 175.0"), encoding="utf-8")
    with pytest.raises(ConfigError) as caught:
        load_machine(str(bad))
    assert str(caught.value) == (f"{bad}: geometry.gauge_offset_mm: the gauge line must be between the platform "
                                 "centre and the tool tip: expected < tool_length_mm = 175 mm, got 175")


def test_exponents_are_numbers():
    table = parse_tool_table("T1 D6e0 Z5.23E1 I-1.5e2\n", path="t.tbl")
    assert table.tools == (Tool(1, None, 6.0, 52.3, "", 1),)
