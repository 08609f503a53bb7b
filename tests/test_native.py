"""The compiled line writer (csrc/render.c through prs3_post.native) against numpy's, and its build hook."""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from prs3_post import fixed, native
from prs3_post.fixed import ChoiceColumn, render_rows, scale_column

ROOT = Path(__file__).resolve().parents[1]
needs_native = pytest.mark.skipif(not native.available(), reason="the compiled line writer was not built here")


def test_ci_builds_the_compiled_writer() -> None:
    """CI installs with a C compiler: there the writer must be there (not a silent fall back to numpy)."""
    if not os.environ.get("CI"):
        pytest.skip("outside CI a machine without a C compiler installs without it")
    assert native.available(), f"{native.LIBRARY} missing: hatch_build.py did not compile csrc/render.c"


@needs_native
@settings(max_examples=120, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 80), lo=st.integers(0, 30),
       decimals=st.lists(st.integers(0, 15), min_size=3, max_size=3),
       prefixes=st.lists(st.sampled_from([b"", b"X", b"AB", b"N"]), min_size=3, max_size=3),
       density=st.floats(0.05, 1.0), separator=st.sampled_from([b" ", b","]),
       ending=st.sampled_from([b"\n", b"\r\n"]))
def test_compiled_writer_writes_numpys_bytes(seed: int, rows: int, lo: int, decimals: list[int],
                                             prefixes: list[bytes], density: float, separator: bytes,
                                             ending: bytes) -> None:
    """Any block (lo > 0), whole parts of 1 to 17 digits, negative zero, nan/inf and numbers too large
    for int64 digits (written from their text), choices, sparse rows: the same bytes and lengths."""
    rng = np.random.default_rng(seed)
    total = lo + rows
    values = rng.uniform(-1, 1, (total, 3)) * 10.0 ** rng.integers(-4, 18, (total, 3))
    values[rng.random((total, 3)) < 0.05] = np.nan
    values[rng.random((total, 3)) < 0.03] = -np.inf
    values[rng.random((total, 3)) < 0.05] = -0.0
    columns = [scale_column(values[:, j], d) for j, d in enumerate(decimals)]
    choice = ChoiceColumn(rng.integers(0, 3, total), (b"G0", b"G1", b"falsity"))
    present = rng.random((total, 4)) < density
    empty = ~present.any(axis=1)
    present[empty, rng.integers(0, 4, int(empty.sum()))] = True
    spec = [(p, c) for p, c in zip(prefixes[:1], columns[:1], strict=True)] + [choice] + [
        (p, c) for p, c in zip(prefixes[1:], columns[1:], strict=True)]
    text, lengths = native.render_block(spec, present, lo, total, separator, ending)
    expected, expected_lengths = fixed._render_block(spec, present, lo, total, separator, ending)
    assert text.tobytes() == expected.tobytes()
    assert lengths.tolist() == expected_lengths.tolist()


def test_numpy_writes_the_lines_where_it_is_turned_off(monkeypatch: pytest.MonkeyPatch) -> None:
    """``PRS3_POST_NATIVE=0``: not loaded, and render_rows gives the same text through numpy."""
    column = scale_column(np.array([1.25, -0.00001, np.nan]), 4)
    present = np.ones((3, 1), dtype=bool)
    monkeypatch.setattr(native, "_function", None)
    monkeypatch.setattr(native, "_library", None)
    monkeypatch.setenv(native.ENV, "0")
    assert not native.available()
    buffer, ends = render_rows([(b"X", column)], present)
    assert buffer.tobytes() == b"X1.2500\nX0.0000\nXnan\n"
    assert ends.tolist() == [0, 8, 16, 21]


@pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")
def test_a_library_of_another_version_is_not_used(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An editable install whose csrc/ changed after its build: numpy writes the lines, nothing crashes."""
    source = tmp_path / "old.c"
    source.write_text("#include <stdint.h>\nint64_t prs3_native_version(void) { return 0; }\n"
                      "int64_t prs3_render_lines(void) { return -1; }\n")
    library = tmp_path / "_native.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-o", str(library), str(source)], check=True)
    monkeypatch.setattr(native, "LIBRARY", library)
    monkeypatch.setattr(native, "_library", None)
    monkeypatch.setattr(native, "_function", None)
    assert native.library() is None and not native.available()
    buffer, _ = render_rows([(b"X", scale_column(np.array([-2.5]), 3))], np.ones((1, 1), dtype=bool))
    assert buffer.tobytes() == b"X-2.500\n"


def _hook_module():  # type: ignore[no-untyped-def]
    pytest.importorskip("hatchling")
    sys.path.insert(0, str(ROOT))
    try:
        import hatch_build
    finally:
        sys.path.remove(str(ROOT))
    return hatch_build


def test_build_hook_compiles_the_writer(tmp_path: Path) -> None:
    hook = _hook_module()
    target = tmp_path / "_native.so"
    assert hook.compile_library(ROOT, target)
    assert ctypes.CDLL(str(target)).prs3_render_lines


def test_build_hook_without_a_compiler_builds_pure_python(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    """No working compiler: False, a message naming the command, no library, nothing raised."""
    hook = _hook_module()
    monkeypatch.setenv("CC", "false")
    target = tmp_path / "_native.so"
    assert not hook.compile_library(ROOT, target)
    assert not target.exists()
    message = capsys.readouterr().err
    assert message.startswith("prs3-post: no compiled line writer (false -O2 -shared -fPIC -o ")
    assert message.rstrip().endswith("failed: ); numpy writes the lines")
