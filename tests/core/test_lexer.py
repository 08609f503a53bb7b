"""The G-code lexer: exact errors, the fast column path, and pygcode as the reference of a differential test."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pygcode
import pygcode.exceptions
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal
from pygcode.comment import split_line
from pygcode.words import text2words

from prs3_post.core.errors import LexError
from prs3_post.core.lexer import (
    LINUXCNC_COMMENTS,
    code_name,
    column_pattern,
    decode,
    lex_columns,
    lex_line,
    lex_words,
    quote,
    split_comments,
)

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus" / "gcode"
PROGRAMS = (sorted((REPO / "fixtures" / "golden").iterdir()) + sorted((REPO / "fixtures" / "verify").glob("*.ngc"))
            + sorted((REPO / "fixtures" / "gcode").glob("*.ngc")))     # the 3+2 reader's CAM programs
CORPUS_FILES = sorted(CORPUS.glob("*")) if CORPUS.is_dir() else []


# ----------------------------------------------------------------------------- exact behaviour


@pytest.mark.parametrize(("code", "words"), [
    ("G1 X-12.5 Y.5 Z5. F100", [("G", 1.0, "G1"), ("X", -12.5, "X-12.5"), ("Y", 0.5, "Y.5"), ("Z", 5.0, "Z5."),
                                ("F", 100.0, "F100")]),
    ("g43.4 h2", [("G", 43.4, "G43.4"), ("H", 2.0, "H2")]),
    ("X  16.339\tY 1 . 5", [("X", 16.339, "X16.339"), ("Y", 1.5, "Y1.5")]),     # spaces inside words
    ("X1e-5", [("X", 1.0, "X1"), ("E", -5.0, "E-5")]),                          # no exponent: E is a word
    ("N007", [("N", 7.0, "N007")]),
    ("   ", []),
])
def test_words(code, words):
    assert list(lex_words(code)) == words


@pytest.mark.parametrize(("code", "message", "column"), [
    ("x-[1+2]", ("column 3: '[' starts an expression ([1+2], LinuxCNC's arithmetic), which is not read here: use "
                "plain numbers"), 3),
    ("G1 X#1", "column 5: '#' is a parameter (#1, #<name>), which is not read here: use plain numbers", 5),
    ("G1 X+1", ("column 4: word 'X' has no plain decimal number: found 'X+1' (a number is -12.5, .5 or 5.; no '+', "
               "no exponent)"), 4),
    ("G1 X", ("column 4: word 'X' has no plain decimal number: found 'X' (a number is -12.5, .5 or 5.; no '+', no "
             "exponent)"), 4),
    ("G1 X1 @", "column 7: cannot read '@' as words (a letter and a plain decimal number, e.g. G1 X-1.5)", 7),
    ("ı1", "column 1: cannot read 'ı1' as words (a letter and a plain decimal number, e.g. G1 X-1.5)", 1),
    ("X١", ("column 1: word 'X' has no plain decimal number: found 'X١' (a number is -12.5, .5 or 5.; no '+', no "
           "exponent)"), 1),
    ("%", "column 1: cannot read '%' as words (a letter and a plain decimal number, e.g. G1 X-1.5)", 1),
])
def test_word_errors_name_the_column(code, message, column):
    with pytest.raises(LexError) as caught:
        lex_words(code)
    assert (str(caught.value), caught.value.column) == (message, column)


def test_the_expression_line_of_the_corpus_is_refused_clearly():
    """linuxcnc_xyzab-tdr-demo.ngc line 10: a LinuxCNC expression (pygcode raises GCodeWordStrError)."""
    line = "g10 l20 p0 x-[#<_hal[xyzab_tdr_kins.x-rot-point]>+#<_hal[xyzab_tdr_kins.x-offset]>] y-#<_hal[x]>"
    with pytest.raises(LexError) as caught:
        lex_line(line)
    assert str(caught.value) == ("column 14: '[' starts an expression ([1+2], LinuxCNC's arithmetic), which is not "
                                 "read here: use plain numbers")


@pytest.mark.parametrize(("line", "delimiters", "result"), [
    ("G1 X1 (a;b) Y2 ; c (d", LINUXCNC_COMMENTS, ("G1 X1  Y2 ", ("a;b", " c (d"))),
    ("G1 (a) (b)", (("(", ")"),), ("G1  ", ("a", "b"))),
    ("G1 ; (x", ((";", ""),), ("G1 ", (" (x",))),
    ("G1", LINUXCNC_COMMENTS, ("G1", ())),
])
def test_comments(line, delimiters, result):
    assert split_comments(line, delimiters) == result


@pytest.mark.parametrize(("line", "message"), [
    ("G1 (open", "comment opened with '(' at column 4 is not closed with ')'"),
    ("G1 (a (b) c)", "comment at column 4 contains another '(' (LinuxCNC rejects nested comments)"),
])
def test_comment_errors(line, message):
    with pytest.raises(LexError) as caught:
        split_comments(line)
    assert (str(caught.value), caught.value.column) == (message, 4)


@pytest.mark.parametrize(("data", "offset", "message"), [
    (b" \n\t\n", None, "not a G-code program: the file is empty"),
    (b"\xef\xbb\xbfG0\n", None, "starts with a UTF-8 byte-order mark, which LinuxCNC rejects ('Bad character')"),
    (b"G0 X1\x00\n", None, "not a G-code program: binary data (byte 0x00 at offset 5)"),
    (b"G0 X1\x7f\n", 100, "not a G-code program: binary data (byte 0x7f at offset 105)"),
    (b"(caf\xe9)\n", None, "not a G-code program: not UTF-8 text (byte 0xe9 at offset 4)"),
])
def test_decode_errors(data, offset, message):
    with pytest.raises(LexError) as caught:
        decode(data, offset=offset)
    assert str(caught.value) == message


def test_decode_reads_text_and_tabs_and_crlf():
    assert decode("G0\tX1 (é)\r\n".encode()) == "G0\tX1 (é)\r\n"
    assert decode(b" \n", offset=10) == " \n"                    # a piece may be blank


def test_code_name_and_quote():
    assert [code_name("G", 43.4), code_name("M", 30.0), code_name("G", 1.25)] == ["G43.4", "M30", "G1.25"]
    assert quote("  short ") == "'short'"
    assert quote("x" * 45) == "'" + "x" * 40 + "...'"


def test_columns_read_the_regular_lines_only():
    lines = ["N10 G1 X1.5 Y-2 F.5", "X3", "", "G1 Y1 X2", "g1 X1", "G1 X1 (c)", "G1 X 1", "G1  X1  F2.", "G1 X1 X2"]
    values, read = lex_columns(lines, "NGXYF")
    assert read.tolist() == [True, True, True, False, False, False, False, True, False]
    assert_array_equal(values[[0, 1, 7]], [[10, 1, 1.5, -2, 0.5], [np.nan, np.nan, 3, np.nan, np.nan],
                                           [np.nan, 1, 1, np.nan, 2]])
    assert np.isnan(values[~read]).all()
    with pytest.raises(ValueError, match="distinct upper-case"):
        lex_columns(["X1"], "XX")


def test_digits_of_an_unread_line_leave_the_line_before_read():
    """A comment with digits (CAM writes one every few moves) is not read in bulk; the move before it is."""
    values, read = lex_columns(["G1 X1.5", "(pass 12)", "G1 X2", "7", "X3", " 8", "G1 X-.5"], "GX")
    assert read.tolist() == [True, False, True, False, True, False, True]
    assert_array_equal(values[[0, 2, 4, 6]], [[1, 1.5], [1, 2], [np.nan, 3], [1, -0.5]])


# ----------------------------------------------------------------------------- the fast path = the careful path

_LETTERS = "NGXYUVWF"


def _digits(least: int, most: int) -> st.SearchStrategy[str]:
    """``least`` to ``most`` digits: what ``st.from_regex(r"[0-9]{least,most}", fullmatch=True)`` gives, drawn
    several times faster (the regex strategy was most of these tests' time)."""
    return st.text(alphabet="0123456789", min_size=least, max_size=most)

_number = st.builds(lambda sign, whole, frac, form: sign + (whole + "." + frac if form == 0 else whole + "." if
                                                            form == 1 else "." + (frac or "0") if form == 2 else whole),
                    st.sampled_from(["", "-"]), _digits(1, 5),
                    _digits(0, 5), st.integers(0, 3))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(_LETTERS + "xMZ"), _number, st.sampled_from(["", " ", "  ", "\t"])),
                max_size=8))
