"""`prs3-post convert`: the corpus CL files, golden programs, FK replay, LinuxCNC, bad inputs, batches.

The corpus files are referenced in ../shared/corpus (never copied). Each placeable file has the
setup that puts it in the workspace (the part origin the limit error suggested); the others fail
with their exact message.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import select
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import compare_golden
from numpy.testing import assert_allclose

from prs3_post.app.batch import collect_inputs, convert_batch
from prs3_post.app.convert import ConvertSettings, convert_file, write_conversion
from prs3_post.cli.main import main
from prs3_post.core.defaults import DEFAULT_CIRCLE_TOLERANCE as CIRCLE_TOL
from prs3_post.core.errors import PoseError
from prs3_post.emit.header import SourceHeader
from prs3_post.emit.header_read import read_header
from prs3_post.kinematics import forward, unit_axes
from prs3_post.machine.loading import load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.part.workplane import WorkPlane
from prs3_post.post.pipeline import place_toolpath
from prs3_post.readers.cl.reader import read_cl
from prs3_post.readers.program import read_program

REPO = Path(__file__).resolve().parents[2]
CORPUS = REPO.parent / "shared" / "corpus" / "cl"
GOLDEN = REPO / "fixtures" / "golden"
pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason="the corpus (../shared/corpus) is not here")

#: Corpus files that fit the machine, with the part origin that places them (rotation 0).
PLACED = {
    "humman_deep_drill.clsf": (94.5, 0.0, -996.0),
    "humman_standart_drill.clsf": (94.5, 0.0, -996.0),
    "mech491_APT_SimpleMillPlane.cls": (0.0, -17.2, -856.0),
    "mech491_APT_Variable_Axis.cls": (-44.0, -81.3, -786.7),
    "mech491_APT_Zig_Zag_Smoothed.cls": (-76.5, -80.8, -788.9),
}
_DEFAULT_SETUP = ("setup: part origin at machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z; "
                  "no translation of the part puts every point inside the machine's limits")
_NO_TURN = "; a setup turns the part about z only, so no setup turns these tool axes toward the spindle"
#: Corpus files no setup fits, and why (their MSYS turns the part upside down: the tool axis points
#: down in the part frame, and a setup turns the part about z only; ust_a also tilts 86°, past the limit).
UNPLACEABLE = {
    "humman_1_KONTUR_NAR_40_N2.cls":
        "lines 9, 12, 15, 16, 18, 19, 20, 21, 22, 23, ...: the axis points away from the spindle (axis z must be "
        "> 0)" + _NO_TURN,
    "humman_4_SVERL_63_N2.cls":
        "lines 8, 10, 12, 15, 18, 21, 23, 26, 29, 31, ...: the axis points away from the spindle (axis z must be "
        "> 0)" + _NO_TURN,
    "humman_ust_a_variable_contour.cls":
        "11: stage Y -1396.5000 mm is below the minimum -300.0000 mm by 1096.5000 mm (546 points outside limits "
        "in all); " + _DEFAULT_SETUP,
}
GOLDEN_FILES = ("humman_deep_drill.clsf", "mech491_APT_SimpleMillPlane.cls", "mech491_APT_Variable_Axis.cls")


def _settings(origin: tuple[float, float, float] | None = None, **kwargs: object) -> ConvertSettings:
    machine = load_machine("patel2020")
    return ConvertSettings(machine=machine, dialect=load_dialect("linuxcnc"), setup=Setup.resolve(machine, origin),
                           **kwargs)  # type: ignore[arg-type]


def _origin_option(origin: tuple[float, float, float]) -> str:
    return "--part-origin=" + ",".join(f"{v:g}" for v in origin)


def test_every_corpus_cl_file_is_placed_or_refused() -> None:
    names = sorted(p.name for p in CORPUS.iterdir() if p.suffix in (".cls", ".clsf"))
    assert names == sorted([*PLACED, *UNPLACEABLE])


@pytest.mark.parametrize("name", sorted(PLACED))
def test_corpus_file_replays_onto_its_cl_points(name: str) -> None:
    """FK of every program line lands on the machine-frame path within rounding, and every CL point is on it."""
    settings = _settings(PLACED[name])
    path = str(CORPUS / name)
    conversion = convert_file(path, settings)
    program = read_program(conversion.text, settings.dialect, path=name)
    moves = program.moves
    fk = forward(settings.machine.geometry, moves.strokes, moves.stage)
    assert fk.converged.all()
    tip = fk.tip                                      # part-relative: the stage included
    rounding = 2e-4                                   # 4 decimals on 5 joint words through the Jacobian (≤ 7.2)
    assert_allclose(tip, conversion.path.tip, atol=1e-6 + rounding)
    # the CL points (MSYS and setup applied): each read row is a row of the program, in order
    cl = place_toolpath(read_cl(path, tolerance=settings.tolerance,
                                circle_tolerance=CIRCLE_TOL).toolpath, settings.setup)
    hits = np.array([np.flatnonzero(np.linalg.norm(conversion.path.tip - p, axis=1) < 1e-9)[:1].size
                     for p in cl.tip])
    assert hits.all()
    assert conversion.report.deviation_after <= settings.tolerance
    assert conversion.report.emitted_moves == len(moves)


@pytest.mark.parametrize("name", sorted(UNPLACEABLE))
def test_unplaceable_corpus_file_fails_with_its_reason(name: str, tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["convert", str(CORPUS / name), "-d", str(tmp_path), "--jobs", "1"])
    assert result.exit_code == 1
    separator = ":" if name == "humman_ust_a_variable_contour.cls" else ": "
    assert result.stdout == f"failed\t{CORPUS / name}\t-\t{CORPUS / name}{separator}{UNPLACEABLE[name]}\n"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", GOLDEN_FILES)
def test_golden_conversion(name: str, tmp_path: Path, update_golden: bool, rs274_check) -> None:
    """Made through the CLI from inside the corpus folder (the header names the file, not a folder)."""
    cwd = os.getcwd()
    os.chdir(CORPUS)
    try:
        result = CliRunner().invoke(main, ["convert", name, "-d", str(tmp_path), "--jobs", "1",
                                           _origin_option(PLACED[name])])
    finally:
        os.chdir(cwd)
    assert result.exit_code == 0, result.output
    out = tmp_path / (Path(name).stem + ".ngc")
    compare_golden(out.read_text(), GOLDEN / f"convert-{Path(name).stem}.ngc", update_golden)
    code, text = rs274_check(out)
    assert code == 0, text
    verified = CliRunner().invoke(main, ["verify", str(out), "--against", str(CORPUS / name)])
    assert verified.exit_code == 0, verified.output
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance"


#: Synthesized 3+2 G-code programs (fixtures/gcode) with their golden programs: the options after the input.
GCODE_GOLDEN = {
    "g68-peck-arc.ngc": ("--part-origin=-60.9,-10.9,-745",),
    "wedge-face-3axis.ngc": ("--part-origin=-77.8,-190.9,-1030.2",
                             "--work-plane", str(REPO / "fixtures" / "parts" / "wedge.stl") + ":4"),
}


@pytest.mark.parametrize("name", sorted(GCODE_GOLDEN))
def test_golden_3_plus_2_conversion(name: str, tmp_path: Path, update_golden: bool, rs274_check) -> None:
    """A G68.2 program (a G83 peck cycle, a G2 arc in G18) and a 3-axis program put on the wedge's face 4,
    byte for byte; LinuxCNC accepts them and verify --against their G-code rebuilds them."""
    src = REPO / "fixtures" / "gcode" / name
    result = CliRunner().invoke(main, ["convert", str(src), "-d", str(tmp_path), "--jobs", "1", *GCODE_GOLDEN[name]])
    assert result.exit_code == 0, result.output
    out = tmp_path / name
    compare_golden(out.read_text(), GOLDEN / f"convert-{name}", update_golden)
    code, text = rs274_check(out)
    assert code == 0, text
    verified = CliRunner().invoke(main, ["verify", str(out), "--against", str(src)])
    assert verified.exit_code == 0, verified.output
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance"


def test_every_placed_output_passes_linuxcnc(tmp_path: Path, rs274_check) -> None:
    for name, origin in PLACED.items():
        result = CliRunner().invoke(main, ["convert", str(CORPUS / name), "-d", str(tmp_path), "--jobs", "1",
                                           _origin_option(origin)])
        assert result.exit_code == 0, result.output
    outputs = sorted(tmp_path.glob("*.ngc"))
    assert len(outputs) == len(PLACED)
    code, text = rs274_check(*outputs)
    assert code == 0, text


def test_verify_against_another_source_is_refused(tmp_path: Path) -> None:
    name = "mech491_APT_SimpleMillPlane.cls"
    CliRunner().invoke(main, ["convert", str(CORPUS / name), "-d", str(tmp_path), "--jobs", "1",
                              _origin_option(PLACED[name])])
    out = tmp_path / "mech491_APT_SimpleMillPlane.ngc"
    other = CORPUS / "humman_deep_drill.clsf"
    result = CliRunner().invoke(main, ["verify", str(out), "--against", str(other)])
    assert result.exit_code == 2
    assert result.stderr == (
        f"prs3-post: error: {out}:4: --against: {other} (SHA-256 "
        "efee317f7d9c2d8c2e4c2e2fc0108bd82f77b5b69a1c5371311335e482421f2c) is not the file the program was converted "
        "from: its header names mech491_APT_SimpleMillPlane.cls (SHA-256 "
        "50ecbbfbfac0b0abd941d807d2dadbbdbb4449ed40d1811d563f7e6f339cccfc)\n")


# ----------------------------------------------------------------------------- bad inputs


def _cli(tmp_path: Path, *args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(main, ["convert", *args, "--jobs", "1"])
    return result.exit_code, result.stdout, result.stderr


def test_truncated_record_fails_and_writes_nothing(tmp_path: Path) -> None:
    src = tmp_path / "truncated.cls"
    src.write_text("RAPID\nGOTO/1,2,3\nGOTO/1,2,$\n")
    out = tmp_path / "out"
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(out))
    assert code == 2
    reason = stdout.split("\t")[3].rstrip("\n")
    assert reason == (f"{src}:3: truncated record: 'GOTO/1,2,' continues with '$' but the file ends (a continued "
                      "record needs its next line)")
    assert list(out.iterdir()) == []


def test_unreachable_point_fails_and_writes_nothing(tmp_path: Path) -> None:
    src = tmp_path / "far.cls"
    src.write_text("FEDRAT/100\nRAPID\nGOTO/0,0,100\nGOTO/0,0,-500\n")
    out = tmp_path / "out"
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(out))
    assert code == 1
    assert stdout.split("\t")[3].rstrip("\n") == (
        f"{src}:4: T1 stroke 865.5270 mm is above the maximum 400.0000 mm by 465.5270 mm; " + _DEFAULT_SETUP)
    assert list(out.iterdir()) == []


def test_the_first_error_in_the_file_is_the_one_reported(tmp_path: Path) -> None:
    """The reader runs a chunk or two ahead on a second thread: a bad record far after an unreachable point
    (read before the point is post-processed) must not be the error reported, nor the other way round."""
    for name, at_start, at_end in (("limit-first", "GOTO/0,0,-500", "GOTO/0,0,1,0"),
                                   ("syntax-first", "GOTO/0,0,1,0", "GOTO/0,0,-500")):
        src = tmp_path / f"{name}.cls"
        moves = "".join(f"GOTO/{k % 7},0,100\n" for k in range(60_000))
        src.write_text(f"FEDRAT/100\nRAPID\nGOTO/0,0,100\n{at_start}\n{moves}{at_end}\n")
        out = tmp_path / f"out-{name}"
        code, stdout, _ = _cli(tmp_path, str(src), "-d", str(out))
        reason = stdout.split("\t")[3].rstrip("\n")
        assert reason.startswith(f"{src}:4: "), reason
        assert code == (1 if name == "limit-first" else 2)
        assert list(out.iterdir()) == []


def test_output_folder_that_cannot_be_made(tmp_path: Path) -> None:
    src = tmp_path / "a.cls"
    src.write_text("RAPID\nGOTO/0,0,0\n")
    blocker = tmp_path / "file"
    blocker.write_text("")
    code, stdout, stderr = _cli(tmp_path, str(src), "-d", str(blocker / "out"))
    assert (code, stdout) == (2, "")
    assert stderr == f"prs3-post: error: {blocker / 'out'}: cannot create the output folder: Not a directory\n"


def test_an_empty_output_folder_name_is_named(tmp_path: Path) -> None:
    """It said "prs3-post: error: : cannot create the output folder: No such file or directory"."""
    src = tmp_path / "a.cls"
    src.write_text("RAPID\nGOTO/0,0,0\n")
    code, stdout, stderr = _cli(tmp_path, str(src), "-d", "")
    assert (code, stdout) == (2, "")
    assert stderr == ("prs3-post: error: '': the output folder's name is empty: give the folder the programs go to "
                      "(e.g. -d out)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.cls"]


def test_an_output_folder_on_a_read_only_file_system_says_so(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """Not "permission denied" (root may write anywhere but there): the file system is read-only."""
    from prs3_post.app import batch as convert

    out = tmp_path / "out"
    out.mkdir()
    flags = os.statvfs(out)
    monkeypatch.setattr(convert.os, "access", lambda path, mode: False)
    monkeypatch.setattr(convert.os, "statvfs", lambda path: os.statvfs_result(
        (*flags[:8], flags.f_flag | os.ST_RDONLY, flags.f_namemax)))
    with pytest.raises(convert.InputError, match=r"out: cannot write in the output folder: read-only file system$"):
        convert.prepare_outdir(str(out))
    monkeypatch.setattr(convert.os, "statvfs", lambda path: flags)
    with pytest.raises(convert.InputError, match=r"out: cannot write in the output folder: permission denied$"):
        convert.prepare_outdir(str(out))


def test_existing_output_is_kept_unless_forced(tmp_path: Path) -> None:
    name = "humman_deep_drill.clsf"
    out = tmp_path / "out"
    out.mkdir()
    kept = out / "humman_deep_drill.ngc"
    kept.write_text("mine\n")
    code, stdout, _ = _cli(tmp_path, str(CORPUS / name), "-d", str(out), _origin_option(PLACED[name]))
    assert code == 2
    assert stdout == f"failed\t{CORPUS / name}\t-\t{kept}: exists already: kept (convert with --force to replace it)\n"
    # the library names no option: its outcome says so neutrally
    outcome = convert_batch([str(CORPUS / name)], str(out), _settings(PLACED[name])).outcomes[0]
    assert (outcome.error, outcome.exists) == (f"{kept}: exists already: kept (it is replaced only when forced)", True)
    assert kept.read_text() == "mine\n"
    code, _, _ = _cli(tmp_path, str(CORPUS / name), "-d", str(out), _origin_option(PLACED[name]), "--force")
    assert code == 0
    assert kept.read_text().startswith("(program: prs3-post")


# ----------------------------------------------------------------------------- batches


def test_a_failing_file_does_not_stop_the_batch(tmp_path: Path) -> None:
    bad = tmp_path / "in" / "bad.cls"
    bad.parent.mkdir()
    bad.write_text("GOTO/1,2\n")
    out = tmp_path / "out"
    settings = _settings(PLACED["humman_deep_drill.clsf"])
    files = [str(bad), str(CORPUS / "humman_deep_drill.clsf"), str(CORPUS / "humman_standart_drill.clsf")]
    result = convert_batch(files, str(out), settings, jobs=1)
    assert [o.ok for o in result.outcomes] == [False, True, True]
    assert result.failures[0].error.startswith(f"{bad}:1: ")
    assert sorted(p.name for p in out.iterdir()) == ["humman_deep_drill.ngc", "humman_standart_drill.ngc"]
    stopped = convert_batch(files, str(tmp_path / "out2"), settings, jobs=1, fail_fast=True)
    assert [o.ok for o in stopped.outcomes] == [False]
    assert stopped.not_started == tuple(files[1:])


def test_jobs_2_gives_the_same_bytes_as_jobs_1(tmp_path: Path) -> None:
    files = [str(CORPUS / n) for n in ("humman_deep_drill.clsf", "humman_standart_drill.clsf",
                                       "mech491_APT_SimpleMillPlane.cls")]
    settings = _settings(PLACED["humman_deep_drill.clsf"])
    one = convert_batch(files, str(tmp_path / "one"), settings, jobs=1)
    two = convert_batch(files, str(tmp_path / "two"), settings, jobs=2)
    assert [o.ok for o in one.outcomes] == [o.ok for o in two.outcomes]
    for name in sorted(os.listdir(tmp_path / "one")):
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes()
    assert sorted(os.listdir(tmp_path / "one")) == sorted(os.listdir(tmp_path / "two"))
    assert len(os.listdir(tmp_path / "one")) >= 2


def test_same_stem_in_two_folders_fails_both(tmp_path: Path) -> None:
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "part.cls").write_bytes((CORPUS / "humman_deep_drill.clsf").read_bytes())
    files = collect_inputs([str(tmp_path / "a"), str(tmp_path / "b")])
    result = convert_batch(files, str(tmp_path / "out"), _settings(PLACED["humman_deep_drill.clsf"]), jobs=1)
    out = tmp_path / "out" / "part.ngc"
    assert [o.error for o in result.outcomes] == [
        f"{tmp_path / 'a' / 'part.cls'}: has the same name as {tmp_path / 'b' / 'part.cls'}: both would be written to "
        f"{out} (convert them into different folders)",
        f"{tmp_path / 'b' / 'part.cls'}: has the same name as {tmp_path / 'a' / 'part.cls'}: both would be written to "
        f"{out} (convert them into different folders)"]
    assert not out.exists()


def test_directory_search_skips_fifos_other_files_and_the_output_folder(tmp_path: Path) -> None:
    src = tmp_path / "cam"
    (src / "deep").mkdir(parents=True)
    (src / "deep" / "x.cls").write_text("GOTO/0,0,0\n")
    (src / "notes.txt").write_text("hello\n")
    os.mkfifo(src / "pipe.cls")
    (src / "out").mkdir()
    (src / "out" / "old.ngc").write_text("G0 X0\n")
    assert collect_inputs([str(src)], exclude=str(src / "out")) == [str(src / "deep" / "x.cls")]
    # the output folder is the folder searched: its programs are left out, its CAM files are not
    (src / "y.ngc").write_text("G0 X0\n")
    (src / "z.nc").write_text("G0 X0\n")
    assert collect_inputs([str(src)], exclude=str(src), exclude_suffix=".ngc") == [
        str(src / "z.nc"), str(src / "deep" / "x.cls"), str(src / "out" / "old.ngc")]


def test_report_json_accounts_for_every_record(tmp_path: Path) -> None:
    name = "mech491_APT_SimpleMillPlane.cls"
    report = tmp_path / "report.json"
    code, _, _ = _cli(tmp_path, str(CORPUS / name), "-d", str(tmp_path / "out"), _origin_option(PLACED[name]),
                      "--report", str(report))
    assert code == 0
    data = json.loads(report.read_text())
    file = data["files"][0]["report"]
    assert sum(file["by_word"].values()) == file["records"]
    assert file["skipped"] == {"PAINT": 36, "TOOL PATH": 1, "Tool Path Listing": 1}
    assert (file["input_moves"], file["arcs"], file["arc_rows"], file["emitted_moves"]) == (33, 2, 70, 103)
    assert data["summary"] == {"files": 1, "converted": 1, "failed": 0, "not_started": 0, "motion_records": 35,
                               "seconds": data["summary"]["seconds"]}


# ----------------------------------------------------------------------------- G-code sources and options

TILTED = """%
O1000 (tilted drill)
G21 G90 G17
G68.2 X0 Y0 Z0 I0 J20 K0
G53.1
S3000 M3
G0 X10 Y0 Z20
G99 G83 X10 Y0 Z-5 R2 Q2 F100
X20
G80
G18 G1 X0 Z5 F200
G2 X10 Z5 I5 K0
G69
M5
M30
%
"""


@pytest.mark.parametrize(("extra", "name"), [((), "tilt.ngc"), (("--dialect", "fanuc", "--tool-length", "180"),
                                                                  "tilt.nc")])
def test_gcode_source_converts_and_verifies(tmp_path: Path, extra: tuple[str, ...], name: str, rs274_check) -> None:
    """A G68.2 program (G83 peck, G2 in G18): the dialect's extension, the tool length in the header,
    LinuxCNC, and verify --against the G-code (a fanuc header is upper case)."""
    src = tmp_path / "tilt.gcode"
    src.write_text(TILTED)
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(tmp_path / "out"), "--part-origin=0,0,-850", *extra)
    assert code == 0, stdout
    out = tmp_path / "out" / name
    assert stdout.split("\t")[:3] == ["ok", str(src), str(out)]
    lines = out.read_text().upper().splitlines()
    expected = "(TOOL LENGTH: 180.000 MM, AS GIVEN)" if extra else "(TOOL LENGTH: 175.000 MM, THE MACHINE'S)"
    assert expected in lines
    assert rs274_check(out)[0] == 0
    verified = CliRunner().invoke(main, ["verify", str(out), "--against", str(src)])
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance", verified.output


def test_work_plane_puts_a_3_axis_program_on_a_plane(tmp_path: Path) -> None:
    src = tmp_path / "flat.nc"
    src.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\nG1 X10\nM30\n")
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(tmp_path / "out"), "--part-origin=0,0,-850",
                           "--work-plane", "0,0,0,0.6,0,0.8")
    assert code == 0, stdout
    conversion = convert_file(str(src), dataclasses.replace(_settings((0.0, 0.0, -850.0)),
                                                            work_plane=WorkPlane.from_values([0, 0, 0, 0.6, 0, 0.8])))
    assert_allclose(conversion.path.axis, np.tile([0.6, 0.0, 0.8], (len(conversion.path), 1)), atol=1e-12)
    assert (tmp_path / "out" / "flat.ngc").read_text() == conversion.text


def test_a_dangling_link_in_a_folder_fails_as_a_missing_file(tmp_path: Path) -> None:
    (tmp_path / "cam").mkdir()
    os.symlink(tmp_path / "nowhere", tmp_path / "cam" / "gone.cls")
    code, stdout, _ = _cli(tmp_path, str(tmp_path / "cam"), "-d", str(tmp_path / "out"))
    assert code == 2
    assert stdout == f"failed\t{tmp_path / 'cam' / 'gone.cls'}\t-\t{tmp_path / 'cam' / 'gone.cls'}: file not found\n"


#: Bad inputs through `convert`: (file name, content, the reason after ``path:``); each fails its file
#: (exit 1), and nothing is written.
BAD_INPUTS = [
    ("goto4.cls", "RAPID\nGOTO/1,2,3,4\n",
     "2: GOTO/ has 4 values: expected 3 (x,y,z) or 6 (x,y,z,i,j,k); found 'GOTO/1,2,3,4'"),
    ("nan.cls", "RAPID\nGOTO/1,nan,3\n",
     "2: GOTO/ value 2: 'nan' is not a number (expected a decimal like -12.5, .5 or 1.5E+02)"),
    ("unknown.cls", "RAPID\nGOTO/0,200,0\nCUTCOM/LEFT\n",
     "3: unknown major word 'CUTCOM' in 'CUTCOM/LEFT' (understood: GOTO, FROM, GOHOME, RAPID, FEDRAT, MULTAX, "
     "TLAXIS, MSYS, UNITS, LOADTL, LOAD, SELECT, TLDATA, SPINDL, COOLNT, CYCLE, CIRCLE, PPRINT, END-OF-PATH, FINI, "
     "STOP, OPSTOP; display-only, skipped: PAINT, TOOL PATH; other words can be ignored on purpose by listing them "
     "as words to ignore)"),
    ("huge.cls", "RAPID\nGOTO/" + "1.0," * 20_000 + "1\n",
     "2: a record of 80,006 characters or more: longer than any CL record may be (65,536 at most); found "
     "'GOTO/1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0,1.0...'"),
    ("continued.cls", "RAPID\n" + "GOTO/1,2,$\n" * 8_000 + "GOTO/1,2,3\n",
     "2: a record of 65,540 characters or more: longer than any CL record may be (65,536 at most); found "
     "'GOTO/1,2,GOTO/1,2,GOTO/1,2,GOTO/1,2,GOTO/1,2,GOTO/1,2,GOTO/1...'"),
    ("hugeblock.nc", "G21 G90\nG0 X0 Y0 Z5\nG1 X1" + " Y2" * 30_000 + " (a comment)\nM30\n",
     "3: a block of 90,005 characters besides its comments: longer than any G-code block may be (65,536 at most)"),
    ("zeroaxis.cls", "RAPID\nGOTO/0,200,0,0,0,0\n",
     "2: GOTO/: zero tool vector (0, 0, 0); i,j,k must be a unit vector from the tool tip toward the spindle"),
    ("msys.cls", "MSYS/0,0,0,1,0,0,0.5,1,0\nRAPID\nGOTO/0,200,0\n",
     "1: MSYS/ axes are not orthogonal unit vectors: x axis (1, 0, 0), y axis (0.5, 1, 0) have |x| = 1, "
     "|y| = 1.11803, x·y = 0.5 (valid: |x| = |y| = 1 and x·y = 0 within 1e-05)"),
    ("arc.cls", "FEDRAT/100\nRAPID\nGOTO/10,200,0\nCIRCLE/0,200,0,0,0,1,10,0.01\nGOTO/-12,200,0\n",
     "5: arc end point (-12.0000, 200.0000, 0.0000) is 2.0000 mm outside the circle of CIRCLE/ at line 4 "
     "(radius 10); start and end must lie on the circle within 0.01 mm"),
    ("g93.nc", "G21 G90\nG93 G1 X1 Y2 Z3\nM30\n",
     "2: G1 under G93 (inverse time) without F: every feed move under G93 needs its own F (1/minute)"),
    ("exp.nc", "G21 G90\nG0 X1e-05 Y0 Z0\nM30\n",
     "2: word 'E-05' is not G-code: E is not read here, and a number with an exponent (1e-05) must be written as a "
     "plain decimal (0.00001)"),
    ("g682.nc", "G21\nG68.2 P3 Q1 X0 Y0 Z0 I1 J0 K0\nG68.2 P3 Q2 I0 J0 K0\n",
     "3: G68.2 P3 Q2: the normal I J K is the zero vector (it must be the plane's z direction, the tool axis)"),
    ("cut.nc", "%\nG21 G90\nG0 X0 Y0 Z5\nG1 X1 Y2 Z-1 F100\nG1 X-26.",      # a file cut short (QA: 5 MB of 30)
     "5: the program opens with '%' (line 1) but the file ends without its closing '%': a program cut short? (a "
     "program that opens with '%' ends with '%')"),
]


@pytest.mark.parametrize(("name", "text", "reason"), BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS])
def test_bad_input_fails_with_its_message(tmp_path: Path, name: str, text: str, reason: str) -> None:
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / "out"
    code, stdout, stderr = _cli(tmp_path, str(src), "-d", str(out))
    assert code == 2
    assert stdout == f"failed\t{src}\t-\t{src}:{reason}\n"
    assert stderr.splitlines()[-1] == f"  {src}:{reason}"
    assert list(out.iterdir()) == []


def test_an_input_in_the_output_folder_is_never_overwritten(tmp_path: Path) -> None:
    src = tmp_path / "t.ngc"
    src.write_text(TILTED)
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(tmp_path), "--part-origin=0,0,-850", "--force")
    assert code == 2
    assert stdout == (f"failed\t{src}\t-\t{src}: is also the input being converted: writing its program would "
                      "destroy it (choose another file)\n")
    assert src.read_text() == TILTED


def test_the_corpus_folder_with_automatic_placement(tmp_path: Path) -> None:
    """`convert ../shared/corpus/cl -o out --part-origin auto`: every placeable file converts (each with
    its own origin, recorded in its header and report), the others fail with their reason."""
    out = tmp_path / "out"
    report = tmp_path / "report.json"
    result = CliRunner().invoke(main, ["convert", str(CORPUS), "-d", str(out), "--part-origin", "auto",
                                       "--jobs", "2", "--report", str(report)])
    assert result.exit_code == 1
    files = {Path(f["input"]).name: f for f in json.loads(report.read_text())["files"]}
    assert sorted(n for n, f in files.items() if f["ok"]) == sorted(PLACED)
    assert sorted(Path(p).stem for p in os.listdir(out)) == sorted(Path(n).stem for n in PLACED)
    assert files["humman_1_KONTUR_NAR_40_N2.cls"]["error"] == (
        f"{CORPUS / 'humman_1_KONTUR_NAR_40_N2.cls'}: {UNPLACEABLE['humman_1_KONTUR_NAR_40_N2.cls']}")
    ust = CORPUS / "humman_ust_a_variable_contour.cls"      # tilts to 86°: placed on its rows as given
    assert files[ust.name]["error"] == (
        f"{ust}: no part origin puts every point inside the machine's limits: the condition number cannot be met, by "
        f"68.7819 at best ({ust}:304: condition number 78.7819 is above the maximum 10.0000 by 68.7819); the tilt is "
        f"outside too, by 41.3459 deg there ({ust}:261: tilt 86.3459 deg is above the maximum 45.0000 deg by 41.3459 "
        f"deg); the stage Y is outside too, by 104.3549 mm there ({ust}:11: stage Y -404.3549 mm is below the "
        "minimum -300.0000 mm by 104.3549 mm); the stroke of leg 1 is outside too, by 62.0725 mm there "
        f"({ust}:432: T1 stroke 462.0725 mm is above the maximum 400.0000 mm by 62.0725 mm); the best setup found: "
        "part origin at machine [110.5425, 792.1451, -802.7035] mm, rotation 0.0000 deg about z")
    assert files["mech491_APT_Variable_Axis.cls"]["report"]["setup"] == (
        "part origin at machine [-44.0000, -81.3000, -786.7000] mm, rotation 0.0000 deg about z")
    for name in PLACED:
        verified = CliRunner().invoke(main, ["verify", str(out / (Path(name).stem + ".ngc")),
                                             "--against", str(CORPUS / name)])
        assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance", verified.output


#: The batch, with each worker's program write held after its first chunk: the worker says so on the
#: readiness pipe (fd argv[1]) and waits for a signal, so the test interrupts both writes mid-file
#: every time (it used to poll for temp files with sleeps, and under load a file could finish first).
_HELD_BATCH = """
import os, signal, sys
from prs3_post.app import convert
from prs3_post.cli.main import main
from prs3_post.core.output_files import HeadLast

