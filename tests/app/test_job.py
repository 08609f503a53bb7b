"""The main job end to end: golden programs, LinuxCNC and pygcode acceptance, and an FK replay.

Every golden program is made through the CLI (``CliRunner`` on ``prs3_post.cli.main.main``) with explicit
options, written with ``-o`` and compared byte for byte with ``fixtures/golden/<name>``
(``pytest --update-golden`` rewrites them; review the diff). While the CLI runs, ``check_job`` is
wrapped (posting 7 rows at a time) so that the test also sees the :class:`~prs3_post.app.job.JobResult`
of ``run_job`` behind the text, and checks that both make the same text in chunks of any size.

The replay is an independent oracle: the program text is read back here with a small regex reader
(cross-checked word by word against pygcode and, for some programs, against LinuxCNC's canonical
calls), the axis words are mapped back to stage X, Y and strokes T1..T3 (X Y U V W), and forward
kinematics of those joints is compared row by row with the operation's toolpath
(``JobResult.path_part``, part frame; machine = part + part origin).
"""

from __future__ import annotations

import hashlib
import itertools
import math
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from unittest import mock

import numpy as np
import pygcode
import pytest
from click.testing import CliRunner
from conftest import compare_golden
from numpy.testing import assert_allclose

import prs3_post.app.job as job_module
from prs3_post.app.job import JobProgram, JobResult, JobSpec, ProfileJob, run_job
from prs3_post.cli.main import main
from prs3_post.core.toolpath import MoveKind
from prs3_post.kinematics import forward, inverse
from prs3_post.machine.loading import Geometry, load_dialect, load_machine
from prs3_post.part.setup_transform import Setup
from prs3_post.toolpaths import Coolant, Cutting, Direction, Entry, ProfileParams, Side, SquareShape

REPO = Path(__file__).resolve().parents[2]
PARTS = REPO / "fixtures" / "parts"
GOLDEN = REPO / "fixtures" / "golden"
RS274_CHECK = REPO.parent / "shared" / "tools" / "rs274-check"

#: The paper's case 2a (DESIGN.md): the drilling point in part coordinates, its machine tip and axis.
PAPER_2A_PART = np.array([18.9736, 221.2132, 290.5135])
PAPER_2A_TIP = np.array([-81.0264, 21.2132, -679.4865])
PAPER_2A_AXIS = np.array([0.447214, 0.0, 0.894427])


@dataclass(frozen=True)
class Case:
    """One golden program: its file name and the CLI arguments that make it (without -o)."""

    name: str
    args: tuple[str, ...]

    def option(self, flag: str, default: float) -> float:
        """The value given to ``flag`` in ``args`` (the CLI default when absent)."""
        args = list(self.args)
        return float(args[args.index(flag) + 1]) if flag in args else default


def _part(name: str) -> str:
    # absolute on purpose: the program must still name only the file
    return str(PARTS / name)


