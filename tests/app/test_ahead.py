"""A conversion read in this process (with the read-ahead thread): what it hashes, how it runs out of
memory, and errors that cross a process boundary (a ``convert --jobs`` worker's) whole.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main
from prs3_post.core.errors import FeatureError, InputError, LimitError
from prs3_post.emit.header_read import read_header


@pytest.mark.parametrize("error", [InputError("bad", path="a.ngc", line=3), InputError("bad", path="a.ngc"),
                                   LimitError("T1 above"), FeatureError("too big", key="side", operation=2)])
def test_errors_pickle_with_their_attributes(error: Exception) -> None:
    back = pickle.loads(pickle.dumps(error))
    assert (type(back), str(back), back.__dict__) == (type(error), str(error), error.__dict__)


def test_an_input_replaced_while_it_is_read_is_hashed_as_it_was_read(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """An editor saving a new version over the input (or deleting it) while it is converted: the
    header's SHA-256 is that of the bytes converted (the reader hashes what it reads; the file
    was hashed again by name afterwards, which named the new file, or failed with 'file not
    found' once it was deleted)."""
    import hashlib

    from prs3_post.readers.gcode.reader import GcodeStream

    src = tmp_path / "part.ngc"
    src.write_text("G21 G90\nG0 X0 Y0 Z5\n" + "".join(f"G1 X{k % 40} Y{k % 37} Z-1 F500\n" for k in range(3000)))
    converted = hashlib.sha256(src.read_bytes()).hexdigest()
    newer = tmp_path / "newer.ngc"
    newer.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 X1 Y1 Z-1 F500\n")
    pieces = GcodeStream._pieces

    def replaced_after_the_first_piece(self: GcodeStream):
        self.piece_bytes = 4096                        # several pieces
        for number, piece in enumerate(pieces(self)):
            yield piece
            if number == 0:
                os.replace(newer, src)

    monkeypatch.setattr(GcodeStream, "_pieces", replaced_after_the_first_piece)
    monkeypatch.setenv("PRS3_POST_THREADS", "2")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(src), "-d", str(out), "--jobs", "1", "--part-origin=0,0,-850"])
    assert result.exit_code == 0, result.output
    header = read_header(str(out / "part.ngc"))
    assert header.source_sha256 == converted
    assert header.counts is not None and header.counts.moves == 3001


def test_running_out_of_memory_is_one_line_not_a_traceback(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """QA ran convert under ``ulimit -v``: numpy's MemoryError, raised where the input is read (the
    read-ahead thread) and raised again here, ended in a traceback."""
    from prs3_post.cli.options import OUT_OF_MEMORY
    from prs3_post.readers.cl.reader import ClStream

    def starved(self: ClStream):
        raise MemoryError
        yield                                          # a generator, as the reader is

    monkeypatch.setattr(ClStream, "__iter__", starved)
    monkeypatch.setenv("PRS3_POST_THREADS", "2")
    src = tmp_path / "part.cls"
    src.write_text("RAPID\nGOTO/0,0,10\nGOTO/1,0,10\n")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(src), "-d", str(out), "--jobs", "1", "--part-origin=0,0,-850"])
    assert (result.exit_code, result.stderr) == (1, f"prs3-post: error: {OUT_OF_MEMORY}\n")
    assert list(out.iterdir()) == []