ready, write_atomic = int(sys.argv[1]), convert.write_atomic

def held(chunks):
    for number, chunk in enumerate(chunks):
        yield chunk
        if number == 0:
            os.write(ready, b"w")
            while True:
                signal.pause()

def holding_write(path, data):
    if isinstance(data, HeadLast):
        data = HeadLast(body=held(data.body), head=data.head)
    else:
        data = held(data)
    write_atomic(path, data)

convert.write_atomic = holding_write
sys.argv[1:] = sys.argv[2:]
main()
"""


def test_ctrl_c_leaves_no_program_and_no_temp_file(tmp_path: Path) -> None:
    """SIGINT to the batch's process group (what a terminal's Ctrl-C does) while both workers are writing:
    no temp file is left, and no program (none was finished)."""
    text = "UNITS/MM\nFEDRAT/MMPM,500\nRAPID\nGOTO/0,40,10\n" + "".join(
        f"GOTO/{40 * np.sin(t * 1e-2):.4f},{40 * np.cos(t * 1e-2):.4f},-1\n" for t in range(2000))
    for name in ("a.cls", "b.cls"):
        (tmp_path / name).write_text(text)
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    ready_read, ready_write = os.pipe()
    try:
        process = subprocess.Popen(
            [sys.executable, "-c", _HELD_BATCH, str(ready_write), "convert", "a.cls", "b.cls", "-d", "out",
             "--part-origin=0,0,-850", "--jobs", "2"],
            cwd=tmp_path, env=env, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            pass_fds=(ready_write,))
        os.close(ready_write)
        said = b""
        while len(said) < 2:                           # both workers are inside their write (no timing)
            if not select.select([ready_read], [], [], 300)[0]:
                process.kill()
                pytest.fail("the batch neither wrote nor ended in 300 s")
            piece = os.read(ready_read, 2 - len(said))
            assert piece, "the batch ended before both workers were writing: " + process.communicate()[1].decode()
            said += piece
    finally:
        os.close(ready_read)
    assert len(list(out.glob(".*.tmp"))) == 2          # what the signal must clean up
    os.killpg(process.pid, signal.SIGINT)
    assert process.wait(timeout=60) == 130             # one line, no traceback (the workers say nothing)
    assert process.communicate()[1] == b"prs3-post: interrupted\n"
    assert sorted(os.listdir(out)) == []
    with pytest.raises(ProcessLookupError):            # the workers ended with it
        os.killpg(process.pid, 0)


def test_a_report_named_like_a_program_is_refused_before_any_work(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """--report OUT/x.ngc would replace the program of x.cls with the JSON report (exit 0)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.cls").write_bytes((CORPUS / "mech491_APT_SimpleMillPlane.cls").read_bytes())
    result = CliRunner().invoke(main, ["convert", "x.cls", "-d", "out", "--part-origin", "0,-17.2,-856",
                                       "--jobs", "1", "--report", "./out/x.ngc"])
    assert (result.exit_code, result.stderr) == (
        2, "prs3-post: error: ./out/x.ngc: the program of x.cls and --report name the same file: one would "
           "overwrite the other\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.cls"]