CASES = (
    # the demo wedge (the paper's part), through `demo` and through `run fixtures/parts/wedge.stl`
    Case("wedge-hole-peck-dwell.ngc",
         ("demo", "--profile", "hole", "--at", "10,0", "--at", "-10,5", "--depth", "8", "--peck", "3",
          "--dwell", "0.5")),
    Case("wedge-hole-case2a.ngc",
         ("demo", "--profile", "hole", "--at-xyz", "18.9736,221.2132,290.5135", "--depth", "5")),
    Case("wedge-square-case2a.ngc",
         ("run", _part("wedge.stl"), "--profile", "square", "--size", "60", "--rotation", "45", "--depth", "1",
          "--step-down", "1")),
    Case("wedge-square-inside.ngc",
         ("demo", "--profile", "square", "--size", "40", "--corner-radius", "5", "--side", "inside", "--depth", "2",
          "--step-down", "1", "--tolerance", "0.01")),
    Case("wedge-square-outside.ngc",
         ("run", _part("wedge.stl"), "--profile", "square", "--size", "30", "--corner-radius", "2", "--side",
          "outside", "--direction", "conventional", "--entry", "plunge", "--depth", "1.5", "--step-down", "1",
          "--tolerance", "0.01")),
    Case("wedge-round.ngc",
         ("demo", "--profile", "round", "--diameter", "25", "--depth", "2", "--step-down", "1", "--tolerance", "0.01")),
    # tilt35: the face tilts 35° toward -y (reachable with the default setup)
    Case("tilt35-hole.ngc",
         ("run", _part("tilt35.stl"), "--profile", "hole", "--at", "0,0", "--at", "15,-10", "--depth", "6",
          "--peck", "2.5", "--dwell", "0.25")),
    Case("tilt35-square.ngc",
         ("run", _part("tilt35.stl"), "--profile", "square", "--size", "40", "--corner-radius", "4", "--side",
          "inside", "--rotation", "15", "--tolerance", "0.01")),
    Case("tilt35-round.ngc",
         ("run", _part("tilt35.stl"), "--profile", "round", "--diameter", "30", "--side", "outside", "--depth", "3",
          "--step-down", "1.5", "--tolerance", "0.01")),
    # twofaces: auto picks face 5 (20°, the larger); --face 6 picks the 30° one (`prs3-post faces`)
    Case("twofaces-auto-hole.ngc",
         ("run", _part("twofaces.stl"), "--profile", "hole", "--at", "5,5", "--depth", "4", "--dwell", "1")),
    Case("twofaces-auto-round-plunge.ngc",
         ("run", _part("twofaces.stl"), "--profile", "round", "--diameter", "40", "--entry", "plunge",
          "--tolerance", "0.01")),
    Case("twofaces-face6-square.ngc",
         ("run", _part("twofaces.stl"), "--face", "6", "--profile", "square", "--size", "20", "--corner-radius", "3",
          "--tolerance", "0.01")),
    Case("twofaces-face6-round-fanuc.nc",
         ("run", _part("twofaces.stl"), "--face", "6", "--profile", "round", "--diameter", "20", "--dialect", "fanuc",
          "--line-numbers", "--line-start", "100", "--line-step", "5", "--tolerance", "0.01")),
)
CASE_NAMES = [c.name for c in CASES]


@dataclass(frozen=True)
class Made:
    """A case as the CLI made it."""

    case: Case
    text: str            # the program, read back from the -o file
    result: JobResult    # what run_job returned while the CLI ran
    stderr: str
    out: Path


def invoke_capturing(args: list[str]) -> tuple[object, list[JobResult]]:
    """Run the CLI; also return, for every job the CLI checked (``check_job``, whose program it
    writes chunk by chunk), the JobResult of ``run_job`` on the same spec (every row's pose, IK and
    limits), whose program and text must be the CLI's."""
    captured: list[JobResult] = []
    real = job_module.check_job                # the CLI imports it when the main job runs

    def spy(spec: JobSpec, **options: bool) -> JobProgram:
        with mock.patch.object(job_module, "POST_ROWS", 7):        # posted 7 rows at a time: the same program
            job = real(spec, **options)
        result = run_job(spec)
        assert "".join(job.chunks(rows=5)) == "".join(job.chunks()) == result.text   # formatted in any chunks
        assert len(job.program) == len(result.post.program)
        captured.append(result)
        return job

    with mock.patch.object(job_module, "check_job", spy):
        outcome = CliRunner().invoke(main, args, prog_name="prs3-post")
    return outcome, captured


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Made]:
    folder = tmp_path_factory.mktemp("programs")
    out: dict[str, Made] = {}
    for case in CASES:
        target = folder / case.name
        outcome, captured = invoke_capturing([*case.args, "-o", str(target)])
        assert outcome.exit_code == 0, (case.name, outcome.output, outcome.exception)
        assert len(captured) == 1
        out[case.name] = Made(case, target.read_bytes().decode("utf-8"), captured[0], outcome.stderr, target)
    return out


# ----------------------------------------------------------------------------- an independent reader

_BLOCK = re.compile(r"(?:\s*[A-Z][-+]?(?:\d+\.?\d*|\.\d+))*\s*")
_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^()]*\)")
#: Program letters of the machine axes, in the order stage X, stage Y, T1, T2, T3 (both dialects).
AXES = ("X", "Y", "U", "V", "W")


def code_lines(text: str) -> list[tuple[int, list[tuple[str, str]]]]:
    """(line number, [(letter, number text)]) of every line that is not blank, ``%`` or only a comment.

    Every character outside a comment must belong to a word: nothing is skipped silently.
    """
    out = []
    for number, line in enumerate(text.split("\n"), start=1):
        code = _COMMENT.sub("", line).strip()
        if code in ("", "%"):
            continue
        assert _BLOCK.fullmatch(code), f"line {number}: not a sequence of words: {line!r}"
        out.append((number, _WORD.findall(code)))
    return out


def _decimals(number: str) -> int:
    return len(number.split(".")[1]) if "." in number else 0


