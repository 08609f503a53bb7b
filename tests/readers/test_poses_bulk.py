"""The bulk pose reader (pyarrow's CSV parser) against the numpy reader: the same values bit for bit,
the same tables, chunks, line numbers and messages, and ``ik --batch`` byte-identical either way."""

from __future__ import annotations

import decimal
import functools
import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from prs3_post.core.errors import InputError
from prs3_post.readers import poses_bulk
from prs3_post.readers.poses import iter_poses
from prs3_post.readers.poses_bulk import iter_poses_bulk

HEADER = "tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n"
SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _only_bulk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make a fall-back to the numpy reader fail the test: the values are pyarrow's."""
    def refused(*args: object, **kwargs: object) -> None:
        raise AssertionError("the bulk reader fell back to the numpy reader (is pyarrow installed? "
                             "pip install -e '.[test]')")
    monkeypatch.setattr(poses_bulk, "iter_poses", refused)


def _bits(value: float) -> int:
    return struct.unpack("<q", struct.pack("<d", value))[0]


def _halfway(value: float) -> str:
    """The exact decimal halfway between ``value`` (finite, > 0) and the next float up: a tie."""
    exact = (decimal.Decimal(value) + decimal.Decimal(math.nextafter(value, math.inf))) / 2
    return format(exact, "f")


#: Decimals as a pose table has them: 17 significant digits, exponents, subnormals, halfway cases.
_MAGNITUDES = st.floats(min_value=5e-324, max_value=1e6, allow_subnormal=True)
DECIMALS = st.one_of(
    st.builds(lambda v, s: f"{'-' if s else ''}{v:.17g}", _MAGNITUDES, st.booleans()),
    st.builds(lambda v: f"{v:.16e}", st.floats(min_value=-1e6, max_value=1e6)),
    st.builds(lambda v: f"{v:.9f}", st.floats(min_value=-1e6, max_value=1e6)),
    st.builds(lambda v: repr(v), st.floats(min_value=-1e6, max_value=1e6)),
    st.builds(_halfway, st.floats(min_value=1e-3, max_value=1e5)),
    st.builds(lambda m, e: f"{m}e{e}", st.integers(-10**17, 10**17), st.integers(-340, -300)),
)


@SETTINGS
@given(st.lists(DECIMALS, min_size=6, max_size=60).filter(lambda c: len(c) % 6 == 0))
@example(["2.2250738585072011e-308", "4.9406564584124654e-324", "2.4703282292062328e-324",
          "1.00000000000000011102230246251565404236316680908203125", "0.1", "-999999.99999999999"])
@example(["2.4703282292062327e-324", "2.2250738585072014e-308", "9007199.254740993e-1", "-0", "+.5", "5."])
def test_bulk_values_are_float_of_the_text_bit_for_bit(tmp_path, monkeypatch, cells):
    _only_bulk(monkeypatch)
    rows = [",".join(cells[i:i + 6]) for i in range(0, len(cells), 6)]
    path = tmp_path / "poses.csv"
    path.write_text(HEADER + "\n".join(rows) + "\n")
    tables = list(iter_poses_bulk(str(path), chunk_lines=4, min_bytes=0))
    values = np.concatenate([np.column_stack([t.tip, t.axis]) for t in tables]).reshape(-1)
    assert [_bits(v) for v in values.tolist()] == [_bits(float(c)) for c in cells]
    assert np.concatenate([t.line for t in tables]).tolist() == list(range(2, 2 + len(rows)))
    assert [len(t.line) for t in tables] == [len(t.line) for t in iter_poses(str(path), chunk_lines=4)]


def test_a_spreadsheets_crlf_table_is_read_by_pyarrow(tmp_path, monkeypatch):
    """``\r\n`` line ends: the bulk reader's, the same tables (with a block boundary between the
    second line's \r and its \n)."""
    row = "1.25,-2.5,-700.125,0.25,0.5,0.75\r\n"
    path = tmp_path / "poses.csv"
    path.write_bytes((HEADER.replace("\n", "\r\n") + row * 40).encode())
    expected = _outcome(iter_poses, path, 9)
    _only_bulk(monkeypatch)
    for block in (1 << 20, 2 * len(row) - 1):
        monkeypatch.setattr(poses_bulk, "BLOCK_BYTES", block)
        assert _outcome(functools.partial(iter_poses_bulk, min_bytes=0), path, 9) == expected
    assert [len(lines) for _, _, lines in expected[0]] == [8, 9, 9, 9, 5] and expected[1] == ""


def _outcome(reader, path: Path, chunk_lines: int) -> tuple[list[tuple[list[float], list[float], list[int]]], str]:
    """What a reader yields: each table (as lists) and the message it ends with ('' if none)."""
    tables = []
    try:
        for t in reader(str(path), chunk_lines=chunk_lines):
            tables.append((t.tip.tolist(), t.axis.tolist(), t.line.tolist()))
    except InputError as error:
        return tables, str(error)
    return tables, ""