def test_a_report_onto_an_input_names_the_input_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.cls").write_bytes((CORPUS / "mech491_APT_SimpleMillPlane.cls").read_bytes())
    result = CliRunner().invoke(main, ["convert", "x.cls", "-d", "out", "--report", "x.cls"])
    assert (result.exit_code, result.stderr) == (
        2, "prs3-post: error: x.cls: is also the input 1 (x.cls): writing --report would destroy it (choose another "
           "file)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.cls"]


def test_the_counts_head_the_program_in_a_file_and_in_a_fifo(tmp_path: Path) -> None:
    """The header's counts are the report's, and a FIFO gets the same bytes as a file (the body is spooled)."""
    name = "humman_deep_drill.clsf"
    settings = _settings(PLACED[name])
    regular = tmp_path / "a.ngc"
    report = write_conversion(str(CORPUS / name), str(regular), settings)
    header = read_header(str(regular))
    assert isinstance(header, SourceHeader)
    assert header.counts == report.counts()
    assert (header.counts.records, header.counts.cycle_holes, header.counts.program_moves) == (14, 2, 6)
    fifo = tmp_path / "f.ngc"
    os.mkfifo(fifo)
    received: list[bytes] = []
    reader = threading.Thread(target=lambda: received.append(fifo.read_bytes()))
    reader.start()
    write_conversion(str(CORPUS / name), str(fifo), settings)
    reader.join(timeout=30)
    assert received == [regular.read_bytes()]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.ngc", "f.ngc"]


