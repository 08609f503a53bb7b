"""A machine file that describes each leg (kinematics "3-prs-general") in every command.

* With the ideal head's numbers written out leg by leg, every golden program comes out with the
  same joint values (the strokes posted agree with the ideal closed form's to 1e-9 mm before
  rounding) and the same text but for the header's machine lines.
* A head as built (rail points, links, rail directions and encoder zeros off by tenths) runs the main
  job, job files, convert, verify, preview, ik, fk, placement, limits, dynamics and collision, and
  its programs replay through its own FK onto the intended tips to 1e-9 mm.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose
from test_convert import CORPUS, GCODE_GOLDEN, GOLDEN_FILES, PLACED, _origin_option
from test_job import CASES
from test_multi_job import EXAMPLE

import prs3_post.app.job as job_module
from prs3_post.app.job import JobProgram, JobSpec, run_job
from prs3_post.cli.main import main
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.machine.model import general_from_ideal
from prs3_post.readers.program import read_program

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "golden"
SHIPPED = REPO / "postproc" / "machines" / "patel2020.toml"
AS_BUILT = REPO / "fixtures" / "machines" / "patel2020-as-built.toml"
WEDGE = str(REPO / "fixtures" / "parts" / "wedge.stl")


def _vector(values: tuple[float, ...]) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def ideal_legs_toml() -> str:
    """patel2020.toml as a general machine, the ideal head's legs written out key by key."""
    general = general_from_ideal(load_machine("patel2020").geometry)
    text = SHIPPED.read_text().replace('kinematics = "3-prs"', 'kinematics = "3-prs-general"')
    assert 'kinematics = "3-prs-general"' in text
    for leg in general.legs:
        text += (f"\n[[legs]]\nrail_point_mm = {_vector(leg.rail_point)}\n"
                 f"rail_direction = {_vector(leg.rail_direction)}\nrevolute_axis = {_vector(leg.revolute_axis)}\n"
                 f"link_length_mm = {leg.link_length!r}\n"
                 f"platform_joint_mm = {_vector(leg.platform_joint)}\nstroke_offset_mm = 0.0\n")
    return text + f"\n[platform]\ntool_tip_mm = {_vector(general.tool_tip)}\ntool_axis = {_vector(general.tool_axis)}\n"