@example([("X", "1", " "), ("X", "2", "")])
@example([("X", "1", " "), ("Y", ".5", "")])
@example([("x", "0.", "")])
def test_columns_agree_with_the_careful_lexer(words):
    line = "".join(f"{letter}{number}{space}" for letter, number, space in words)
    values, read = lex_columns([line], _LETTERS)
    careful = lex_words(line)
    assert read[0] == (column_pattern(_LETTERS).fullmatch(line) is not None)
    if read[0]:
        expected = np.full(len(_LETTERS), np.nan)
        for letter, value, _ in careful:
            expected[_LETTERS.index(letter)] = value
        assert_array_equal(values[0], expected)
        assert [w[0] for w in careful] == sorted((w[0] for w in careful), key=_LETTERS.index)


_long_number = st.builds(lambda sign, digits, point: sign + (digits[:point] + "." + digits[point:] if point >= 0
                                                                else digits),
                         st.sampled_from(["", "-"]), _digits(1, 15),
                         st.integers(-1, 15))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(_long_number, min_size=1, max_size=3), min_size=1, max_size=6))
@example([["-0.000", "0", "-0"], ["123456789012345", "-.123456789012345", "99999999999999.9"]])
@example([["5.", "-.5", "007"], ["1.0000000000001", "-12.3456", "0.00000000000001"]])
def test_columns_read_each_number_as_float_does(numbers):
    """Every value is float(text) to the bit, sign of zero included, for 1 to 15 digits with the point
    anywhere (numbers of up to 8 bytes and longer ones in one chunk)."""
    lines = [" ".join(f"{letter}{n}" for letter, n in zip("XYZ", row, strict=False)) for row in numbers]
    values, read = lex_columns(lines, "XYZ")
    assert read.all()
    expected = np.array([[float(n) for n in row] + [np.nan] * (3 - len(row)) for row in numbers])
    assert_array_equal(values, expected)
    assert_array_equal(np.signbit(values), np.signbit(expected))