# ----------------------------------------------------------------------------- QA sweep: input and option errors


@pytest.mark.parametrize(("name", "text", "valid"), [
    ("feed.cls", "FEDRAT/100\nGOTO/0,0,0\nGOTO/10,0,0\n",
     "start with FROM/x,y,z, or RAPID and a GOTO/ to the start point, before the first feed"),
    ("feed.nc", "G21 G90\nG1 X0 Y0 Z0 F100\nG1 X10\nM30\n", "move to the start point with G0 before the first G1"),
])
@pytest.mark.parametrize("origin", ["--part-origin=0,0,-850", "--part-origin=auto"])
def test_a_feed_as_first_motion_is_an_input_error(tmp_path: Path, name: str, text: str, valid: str,
                                                  origin: str) -> None:
    """An input property, named at its line with what would be valid: exit 2, no setup or placement advice."""
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / "out"
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(out), origin)
    assert code == 2
    assert stdout == (f"failed\t{src}\t-\t{src}:2: the first motion is a feed move, so its start point is unknown: "
                      f"{valid}\n")
    assert list(out.iterdir()) == []


@pytest.mark.parametrize(("goto", "shown"), [("1e308,0,0", "value 1: '1e308'"),
                                             ("0,0,2000000.0", "value 3: '2000000.0'")])
