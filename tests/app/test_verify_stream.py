"""verify in chunks: the same report (text and JSON) for any chunking, streamed from the file or not."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from prs3_post.app.read_ahead import read_ahead
from prs3_post.app.verify import open_program, open_setting, tool_lengths_of, verify_file, verify_loaded
from prs3_post.app.verify_report import report_record, report_text
from prs3_post.check.verify import Intended, verify_program
from prs3_post.core.defaults import DEFAULT_ANGLE_TOLERANCE, DEFAULT_TOLERANCE, NOMINAL_RAPID_RATE
from prs3_post.machine.loading import load_machine
from prs3_post.readers.poses import read_poses

REPO = Path(__file__).resolve().parents[2]
VERIFY = REPO / "fixtures" / "verify"
GOLDEN = REPO / "fixtures" / "golden"
PROGRAMS = [VERIFY / "small.ngc", VERIFY / "tilt_midmove.ngc", VERIFY / "paper_2a_2b.ngc",
            GOLDEN / "wedge-hole-peck-dwell.ngc", GOLDEN / "wedge-round.ngc", GOLDEN / "twofaces-face6-round-fanuc.nc",
            GOLDEN / "twofaces-job-example.ngc"]


def _edited(tmp_path: Path) -> Path:
    """wedge-round.ngc with one F 1 % off (a feed warning) and one stroke 3 mm off mid-program (its moves curve)."""
    lines = (GOLDEN / "wedge-round.ngc").read_text().split("\n")
    g1 = [i for i, ln in enumerate(lines) if ln.startswith("G1 ") and " V" in ln and " F" in ln]
    words = lines[g1[40]].split()
    words[-1] = f"F{float(words[-1][1:]) * 1.01:.4f}"
    lines[g1[40]] = " ".join(words)
    words = lines[g1[90]].split()
    at = next(i for i, w in enumerate(words) if w.startswith("V"))
    words[at] = f"V{float(words[at][1:]) + 3.0:.4f}"
    lines[g1[90]] = " ".join(words)
    out = tmp_path / "edited.ngc"
    out.write_text("\n".join(lines))
    return out


@pytest.mark.parametrize("name", [p.name for p in PROGRAMS] + ["edited"])
def test_text_report_is_the_same_in_chunks_of_1_7_and_10000_lines(name, tmp_path):
    path = _edited(tmp_path) if name == "edited" else next(p for p in PROGRAMS if p.name == name)
    setting = open_setting(str(path))
    context = open_program(str(path))
    whole = verify_loaded(context.program, context.machine, context.setup, context.dialect, tolerance=0.002,
                          tool_lengths=tool_lengths_of(context.header))     # as verify_file takes them
    expected = report_text(whole, path="p", dialect=context.dialect.name, rapid_rate=NOMINAL_RAPID_RATE)
    if name == "edited":
        assert not whole.ok and whole.warnings and "FAIL" in expected        # the case has something to say
    for lines in (1, 7, 10_000):
        streamed = verify_file(setting, tolerance=0.002, chunk_lines=lines)
        assert streamed.replay is None
        assert report_text(streamed, path="p", dialect=context.dialect.name, rapid_rate=NOMINAL_RAPID_RATE) == expected
        for name_ in ("rounding", "straightness", "chord", "implied_feed", "feed_slack", "intervals", "bound"):
            np.testing.assert_array_equal(getattr(streamed, name_), getattr(whole, name_), err_msg=name_)


@pytest.mark.parametrize("name", [p.name for p in PROGRAMS[:4]] + ["edited"])
def test_json_report_is_the_same_in_chunks_of_1_7_and_10000_rows(name, tmp_path):
    path = _edited(tmp_path) if name == "edited" else next(p for p in PROGRAMS if p.name == name)
    context = open_program(str(path))
    machine, moves = context.machine, context.program.moves

    def record(rows: int) -> str:
        report = verify_program(machine, moves, setup=context.setup, chunk_rows=rows,
                                blending_lines=context.program.blending_lines,
                                tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
                                length_decimals=4, feed_decimals=4)
        return json.dumps(report_record(report, path="p", dialect="linuxcnc", rapid_rate=NOMINAL_RAPID_RATE),
                          allow_nan=False)

    expected = record(1 << 30)
    assert [record(rows) for rows in (1, 7, 10_000)] == [expected] * 3


def test_against_report_is_the_same_in_chunks():
    """An intended path (the paper's poses): every sample kept and compared, in any chunking."""
    context = open_program(str(VERIFY / "paper_2a_2b.ngc"))
    table = read_poses(str(VERIFY / "paper_2a_2b.csv"))
    unit = table.axis / np.linalg.norm(table.axis, axis=1, keepdims=True)
    intended = Intended(tip=table.tip, axis=unit, feed=np.full(len(unit), np.nan),
                        kind=np.full(len(unit), -1, dtype=np.int64), label="paper_2a_2b.csv")
    machine = load_machine("patel2020")
    records = [json.dumps(report_record(verify_program(machine, context.program.moves, setup=context.setup,
                                                       intended=intended, chunk_rows=rows,
        tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE,
        length_decimals=4, feed_decimals=4), path="p", rapid_rate=NOMINAL_RAPID_RATE))
               for rows in (1, 7, 10_000)]
    assert records[0] == records[1] == records[2]
    assert json.loads(records[0])["problems"]                 # the rigid head's axis errors, as before


def test_read_ahead_keeps_the_order_and_raises_where_the_error_was():
    assert list(read_ahead(iter(range(50)), depth=3)) == list(range(50))

    def failing():
        yield from (1, 2, 3)
        raise ValueError("line 4")

    seen = []
    with pytest.raises(ValueError, match="line 4"):
        for item in read_ahead(failing()):
            seen.append(item)
    assert seen == [1, 2, 3]


def test_read_ahead_stops_its_producer_when_the_consumer_stops():
    produced = []

    def endless():
        n = 0
        while True:
            produced.append(n)
            yield n
            n += 1

    for item in read_ahead(endless(), depth=2):
        if item == 5:
            break
    count = len(produced)
    assert 6 <= count <= 9                                # at most depth + 2 ahead, and then no more


@pytest.mark.parametrize("name", ["twofaces-job-example.ngc", "twofaces-face6-round-fanuc.nc", "wedge-round.ngc"])
def test_json_report_of_a_job_program_is_the_same_in_chunks_of_7_and_65536_rows(name):
    """verify --json of the two-face job program (two tools: a tool length per row, as its header says) and of
    the programs the test above leaves out: every per-move array and value the same for any chunk size."""
    context = open_program(str(GOLDEN / name))
    decimals = context.dialect.decimals

    def record(rows: int) -> str:
        report = verify_program(context.machine, context.program.moves, setup=context.setup, chunk_rows=rows,
                                blending_lines=context.program.blending_lines,
                                tool_lengths=tool_lengths_of(context.header), length_decimals=decimals.length,
                                feed_decimals=decimals.inverse_time,
                                tolerance=DEFAULT_TOLERANCE, axis_tolerance=DEFAULT_ANGLE_TOLERANCE)
        return json.dumps(report_record(report, path="p", dialect=context.dialect.name,
                                        rapid_rate=NOMINAL_RAPID_RATE), allow_nan=False)

    if name == "twofaces-job-example.ngc":
        assert len(set(tool_lengths_of(context.header).values())) == 2      # the case has two tool lengths
    expected = record(65536)
    assert record(7) == expected
    assert record(1) == expected
