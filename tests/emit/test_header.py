"""The program header: written by the main job, read back into the same job."""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from prs3_post.app.job import JobSpec, run_job, run_operations, spec_from_header, specs_from_header
from prs3_post.cli.options import flag_of
from prs3_post.core.errors import InputError
from prs3_post.core.numbers import degrees_text, exact_text
from prs3_post.emit.gcode import ProgramEmitter
from prs3_post.emit.header import SourceCounts, SourceHeader
from prs3_post.emit.header_read import header_comments, parse_header, read_header
from prs3_post.emit.header_write import source_header_entries
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.toolpaths import (
    Coolant,
    Cutting,
    Direction,
    Entry,
    HoleParams,
    ProfileParams,
    RoundShape,
    Side,
    SquareShape,
)
from prs3_post.toolpaths.work import HoleJob, ProfileJob

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "golden"
PARTS = REPO / "fixtures" / "parts"
WEDGE = REPO / "postproc" / "parts" / "patel2020-wedge.stl"
MACHINE = load_machine("patel2020")
LINUXCNC = load_dialect("linuxcnc")


def assert_same_spec(a: JobSpec, b: JobSpec) -> None:
    """Every field equal, bit for bit (arrays element-wise)."""
    for field in dataclasses.fields(JobSpec):
        x, y = getattr(a, field.name), getattr(b, field.name)
        if isinstance(x, np.ndarray):
            assert x.shape == y.shape, field.name
            assert_array_equal(x, y, strict=True, err_msg=field.name)
        else:
            assert x == y, field.name


def _rebuild(text: str, part: str, path: str = "prog.ngc") -> JobSpec:
    header = parse_header(header_comments(text), path=path)
    assert header is not None
    return spec_from_header(header, part, load_machine(header.machine_file or header.machine.lower()),
                            load_dialect(header.dialect_file or header.dialect.lower()))


@pytest.mark.parametrize("name", sorted(p.name for p in GOLDEN.iterdir() if not p.name.startswith("convert-")))
def test_every_golden_header_rebuilds_its_program(name):
    """Read the header of a golden program, rebuild the job from it alone: the same program, byte for byte."""
    golden = GOLDEN / name
    header = read_header(str(golden))
    assert header is not None
    part = WEDGE if header.part_name == "patel2020-wedge.stl" else PARTS / header.part_name.lower()
    specs = specs_from_header(header, str(part), load_machine(header.machine.lower()),
                              load_dialect(header.dialect.lower()))
    assert len(specs) == max(1, len(header.operations))
    assert run_operations(specs).text == golden.read_text(encoding="utf-8")


def _spec(**changes) -> JobSpec:
    base = JobSpec(
        part=str(WEDGE), units="mm", face=None,
        work=ProfileJob(SquareShape(size=30.000001, corner_radius=1.0 / 3.0, rotation=math.radians(15.3)),
                        ProfileParams(side=Side.INSIDE, depth=2.00001, step_down=0.7, direction=Direction.CONVENTIONAL,
                                      entry=Entry.PLUNGE, ramp_angle=0.1, clearance=2.5, retract=10.25)),
        at_uv=np.array([[1.0 / 7.0, -2.5]]), at_xyz=np.zeros((0, 3)),
        cutting=Cutting(tool_diameter=5.9, feed=333.3, plunge_feed=99.99, spindle_rpm=2999.5,
                        coolant=Coolant.MIST, tool_number=12),
        machine=MACHINE, dialect=LINUXCNC, setup=Setup((-100.0, -200.0, -970.0), 0.0), tolerance=0.0025,
    )
    return dataclasses.replace(base, **changes)


