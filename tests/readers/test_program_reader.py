"""The program reader's bulk path and its streaming: exactly what the careful line-by-line reader reads."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from prs3_post.core.errors import InputError
from prs3_post.core.toolpath import JointProgram, MoveKind, join_programs
from prs3_post.machine.loading import load_dialect
from prs3_post.readers import program as reader_module
from prs3_post.readers.program import ProgramStream, load_program, read_program

REPO = Path(__file__).resolve().parents[2]
VERIFY = REPO / "fixtures" / "verify"
PROGRAMS = sorted((REPO / "fixtures" / "golden").iterdir()) + sorted(VERIFY.glob("*.ngc"))
BAD = sorted((VERIFY / "bad").iterdir())


def _dialect(path: Path):
    return load_dialect("fanuc" if path.suffix == ".nc" else "linuxcnc")


def _rows(moves: JointProgram) -> tuple:
    return (moves.kind.tolist(), moves.stage.tolist(), moves.strokes.tolist(), moves.inverse_time.tolist(),
            moves.source.tolist(), [(e.before, e.kind, e.value, e.text) for e in moves.events])


def _careful_only(monkeypatch) -> None:
    monkeypatch.setattr(reader_module._Reader, "bulk", lambda self, first, values: False)


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_bulk_and_chunks_read_what_the_careful_reader_reads(path, monkeypatch):
    text = path.read_text()
    dialect = _dialect(path)
    reads = [read_program(text, dialect, path="p", chunk_lines=n) for n in (1, 7, 10_000)]
    _careful_only(monkeypatch)
    careful = read_program(text, dialect, path="p")
    for read in reads:
        assert _rows(read.moves) == _rows(careful.moves)
        assert (read.end_line, read.blending_lines, read.lines) == (careful.end_line, careful.blending_lines,
                                                                   careful.lines)


def test_the_bulk_path_takes_the_motion_lines(monkeypatch):
    """Of wedge-round.ngc's 230 lines only the header, setup and comment lines go line by line."""
    careful: list[int] = []
    original = reader_module._Reader.line

    def counted(self, number, line, *, crlf=False):
        careful.append(number)
        original(self, number, line, crlf=crlf)

    monkeypatch.setattr(reader_module._Reader, "line", counted)
    read = load_program(str(REPO / "fixtures" / "golden" / "wedge-round.ngc"), load_dialect("linuxcnc"))
    assert len(read.moves) > 190 and len(careful) < 40


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
@pytest.mark.parametrize(("chunk_lines", "piece_bytes"), [(1, 5), (7, 100), (10_000, 1 << 22)])
def test_stream_chunks_join_to_the_whole_program(path, chunk_lines, piece_bytes):
    dialect = _dialect(path)
    whole = load_program(str(path), dialect)
    stream = ProgramStream(str(path), dialect, chunk_lines=chunk_lines, piece_bytes=piece_bytes)
    chunks = list(stream)
    assert all(len(c) <= chunk_lines for c in chunks)
    assert _rows(join_programs(chunks)) == _rows(whole.moves)
    assert (stream.end_line, stream.blending_lines, stream.line_count) == (whole.end_line, whole.blending_lines,
                                                                           len(whole.lines))


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.name)
def test_stream_errors_are_the_whole_reads(path):
    dialect = load_dialect("linuxcnc")
    with pytest.raises(InputError) as whole:
        load_program(str(path), dialect)
    with pytest.raises(InputError) as streamed:
        list(ProgramStream(str(path), dialect, chunk_lines=3, piece_bytes=16))
    assert str(streamed.value) == str(whole.value)


@pytest.mark.parametrize(("data", "message"), [
    (b"  \n" * 20, "not a G-code program: the file is empty"),
    (b"\xef\xbb\xbfG0 X1\n" + b"\x00" * 40, ("starts with a UTF-8 byte-order mark, which LinuxCNC rejects ('Bad "
                                            "character')")),
    (b"G0 X1 Y1 U1 V1 W1 Q2\n" * 5 + b"\x01\n", "not a G-code program: binary data (byte 0x01 at offset 105)"),
    (b"G0 X1 Y1 U1 V1 W1\n" * 5 + b"(\xe9)\n", "not a G-code program: not UTF-8 text (byte 0xe9 at offset 91)"),
])
def test_stream_checks_the_whole_file_first(tmp_path, data, message):
    """Empty, byte-order mark, then the first bad byte, before any line: as a whole read."""
    path = tmp_path / "p.ngc"
    path.write_bytes(data)
    with pytest.raises(InputError) as caught:
        list(ProgramStream(str(path), load_dialect("linuxcnc"), chunk_lines=2, piece_bytes=8))
    assert str(caught.value) == f"{path}: {message}"