@dataclass(frozen=True)
class Moves:
    """The motion rows of a program as the controller sees them (modal words carried forward)."""

    kind: np.ndarray       # (N,) MoveKind values
    joints: np.ndarray     # (N, 5) mm: X, Y, T1, T2, T3 in effect after the row
    half_unit: np.ndarray  # (N, 5) mm: half the last printed digit of each value in effect
    words: list[dict[str, str]]  # (N) letter -> number text in effect
    feed: np.ndarray       # (N,) the F word of G1 rows (NaN on G0 rows)
    feed_half_unit: np.ndarray  # (N,)
    line: np.ndarray       # (N,) line number


def read_moves(text: str) -> Moves:
    """Read the G0/G1 rows: G0/G1 are modal, axis words keep their value until written again."""
    motion: int | None = None
    value: dict[str, str] = {}
    rows: dict[str, list] = {k: [] for k in ("kind", "joints", "half", "words", "feed", "feed_half", "line")}
    for number, words in code_lines(text):
        letters = [letter for letter, _ in words]
        g_words = [float(v) for letter, v in words if letter == "G"]
        for g in g_words:
            if g in (0.0, 1.0):
                motion = int(g)
        moving = any(letter in AXES for letter in letters) or any(g in (0.0, 1.0) for g in g_words)
        if not moving:
            continue
        assert set(g_words) <= {0.0, 1.0}, f"line {number}: a motion line with another G word"
        assert motion is not None, f"line {number}: axis words before any G0/G1"
        value.update((letter, v) for letter, v in words if letter in AXES)
        assert set(value) == set(AXES), f"line {number}: the first motion line must state every axis"
        feed = [v for letter, v in words if letter == "F"]
        assert len(feed) == (1 if motion == 1 else 0), f"line {number}: G1 needs one F (G93), G0 none"
        rows["kind"].append(MoveKind.FEED if motion == 1 else MoveKind.RAPID)
        rows["joints"].append([float(value[a]) for a in AXES])
        rows["half"].append([0.5 * 10.0 ** -_decimals(value[a]) for a in AXES])
        rows["words"].append(dict(value))
        rows["feed"].append(float(feed[0]) if feed else math.nan)
        rows["feed_half"].append(0.5 * 10.0 ** -_decimals(feed[0]) if feed else math.nan)
        rows["line"].append(number)
    return Moves(
        kind=np.array(rows["kind"], dtype=np.int64), joints=np.array(rows["joints"]).reshape(-1, 5),
        half_unit=np.array(rows["half"]).reshape(-1, 5), words=rows["words"], feed=np.array(rows["feed"]),
        feed_half_unit=np.array(rows["feed_half"]), line=np.array(rows["line"], dtype=np.int64),
    )


# ----------------------------------------------------------------------------- kinematic helpers


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) rad between rows of (N, 3) vectors; atan2 keeps its accuracy for tiny angles (acos does not)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1))