def test_a_coordinate_beyond_a_kilometre_is_bad_input_not_out_of_reach(tmp_path: Path, goto: str, shown: str) -> None:
    """It was exit 1, a stage X '1e+308 mm above the maximum' (the reach search ran on it)."""
    src = tmp_path / "far.cls"
    src.write_text(f"RAPID\nGOTO/0,0,0\nGOTO/{goto}\n")
    out = tmp_path / "out"
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(out), "--part-origin", "0,0,-700")
    assert code == 2
    assert stdout == (f"failed\t{src}\t-\t{src}:3: GOTO/ {shown} is out of range (allowed: within ±1e+06 mm; is the "
                      "file in the right units?)\n")
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("tolerance", ["100", "0.00001"])
def test_a_tolerance_outside_its_range_is_refused_before_any_work(tmp_path: Path, tolerance: str) -> None:
    out = tmp_path / "out"
    code, stdout, stderr = _cli(tmp_path, str(CORPUS / "humman_deep_drill.clsf"), "-d", str(out), "--tolerance",
                                tolerance)
    assert (code, stdout) == (2, "")
    assert stderr == (f"prs3-post: error: --tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm "
                      f"(got {float(tolerance):g})\n")
    assert not out.exists()


def test_rows_of_one_line_are_named_once() -> None:
    tip = np.zeros((5, 3))
    axis = np.array([[0, 0, 1], [0, 0, -1], [0, 0, -1], [0, 0, -1], [0, 0, -1.0]])
    with pytest.raises(PoseError) as caught:
        unit_axes(tip, axis, row_name="line", row_numbers=np.array([3, 7, 7, 7, 9]))
    assert str(caught.value) == "lines 7, 9: the axis points away from the spindle (axis z must be > 0)"
    with pytest.raises(PoseError) as caught:
        unit_axes(tip[:3], axis[:3], row_name="line", row_numbers=np.array([3, 7, 7]))
    assert str(caught.value) == "line 7: the axis points away from the spindle (axis z must be > 0)"