#: Cells and line ends that the numpy reader takes or refuses, each with its own message.
_CELLS = st.sampled_from(["1", "-2.5", " 3 ", "0", "0.25", "1e-3", "+.5", "5.", "\t1", "1_0", "nan", "-inf", "1e308",
                          "2000000", '"1"', "", " ", "abc", "nan(1)", "١", "0x1", "1e", "Infinity"])
_ROW = st.one_of(
    st.lists(st.sampled_from(["1", "-2.5", "0.125", "3e2", "0", "1"]), min_size=6, max_size=6).map(",".join),
    st.lists(_CELLS, min_size=5, max_size=7).map(",".join),
    st.sampled_from(["", "   ", "1,2,3,0,0,0", "1,2,3,0,0,-1", "1,2,3,0,0,1,", "1,2,3,0,0,1\r",
                     "1,2,3,0,0,1\r1,2,3,0,0,1"]),
)


@SETTINGS
@given(rows=st.lists(_ROW, max_size=12), ending=st.sampled_from(["\n", "\r\n", ""]), chunk_lines=st.integers(1, 5),
       regular=st.integers(0, 10), block=st.sampled_from([1 << 20, 64, 73]), crlf=st.booleans())
@example(rows=["1,2,3,0,0,1", "", "1e308,2,3,0,0,1"], ending="\n", chunk_lines=65536, regular=0, block=1 << 20,
         crlf=False)
@example(rows=["1,2,3,0,0,1", "1,2,3,0,nan(1),1"], ending="\n", chunk_lines=2, regular=3, block=1 << 20, crlf=False)
@example(rows=["1,2,3,0,0,1\r1,2,3,0,0,1", "1,2,3,0,0,0"], ending="\n", chunk_lines=2, regular=0, block=1 << 20,
         crlf=False)
@example(rows=["1,2,3,0,0,1\r1,2,3,0,0,1"], ending="\n", chunk_lines=2, regular=4, block=73, crlf=True)
def test_bulk_reader_yields_and_says_what_the_numpy_reader_does(tmp_path, monkeypatch, rows, ending, chunk_lines,
                                                                regular, block, crlf):
    """Every table (values, lines, chunks) and the message, on plain tables and on every kind of
    irregular one (the bulk reader hands those to the numpy reader, from the chunk where it
    stopped: ``regular`` plain lines come first, so the hand-over is often after a few chunks).
    Small blocks put a block boundary anywhere, also between a \r and its \n."""
    monkeypatch.setattr(poses_bulk, "BLOCK_BYTES", block)
    path = tmp_path / "poses.csv"
    lines = ["1,2,-3.5,0,0.5,1"] * regular + rows
    newline = "\r\n" if crlf else "\n"
    path.write_bytes((HEADER + newline.join(lines) + (ending if lines else "")).encode())
    bulk = _outcome(functools.partial(iter_poses_bulk, min_bytes=0), path, chunk_lines)
    assert bulk == _outcome(iter_poses, path, chunk_lines)


@pytest.mark.parametrize(("content", "message"), [
    (b"", "{p}:1: expected the header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z, got an empty file"),
    (b"x,y,z\n1,2,3\n", "{p}:1: expected the header tip_x,tip_y,tip_z,axis_x,axis_y,axis_z, got 'x,y,z'"),
    (HEADER.encode() + b"1,2,3,0,0,1\n" * 5 + b"1,2,3,0,0\n", "{p}:7: expected 6 values "
     "(tip_x,tip_y,tip_z,axis_x,axis_y,axis_z), got 5"),
    (HEADER.encode() + b"1,2,3,0,0,1\n" * 5 + b"1,2,\xff,0,0,1\n", "{p}: not UTF-8 text: invalid start byte at "
     "byte 103"),
    (HEADER.encode() + b"1,2,3,0,0,1\n" * 5 + b"1,2,nan(1),0,0,1\n", "{p}:7: not a number: 'nan(1)'"),
])
def test_bulk_reader_messages(tmp_path, content, message):
    path = tmp_path / "poses.csv"
    path.write_bytes(content)
    with pytest.raises(InputError) as caught:
        list(iter_poses_bulk(str(path), chunk_lines=3, min_bytes=0))
    assert str(caught.value) == message.format(p=path)


def test_bulk_reader_without_pyarrow_is_the_numpy_reader(tmp_path, monkeypatch):
    """Without the optional pyarrow (the fast-csv extra) a large table is still read (the numpy way)."""
    path = tmp_path / "poses.csv"
    path.write_text(_pose_text(20))
    monkeypatch.setitem(sys.modules, "pyarrow", None)          # import pyarrow: ImportError
    assert _outcome(functools.partial(iter_poses_bulk, min_bytes=0), path, 7) == _outcome(iter_poses, path, 7)
    assert len(_outcome(iter_poses, path, 7)[0]) == 3