_chunk_line = st.one_of(
    st.text(alphabet="NGXYUVWFx0123456789.- (", max_size=30),
    st.lists(st.tuples(st.sampled_from(_LETTERS), _number), max_size=8).map(
        lambda ws: " ".join(f"{letter}{number}" for letter, number in ws)))


@settings(max_examples=200, deadline=None)
@given(st.lists(_chunk_line, max_size=12))
@example(["X1", "5", "X2 3"])
@example(["", "N10 G1 X-12.5 Y.5 U5. V0 W-0.000 F100.4746"])
def test_column_chunks_agree_line_by_line(lines):
    """A chunk reads as its lines one at a time (no line leaks into another), and as the careful lexer.

    A line next to one that is not read may be left to the careful lexer too (a stray number after
    it is counted against it): never read otherwise."""
    values, read = lex_columns(lines, _LETTERS)
    each = [lex_columns([line], _LETTERS) for line in lines]
    if all(alone_read[0] for _, alone_read in each):
        assert read.all()
    for i, line in enumerate(lines):
        alone, alone_read = each[i]
        assert_array_equal(values[i], alone[0] if read[i] else np.full(len(_LETTERS), np.nan))
        if read[i]:
            assert alone_read[0]
            expected = np.full(len(_LETTERS), np.nan)
            for letter, value, _ in lex_words(line):
                expected[_LETTERS.index(letter)] = value
            assert_array_equal(values[i], expected)


# ----------------------------------------------------------------------------- pygcode as the reference
#
# Where pygcode 0.2.1 is documented wrong (LinuxCNC's manual, "G-code overview"), the lexer follows
# LinuxCNC and the comparison leaves the case out:
#   1. pygcode skips any characters before a letter (``G1 @X1`` reads G1 X1; NUL bytes vanish): refused here.
#   2. pygcode reads G and M values as ``\d+(\.\d)?`` and N, T, L as whole numbers, and fails on the rest
#      (``G1.25``, ``T1.5``, ``N-5``): read here as the numbers they are (the readers decide what is allowed).
#   3. spaces inside a number (``X1 .5``, ``X- 1``): LinuxCNC ignores spaces; pygcode fails.
#   4. ``;`` inside a parenthesised comment starts pygcode's comment (it fails on ``(a; b)``); LinuxCNC reads
#      ``(a; b)`` as one comment. pygcode also takes only one comment style per line.
#   5. ``%`` lines are program delimiters; pygcode takes a ``%`` anywhere (even in a comment) as the start
#      of a "macro": the readers handle ``%`` lines before the lexer (which refuses ``%`` as a word).
#   6. pygcode's letter match ignores case the Unicode way (``ı`` reads as I, ``ſ`` as S): refused here.
#   7. An O word takes pygcode's whole rest of the line (``O1000 G1`` fails there): read here as words.