@pytest.mark.parametrize(("name", "text", "forced", "message"), [
    ("empty.cls", "", (), "the file is empty (0 bytes): nothing to convert"),
    ("empty.cls", "", ("--format", "cl"), "the file is empty (0 bytes): nothing to convert"),
    ("empty.nc", "", ("--format", "gcode"), "the file is empty (0 bytes): nothing to convert"),
    ("blank.cls", "\n  \n\n", (), "the file has only blank lines: nothing to convert"),
])
def test_an_empty_file_is_said_to_be_empty(tmp_path: Path, name: str, text: str, forced: tuple[str, ...],
                                           message: str) -> None:
    src = tmp_path / name
    src.write_text(text)
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(tmp_path / "out"), *forced)
    assert (code, stdout) == (2, f"failed\t{src}\t-\t{src}: {message}\n")


def test_a_report_in_a_missing_folder_is_refused_before_any_work(tmp_path: Path) -> None:
    name = "humman_deep_drill.clsf"
    out = tmp_path / "out"
    report = tmp_path / "no" / "r.json"
    code, stdout, stderr = _cli(tmp_path, str(CORPUS / name), "-d", str(out), _origin_option(PLACED[name]),
                                "--report", str(report))
    assert (code, stdout) == (2, "")
    assert stderr == f"prs3-post: error: {report}: cannot write the output here: No such file or directory\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == []                 # not even OUTDIR


