"""A new CAM format is one package and a registry entry: a toy format, registered here, is detected by its
content and converted as the shipped ones are, with no change to ``convert``.

The toy format: one move per line, ``x,y,z,i,j,k`` (tip in mm, tool axis), the first a rapid to the start
point and the rest feed moves at 600 mm/min. Its program must be the one of the same moves written as
G-code (motion line for motion line).
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from prs3_post.app.batch import collect_inputs
from prs3_post.app.convert import ConvertSettings, convert_file, input_format
from prs3_post.core.toolpath import MoveKind, Toolpath
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.readers.detect import detect_format
from prs3_post.readers.protocol import CamStream, ReadCounts, ReadFile, ReadOptions, StreamDefaults
from prs3_post.readers.registry import register, suffixes, unregister

_ROW = re.compile(r"-?[0-9.]+(?:,-?[0-9.]+){5}\Z")
FEED = 600.0


class CsvStream(StreamDefaults):
    """The toy format's stream: the whole file in one chunk."""

    def __init__(self, path: str, options: ReadOptions):
        self.path = path
        self.sha256: str | None = None
        self.summary: ReadFile | None = None

    def __iter__(self) -> Iterator[Toolpath]:
        data = Path(self.path).read_bytes()
        values = np.array([[float(v) for v in line.split(",")] for line in data.decode().split()])
        n = len(values)
        kind = np.full(n, int(MoveKind.FEED))
        kind[0] = int(MoveKind.RAPID)
        chunk = Toolpath(kind=kind, tip=values[:, :3], axis=values[:, 3:],
                         feed=np.where(kind == MoveKind.FEED, FEED, 0.0), source=np.arange(1, n + 1),
                         source_file=self.path)
        yield chunk
        self.sha256 = hashlib.sha256(data).hexdigest()
        self.summary = ReadFile(path=self.path, units="mm", toolpath=chunk,
                                counts=ReadCounts(records=n, by_word=(("row", n),), moves=n))

    def whole(self) -> ReadFile:
        for _ in self:
            pass
        assert self.summary is not None
        return self.summary


@dataclass(frozen=True, slots=True)
class CsvReader:
    name: str = "toy-csv"
    suffixes: tuple[str, ...] = (".toycsv",)
    first_move: str = "start with a rapid row"

    def claims(self, line: str) -> bool:
        return _ROW.match(line) is not None

    def check(self, options: ReadOptions) -> None:
        pass

    def open(self, path: str, options: ReadOptions) -> CamStream:
        return CsvStream(path, options)


@pytest.fixture
def toy() -> Iterator[CsvReader]:
    reader = CsvReader()
    register(reader)
    try:
        yield reader
    finally:
        unregister(reader.name)


POINTS = [(0.0, 0.0, 5.0), (0.0, 0.0, -1.0), (10.0, 0.0, -1.0), (10.0, 8.0, -1.0), (0.0, 8.0, -1.5)]


def _settings() -> ConvertSettings:
    machine = load_machine("patel2020")
    return ConvertSettings(machine=machine, dialect=load_dialect("linuxcnc"),
                           setup=Setup.resolve(machine, (0.0, 0.0, -850.0)))


def _motion_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if re.match(r"G[01] ", line)]


def test_a_registered_format_is_detected_by_content_and_converted(toy: CsvReader, tmp_path: Path) -> None:
    src = tmp_path / "part.toycsv"
    src.write_text("".join(f"{x},{y},{z},0,0,1\n" for x, y, z in POINTS))
    assert detect_format(src.read_bytes()) == "toy-csv"
    assert detect_format(b"G0 X1\n") == "gcode" and detect_format(b"GOTO/1,2,3\n") == "cl"
    assert input_format(str(src)) == "toy-csv"
    assert ".toycsv" in suffixes() and collect_inputs([str(tmp_path)]) == [str(src)]

    toy_program = convert_file(str(src), _settings())
    assert toy_program.report.format == "toy-csv"
    assert (toy_program.report.records, toy_program.report.input_moves) == (5, 5)
    assert "(source: part.toycsv, format toy-csv, units auto, sha256 " in toy_program.text

    twin = tmp_path / "part.ngc"                         # the same moves as G-code
    twin.write_text("G21 G90 G94\n" + f"G0 X{POINTS[0][0]} Y{POINTS[0][1]} Z{POINTS[0][2]}\n"
                    + "".join(f"G1 X{x} Y{y} Z{z} F{FEED:g}\n" for x, y, z in POINTS[1:]))
    gcode_program = convert_file(str(twin), _settings())
    assert _motion_lines(toy_program.text) == [
        "G0 X0.0000 Y0.0000 U240.5270 V240.5270 W240.5270",
        "G1 U246.5270 V246.5270 W246.5270 F100.0000",
        "G1 X10.0000 F60.0000",
        "G1 Y8.0000 F75.0000",
        "G1 X0.0000 U247.0270 V247.0270 W247.0270 F59.9251",
    ] == _motion_lines(gcode_program.text)


def test_a_format_once_unregistered_is_no_longer_detected(tmp_path: Path) -> None:
    reader = CsvReader()
    register(reader)
    unregister(reader.name)
    assert detect_format(b"1,2,3,0,0,1\n") == "gcode"           # the fallback: its messages say what is wrong
    with pytest.raises(ValueError, match="registered already"):
        register(CsvReader(name="cl"))