def test_bulk_reader_of_a_missing_file(tmp_path):
    with pytest.raises(InputError) as caught:
        list(iter_poses_bulk(str(tmp_path / "none.csv"), min_bytes=0))
    assert str(caught.value) == f"{tmp_path / 'none.csv'}: file not found"


def _pose_text(n: int, seed: int = 3) -> str:
    """``n`` poses of 17 digits, some of them outside the workspace or the limits."""
    rng = np.random.default_rng(seed)
    tilt, azimuth = np.radians(rng.uniform(0, 60, n)), rng.uniform(0, 2 * np.pi, n)
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    tip = np.column_stack([rng.uniform(-200, 200, (n, 2)), rng.uniform(-780, -580, n)])
    return HEADER + "".join(",".join(f"{v:.17g}" for v in row) + "\n" for row in np.hstack([tip, axis]).tolist())


@pytest.mark.parametrize("chunk_lines", [7, 65536])
def test_ik_batch_output_is_byte_identical_with_and_without_the_bulk_reader(tmp_path, monkeypatch, chunk_lines):
    from prs3_post.app.ik_batch import IKBatch
    from prs3_post.machine.loading import load_machine

    path = tmp_path / "poses.csv"
    path.write_text(_pose_text(300))
    machine = load_machine("patel2020")
    monkeypatch.setattr("prs3_post.app.ik_batch.iter_poses_bulk", iter_poses)
    numpy_batch = IKBatch(machine, str(path), chunk_lines=chunk_lines)
    expected = b"".join(numpy_batch.chunks())
    _only_bulk(monkeypatch)
    monkeypatch.setattr("prs3_post.app.ik_batch.iter_poses_bulk", functools.partial(iter_poses_bulk, min_bytes=0))
    bulk_batch = IKBatch(machine, str(path), chunk_lines=chunk_lines)
    assert b"".join(bulk_batch.chunks()) == expected
    assert expected.count(b"\n") == 301 and expected.count(b",false\n") > 10
    assert bulk_batch.summary() == numpy_batch.summary() is not None
    assert (bulk_batch.poses, bulk_batch.outside_lines) == (numpy_batch.poses, numpy_batch.outside_lines)


_PROBE = """
import json, sys
from prs3_post.cli.main import main
try:
    main(["ik", "--batch", sys.argv[1], "-o", sys.argv[2]])
except SystemExit:
    pass
print(json.dumps("pyarrow" in sys.modules))
"""


@pytest.mark.parametrize("large", [False, True], ids=["small", "large"])
def test_pyarrow_is_loaded_only_for_a_large_table(tmp_path, large):
    """Its import costs more than it saves on a small table (and `ik` on one pose never loads it)."""
    path = tmp_path / "poses.csv"
    body = _pose_text(100).removeprefix(HEADER)
    copies = poses_bulk.BULK_BYTES // len(body) + 1 if large else 1
    path.write_text(HEADER + body * copies)
    done = subprocess.run([sys.executable, "-c", _PROBE, str(path), str(tmp_path / "out.csv")],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) is large
    assert (tmp_path / "out.csv").read_bytes().count(b"\n") == 1 + 100 * copies


_BLOCKED = """
import sys
sys.modules["pyarrow"] = None                      # import pyarrow: ImportError, as where it is not installed
from prs3_post.cli.main import main
try:
    main(["ik", "--batch", sys.argv[1], "-o", sys.argv[2]])
except SystemExit as done:
    print(done.code)
"""


def test_ik_batch_without_pyarrow_writes_what_it_writes_with_it(tmp_path):
    """The default install has no pyarrow: ``ik --batch`` on a table large enough for the bulk reader,
    in a process where pyarrow cannot be imported, writes the same bytes and says the same as with it."""
    path = tmp_path / "poses.csv"
    body = _pose_text(100).removeprefix(HEADER)
    copies = poses_bulk.BULK_BYTES // len(body) + 1
    path.write_text(HEADER + body * copies)
    blocked = subprocess.run([sys.executable, "-c", _BLOCKED, str(path), str(tmp_path / "numpy.csv")],
                             capture_output=True, text=True, check=False)
    with_it = subprocess.run([sys.executable, "-c", _PROBE, str(path), str(tmp_path / "arrow.csv")],
                             capture_output=True, text=True, check=False)
    assert json.loads(with_it.stdout) is True                  # pyarrow read it there (the test extras have it)
    assert blocked.stdout.split() == ["1"]                     # poses outside the limits: exit 1, both ways
    assert blocked.stderr == with_it.stderr != ""
    assert (tmp_path / "numpy.csv").read_bytes() == (tmp_path / "arrow.csv").read_bytes()
    assert (tmp_path / "numpy.csv").read_bytes().count(b"\n") == 1 + 100 * copies