def test_one_tcp_code_for_on_and_off_is_an_option_error(tmp_path: Path) -> None:
    """Refused once, before any file is read (the files are not even looked at)."""
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "a.nc"), str(tmp_path / "b.nc"), "-d", str(out),
                                       "--source", "head-ab", "--tcp-on", "G43.4", "--tcp-off", "G43.4"])
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == ("Error: Invalid value for '--tcp-on' / '--tcp-off': tcp: G43.4 both "
                                              "switches TCP on and off (source head-ab)")
    assert not out.exists()


@pytest.mark.parametrize("kind", ["source", "machine", "dialect"])
def test_a_folder_given_as_a_config_file_is_named_a_folder(tmp_path: Path, kind: str) -> None:
    folder = tmp_path / "dir.stl"
    folder.mkdir()
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "a.nc"), "-d", str(tmp_path / "out"),
                                       f"--{kind}", str(folder)])
    assert result.exit_code == 2
    assert result.stderr.startswith(f"prs3-post: error: {folder}: is a folder, not a {kind} file: give a {kind} TOML "
                                    "file or a shipped name (shipped: ")


def test_a_file_named_twice_is_converted_once_and_said_so(tmp_path: Path) -> None:
    """QA: a symbolic link beside its file (or a file named twice) was converted once without a word."""
    src = tmp_path / "a.cls"
    src.write_text("FEDRAT/100\nRAPID\nGOTO/0,0,100\nGOTO/1,0,100\n")
    (tmp_path / "b.cls").symlink_to(src)
    repeats: list[tuple[str, str]] = []
    names = [str(src), str(tmp_path / "b.cls"), str(src)]
    assert collect_inputs(names, repeats=repeats) == [str(src)]
    assert repeats == [(str(tmp_path / "b.cls"), str(src)), (str(src), str(src))]
    code, _, stderr = _cli(tmp_path, *names, "-d", str(tmp_path / "out"), "--part-origin=0,0,-850")
    assert code == 0
    assert stderr.splitlines()[-1] == (f"prs3-post: 2 more names of files above, each converted once: "
                                       f"{tmp_path / 'b.cls'} (= {src}), {src} (= {src})")


# ----------------------------------------------------------------------------- feeds slowed to the axis speeds

#: A 3-axis program at F20000: every cut is faster than the stage and strokes allow (issue 20, defect 9).
FAST = """G21 G90 G17
S3000 M3
G0 X0 Y0 Z20
G0 X0 Y0 Z2
G1 Z-1 F20000
G1 X40 Y0
G1 X40 Y30
G1 X0 Y30
G1 X0 Y0
G0 Z20
M5
M30
"""
_FAST_ORIGIN = "--part-origin=-20,-15,-764"