def stroke_jacobians(geometry: Geometry, strokes: np.ndarray, step: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """∂tip/∂T and ∂axis/∂T, (N, 3, 3) each ([:, :, j] = column of T_j), by central differences of FK.

    The stage adds (X, Y, 0) to the tip and nothing to the axis, so it needs no differencing. FK
    converges to 1e-11 mm, so the differences carry a noise of ~1e-11/1e-3 = 1e-8 relative.
    """
    n = len(strokes)
    shifted = np.repeat(strokes[None], 6, axis=0)            # (6, N, 3): +T1 -T1 +T2 -T2 +T3 -T3
    for j in range(3):
        shifted[2 * j, :, j] += step
        shifted[2 * j + 1, :, j] -= step
    fk = forward(geometry, shifted.reshape(-1, 3))
    assert fk.converged.all()
    tip, axis = fk.tip.reshape(6, n, 3), fk.axis.reshape(6, n, 3)
    d_tip = np.stack([(tip[2 * j] - tip[2 * j + 1]) / (2 * step) for j in range(3)], axis=2)
    d_axis = np.stack([(axis[2 * j] - axis[2 * j + 1]) / (2 * step) for j in range(3)], axis=2)
    return d_tip, d_axis


def rounding_bounds(geometry: Geometry, strokes: np.ndarray, half_unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Worst-case tip (mm) and axis (rad) error of each row caused by printing the joints rounded.

    Each printed word is within half a unit of its last digit of the true value: |δX|, |δY|, |δT_j| ≤ h
    (h = 5e-5 mm with 4 decimals, 5e-4 mm with the fanuc dialect's 3). To first order the tip moves
    by J δ with J = [e_x e_y ∂tip/∂T] (3 × 5) and the axis by ∂axis/∂T δT. A norm of a linear map is
    convex, so its maximum over the box |δ_j| ≤ h_j is at a corner: the bound is the exact worst case
    of the linearized error, the largest of the 32 (tip) or 8 (axis) corners, per row.

    What the linearization leaves out is second order, ≤ ½·|∂²FK|·|δ|² ≈ ½·(1/100 mm)·(1.2e-3 mm)²
    < 1e-8 mm even with 3 decimals, and the test adds 1e-6 mm (1e-9 rad) on top for it and for FK's
    own convergence.
    """
    d_tip, d_axis = stroke_jacobians(geometry, strokes)
    n = len(strokes)
    full = np.zeros((n, 3, 5))
    full[:, 0, 0] = full[:, 1, 1] = 1.0
    full[:, :, 2:] = d_tip
    corners5 = np.array(list(itertools.product((-1.0, 1.0), repeat=5)))      # (32, 5)
    corners3 = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))      # (8, 3)
    tip_bound = np.linalg.norm(np.einsum("nij,nkj->nki", full, corners5[None] * half_unit[:, None, :]), axis=2)
    axis_bound = np.linalg.norm(np.einsum("nij,nkj->nki", d_axis, corners3[None] * half_unit[:, None, 2:]), axis=2)
    return tip_bound.max(axis=1), axis_bound.max(axis=1)


# ----------------------------------------------------------------------------- goldens and acceptance


@pytest.mark.parametrize("name", CASE_NAMES)
def test_golden_program(made: dict[str, Made], name: str, update_golden: bool) -> None:
    item = made[name]
    compare_golden(item.text, GOLDEN / name, update_golden)
    result = item.result
    assert item.text == result.text
    # what the CLI says after writing the file
    assert item.stderr == (f"prs3-post: wrote {item.out}: {item.text.count(chr(10))} lines, "
                           f"{len(result.post.program)} moves; {result.face_note}\n"
                           f"prs3-post: {result.dynamics}\n")


@pytest.mark.parametrize("name", CASE_NAMES)
def test_program_names_no_absolute_path(made: dict[str, Made], name: str) -> None:
    item = made[name]
    part = "patel2020-wedge.stl" if item.case.args[0] == "demo" else Path(item.case.args[1]).name
    header = [line for line in item.text.split("\n") if line.lower().startswith("(part: ")]
    source = REPO / "postproc" / "parts" / part if item.case.args[0] == "demo" else Path(item.case.args[1])
    digest = hashlib.sha256(source.read_bytes()).hexdigest()
    expected = f"(part: {part}, units mm, up z, sha256 {digest})"
    assert header == [expected.upper() if name.endswith(".nc") else expected]   # fanuc upper-cases comments
    for folder in (REPO, REPO.parent, item.out.parent):
        assert str(folder) not in item.text
        assert str(folder).upper() not in item.text
    assert re.search(r"(^|[\s(\[:,=])/[A-Za-z]", item.text, flags=re.MULTILINE) is None   # no /abs/path token


def test_goldens_pass_linuxcnc(rs274_check) -> None:
    """Every golden program, in one rs274-check call (LinuxCNC's interpreter, axes X Y U V W)."""
    paths = [GOLDEN / name for name in CASE_NAMES]
    code, output = rs274_check(*paths, axes="XYUVW")
    assert code == 0, output
    reported = [line.split(": ", 1) for line in output.splitlines() if line.startswith(str(GOLDEN))]
    assert [Path(path).name for path, _ in reported] == CASE_NAMES
    assert all(status.startswith("OK (") for _, status in reported), output


@pytest.mark.parametrize("name", CASE_NAMES)
def test_golden_lines_parse_with_pygcode(name: str) -> None:
    """pygcode 0.2.1 reads every line, and finds exactly the words the reader here finds."""
    text = (GOLDEN / name).read_bytes().decode("utf-8")
    assert text.endswith("\n")
    lines = text[:-1].split("\n")
    assert max(len(line) for line in lines) <= 252
    mine = dict(code_lines(text))
    for number, line in enumerate(lines, start=1):
        parsed = pygcode.Line(line)
        theirs = [(w.letter, float(w.value)) for w in parsed.block.words]
        assert theirs == [(letter, float(v)) for letter, v in mine.get(number, [])], (number, line)
        if line.startswith("("):
            assert parsed.comment is not None and parsed.block.words == []


def test_reader_agrees_with_linuxcnc_canon(rs274_check, made: dict[str, Made], tmp_path: Path) -> None:
    """The reader above sees the same end points and feeds as LinuxCNC's own interpreter.

    Two programs: the fanuc one (modal G0/G1, N words, 3 decimals) and a pecked hole with dwells.
    """
    names = ["twofaces-face6-round-fanuc.nc", "wedge-hole-peck-dwell.ngc"]
    canon = tmp_path / "canon.txt"
    done = subprocess.run([str(RS274_CHECK), "-a", "XYUVW", "-q", "--canon", str(canon),
                           *(str(made[n].out) for n in names)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    calls: dict[str, list[tuple[int, str, dict[str, float]]]] = {}
    current = ""
    for line in canon.read_text().splitlines():
        if line.startswith("# FILE "):
            current = Path(line.split()[2]).name
            calls[current] = []
            continue
        number, call, *fields = line.split()
        if call in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            values = dict(f.split("=", 1) for f in fields)
            calls[current].append((int(number), call, {k: float(v) for k, v in values.items() if k != "MODE"}))
    for name in names:
        moves = read_moves(made[name].text)
        seen = calls[name]
        assert [n for n, _, _ in seen] == moves.line.tolist()
        assert [c == "STRAIGHT_FEED" for _, c, _ in seen] == (moves.kind == MoveKind.FEED).tolist()
        assert_allclose([[v[a] for a in AXES] for _, _, v in seen], moves.joints, rtol=0, atol=1e-6)


# ----------------------------------------------------------------------------- the FK replay


@pytest.mark.parametrize("name", CASE_NAMES)
def test_replay_through_forward_kinematics(made: dict[str, Made], name: str) -> None:
    """Every emitted point, replayed through FK, is where the operation wanted the tool.

    Bounds (mm, rad): unrounded joints from JobResult.post.program — tip 1e-6, axis 1e-9;
    printed joints — 1e-6 + the per-row rounding bound of :func:`rounding_bounds` (tip) and
    1e-9 + its axis counterpart.
    """
    item = made[name]
    result = item.result
    geometry = load_machine("patel2020").geometry
    program, path_part, face = result.post.program, result.path_part, result.face
    moves = read_moves(item.text)

    # row by row: the program has one motion line per toolpath row (constant axis: no subdivision)
    n = len(path_part)
    assert len(program) == len(result.post.path) == len(moves.kind) == n
    assert moves.kind.tolist() == program.kind.tolist() == path_part.kind.tolist()
    assert_allclose(path_part.axis, np.tile(face.normal, (n, 1)), rtol=0, atol=0)
    intended_tip = path_part.tip + result.setup.shift                      # machine frame, part-relative
    exact = np.column_stack([program.stage, program.strokes])              # (N, 5) unrounded X Y T1 T2 T3

    # the printed words are the program's values rounded to their last digit
    assert np.all(np.abs(moves.joints - exact) <= moves.half_unit * (1 + 1e-9)), name

    # unrounded joints: tip on the path within 1e-6 mm, axis on the face normal within 1e-9 rad
    fk = forward(geometry, exact[:, 2:], exact[:, :2])
    assert fk.converged.all()
    assert np.linalg.norm(fk.tip - intended_tip, axis=1).max() <= 1e-6
    assert angle_between(fk.axis, np.tile(face.normal, (n, 1))).max() <= 1e-9

    # printed joints: within the rounding bound derived from the FK Jacobian, row by row
    tip_bound, axis_bound = rounding_bounds(geometry, exact[:, 2:], moves.half_unit)
    fk_printed = forward(geometry, moves.joints[:, 2:], moves.joints[:, :2])
    assert fk_printed.converged.all()
    tip_error = np.linalg.norm(fk_printed.tip - intended_tip, axis=1)
    axis_error = angle_between(fk_printed.axis, np.tile(face.normal, (n, 1)))
    assert np.all(tip_error <= 1e-6 + tip_bound), (tip_error.max(), tip_bound[np.argmax(tip_error)])
    assert np.all(axis_error <= 1e-9 + axis_bound), (axis_error.max(), axis_bound[np.argmax(axis_error)])
    # the bound is honest, not loose: 4 decimals give ~1e-4 mm, and no row is off by more than it
    half = moves.half_unit.max()
    assert tip_bound.max() <= 5 * half and tip_bound.min() >= half

    # depth: lap rows (profiles) and feed bottoms (holes) sit at -d_k in face coordinates
    labels = [path_part.source_labels[s] for s in path_part.source.tolist()]
    depth_of = {}
    depth = item.case.option("--depth", 5.0 if "hole" in item.case.args else 2.0)
    if "hole" in item.case.args:
        peck = item.case.option("--peck", 0.0)
        for row, label in enumerate(labels):
            hit = re.fullmatch(r"hole \d+ (?:peck (\d+) )?feed", label)
            if hit:
                depth_of[row] = min(int(hit[1]) * peck, depth) if hit[1] else depth
    else:
        step = item.case.option("--step-down", 1.0)
        for row, label in enumerate(labels):
            hit = re.fullmatch(r"(?:square|round) pass (\d+)/\d+ lap", label)
            if hit:
                depth_of[row] = min(int(hit[1]) * step, depth)
    rows = np.array(sorted(depth_of))
    assert len(rows) >= 1
    want = -np.array([depth_of[r] for r in rows])
    w_exact = (fk.tip[rows] - result.setup.shift - face.origin) @ face.normal
    w_printed = (fk_printed.tip[rows] - result.setup.shift - face.origin) @ face.normal
    assert_allclose(w_exact, want, rtol=0, atol=1e-6)
    assert np.all(np.abs(w_printed - want) <= 1e-6 + tip_bound[rows])
    assert want.min() == -depth

    # inverse-time feeds: F = tip feed / tip path length of the move (1/min), printed rounded
    feed_rows = np.flatnonzero(moves.kind == MoveKind.FEED)
    length = np.linalg.norm(intended_tip[feed_rows] - intended_tip[feed_rows - 1], axis=1)
    assert np.all(np.abs(moves.feed[feed_rows] - path_part.feed[feed_rows] / length)
                  <= moves.feed_half_unit[feed_rows] * (1 + 1e-9))


@pytest.mark.parametrize("name", CASE_NAMES)
def test_joint_space_moves_stay_straight(made: dict[str, Made], name: str) -> None:
    """At t = 0.25, 0.5, 0.75 of every move, FK of the linearly interpolated joints is on the
    straight tip segment (1e-9 mm) with the face normal as axis (1e-9 rad): with a constant axis the
    joints are affine in the tip, so the controller's joint-space line is the straight tip line."""
    result = made[name].result
    geometry = load_machine("patel2020").geometry
    program = result.post.program
    joints = np.column_stack([program.stage, program.strokes])
    tip = result.path_part.tip + result.setup.shift
    for t in (0.25, 0.5, 0.75):
        mixed = (1 - t) * joints[:-1] + t * joints[1:]
        fk = forward(geometry, mixed[:, 2:], mixed[:, :2])
        assert fk.converged.all()
        assert np.linalg.norm(fk.tip - ((1 - t) * tip[:-1] + t * tip[1:]), axis=1).max() <= 1e-9
        assert angle_between(fk.axis, np.tile(result.face.normal, (len(mixed), 1))).max() <= 1e-9


# ----------------------------------------------------------------------------- the paper's case 2a


def _exact_ik(tip: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(5,) X, Y, T1, T2, T3 of one pose, exact model."""
    geometry = load_machine("patel2020").geometry
    unit = axis / np.linalg.norm(axis)
    ik = inverse(geometry, tip[None], unit[None])
    assert ik.reachable.all()
    return np.concatenate([ik.stage[0], ik.strokes[0]])


def test_case_2a_paper_point_lies_off_the_face() -> None:
    """The paper's point is 2.683e-4 mm above the wedge's face z = 300 - x/2 (printed with 4
    decimals), which is why the strokes below can only match the paper's pose to ~5e-4 mm."""
    normal = np.array([1.0, 0.0, 2.0]) / math.sqrt(5.0)
    offset = float((PAPER_2A_PART - np.array([0.0, 200.0, 300.0])) @ normal)
    assert_allclose(offset, 2.683e-4, atol=1e-7)
    # and the part point is the machine tip under the default setup
    assert_allclose(PAPER_2A_PART + np.array([-100.0, -200.0, -970.0]), PAPER_2A_TIP, atol=1e-9)


def test_case_2a_square_first_feed_ends_at_the_paper_point(made: dict[str, Made]) -> None:
    """A 60 mm square turned 45° about the face centre starts at face (15√2, 15√2): the paper's point.

    Its first feed ("down to face") ends there, on the face (w = 0), so one printed row holds the
    exact-model actuation of case 2a (DESIGN.md): stage X, Y = (-2.7639, 12.0703) within 1e-4, and
    the strokes of the exact IK of the paper's pose (T ≈ 36.2244, 170.3886, 88.9519) within 5e-4
    (the paper's point is 2.68e-4 mm off the face, and 2.1e-4 mm from (15√2, 15√2) along u).
    """
    item = made["wedge-square-case2a.ngc"]
    result = item.result
    path = result.path_part
    row = int(np.argmin(np.linalg.norm(path.tip - PAPER_2A_PART, axis=1)))
    assert path.source_labels[path.source[row]] == "square down to face"
    assert row == int(np.flatnonzero(path.kind == MoveKind.FEED)[0])          # the end of the first feed
    assert np.linalg.norm(path.tip[row] - PAPER_2A_PART) <= 3.5e-4
    uvw = result.face.from_part(path.tip[row : row + 1])[0]
    assert_allclose(uvw, [15 * math.sqrt(2), 15 * math.sqrt(2), 0.0], rtol=0, atol=1e-12)

    program = result.post.program
    joints = np.concatenate([program.stage[row], program.strokes[row]])
    paper = _exact_ik(PAPER_2A_TIP, PAPER_2A_AXIS)
    assert_allclose(paper, [-2.7640, 12.0703, 36.2244, 170.3886, 88.9519], atol=1e-4)
    assert_allclose(joints[:2], [-2.7639, 12.0703], rtol=0, atol=1e-4)
    assert_allclose(joints[2:], paper[2:], rtol=0, atol=5e-4)
    assert_allclose(joints[2:], [36.2244, 170.3886, 88.9519], rtol=0, atol=5e-4)

    # the printed words of that row are the exact IK of the row's tip, rounded to 4 decimals
    mine = _exact_ik(path.tip[row] + result.setup.shift, result.face.normal)
    assert_allclose(mine, joints, rtol=0, atol=1e-9)
    words = read_moves(item.text).words[row]
    assert words == {a: f"{v:.4f}" for a, v in zip(AXES, mine, strict=False)}
    assert words == {"X": "-2.7640", "Y": "12.0703", "U": "36.2247", "V": "170.3888", "W": "88.9522"}


def test_case_2a_hole_at_the_paper_point(made: dict[str, Made]) -> None:
    """`demo --profile hole --at-xyz 18.9736,221.2132,290.5135`: the hole's axis goes through the
    paper's point dropped onto the face (2.683e-4 mm along the normal). No row of a hole is on the
    face (the feed runs from the clearance height to the bottom); it crosses the face at
    t = clearance / (clearance + depth), where the joints are the linear interpolation of the two
    rows (constant axis: the joints are affine in the tip, see test_joint_space_moves_stay_straight).
    """
    item = made["wedge-hole-case2a.ngc"]
    result = item.result
    path, program, face = result.path_part, result.post.program, result.face
    feed = int(np.flatnonzero(path.kind == MoveKind.FEED)[0])
    assert path.source_labels[path.source[feed]] == "hole 1 feed"
    clearance, depth = 2.0, 5.0
    uvw = face.from_part(path.tip[feed - 1 : feed + 1])
    assert_allclose(uvw[:, 2], [clearance, -depth], rtol=0, atol=1e-12)
    offset = float((PAPER_2A_PART - face.origin) @ face.normal)
    assert_allclose(offset, 2.683e-4, rtol=0, atol=1e-7)
    dropped = PAPER_2A_PART - offset * face.normal
    assert_allclose(face.to_part(uvw[:1, :2])[0], dropped, rtol=0, atol=1e-9)

    t = clearance / (clearance + depth)
    joints = np.column_stack([program.stage, program.strokes])
    at_face = (1 - t) * joints[feed - 1] + t * joints[feed]
    face_tip = dropped + result.setup.shift
    fk = forward(load_machine("patel2020").geometry, at_face[None, 2:], at_face[None, :2])
    assert_allclose(fk.tip[0], face_tip, rtol=0, atol=1e-6)
    assert_allclose(at_face, _exact_ik(face_tip, face.normal), rtol=0, atol=1e-9)
    # against the paper's pose: dropping the tip by δ along n moves the stage by δ·n_xy and the
    # strokes by δ·n_z; the paper's rounded axis differs from n by |Δa|, which moves the stage by TL·|Δa|
    paper = _exact_ik(PAPER_2A_TIP, PAPER_2A_AXIS)
    delta_axis = np.linalg.norm(PAPER_2A_AXIS / np.linalg.norm(PAPER_2A_AXIS) - face.normal)
    stage_tol = offset * abs(face.normal[0]) + 175.0 * delta_axis + 1e-6
    assert_allclose(at_face[:2], paper[:2], rtol=0, atol=stage_tol)
    assert_allclose(at_face[2:], paper[2:], rtol=0, atol=5e-4)


# ----------------------------------------------------------------------------- the same job, the same bytes


def test_same_job_twice_gives_the_same_bytes(made: dict[str, Made], tmp_path: Path) -> None:
    """In-process twice (run and the `prs3-post PART.stl` shorthand), and once more in a fresh
    interpreter with another hash seed and working folder: identical bytes."""
    case = next(c for c in CASES if c.name == "tilt35-square.ngc")
    first, second, third = tmp_path / "a.ngc", tmp_path / "b.ngc", tmp_path / "c.ngc"
    assert CliRunner().invoke(main, [*case.args, "-o", str(first)]).exit_code == 0
    assert CliRunner().invoke(main, [*case.args[1:], "-o", str(second)]).exit_code == 0
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    done = subprocess.run(
        [sys.executable, "-c", "from prs3_post.cli.main import main; main()", *case.args, "-o", str(third)],
        cwd=tmp_path, env=env, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    expected = made[case.name].text.encode("utf-8")
    assert first.read_bytes() == expected
    assert second.read_bytes() == expected
    assert third.read_bytes() == expected


def test_job_spec_gives_the_cli_program(made: dict[str, Made]) -> None:
    """run_job with a JobSpec built by hand is the program the CLI wrote (options map one to one;
    --rotation is in degrees on the command line, radians in SquareShape)."""
    spec = JobSpec(
        part=_part("tilt35.stl"), units="mm", face=None,
        work=ProfileJob(SquareShape(size=40.0, corner_radius=4.0, rotation=math.radians(15.0)),
                        ProfileParams(side=Side.INSIDE, depth=2.0, step_down=1.0, direction=Direction.CLIMB,
                                      entry=Entry.RAMP, ramp_angle=math.radians(3.0), clearance=2.0, retract=10.0)),
        at_uv=np.zeros((0, 2)), at_xyz=np.zeros((0, 3)),
        cutting=Cutting(tool_diameter=6.0, feed=300.0, plunge_feed=100.0, spindle_rpm=3000.0,
                        coolant=Coolant.FLOOD, tool_number=1),
        machine=load_machine("patel2020"), dialect=load_dialect("linuxcnc"),
        setup=Setup.resolve(load_machine("patel2020")), tolerance=0.01,
    )
    result = run_job(spec)
    assert result.text == made["tilt35-square.ngc"].text
    assert result.face.index == 4
    assert_allclose(result.setup.shift, [-100.0, -200.0, -970.0], rtol=0, atol=0)


@pytest.mark.parametrize(("name", "times", "options", "holder"), [
    ("wedge.stl", 4, ("--profile", "round", "--diameter", "25", "--depth", "2", "--step-down", "1", "--tolerance",
                      "0.01"), "holder over 11.000 mm"),
    # the holder passes 8.6 mm from the wall: the collision header's minimum is measured, not only bounded
    ("wall30.stl", 3, ("--profile", "hole", "--at", "8.1,0"), "holder 8.635 mm"),
])
def test_a_finely_cut_part_gives_the_coarse_parts_program(name: str, times: int, options: tuple[str, ...],
                                                          holder: str, tmp_path: Path) -> None:
    """The main job on a part whose every triangle is cut into 4^times writes the coarse part's program,
    but for the part's own line (its name and checksum)."""
    import trimesh

    mesh = trimesh.load(PARTS / name)
    for _ in range(times):
        mesh = mesh.subdivide()
    fine = tmp_path / f"fine-{name}"
    fine.write_bytes(trimesh.exchange.stl.export_stl(mesh))
    texts = []
    for part in (PARTS / name, fine):
        out = tmp_path / f"{part.stem}.ngc"
        outcome = CliRunner().invoke(main, ["run", str(part), *options, "-o", str(out)])
        assert outcome.exit_code == 0, outcome.output
        texts.append(out.read_text().splitlines())
    coarse_text, fine_text = texts
    assert [ln for ln in fine_text if not ln.startswith("(part: ")] == \
        [ln for ln in coarse_text if not ln.startswith("(part: ")]
    assert next(ln for ln in fine_text if ln.startswith("(part: ")).startswith(f"(part: fine-{name}, units mm")
    assert next(ln for ln in fine_text if ln.startswith("(collision: ")) == (
        f"(collision: clear of the part by at least 1.000 mm: tool over 11.000 mm, {holder}, spindle nose over "
        "11.000 mm)")