@pytest.mark.parametrize("spec", [
    _spec(),
    _spec(work=ProfileJob(RoundShape(diameter=24.123456789),
                          ProfileParams(side=Side.OUTSIDE, depth=1.5, step_down=1.0, direction=Direction.CLIMB,
                                        entry=Entry.RAMP, ramp_angle=math.radians(2.9308158971662404),
                                        clearance=2.0, retract=10.0))),
    _spec(work=HoleJob(HoleParams(depth=5.5, peck=1.25, dwell=0.125, clearance=2.0, retract=10.0,
                                  reapproach_gap=0.3)),
          at_uv=np.array([[10.0, 0.0], [-10.0, 5.0]]), at_xyz=np.array([[18.9736, 221.2132, 290.5135]]), face=4),
    _spec(setup=Setup((-118.0, -10.0, -678.0), 30.0), line_numbers=True, line_start=7, line_step=3),
    _spec(dialect=load_dialect("fanuc"), line_numbers=False, at_uv=np.zeros((0, 2))),
], ids=["square", "round", "holes-both-positions", "rotated-setup-numbered", "fanuc-upper-case"])
def test_header_round_trip_gives_the_same_spec(spec):
    from prs3_post.app.job import header_of
    from prs3_post.core.toolpath import JointProgram
    from prs3_post.emit.gcode import emit_program
    from prs3_post.emit.header_write import header_entries
    from prs3_post.part.faces import find_faces
    from prs3_post.part.stl import load_part

    face = find_faces(load_part(spec.part))[4]
    entries = header_entries(header_of(spec, "ab" * 32), face, description="a machine (with parentheses)")
    empty = JointProgram(kind=np.zeros(0, dtype=np.int64), stage=np.zeros((0, 2)), strokes=np.zeros((0, 3)),
                         inverse_time=np.zeros(0), source=np.zeros(0, dtype=np.int64), events=(),
                         source_labels=())
    text = emit_program(empty, spec.dialect, header=entries, stage=True)
    assert_same_spec(_rebuild(text, spec.part), spec)


def test_machine_given_by_path_is_recorded_and_used(tmp_path):
    machine_file = tmp_path / "my-machine.toml"
    shutil.copy(REPO / "postproc" / "machines" / "patel2020.toml", machine_file)
    spec = _spec(machine=load_machine(str(machine_file)),
                 work=ProfileJob(RoundShape(diameter=20.0), _spec().work.params))
    text = run_job(spec).text
    assert f"(machine file: {machine_file})" in text.split("\n")
    rebuilt = _rebuild(text, spec.part)
    assert_same_spec(rebuilt, spec)


def test_exact_numbers_keep_the_usual_decimals_where_they_can():
    assert [exact_text(v, 3) for v in (6.0, 2.00001, 1e-7, -0.0)] == ["6.000", "2.00001", "0.0000001", "0.000"]
    for deg in (15.0, 15.3, 2.9308158971662404, 0.1, 359.99):
        assert math.radians(float(degrees_text(math.radians(deg), 3))) == math.radians(deg)
    assert degrees_text(math.radians(45.0), 3) == "45.000"


def _header_lines(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").split("\n")


def test_a_malformed_entry_is_an_error_with_its_line(tmp_path):
    lines = _header_lines(GOLDEN / "wedge-round.ngc")
    number = next(i for i, ln in enumerate(lines) if ln.startswith("(setup: "))
    lines[number] = "(setup: part origin at machine [-100, -200] mm, rotation 0 deg about z)"
    bad = tmp_path / "bad.ngc"
    bad.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError) as caught:
        read_header(str(bad))
    assert str(caught.value) == (
        f"{bad}:{number + 1}: header: setup: expected [3 numbers], got '[-100, -200]'")


@pytest.mark.parametrize(("name", "tolerance", "expected"), [
    ("wedge-round.ngc", "5 mm", "expected a tolerance from 0.0001 to 1 mm (as --tolerance), got '5 mm'"),
    ("wedge-round.ngc", "0.00001 mm", "expected a tolerance from 0.0001 to 1 mm (as --tolerance), got '0.00001 mm'"),
    ("convert-mech491_APT_SimpleMillPlane.ngc", "5 mm, angle 0.01 deg",
     "expected a tolerance from 0.0001 to 1 mm (as --tolerance) and an angle in (0, 90] deg, got '5 mm, angle 0.01 "
     "deg'"),
])
def test_a_header_tolerance_outside_the_options_range_is_refused(tmp_path, name, tolerance, expected):
    """A header edited to 'tolerance: 5 mm' made verify accept G1 tips 5 mm off their chords: no program is made
    with a tolerance over 1 mm (--tolerance), and the header sets verify's."""
    lines = _header_lines(GOLDEN / name)
    number = next(i for i, ln in enumerate(lines) if ln.startswith("(tolerance: "))
    lines[number] = f"(tolerance: {tolerance})"
    bad = tmp_path / "bad.ngc"
    bad.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError) as caught:
        read_header(str(bad))
    assert caught.value.worded(flag_of) == f"{bad}:{number + 1}: header: tolerance: {expected}"   # as the CLI says it