def test_reader_refuses_expressions_clearly():
    with pytest.raises(InputError) as caught:
        read_program("G0 X[1+2] Y1 U1 V1 W1\nM2\n", load_dialect("linuxcnc"), path="e.ngc")
    assert str(caught.value) == ("e.ngc:1: not G-code: column 5: '[' starts an expression ([1+2], LinuxCNC's "
                                 "arithmetic), which is not read here: use plain numbers")


def test_bulk_rows_keep_modal_state_across_chunks():
    """G0 stays active across a chunk boundary, an axis keeps its value, G93 carries."""
    text = "G0 X1 Y2 U3 V4 W5\nX2\nG93\nG1 U4 F2\nV5 F3\nG0 W1\nM2\n"
    for n in (1, 2, 3, 100):
        m = read_program(text, load_dialect("linuxcnc"), path="t", chunk_lines=n).moves
        assert m.kind.tolist() == [MoveKind.RAPID, MoveKind.RAPID, MoveKind.FEED, MoveKind.FEED, MoveKind.RAPID]
        assert np.column_stack([m.stage, m.strokes]).tolist() == [
            [1, 2, 3, 4, 5], [2, 2, 3, 4, 5], [2, 2, 4, 4, 5], [2, 2, 4, 5, 5], [2, 2, 4, 5, 1]]
        assert m.inverse_time.tolist() == [0, 0, 2, 3, 0]


def _variants() -> dict[str, bytes]:
    """wedge-round.ngc with CRLF line ends (all, or a few), a non-ASCII comment, no final line end, a
    motion line over the dialect's length limit, lower-case words."""
    lines = (REPO / "fixtures" / "golden" / "wedge-round.ngc").read_bytes().split(b"\n")[:-1]
    g1 = [i for i, ln in enumerate(lines) if ln.startswith(b"G1 ")]
    mixed = [ln + b"\r" if i in g1[5:9] or i == 3 else ln for i, ln in enumerate(lines)]
    accented = [*lines[:g1[20]], "(passe d'ébauche)".encode(), *lines[g1[20]:]]
    long_line = list(lines)
    long_line[g1[30]] += b" " * 300
    lower = list(lines)
    lower[g1[40]] = lower[g1[40]].lower()
    return {"crlf": b"\r\n".join(lines) + b"\r\n", "mixed-crlf": b"\n".join(mixed) + b"\n",
            "non-ascii-no-final-lf": b"\n".join(accented), "too-long": b"\n".join(long_line) + b"\n",
            "lower-case": b"\n".join(lower) + b"\n"}


@pytest.mark.parametrize("name", list(_variants()))
@pytest.mark.parametrize(("chunk_lines", "piece_bytes"), [(1, 5), (7, 100), (64, 1000), (10_000, 1 << 22)])
def test_stream_reads_bytes_as_the_whole_read_reads_text(tmp_path, name, chunk_lines, piece_bytes):
    """The stream lexes undecoded bytes; line ends, CRs, non-ASCII text and errors come out as from the text."""
    path = tmp_path / f"{name}.ngc"
    path.write_bytes(_variants()[name])
    dialect = load_dialect("linuxcnc")
    stream = ProgramStream(str(path), dialect, chunk_lines=chunk_lines, piece_bytes=piece_bytes)
    try:
        whole = load_program(str(path), dialect)
    except InputError as error:
        with pytest.raises(InputError) as streamed:
            list(stream)
        assert str(streamed.value) == str(error)
        assert name == "too-long"
        assert str(error) == f"{path}:57: the line is 360 characters, dialect linuxcnc allows 252"
        return
    chunks = list(stream)
    assert _rows(join_programs(chunks)) == _rows(whole.moves) and len(whole.moves) > 190
    assert (stream.end_line, stream.blending_lines, stream.line_count) == (whole.end_line, whole.blending_lines,
                                                                           len(whole.lines))