@pytest.fixture(scope="module")
def equal(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("machines") / "patel2020-legs.toml"
    path.write_text(ideal_legs_toml())
    return path


def invoke(*args: str) -> object:
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def without_machine_lines(text: str) -> str:
    """The program without the header's ``(machine: ...)`` and ``(machine file: ...)`` lines (any case)."""
    return "".join(line for line in text.splitlines(keepends=True) if not line.lower().startswith("(machine"))


def joint_words(text: str, dialect: str = "linuxcnc") -> np.ndarray:
    moves = read_program(text, load_dialect(dialect), path="p").moves
    return np.column_stack([moves.stage, moves.strokes])


def posted(args: list[str]) -> tuple[object, JobProgram]:
    """Run the CLI and keep the checked job it wrote (every row's joints before rounding)."""
    kept: list[JobProgram] = []
    real = job_module.check_job

    def spy(spec: JobSpec, **options: bool) -> JobProgram:
        kept.append(real(spec, **options))
        return kept[-1]

    with mock.patch.object(job_module, "check_job", spy):
        outcome = invoke(*args)
    assert outcome.exit_code == 0, outcome.output
    return outcome, kept[0]


def test_the_loaded_legs_are_the_ideal_head_to_the_last_bits(equal: Path) -> None:
    machine = load_machine(str(equal))
    assert machine.kinematics == "3-prs-general"
    ideal = general_from_ideal(machine.geometry)
    assert machine.geometry.general is not None
    for leg, nominal in zip(machine.geometry.general.legs, ideal.legs, strict=True):
        assert leg.rail_point == nominal.rail_point and leg.platform_joint == nominal.platform_joint
        assert_allclose(leg.revolute_axis, nominal.revolute_axis, atol=2e-16)
    assert kinematics_of(machine).shift_direction == (0.0, 0.0, -1.0)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_every_golden_job_with_the_ideal_head_written_leg_by_leg(case, equal: Path, tmp_path: Path) -> None:
    _, ideal = posted([*case.args, "-o", str(tmp_path / "ideal.ngc")])
    _, general = posted([*case.args, "--machine", str(equal), "-o", str(tmp_path / case.name)])
    assert_allclose(general.program.strokes, ideal.program.strokes, atol=1e-9, rtol=0)
    assert_allclose(general.program.stage, ideal.program.stage, atol=1e-9, rtol=0)
    text, golden = (tmp_path / case.name).read_text(), (GOLDEN / case.name).read_text()
    dialect = "fanuc" if case.name.endswith(".nc") else "linuxcnc"
    assert_allclose(joint_words(text, dialect), joint_words(golden, dialect), atol=1e-9, rtol=0)
    # byte for byte but for the machine's name and file in the header and, on twofaces' face 6, the tool's
    # clearance in the collision line: the smallest tool distance sampled there moves with FK's last bits
    # (1e-13 mm), by 0.08 mm (a sample enters or leaves the swept region the cut is spared in)
    assert changed_lines(golden, text) == COLLISION_LINE_MOVES.get(case.name, [])
    assert [line.lower() for line in text.splitlines() if line.lower().startswith("(machine")] == [
        "(machine: patel2020-legs [patel 2020 3-prs head over an xy stage [the paper's numbers, assumed limits]])",
        f"(machine file: {str(equal).lower()})"]


#: The golden programs whose collision line reads otherwise with the general kinematics: (old, new).
COLLISION_LINE_MOVES = {
    "twofaces-face6-square.ngc": [(
        "(collision: clear of the part by at least 1.000 mm: tool 10.143 mm, holder over 11.000 mm, spindle nose "
        "over 11.000 mm)",
        "(collision: clear of the part by at least 1.000 mm: tool 10.225 mm, holder over 11.000 mm, spindle nose "
        "over 11.000 mm)")],
    "twofaces-face6-round-fanuc.nc": [(
        "(COLLISION: CLEAR OF THE PART BY AT LEAST 1.000 MM: TOOL 10.231 MM, HOLDER OVER 11.000 MM, SPINDLE NOSE "
        "OVER 11.000 MM)",
        "(COLLISION: CLEAR OF THE PART BY AT LEAST 1.000 MM: TOOL 10.290 MM, HOLDER OVER 11.000 MM, SPINDLE NOSE "
        "OVER 11.000 MM)")],
}


def changed_lines(golden: str, text: str) -> list[tuple[str, str]]:
    """The lines (golden, now) that differ, the header's machine lines left out (the same count of lines)."""
    old, new = without_machine_lines(golden).splitlines(), without_machine_lines(text).splitlines()
    assert len(old) == len(new)
    return [(a, b) for a, b in zip(old, new, strict=True) if a != b]


def test_the_golden_job_file_with_the_ideal_head_written_leg_by_leg(equal: Path, tmp_path: Path) -> None:
    out = tmp_path / "example.ngc"
    assert invoke("job", str(EXAMPLE), "--machine", str(equal), "-o", str(out)).exit_code == 0
    golden = (GOLDEN / "twofaces-job-example.ngc").read_text()
    assert_allclose(joint_words(out.read_text()), joint_words(golden), atol=1e-9, rtol=0)
    assert without_machine_lines(out.read_text()) == without_machine_lines(golden)


@pytest.mark.parametrize("name", [*GOLDEN_FILES, *sorted(GCODE_GOLDEN)])
def test_every_golden_conversion_with_the_ideal_head_written_leg_by_leg(name: str, equal: Path,
                                                                       tmp_path: Path) -> None:
    if name in GCODE_GOLDEN:
        source, options, golden = REPO / "fixtures" / "gcode" / name, GCODE_GOLDEN[name], f"convert-{name}"
    else:
        source, options, golden = CORPUS / name, (_origin_option(PLACED[name]),), f"convert-{Path(name).stem}.ngc"
    cwd = os.getcwd()
    os.chdir(source.parent)                          # the header names the file, not a folder
    try:
        result = invoke("convert", source.name, "-d", str(tmp_path), "--jobs", "1", "--machine", str(equal),
                        *options)
    finally:
        os.chdir(cwd)
    assert result.exit_code == 0, result.output
    text = (tmp_path / (Path(name).stem + ".ngc")).read_text()
    expected = (GOLDEN / golden).read_text()
    assert_allclose(joint_words(text), joint_words(expected), atol=1e-9, rtol=0)
    assert without_machine_lines(text) == without_machine_lines(expected)


# ----------------------------------------------------------------------------- a head as built


def test_the_main_job_places_posts_and_round_trips_on_a_head_as_built(tmp_path: Path) -> None:
    out = tmp_path / "square.ngc"
    kept: list[JobSpec] = []
    real = job_module.check_job

    def spy(spec: JobSpec, **options: bool) -> JobProgram:
        kept.append(spec)
        return real(spec, **options)

    with mock.patch.object(job_module, "check_job", spy):
        result = invoke("demo", "--profile", "square", "--part-origin", "auto", "--part-rotation", "auto",
                        "--machine", str(AS_BUILT), "-o", str(out))
    assert result.exit_code == 0, result.output
    job = run_job(kept[0])
    machine = load_machine(str(AS_BUILT))
    program, rows = job.post.program, job.post.path
    fk = kinematics_of(machine).forward(program.strokes, program.stage)
    assert fk.converged.all()
    assert_allclose(fk.tip, rows.tip, atol=1e-9, rtol=0)
    assert_allclose(fk.axis, rows.axis, atol=1e-12, rtol=0)
    # the nominal head would need other strokes: tenths of a millimetre
    nominal = kinematics_of(load_machine("patel2020")).inverse(rows.tip, rows.axis)
    assert 0.1 < np.abs(nominal.strokes - program.strokes).max() < 2.0
    verified = invoke("verify", str(out))
    assert verified.exit_code == 0, verified.output
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance"


def test_job_file_convert_verify_and_preview_on_a_head_as_built(tmp_path: Path) -> None:
    out = tmp_path / "example.ngc"
    assert invoke("job", str(EXAMPLE), "--machine", str(AS_BUILT), "-o", str(out)).exit_code == 0
    assert invoke("verify", str(out)).output.splitlines()[-1] == "OK: within every limit and tolerance"
    source = CORPUS / "mech491_APT_Variable_Axis.cls"
    result = invoke("convert", str(source), "-d", str(tmp_path), "--jobs", "1", "--machine", str(AS_BUILT),
                    _origin_option(PLACED[source.name]))
    assert result.exit_code == 0, result.output
    converted = tmp_path / "mech491_APT_Variable_Axis.ngc"
    verified = invoke("verify", str(converted), "--against", str(source))
    assert verified.exit_code == 0, verified.output
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance"
    pytest.importorskip("matplotlib")
    picture = tmp_path / "p.png"
    shown = invoke("preview", str(converted), "-o", str(picture))
    assert shown.exit_code == 0, shown.output
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_ik_and_fk_json_round_trip_on_a_head_as_built() -> None:
    ik = invoke("ik", "--tip", "-81.0264,21.2132,-679.4865", "--axis", "0.447214,0,0.894427", "--json",
                "--machine", str(AS_BUILT))
    assert ik.exit_code == 0, ik.output
    pose = json.loads(ik.output)
    assert pose["ok"] and pose["reachable"]
    assert_allclose([pose["X"], pose["Y"]], [-2.9141, 12.7745], atol=1e-4)
    fk = invoke("fk", "--strokes", f"{pose['T1']!r},{pose['T2']!r},{pose['T3']!r}",
                "--xy", f"{pose['X']!r},{pose['Y']!r}", "--json", "--machine", str(AS_BUILT))
    assert fk.exit_code == 0, fk.output
    back = json.loads(fk.output)
    assert_allclose([back["tip_x"], back["tip_y"], back["tip_z"]], [-81.0264, 21.2132, -679.4865], atol=1e-9)
    assert_allclose([back["axis_x"], back["axis_y"], back["axis_z"]], [pose["axis_x"], pose["axis_y"], pose["axis_z"]],
                    atol=1e-12)
    assert back["converged"] and back["residual_mm"] < 1e-10


def test_paper_model_is_refused_for_a_head_as_built() -> None:
    result = invoke("ik", "--model", "paper", "--tip", "-81.0264,21.2132,-679.4865", "--axis", "0.447214,0,0.894427",
                    "--machine", str(AS_BUILT))
    assert (result.exit_code, result.output) == (
        2, "prs3-post: error: the paper's IK model exists for the ideal head only (kinematics = \"3-prs\"), not for "
           "3-prs-general (use the model exact or head)\n")


def test_limits_suggestion_dynamics_and_collision_on_a_head_as_built(tmp_path: Path) -> None:
    out = tmp_path / "x.ngc"
    result = invoke("run", WEDGE, "--profile", "hole", "--part-origin", "0,0,0", "--machine", str(AS_BUILT),
                    "-o", str(out))
    assert (result.exit_code, result.output) == (1, (
        "prs3-post: error: hole 1 approach: T1 stroke -951.9079 mm is below the minimum -100.0000 mm by 851.9079 mm "
        "(5 points outside limits in all); setup: part origin at machine [0.0000, 0.0000, 0.0000] mm, rotation "
        "0.0000 deg about z; a part origin at machine [-78.8, -192.4, -1028.7] mm puts every point inside the "
        "machine's limits: --part-origin=-78.8,-192.4,-1028.7\n"))
    assert not out.exists()
    suggested = invoke("run", WEDGE, "--profile", "hole", "--part-origin=-78.8,-192.4,-1028.7", "--machine",
                       str(AS_BUILT), "-o", str(out))
    assert suggested.exit_code == 0, suggested.output
    header = out.read_text().splitlines()
    assert [line for line in header if line.startswith("(dynamics:")] == [
        "(dynamics: cycle time 0.082 min = 4.9 s, no feed slowed by the axis speed limits)"]
    wall = str(REPO / "fixtures" / "parts" / "wall30.stl")
    hit = invoke("run", wall, "--profile", "hole", "--at", "30,0", "--machine", str(AS_BUILT), "-o", str(out))
    assert (hit.exit_code, hit.output) == (
        1, "prs3-post: error: hole 1 approach: the holder hits the part, 2.446 mm deep (clearance min 1.000 mm); no "
           "setup changes that (the part and the tool axes move together): try a longer tool (--tool-table), a "
           "shorter holder (the machine file's [holder]), or another --at (or --face)\n")