def test_a_missing_entry_is_an_error(tmp_path):
    lines = [ln for ln in _header_lines(GOLDEN / "wedge-round.ngc") if not ln.startswith("(tool: ")]
    bad = tmp_path / "bad.ngc"
    bad.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError) as caught:
        read_header(str(bad))
    assert str(caught.value) == (
        f"{bad}:12: header: no 'tool' entry (a prs3-post header has program, machine, dialect, part, face, setup, "
        "operation, parameters, tool, tolerance, units)")


def test_a_program_without_a_header_has_none(tmp_path):
    plain = tmp_path / "plain.ngc"
    plain.write_text("(hand written)\nG0 X0 Y0 U100 V100 W100\nM2\n", encoding="utf-8")
    assert read_header(str(plain)) is None
    # a header entry after the first code line is not the header
    later = tmp_path / "later.ngc"
    later.write_text("G0 X0 Y0 U100 V100 W100\n" + (GOLDEN / "wedge-round.ngc").read_text(), encoding="utf-8")
    assert read_header(str(later)) is None


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_a_mutated_header_is_read_or_refused_never_a_traceback(tmp_path, data):
    """Any one-character change to a header: a header, None, or an InputError with a line."""
    text = (GOLDEN / "tilt35-square.ngc").read_text(encoding="utf-8")
    end = text.index("G17 ")
    where = data.draw(st.integers(0, end - 1))
    char = data.draw(st.sampled_from([*"0123456789.-+e,[]():x ", "1e999", "nan", "", "99999999999"]))
    mutated = tmp_path / "m.ngc"
    mutated.write_text(text[:where] + char + text[where + 1:], encoding="utf-8")
    try:
        read_header(str(mutated))
    except InputError as error:
        assert error.line is not None and str(error).startswith(f"{mutated}:")


# ----------------------------------------------------------------------------- a converted program's counts

CONVERTED = GOLDEN / "convert-mech491_APT_SimpleMillPlane.ngc"


def test_a_converted_program_states_its_counts_in_the_header():
    header = read_header(str(CONVERTED))
    assert isinstance(header, SourceHeader)
    assert header.counts == SourceCounts(records=82, moves=33, arcs=2, arc_rows=70, cycle_holes=0, cycle_rows=0,
                                         comments=1, program_moves=103, subdivisions=0,
                                         skipped=(("PAINT", 36), ("TOOL PATH", 1), ("Tool Path Listing", 1)))
    assert header.line("counts") == 8
    assert sum(ln.startswith("(counts: ") for ln in CONVERTED.read_text().splitlines()) == 1


@pytest.mark.parametrize("skipped", [(), (("G53 (machine coordinates, not converted)", 2), ("PAINT", 3))])
def test_counts_read_back_through_an_upper_case_wrapping_dialect(skipped):
    """Fanuc upper-cases comments; a short line limit wraps the entry; a word's remark keeps its commas."""
    counts = SourceCounts(records=9, moves=4, arcs=1, arc_rows=12, cycle_holes=2, cycle_rows=6, comments=0,
                          program_moves=22, subdivisions=5, skipped=skipped)
    header = dataclasses.replace(read_header(str(CONVERTED)), counts=counts, lines=(), path="")
    dialect = dataclasses.replace(load_dialect("fanuc"), max_line_length=100)
    text = ProgramEmitter(dialect).begin(source_header_entries(header))
    assert "(COUNTS: 9 RECORDS, 4 MOVES" in text
    back = parse_header(header_comments(text), path="p.nc")
    assert back.counts == dataclasses.replace(counts, skipped=tuple((w.upper().replace("(", "[").replace(")", "]"), n)
                                                                    for w, n in skipped))


def test_a_malformed_counts_entry_is_an_error_with_its_line(tmp_path):
    lines = _header_lines(CONVERTED)
    number = next(i for i, ln in enumerate(lines) if ln.startswith("(counts: "))
    lines[number] = lines[number].replace("skipped PAINT 36", "skipped PAINT")
    bad = tmp_path / "bad.ngc"
    bad.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(InputError) as caught:
        read_header(str(bad))
    assert str(caught.value) == (
        f"{bad}:{number + 1}: header: counts: expected 'skipped none' or 'WORD N' for each skipped word, got 'PAINT'")