def _pygcode_words(line: str) -> list[tuple[str, float]] | None:
    """pygcode's lexing of a line (its ``Line`` up to the words, without the modal-group checks of its
    ``Block``, which are a reader's business), or None where it raises."""
    try:
        match = pygcode.Line.line_regex.search(line)
        block, _ = split_line(match.group("block_and_comment") if match else line)
        return [(w.letter.upper(), float(w.value)) for w in text2words(block)]
    except (pygcode.exceptions.GCodeWordStrError, ValueError):
        return None


def _our_words(line: str) -> list[tuple[str, float]] | None:
    try:
        return [(letter, value) for letter, value, _ in lex_line(line)]
    except LexError:
        return None


def _documented(line: str) -> bool:
    """A line where pygcode is documented wrong: cases 4 (both comment styles) and 5 (``%``) above; the others
    do not occur in the files and are left out of the generated lines."""
    return "%" in line or (";" in line and "(" in line)


@pytest.mark.parametrize("path", PROGRAMS + CORPUS_FILES, ids=lambda p: p.name)
def test_every_fixture_and_corpus_line_lexes_as_pygcode_reads_it(path):
    """Same words, or both refuse the line (the corpus' expression line 10, a listing line, an O name)."""
    lines = path.read_bytes().decode("utf-8").replace("\r\n", "\n").split("\n")
    compared = 0
    for number, line in enumerate(lines, start=1):
        if _documented(line):
            continue
        assert _our_words(line) == _pygcode_words(line), (number, line)
        compared += 1
    assert compared >= len(lines) - 3


def test_documented_pygcode_differences():
    """Each documented case, pinned: what pygcode does, and what the lexer does."""
    cases = {
        "G1 @X1": ([("G", 1.0), ("X", 1.0)], None),
        "T1.5": (None, [("T", 1.5)]),
        "G1.25": (None, [("G", 1.25)]),
        "X1 .5": (None, [("X", 1.5)]),
        "G1 (a; b) X1": (None, [("G", 1.0), ("X", 1.0)]),
        "ı1": ([("I", 1.0)], None),
        "O1000 G1": (None, [("O", 1000.0), ("G", 1.0)]),
        "G1 (100%)": (None, [("G", 1.0)]),
    }
    assert {line: (_pygcode_words(line), _our_words(line)) for line in cases} == cases


_spaces = st.sampled_from(["", " ", "  "])
_float_letter = st.sampled_from("ABCDEFHIJKPQRSUVWXYZabcfijkrsxyz")
_float_number = st.builds(lambda sign, number: sign + number, st.sampled_from(["", "-"]),
                          st.from_regex(r"[0-9]{1,4}(\.[0-9]{0,4})?|\.[0-9]{1,4}", fullmatch=True))
_code = st.builds(lambda letter, number: letter + number, st.sampled_from("GMgm"),
                  st.from_regex(r"[0-9]{1,3}(\.[0-9])?", fullmatch=True))
_whole = st.builds(lambda letter, number: letter + number, st.sampled_from("NTLnt"),
                   _digits(1, 5))
_word = st.one_of(st.builds(lambda a, s, b: a + s + b, _float_letter, _spaces, _float_number), _code, _whole)
_comment = st.one_of(st.just(""), st.from_regex(r"\([a-zA-Z0-9 ,.:]{0,12}\)", fullmatch=True),
                     st.from_regex(r";[a-zA-Z0-9 ,.:()]{0,12}", fullmatch=True))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(_word, _spaces), max_size=7), _comment)
def test_generated_lines_lex_as_pygcode_reads_them(words, comment):
    line = "".join(w + s for w, s in words) + comment
    assert _our_words(line) == _pygcode_words(line)


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="XYZFxy0123456789.-+e[]#@()%;", max_size=16))
@example("X1-2")
@example("X--1")
def test_noise_the_lexer_accepts_pygcode_reads_the_same(line):
    """The lexer is the stricter one: whatever it reads (no spaces here, case 3), pygcode reads the same way."""
    ours = _our_words(line)
    if ours is not None and not _documented(line):
        assert _pygcode_words(line) == ours