def test_slowed_feeds_are_stated_in_the_header_and_the_report(tmp_path: Path, rs274_check) -> None:
    """Defect 9: the feeds were lowered to the axis speed limits without a word. The program says so as the
    main job does (its ``dynamics`` line), the report counts the moves slowed, and verify still accepts it."""
    src = tmp_path / "fast.ngc"
    src.write_text(FAST)
    report = tmp_path / "report.json"
    code, _, _ = _cli(tmp_path, str(src), "-d", str(tmp_path / "out"), _FAST_ORIGIN, "--report", str(report))
    assert code == 0
    out = tmp_path / "out" / "fast.ngc"
    text = out.read_text()
    lines = [line for line in text.splitlines() if line.startswith("(dynamics: ")]
    assert len(lines) == 1
    found = re.fullmatch(r"\(dynamics: cycle time \d+\.\d{3} min = \d+\.\d s, (\d+) moves slowed to the axis speed "
                         r"limits, worst \d+\.\d\d x at fast\.ngc:(\d+) [([](stage [XY]|stroke T[123])[])]\)", lines[0])
    assert found is not None, lines[0]
    slowed = int(found.group(1))
    assert slowed == 5                                  # the five G1 moves
    assert json.loads(report.read_text())["files"][0]["report"]["slowed_moves"] == slowed
    header = read_header(str(out), open_="(", close=")")
    assert isinstance(header, SourceHeader)
    assert header.dynamics == lines[0][len("(dynamics: "):-1]
    code_, checked = rs274_check(out)
    assert code_ == 0, checked
    verified = CliRunner().invoke(main, ["verify", str(out), "--against", str(src)])
    assert verified.exit_code == 0, verified.output
    assert verified.output.splitlines()[-1] == "OK: within every limit and tolerance"


def test_no_clamp_refuses_a_feed_that_would_be_slowed(tmp_path: Path) -> None:
    """Defect 9: ``--no-clamp`` refuses instead, naming the first line that would be slowed; nothing is written."""
    src = tmp_path / "fast.ngc"
    src.write_text(FAST)
    out = tmp_path / "out"
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(out), _FAST_ORIGIN, "--no-clamp")
    assert code == 1
    reason = stdout.split("\t")[3].rstrip("\n")
    assert reason.startswith(f"{src}:5: the feed needs "), reason
    assert reason.endswith("x its top speed 5000.0 mm/min (slow the feed, or let it be clamped)"), reason
    assert not (out / "fast.ngc").exists()
    code, _, _ = _cli(tmp_path, str(src), "-d", str(tmp_path / "clamped"), _FAST_ORIGIN, "--clamp")
    assert code == 0


def test_a_5_axis_program_without_a_source_is_told_to_name_one(tmp_path: Path) -> None:
    """Issue 20: a rotary program read by the 3+2 reader names --source and the command that lists them."""
    src = REPO / "fixtures" / "bad" / "gcode" / "rotary_word.ngc"
    code, stdout, _ = _cli(tmp_path, str(src), "-d", str(tmp_path / "out"))
    assert (code, stdout) == (2, (
        f"failed\t{src}\t-\t{src}:4: 5-axis program: rotary word 'A30' (A, B and C words turn rotary axes); the "
        "3+2 reader reads programs whose tool axis is set by G68.2/G53.1 or by the work plane, so it refuses this "
        "program rather than misread it; a 5-axis program under TCP converts when --source names the machine it "
        "was written for (prs3-post sources lists them)\n"))


def test_a_limit_error_gives_the_part_origin_as_the_option_and_it_converts(tmp_path):
    """Issue 20 §3: convert's limit errors said the part origin that fits in words only; they give it as
    --part-origin=X,Y,Z, as the main job does, and that option converts the file."""
    drill = CORPUS / "humman_deep_drill.clsf"
    (tmp_path / "out").mkdir()
    result = CliRunner().invoke(main, ["convert", str(drill), "-d", str(tmp_path / "out")])
    assert result.exit_code == 1
    assert result.stdout.splitlines() == [
        f"failed\t{drill}\t-\t{drill}:10: stage X -355.0000 mm is below the minimum -300.0000 mm by 55.0000 mm (3 "
        "points outside limits among the 6 checked so far); setup: part origin at machine [-100.0000, -200.0000, "
        "-970.0000] mm, rotation 0.0000 deg about z; a part origin at machine [94.5, 0.0, -996.0] mm puts every "
        "point inside the machine's limits: --part-origin=94.5,0.0,-996.0"]
    option = result.stdout.rsplit(": ", 1)[1].strip()
    again = CliRunner().invoke(main, ["convert", str(drill), "-d", str(tmp_path / "out"), option])
    assert again.exit_code == 0, again.output
    assert (tmp_path / "out" / "humman_deep_drill.ngc").is_file()


@pytest.mark.parametrize(("name", "text", "message"), [
    ("t.cls", "LOADTL/100000\nRAPID\nGOTO/0,0,10\nGOTO/0,0,0\n",
     "t.cls:1: LOADTL/ tool number 100000 is out of range (allowed: whole numbers 0 to 99999, the largest the "
     "output dialect takes: its words.tool_number_max)"),
    ("t.ngc", "G21 G90 G17\nT100000 M6\nG0 X0 Y0 Z10\nG1 Z0 F100\nM30\n",
     "t.ngc:2: T100000 is out of range (allowed: whole tool numbers 0 to 99999, the largest the output dialect "
     "takes: its words.tool_number_max)"),
])
def test_a_tool_number_beyond_the_dialects_is_bad_input_at_its_line(tmp_path, name, text, message):
    """Issue 20 §4.5: a tool number above the dialect's words.tool_number_max (99999) but below any dialect's
    failed when the program was written, exit 1 (the limit code), "tool_change event before row 0 ...", with a
    part origin suggested; it is bad input, refused where it is read, exit 2, naming the valid range."""
    source = tmp_path / name
    source.write_text(text)
    (tmp_path / "out").mkdir()
    result = CliRunner().invoke(main, ["convert", str(source), "-o", str(tmp_path / "out"), "--part-origin", "auto"])
    assert result.exit_code == 2
    assert result.stdout.splitlines() == [f"failed\t{source}\t-\t{tmp_path}/{message}"]
    assert list((tmp_path / "out").iterdir()) == []
