"""The compiled line writer (csrc/render.c), lexer (csrc/lex.c) and CL GOTO reader (csrc/goto.c), through
prs3_post.core.native, against numpy's, and their build hook."""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import os
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from prs3_post.core import input_files as files
from prs3_post.core import lexer, native
from prs3_post.core import numbers as fixed
from prs3_post.core.errors import LimitError, Prs3Warning
from prs3_post.core.numbers import ChoiceColumn, ScaledColumn, render_rows, scale_column
from prs3_post.core.toolpath import Event, EventKind, JointProgram
from prs3_post.emit import gcode as emit_gcode
from prs3_post.emit.gcode import emit_program
from prs3_post.machine.loading import load_dialect
from prs3_post.part.workplane import WorkPlane, euler_zxz_deg, rotate_rows
from prs3_post.readers import common
from prs3_post.readers.cl import bulk as apt
from prs3_post.readers.gcode import bulk as gcode

ROOT = Path(__file__).resolve().parents[2]
INSTALLED = native.LIBRARY
LIBRARY_BUILT = INSTALLED.is_file()
needs_native = pytest.mark.skipif(not native.available(), reason="the compiled line writer was not built here")
needs_lexer = pytest.mark.skipif(native.lex_text(b"\n", b"\0" * 256, 0) is None,
                                 reason="the compiled lexer was not built here")


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
@pytest.mark.filterwarnings("ignore::prs3_post.core.errors.Prs3Warning")     # the fall back's (tested below)
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


#: C parameter types and the ctypes type that passes each (a pointer: an address, or bytes as ``char *``).
_C_TYPES = {"int64_t": {ctypes.c_int64}, "int32_t": {ctypes.c_int32}, "uint8_t": {ctypes.c_uint8},
            "pointer": {ctypes.c_void_p, ctypes.c_char_p}}


def _c_functions() -> dict[str, list[str]]:
    """Each exported function of csrc/*.c (not static): its parameters' types (``pointer`` for any pointer)."""
    found = {}
    for source in sorted((ROOT / "csrc").glob("*.c")):
        text = re.sub(r"/\*.*?\*/", "", source.read_text(), flags=re.S)
        for name, parameters in re.findall(r"^int64_t (prs3_\w+)\(([^)]*)\)\s*\{", text, flags=re.M):
            pieces = [] if parameters.strip() == "void" else [p.strip() for p in parameters.split(",")]
            found[name] = ["pointer" if "*" in p else p.split()[-2] for p in pieces]
    return found


def test_every_c_function_has_its_argument_types_in_one_table() -> None:
    """native.SIGNATURES holds every exported function of csrc/ with one ctypes type per C parameter, of
    the C parameter's width: a function added or changed in C without its types there fails here."""
    functions = _c_functions()
    assert set(functions) == set(native.SIGNATURES) and len(functions) == 10
    for name, parameters in functions.items():
        types = native.SIGNATURES[name]
        assert len(types) == len(parameters), name
        for position, (c_type, passed) in enumerate(zip(parameters, types, strict=True)):
            assert passed in _C_TYPES[c_type], (name, position, c_type, passed)


@needs_native
@pytest.mark.parametrize("column", [
    (b"X", ScaledColumn(np.array([1], dtype=np.int64), 20, np.zeros(0, dtype=np.int64), ())),
    (b"X", ScaledColumn(np.array([1], dtype=np.int64), -1, np.zeros(0, dtype=np.int64), ())),
    ChoiceColumn(np.array([2]), (b"G0", b"G1")),
    ChoiceColumn(np.array([-1]), (b"G0", b"G1")),
    ChoiceColumn(np.array([0]), ()),
], ids=["decimals 20", "decimals -1", "choice 2 of 2", "choice -1", "no texts"])
def test_compiled_writer_refuses_decimals_and_choices_it_cannot_write(column: fixed.Column) -> None:
    """prs3_render_lines checks what it would otherwise read or write out of bounds (as prs3_emit_lines
    checks its decimals): an error, not a line made of another column's texts."""
    with pytest.raises(ValueError, match="decimals are not 0 to 19, or a choice is not one of its column"):
        native.render_block([column], np.ones((1, 1), dtype=bool), 0, 1, b" ", b"\n")
    good = native.render_block([ChoiceColumn(np.array([1]), (b"G0", b"G1")),
                                (b"X", ScaledColumn(np.array([-15], dtype=np.int64), 19, np.zeros(0, dtype=np.int64),
                                                    ()))], np.ones((1, 2), dtype=bool), 0, 1, b" ", b"\n")
    assert good[0].tobytes() == b"G1 X-0.0000000000000000015\n"


def _fresh(monkeypatch: pytest.MonkeyPatch, library: Path | None = None) -> None:
    """The native module as in a new process (nothing loaded, nothing reported), with ``library``."""
    for name in ("_library", "_function"):
        monkeypatch.setattr(native, name, None)
    monkeypatch.setattr(native, "_warned", False)
    if library is not None:
        monkeypatch.setattr(native, "LIBRARY", library)


@pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")
def test_a_stale_or_missing_library_is_reported_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """numpy taking over from a library of another version or none at all: one Prs3Warning a process,
    naming the reason; the output is the same."""
    source = tmp_path / "old.c"
    source.write_text("#include <stdint.h>\nint64_t prs3_native_version(void) { return 3; }\n")
    stale = tmp_path / "_native.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-o", str(stale), str(source)], check=True)
    _fresh(monkeypatch, stale)
    with pytest.warns(Prs3Warning, match=rf"is version 3, this package needs {native.NATIVE_VERSION} .*; numpy "
                                         r"writes and reads instead \(the same output, slower; PRS3_POST_NATIVE=0"):
        assert not native.available()
    monkeypatch.setattr(native, "_library", None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert native.library() is None                                   # once a process
        buffer, _ = render_rows([(b"X", scale_column(np.array([-2.5]), 3))], np.ones((1, 1), dtype=bool))
    assert buffer.tobytes() == b"X-2.500\n"
    _fresh(monkeypatch, tmp_path / "missing.so")
    with pytest.warns(Prs3Warning, match="no compiled library at .*missing.so"):
        assert native.library() is None


def test_numpy_chosen_with_the_environment_is_not_reported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``PRS3_POST_NATIVE=0`` (the user's choice) and the installed library: no warning."""
    monkeypatch.setenv(native.ENV, "0")
    _fresh(monkeypatch, tmp_path / "missing.so")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert native.library() is None
    if LIBRARY_BUILT:                                     # (without it, the missing library is reported)
        monkeypatch.delenv(native.ENV)
        _fresh(monkeypatch, INSTALLED)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert native.library() is not None


# ----------------------------------------------------------------------------- the compiled emitter

needs_emitter = pytest.mark.skipif(not native.available(), reason="the compiled emitter was not built here")
#: Comment texts: the usual ones (put in by C), and ones that need sanitizing, wrapping, an active word
#: made inert, trailing spaces dropped, upper case (fanuc).
_COMMENTS = ["pass 1", "pass 2 of 9", "", "  ", "trailing  ", "MSG, stop", "msg x", "a(b)", "26.6°", "tab\there",
             "x" * 300, "word " * 70, "semi;colon", "100%"]


@st.composite
def _joint_programs(draw: st.DrawFn) -> JointProgram:
    """Rows that repeat values (words left out) or round to the same text, near ties at the printed
    decimals (x.xxxx5: formatted one by one), values too large for exact integers, tiny negatives
    (-0.0000), both kinds, and every kind of event on any row (and after the last)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(0, 40))
    values = np.round(rng.uniform(-300, 300, (n, 5)), rng.integers(0, 6))
    pick = rng.random((n, 5))
    values[pick < 0.2] = values[np.maximum(np.arange(n) - 1, 0)][pick < 0.2]      # the row before's
    odd = draw(st.booleans())                       # else every row is the compiled writer's
    ties = np.round(rng.uniform(-300, 300, (n, 5)), 3) + rng.choice([0.00005, -0.00005, 0.0005], (n, 5))  # near
    values[(0.2 <= pick) & (pick < 0.25)] = (ties if odd else np.zeros_like(ties))[(0.2 <= pick) & (pick < 0.25)]
    values[(0.3 <= pick) & (pick < 0.32)] = 0.00005 * rng.integers(-3, 4) if odd else 0.0     # ties, -0.0000
    values[(0.25 <= pick) & (pick < 0.28)] = rng.uniform(0, 1) * 10.0 ** rng.integers(8, 16 if odd else 10)
    values[(0.28 <= pick) & (pick < 0.3)] = -1e-9
    inverse_time = rng.uniform(0.5, 50.0, n)
    inverse_time[rng.random(n) < (0.05 if odd else 0)] = 1e13                     # an F too large for integers
    near = rng.random(n) < (0.1 if odd else 0)                                     # an F near a tie
    inverse_time[near] = np.round(inverse_time[near], 3) + 0.00005
    kinds = ["comment"] * 6 + ["stop", "optional_stop", "tool_change", "dwell", "coolant_off", "spindle_off"]
    texts = st.sampled_from(_COMMENTS[:3] if draw(st.booleans()) else _COMMENTS)   # all usual: made together
    events = [Event(int(rng.integers(0, n + 1)), EventKind(draw(st.sampled_from(kinds))), 2.0, draw(texts))
              for _ in range(draw(st.integers(0, 15)))]
    return JointProgram(kind=rng.integers(0, 2, n), stage=values[:, :2], strokes=values[:, 2:],
                        inverse_time=inverse_time, source=np.arange(n), events=tuple(events))


@needs_emitter
@settings(max_examples=150, deadline=None)
@given(program=_joint_programs(), dialect_name=st.sampled_from(["linuxcnc", "fanuc"]),
       modal_motion=st.booleans(), crlf=st.booleans(), length=st.sampled_from([3, 4, 15]),
       limit=st.sampled_from([60, 256]), chunk_rows=st.sampled_from([1, 3, 65536]), stage=st.booleans(),
       numbered=st.sampled_from([None, 0, 99990]))
def test_compiled_emitter_writes_numpys_program(program: JointProgram, dialect_name: str, modal_motion: bool,
                                                crlf: bool, length: int, limit: int, chunk_rows: int,
                                                stage: bool, numbered: int | None) -> None:
    """prs3_emit_lines (scaling, the words left out, G0/G1, F, the block numbers (wrapping after
    99999), the comments between the rows, in one pass) against the numpy way (PRS3_POST_NATIVE=0's),
    over every chunking: the same program, or the same error."""
    dialect = load_dialect(dialect_name)
    dialect = dataclasses.replace(dialect, modal_motion=modal_motion, line_ending="\r\n" if crlf else "\n",
                                  max_line_length=limit,
                                  decimals=dataclasses.replace(dialect.decimals, length=length))
    if not stage:
        program = dataclasses.replace(program, stage=np.zeros_like(program.stage))

    def emitted() -> str:
        try:
            return emit_program(program, dialect, header=(("a", "b"),), stage=stage,
                                line_numbers=numbered is not None, line_start=numbered, line_step=3)
        except LimitError as error:
            return f"LimitError: {error}"

    with pytest.MonkeyPatch.context() as patch:        # (a function-scoped fixture outlives one example)
        patch.setattr(emit_gcode, "CHUNK_ROWS", chunk_rows)
        compiled = emitted()
        patch.setattr(native, "_emitter", False)
        assert compiled == emitted()


@needs_emitter
def test_compiled_emitter_is_used_and_leaves_ties_to_numpy(monkeypatch: pytest.MonkeyPatch) -> None:
    """The usual rows are written by C; a row with a value near a tie at the printed decimals (0.00005
    with 4: Python's correctly rounded formatting decides) or too large for exact integers is not."""
    calls: list[bool] = []
    compiled = native.emit_rows

    def spy(*args: object, **kwargs: object) -> object:
        result = compiled(*args, **kwargs)  # type: ignore[arg-type]
        calls.append(result is not None)
        return result

    monkeypatch.setattr(native, "emit_rows", spy)
    dialect = load_dialect("linuxcnc")
    for x, used in [(1.25, True), (0.00005, False), (1e12, False), (-1e-9, True)]:
        program = JointProgram(kind=np.array([0, 1]), stage=np.array([[x, 0.0], [x, 1.0]]),
                               strokes=np.ones((2, 3)), inverse_time=np.array([0.0, 2.0]), source=np.arange(2))
        text = emit_program(program, dialect)
        assert calls[-1] is used
        assert f"G0 X{fixed.fixed(x, 4)} Y0.0000 U1.0000 V1.0000 W1.0000\nG93\nG1 Y1.0000 F2.0000\n" in text


# ----------------------------------------------------------------------------- the compiled lexer

#: 1 to 17 digits: the strings ``st.from_regex(r"\A[0-9]{1,17}\Z")`` gives, drawn several times faster (the
#: regex strategy was most of what the hypothesis tests below cost).
_DIGITS = st.text(alphabet="0123456789", min_size=1, max_size=17)
#: A plain number: an optional minus, 1 to 17 digits (16 and 17: too many for the fast path), the point
#: anywhere or nowhere (before, inside, after the digits).
_number = st.builds(lambda sign, digits, point: sign + (digits[:point] + b"." + digits[point:] if point >= 0
                                                        else digits),
                    st.sampled_from([b"", b"-"]), _DIGITS.map(str.encode), st.integers(-1, 17))
#: What breaks the regular shape: lower case, comments, tab, CR, non-ASCII bytes (UTF-8 and not), a
#: second point, a lonely point, a minus without digits, a letter without a number, letters not
#: read in bulk, a sign or exponent, a number without a letter.
_odd = st.sampled_from([b"x1", b"g0", b"(note)", b";end", b"(", b"\t", b"\r", b"\xc3\xa9", b"\xff", b"\x00",
                        b"X1.2.3", b"Y..5", b"X.", b"Z-.", b"X-", b"-", b".", b"Y", b"Q1", b"X+1", b"E5", b"7",
                        b"X1e5", b"#1", b"[1]"])


@st.composite
def _regular_words(draw: st.DrawFn, letters: str) -> list[tuple[bytes, bytes]]:
    """A regular line's (space, word) pairs: some of ``letters``, each once, in order."""
    chosen = draw(_chosen_letters(letters))
    return [(draw(_SPACE), c.encode() + draw(_number)) for c in sorted(chosen, key=letters.index)]


_SPACE = st.sampled_from([b"", b" ", b"  "])


@functools.cache
def _chosen_letters(letters: str) -> st.SearchStrategy[list[str]]:
    return st.lists(st.sampled_from(letters), unique=True)


@functools.cache
def _line_strategy(letters: str) -> st.SearchStrategy[tuple[list[tuple[bytes, bytes]], bytes]]:
    """One line of :func:`_blocks` for ``letters``: (its (space, piece) pairs, its tail). Built once per
    letters (building strategies on every draw was most of what the lexer's hypothesis test cost)."""
    word = st.builds(lambda letter, number: letter + number, st.sampled_from([c.encode() for c in letters]),
                     _number)
    regular = _regular_words(letters)
    spoilt = st.tuples(regular, st.integers(0, 9), _SPACE, st.one_of(_odd, word)).map(
        lambda r: [*r[0][:r[1]], (r[2], r[3]), *r[0][r[1]:]])
    mixed = st.lists(st.tuples(_SPACE, st.one_of(word, word, _odd)), max_size=7)
    return st.tuples(st.one_of(regular, regular, spoilt, mixed), st.sampled_from([b"", b" "]))


@st.composite
def _blocks(draw: st.DrawFn, letters: str) -> bytes:
    """Lines of a block: regular ones (words of ``letters`` in order), regular ones with one word or
    piece that breaks the shape, and mixes of words in any order (repeats) and odd pieces; joined by
    no space, one or two; empty lines; a final LF or not."""
    lines = draw(st.lists(_line_strategy(letters), max_size=25))
    text = b"\n".join(b"".join(gap + piece for gap, piece in words) + tail for words, tail in lines)
    return text + draw(st.sampled_from([b"", b"\n"]))


def _numpy_lex_block(block: bytes, letters: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """lexer.lex_column_block with numpy (its text as lex_column_block makes it)."""
    return lexer._lex_text_numpy(b"\n" + block + (b"" if block.endswith(b"\n") else b"\n"), letters)


def _assert_same_lexing(block: bytes, letters: str) -> tuple[np.ndarray, np.ndarray]:
    values, read, ends = lexer.lex_column_block(block, letters)       # C
    expected_values, expected_read, expected_ends = _numpy_lex_block(block, letters)
    assert values.dtype == np.float64 and values.shape == expected_values.shape
    assert values.view(np.uint64).tolist() == expected_values.view(np.uint64).tolist()   # bits: -0.0, NaN
    assert read.dtype == np.bool_ and read.tolist() == expected_read.tolist()
    assert ends.dtype == np.int64 and ends.tolist() == expected_ends.tolist()
    _assert_same_kinds(block, letters)
    return values, read


def _assert_same_kinds(block: bytes, letters: str) -> tuple[list[int], list[bytes]]:
    """lex_block_lines' line kinds and comment spans in C and with numpy; returns the kinds and the
    comment texts (C's)."""
    text = b"\n" + block + (b"" if block.endswith(b"\n") else b"\n")
    _, read, ends = lexer._lex_text_numpy(text, letters)
    expected_kinds, expected_spans = lexer._line_kinds_numpy(text, read, ends)
    _, kinds, bounds, spans = lexer.lex_block_lines(block, letters)                   # C
    assert kinds.dtype == np.uint8 and kinds.tolist() == expected_kinds.tolist()
    comment = kinds == lexer.LINE_COMMENT
    assert (spans[comment] + 1).tolist() == expected_spans[comment].tolist()          # block, text positions
    assert bounds.tolist() == ends.tolist()
    return kinds.tolist(), [block[a:b] for a, b in spans[comment].tolist()]


@needs_lexer
@settings(max_examples=400, deadline=None)
@given(case=st.sampled_from(["NGXYZF", "NGXYZABCF", "XYZ", "G"]).flatmap(
    lambda letters: st.tuples(st.just(letters), _blocks(letters))))
@example(case=("NGXYZF", b"N1 G1 X-0 Y.5\n\nX1"))
def test_compiled_lexer_reads_as_numpy(case: tuple[str, bytes]) -> None:
    """Generated blocks mixing regular lines with every irregularity: the same values (to the bit, NaN
    where absent or not read), the same lines read and the same line ends."""
    letters, block = case
    assume(block)                                       # (an empty block never gets to either)
    _assert_same_lexing(block, letters)


@needs_lexer
def test_compiled_lexer_reads_the_regular_lines_only() -> None:
    """Each irregularity once, with the lines read and the values written out (not only the agreement)."""
    lines = [b"N10 G1 X-12.5 Y.5 Z5. F100", b"", b"  ", b"X-0 Z123456789012345", b"X1234567890123456",
             b"g1 X1", b"G1 X1 (c)", b"G1\tX1", b"G1 X1\r", b"X1 \xc3\xa9", b"X1.2.3", b"X.", b"X-.", b"X- Y1",
             b"X1 X2", b"Y1 X2", b"Q1", b"7", b"X1 2", b" .5", b"X1Y2Z-.25", b"X-.5 Y5. F007"]
    values, read = _assert_same_lexing(b"\n".join(lines), "NGXYZF")
    assert read.tolist() == [True, True, True, True] + [False] * 16 + [True, True]
    nan = np.nan
    expected = np.array([[10, 1, -12.5, 0.5, 5, 100], [nan] * 6, [nan] * 6, [nan, nan, -0.0, nan, 123456789012345, nan]]
                        + [[nan] * 6] * 16 + [[nan, nan, 1, 2, -0.25, nan], [nan, nan, -0.5, 5, nan, 7]])
    assert values.view(np.uint64).tolist() == expected.view(np.uint64).tolist()


#: Lines that are, or nearly are, the usual comment line (lex_block_lines): one comment, spaces and
#: tabs around it, its text printable ASCII; and what is not (two comments, a tab or a byte not ASCII
#: inside, nested or unclosed, code before or after, ';').
_comment_lines = st.sampled_from([b"(pass 1)", b" ( a b ) ", b"\t(x)\t ", b"()", b"(   )", b"( ;x )", b"(a)(b)",
                                  b"(a\tb)", b"(\xc3\xa9)", b"((a))", b"(a", b"a)", b"G1 (a)", b"(a) X1", b";x",
                                  b"(a) ;b", b"(a)\r", b"\x7f", b"(\x7e!\x20)", b"", b" ", b"\t", b"X1 Y2"])


@needs_lexer
@settings(max_examples=300, deadline=None)
@given(lines=st.lists(_comment_lines, max_size=12), final=st.sampled_from([b"", b"\n"]))
@example(lines=[b" ( a b ) ", b"()", b"(   )", b"(a)(b)", b"\t(x)\t "], final=b"")
def test_compiled_lexer_finds_the_usual_comment_lines_as_numpy(lines: list[bytes], final: bytes) -> None:
    """The line kinds and the comments' spans, C and numpy: the same; the texts are split_comments'
    texts, stripped, exactly on the LINE_COMMENT lines."""
    block = b"\n".join(lines) + final
    assume(block)
    kinds, texts = _assert_same_kinds(block, "NGXYZF")
    pieces = block.split(b"\n")[:-1] if block.endswith(b"\n") else block.split(b"\n")       # the block's lines
    usual = (b"(pass 1)", b" ( a b ) ", b"\t(x)\t ", b"()", b"(   )", b"( ;x )", b"(\x7e!\x20)")
    assert kinds == [lexer.LINE_READ if line.strip(b" ") == b"" or line == b"X1 Y2" else
                     lexer.LINE_COMMENT if line in usual else lexer.LINE_OTHER for line in pieces]
    assert texts == [lexer.split_comments(line.decode())[1][0].strip().encode() for line in pieces if line in usual]


@needs_lexer
def test_compiled_lexer_never_writes_past_its_outputs() -> None:
    """Room for fewer lines than the text has: -1, and nothing written past the room given; a text that
    does not end with a LF: -1; no text: no lines."""
    function = native._lexer
    codes = lexer._tables("XY")[0]
    text = b"X1\n(a)\nX3 Y4\n"
    values = np.full((3, 2), 7.0)
    read = np.full(3, 5, dtype=np.uint8)
    ends = np.full(4, 9, dtype=np.int64)
    spans = np.full((3, 2), 8, dtype=np.int64)
    for rows in (0, 1, 2):
        done = function(text, len(text), codes, 2, values.ctypes.data, read.ctypes.data, ends.ctypes.data, rows,
                        spans.ctypes.data)
        assert done == -1
        assert values[rows:].tolist() == [[7.0, 7.0]] * (3 - rows)
        assert read[rows:].tolist() == [5] * (3 - rows)
        assert ends[rows + 1:].tolist() == [9] * (3 - rows)
        assert spans[rows:].tolist() == [[8, 8]] * (3 - rows)
    for bad in (b"\nX1", b"X1"):
        assert function(bad, len(bad), codes, 2, values.ctypes.data, read.ctypes.data, ends.ctypes.data, 3,
                        spans.ctypes.data) == -1
    assert function(text, len(text), codes, 2, values.ctypes.data, read.ctypes.data, ends.ctypes.data, 3,
                    spans.ctypes.data) == 3
    assert values[2].tolist() == [3.0, 4.0] and read.tolist() == [1, 2, 1] and ends.tolist() == [0, 3, 7, 13]
    assert spans.tolist() == [[8, 8], [4, 5], [8, 8]]                    # written on the comment line only
    assert function(b"", 0, codes, 2, values.ctypes.data, read.ctypes.data, ends.ctypes.data, 3,
                    spans.ctypes.data) == 0


@needs_lexer
@settings(max_examples=300, deadline=None)
@given(pieces=st.lists(st.sampled_from([b"G1 X1", b"a", b"B", b"c ", b"C\t-", b" - ", b".", b"7", b"/", b"\n",
                                        b"\t", b"(pass 1)", b"\x01", b"\x7f", b"\r", b"\x0c", b"\xc3\xa9", b"\xff",
                                        b"a" * 4090]), max_size=40),
       at=st.integers(0, 5000))
@example(pieces=[b"x" * 4095, b"A", b"1"], at=0)
@example(pieces=[b"x" * 4095, b"A", b" " * 4096, b"1"], at=0)
def test_compiled_scan_finds_what_numpy_finds(pieces: list[bytes], at: int) -> None:
    """prs3_scan_text against numpy (control bytes, bytes not ASCII, LFs, the first rotary hint), on
    texts across its strides of 4096 bytes (a hint that straddles two, the last byte); and
    prs3_line_end against the LFs numpy finds."""
    data = b"".join(pieces)
    assert native.scan_text(data) == gcode._scan_bytes_numpy(data)
    ends = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == ord("\n")) + 1
    start = min(at, len(data))
    for count in (1, 2, 7):
        after = ends[ends > start]
        expected = int(after[count - 1]) if len(after) >= count else -1 - len(after)
        assert native.line_end(data, start, count) == expected


@needs_lexer
@settings(max_examples=400, deadline=None)
@given(rows=st.lists(st.tuples(st.booleans(), st.sampled_from([np.nan, np.nan, 0.0, 1.0, 2.0]),
                               *[st.sampled_from([np.nan, np.nan, -0.0, 1.5, -2.25, 1e300]) for _ in range(3)],
                               st.sampled_from([np.nan, np.nan, np.nan, 100.0, 0.0, -5.0, 1e-9, 1e9])),
                     min_size=1, max_size=12),
       state=st.tuples(st.sampled_from([np.nan, 0.0, 1.0]), st.sampled_from([np.nan, 300.0]),
                       st.sampled_from([np.nan, 5.0]), st.sampled_from([np.nan, -1.0]), st.just(2.0)),
       scale=st.sampled_from([1.0, 25.4, 1e300]))
@example(rows=[(True, 1.0, 1.0, 2.0, 3.0, 100.0), (False, np.nan, np.nan, np.nan, np.nan, np.nan),
               (True, np.nan, -0.0, np.nan, np.nan, np.nan), (True, 0.0, np.nan, 1.5, np.nan, np.nan)],
         state=(np.nan, np.nan, np.nan, np.nan, np.nan), scale=25.4)
def test_compiled_bulk_fill_is_numpys(rows: list[tuple[bool, float, float, float, float, float]],
                                      state: tuple[float, ...], scale: float) -> None:
    """prs3_fill_moves against the numpy bulk step: the same refusals (no motion or not G0/G1, F out of
    its limits, a feed move without F, an unknown or infinite position) and else the same rows to the
    bit, state after the run and G0/G1 words."""
    moves = np.array([r[0] for r in rows])
    values = np.array([[np.nan, *r[1:]] if r[0] else [np.nan] * 6 for r in rows])
    start = np.array(state)
    with np.errstate(over="ignore"):                                   # (1.5 × 1e300: inf, refused)
        numpy_filled = gcode._fill_moves_numpy(values, moves, start, scale, 7)
    filled = native.fill_moves(values, moves, start, np.array([scale, common.MIN_FEED_MM_MIN, common.MAX_FEED_MM_MIN]),
                               gcode._FILL_CODES, 7)
    assert np.array_equal(start, np.array(state), equal_nan=True)    # the caller's state untouched
    if numpy_filled is None:
        assert filled is False
        return
    assert isinstance(filled, tuple)
    for got, expected in zip(filled, numpy_filled, strict=True):
        assert got.dtype == expected.dtype and got.shape == expected.shape
        assert got.view(np.uint64 if got.dtype == np.float64 else got.dtype).tolist() == expected.view(
            np.uint64 if expected.dtype == np.float64 else expected.dtype).tolist()


@needs_lexer
@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 40), scale=st.sampled_from([1e-3, 1.0, 1e3, 1e300]))
@example(seed=0, rows=1, scale=1.0)
def test_compiled_rows_to_part_are_the_work_planes_bits(seed: int, rows: int, scale: float) -> None:
    """prs3_rows_to_part against WorkPlane.to_part (rotate_rows, then the origin): the same bits for any
    rows, planes and magnitudes (no fused multiply-add), N = 0 and 1 included."""
    rng = np.random.default_rng(seed)
    plane = WorkPlane(rng.uniform(-1e3, 1e3, 3), euler_zxz_deg(*rng.uniform(-180.0, 180.0, 3).tolist()))
    local = rng.uniform(-1.0, 1.0, (rows, 3)) * scale
    with np.errstate(over="ignore", invalid="ignore"):                # (1e300 rows: inf and nan, compared too)
        expected = plane.to_part(local)
    tip = native.rows_to_part(local, plane.rotation, plane.origin)
    assert tip is not None and tip.shape == expected.shape == (rows, 3)
    assert tip.view(np.uint64).tolist() == expected.view(np.uint64).tolist()
    local[::3] = -0.0                                                 # directions: no origin, -0.0 kept
    with np.errstate(over="ignore", invalid="ignore"):
        expected = rotate_rows(local, plane.rotation)
    turned = native.rows_to_part(local, plane.rotation, None)
    assert turned is not None and turned.view(np.uint64).tolist() == expected.view(np.uint64).tolist()


@needs_lexer
@settings(max_examples=200, deadline=None)
@given(rows=st.lists(st.tuples(st.sampled_from([0, 1, 1, 2]),
                               *[st.sampled_from([np.nan, np.nan, 0.0, 1.0, 2.0, -0.0]) for _ in range(6)]),
                     max_size=30))
@example(rows=[(1, *[np.nan] * 6), (1, np.nan, 1.0, np.nan, np.nan, np.nan, 5.0), (2, *[np.nan] * 6),
               (1, 3.0, 1.0, 2.0, np.nan, np.nan, np.nan), (0, np.nan, 0.0, 1.0, np.nan, np.nan, np.nan)])
def test_compiled_line_roles_are_numpys(rows: list[tuple[int, ...]]) -> None:
    """prs3_line_roles against the numpy sorting of a block's lines: the same regular moves (read, G0,
    G1 or no G, an axis word) and quiet lines (the usual comment line, or read and blank), N = 0 too."""
    kinds = np.array([r[0] for r in rows], dtype=np.uint8)
    values = np.array([r[1:] for r in rows], dtype=np.float64).reshape(-1, 6)
    roles = native.line_roles(values, kinds)
    assert roles is not None
    expected = gcode._line_roles_numpy(values, kinds)
    assert [a.tolist() for a in roles] == [a.tolist() for a in expected]


@settings(max_examples=200, deadline=None)
@given(data=st.binary(min_size=1, max_size=120).map(lambda b: b.replace(b"\x00", b"\n")),
       cuts=st.lists(st.integers(1, 40), max_size=8), chunk_lines=st.sampled_from([1, 2, 3, 7, 50]),
       compiled=st.booleans())
def test_line_blocks_cut_whole_lines_across_pieces(data: bytes, cuts: list[int], chunk_lines: int,
                                                    compiled: bool) -> None:
    """files.line_blocks (C's line ends, or numpy's): blocks of chunk_lines whole lines at their
    offsets, the last one the lines left, from pieces cut anywhere at line ends."""
    pieces, at = [], 0
    for size in cuts:                                   # pieces that end at line ends (the last: anywhere)
        end = data.rfind(b"\n", at, at + size) + 1
        if end > at:
            pieces.append((at, data[at:end]))
            at = end
    if at < len(data):
        pieces.append((at, data[at:]))
    *whole, last = data.split(b"\n")
    lines = [line + b"\n" for line in whole] + ([last] if last else [])      # (splitlines cuts at CR too)
    starts = np.cumsum([0, *[len(line) for line in lines]]).tolist()
    expected = [(starts[k], b"".join(lines[k:k + chunk_lines])) for k in range(0, len(lines), chunk_lines)]
    if compiled or native.line_end(b"\n", 0, 1) is None:
        assert list(files.line_blocks(pieces, chunk_lines)) == expected
    else:
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(native, "line_end", lambda *_: None)
            assert list(files.line_blocks(pieces, chunk_lines)) == expected


def test_numpy_lexes_where_it_is_turned_off(monkeypatch: pytest.MonkeyPatch) -> None:
    """``PRS3_POST_NATIVE=0``: no compiled lexer, and lex_column_block reads the same through numpy."""
    monkeypatch.setattr(native, "_lexer", None)
    monkeypatch.setattr(native, "_library", None)
    monkeypatch.setenv(native.ENV, "0")
    assert native.lex_text(b"\nX1\n", lexer._tables("X")[0], 1) is None
    values, read, ends = lexer.lex_column_block(b"G1 X1.5\n(note)\nX-0", "GX")
    assert values.view(np.uint64).tolist() == np.array([[1.0, 1.5], [np.nan, np.nan], [np.nan, -0.0]]).view(
        np.uint64).tolist()
    assert read.tolist() == [True, False, True] and ends.tolist() == [0, 8, 15, 19]
    _, kinds, _, spans = lexer.lex_block_lines(b"G1 X1.5\n ( note )\nX-0", "GX")
    assert kinds.tolist() == [1, 2, 1] and spans.tolist() == [[0, 0], [11, 15], [0, 0]]
    monkeypatch.setattr(native, "_scan", None)
    monkeypatch.setattr(native, "_line_end", None)
    monkeypatch.setattr(native, "_fill", None)
    monkeypatch.setattr(native, "_to_part", None)
    monkeypatch.setattr(native, "_roles", None)
    assert native.scan_text(b"A1") is None and native.line_end(b"\n", 0, 1) is None
    assert native.rows_to_part(np.zeros((1, 3)), np.eye(3), np.zeros(3)) is None
    assert native.line_roles(np.zeros((1, 6)), np.ones(1, dtype=np.uint8)) is None
    assert native.fill_moves(np.zeros((1, 6)), np.ones(1, dtype=bool), np.zeros(5), np.ones(3), np.zeros(2), 1) is True
    assert gcode.scan_bytes(b"G0 X1\nA1\x01") == (8, False, 1, 6)
    assert list(files.line_blocks([(0, b"a\nb\n"), (4, b"c\nd\ne\n")], 2)) == [(0, b"a\nb\n"), (4, b"c\nd\n"),
                                                                             (8, b"e\n")]


# ----------------------------------------------------------------------------- the compiled CL GOTO reader

needs_gotos = pytest.mark.skipif(native.plain_gotos(b"\n", apt._GOTO_CODES, apt._GOTO_PAIR_BAD, 0) is None,
                                 reason="the compiled CL GOTO reader was not built here")

#: A CL number: a sign or none, 1 to 17 digits (16 and 17: too many for the bulk path), the point
#: anywhere or nowhere.
_cl_number = st.builds(lambda sign, digits, point: sign + (digits[:point] + "." + digits[point:] if point >= 0
                                                           else digits),
                       st.sampled_from(["", "-", "+"]), _DIGITS, st.integers(-1, 17))
#: Numbers that break a plain GOTO: none, a lone point, a sign alone, two points, an exponent, spaces,
#: other digits and scripts, a lone surrogate (encoded as '?'), a continuation, a CR inside.
_cl_odd = st.sampled_from(["", ".", "-.", "+.", "+", "-", "+-1", "1.2.3", "..5", "5..", "1e5", "1E-3", " 1", "1 ",
                           "1\t", "١", "é", "\ud800", "1$", "$", "inf", "1_0", "\r1", "1\r", "0x1", "1/2"])
#: What a line starts with: mostly GOTO/, else lower case, a space, no slash, other words.
_cl_head = st.sampled_from(["GOTO/"] * 6 + ["goto/", "GOTO /", "GOTO", "GOT/", "GOTOGOTO/", "GOTO//", " GOTO/",
                                            "FEDRAT/MMPM,", "PAINT/COLOR,", "PPRINT/", "/", ""])
#: A byte or character put anywhere in a line.
_cl_stray = st.sampled_from(["\r", " ", "\t", "$", "é", "\ud800", "\x85", "\x00", "G", "O", "/", ",", ".", "+", "-",
                             "0", "E"])


@st.composite
def _cl_lines(draw: st.DrawFn) -> list[str]:
    """Lines of a CL chunk: plain GOTOs of 3 or 6 numbers (CR or not), and plain GOTOs with one thing
    wrong (4/5/7 numbers, an odd number, another head, another ending, a stray character anywhere),
    other records and empty lines."""
    lines: list[str] = []
    for _ in range(draw(st.integers(0, 20))):
        count = draw(st.sampled_from([3, 3, 6, 6, 0, 1, 2, 4, 5, 7]))
        numbers = draw(st.lists(_cl_number, min_size=count, max_size=count))
        if draw(st.integers(0, 3)) == 0 and count:
            numbers[draw(st.integers(0, count - 1))] = draw(_cl_odd)
        head = draw(_cl_head) if draw(st.integers(0, 3)) == 0 else "GOTO/"
        separator = draw(st.sampled_from([","] * 6 + [", ", ",,", ";"]))
        ending = draw(st.sampled_from(["", "", "\r", "\r\r", " ", "$", " $", "\t"]))
        line = head + separator.join(numbers) + ending
        if draw(st.integers(0, 4)) == 0:
            at = draw(st.integers(0, len(line)))
            line = line[:at] + draw(_cl_stray) + line[at:]
        lines.append(draw(st.sampled_from([line] * 8 + ["", "RAPID", "FEDRAT/MMPM,600", "$$ comment"])))
    return lines


def _not_numpy(text: bytes, n: int) -> None:
    raise AssertionError("the compiled GOTO reader is built, but _plain_gotos read with numpy")


def _digit_count(number: str) -> int:
    return sum(c.isdigit() for c in number)


@needs_gotos
@settings(max_examples=500, deadline=None)
@given(lines=_cl_lines())
@example(lines=["GOTO/-0,+0,-.5,5.,0.000,-1\r", "", "GOTO/1,2,3,4", "GOTO/1,2,1234567890123456", "goto/1,2,3"])
def test_compiled_goto_reader_reads_as_numpy_and_as_the_pattern(lines: list[str]) -> None:
    """Generated chunks mixing plain GOTOs with every irregularity: C and numpy give the same values (to
    the bit: -0.0, NaN where absent or not read) and the same lines read; and those are exactly the
    lines _PLAIN_GOTO matches with numbers of at most 15 digits, each value float() of its text."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(apt, "_plain_goto_text_numpy", _not_numpy)        # C, not numpy
        values, read = apt._plain_gotos(lines)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(native, "_gotos", False)                          # not there: numpy
        expected_values, expected_read = apt._plain_gotos(lines)
    assert values.dtype == np.float64 and values.shape == (len(lines), 6) == expected_values.shape
    assert values.view(np.uint64).tolist() == expected_values.view(np.uint64).tolist()
    assert read.dtype == np.bool_ and read.tolist() == expected_read.tolist()
    matches = [apt._PLAIN_GOTO.match(line) for line in lines]
    groups = [m.groups() if m is not None and all(_digit_count(g or "") <= 15 for g in m.groups()) else None
              for m in matches]
    assert read.tolist() == [g is not None for g in groups]
    specified = np.array([[np.nan if n is None else float(n) for n in g] if g is not None else [np.nan] * 6
                          for g in groups]).reshape(-1, 6)
    assert values.view(np.uint64).tolist() == specified.view(np.uint64).tolist()


@needs_gotos
def test_compiled_goto_reader_never_writes_past_its_outputs() -> None:
    """Room for fewer lines than the text has: -1, and nothing written past the room given; a text that
    does not start and end with a LF: -1; a line of 'GOTO/' alone at the very end: not read."""
    function = native._gotos
    text = b"\nGOTO/1,2,3\nGOTO/4,5,6,0,0,1\nGOTO/\n"
    values = np.full((3, 6), 7.0)
    read = np.full(3, 5, dtype=np.uint8)

    def call(text: bytes, rows: int) -> int:
        return int(function(text, len(text), apt._GOTO_CODES, apt._GOTO_PAIR_BAD, values.ctypes.data,
                            read.ctypes.data, rows))

    for rows in (0, 1, 2):
        assert call(text, rows) == -1
        assert values[rows:].tolist() == [[7.0] * 6] * (3 - rows)
        assert read[rows:].tolist() == [5] * (3 - rows)
    for bad in (b"GOTO/1,2,3\n", b"\nGOTO/1,2,3", b""):
        assert call(bad, 3) == -1
    assert call(text, 3) == 3
    nan = np.nan
    expected = np.array([[1, 2, 3, nan, nan, nan], [4, 5, 6, 0, 0, 1], [nan] * 6])
    assert values.view(np.uint64).tolist() == expected.view(np.uint64).tolist()
    assert read.tolist() == [1, 1, 0]
    for short in (b"\nGOTO\n", b"\nGOTO/\n", b"\nG\n", b"\n\n"):
        assert call(short, 1) == 1 and read[0] == 0 and np.isnan(values[0]).all()


def test_numpy_reads_the_gotos_where_it_is_turned_off(monkeypatch: pytest.MonkeyPatch) -> None:
    """``PRS3_POST_NATIVE=0``: no compiled GOTO reader, and _plain_gotos reads the same through numpy."""
    monkeypatch.setattr(native, "_gotos", None)
    monkeypatch.setattr(native, "_library", None)
    monkeypatch.setenv(native.ENV, "0")
    assert native.plain_gotos(b"\nGOTO/1,2,3\n", apt._GOTO_CODES, apt._GOTO_PAIR_BAD, 1) is None
    values, read = apt._plain_gotos(["GOTO/1.5,-0,+.25", "PAINT/COLOR,186", "GOTO/1,2,3,0,0,1\r"])
    nan = np.nan
    assert values.view(np.uint64).tolist() == np.array([[1.5, -0.0, 0.25, nan, nan, nan], [nan] * 6,
                                                        [1, 2, 3, 0, 0, 1]]).view(np.uint64).tolist()
    assert read.tolist() == [True, False, True]


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
    assert message.startswith("prs3-post: no compiled library (false -O2 -shared -fPIC -o ")
    assert message.rstrip().endswith("failed: ); numpy writes and lexes instead")
