"""Fuzzing every command of the CLI: random option values and mutated input files.

For each command (``run``, ``demo``, ``faces``, ``ik``, ``fk``, ``verify``, ``preview``,
``machines``, ``job``, ``convert``, ``calibrate`` and ``calibrate plan``, ``accuracy``, ``export``,
``linuxcnc-config``, ``sim`` up to LinuxCNC's run) hypothesis
draws option values for the command's own click parameters (read from
the command, so a new option is fuzzed too): mostly sensible values, sometimes hostile ones
(``nan``, ``1e308``, ``1_0``, empty, non-ASCII digits), and input files (STL, program, CSV,
machine and dialect TOML) with bytes flipped, inserted, deleted or truncated. Every run must:

- exit with 0, 1 (a limit or reach) or 2 (bad input), never with a traceback;
- leave no output file when it fails (``ik --batch`` writes its table with exit 1: the ok column
  says which rows failed), and never a temp file;
- leave every input file as it was.

Deterministic (``derandomize``) so that CI sees the same examples every run.
"""

from __future__ import annotations

import functools
import tempfile
import traceback
from pathlib import Path
from typing import Any

import click
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from prs3_post.cli.main import main
from prs3_post.cli.options import Decimal, Integer, Numbers, OutputPath
from prs3_post.core.errors import MissingDependency

REPO = Path(__file__).resolve().parents[2]

#: How many examples each command gets (the whole file runs in ~15 s; preview draws a figure).
EXAMPLES = {"run": 40, "demo": 50, "faces": 40, "ik": 50, "fk": 50, "verify": 50, "preview": 12, "machines": 5,
            "sources": 5,
            "job": 25, "convert": 30, "calibrate": 12, "accuracy": 6, "export": 30, "linuxcnc-config": 20, "sim": 25}
#: Options set in one example, besides the required ones.
MAX_OPTIONS = 4

# ----------------------------------------------------------------------------- the inputs


@functools.cache
def originals() -> dict[str, tuple[bytes, ...]]:
    """The valid files each kind of input is mutated from."""
    runner = CliRunner()
    programs = tuple(
        runner.invoke(main, ["demo", "--profile", profile, *extra]).stdout_bytes
        for profile, extra in (("hole", ["--peck", "2"]), ("square", []), ("round", ["--dialect", "fanuc"]))
    )
    wedge = (REPO / "fixtures" / "parts" / "wedge.stl").read_bytes()
    return {
        "stl": (wedge, (REPO / "fixtures" / "parts" / "twofaces.stl").read_bytes(), _ascii_box()),
        "ngc": (*programs, (REPO / "fixtures" / "verify" / "small.ngc").read_bytes(),
                (REPO / "fixtures" / "golden" / "twofaces-job-example.ngc").read_bytes()),
        "csv": ((REPO / "fixtures" / "poses" / "cases_2a_2b.csv").read_bytes(),
                b"tip_x,tip_y,tip_z,axis_x,axis_y,axis_z\n0,200,-680,0,0,1\n-81.0264,21.2132,-679.4865,0.447214,0,0.894427\n"),
        "machine": ((REPO / "postproc" / "machines" / "patel2020.toml").read_bytes(),),
        "cl": (b"UNITS/MM\nFEDRAT/MMPM,200\n$$ a drill\nRAPID\nGOTO/0,200,20,0,0,1\n"
               b"CYCLE/DRILL,RAPTO,3,FEDTO,5,MMPM,100\nGOTO/0,200,0\nGOTO/10,200,0\nCYCLE/OFF\nGOTO/10,200,0\n"
               b"CIRCLE/0,200,0,0,0,1,10,0.01\nGOTO/-10,200,0\nFINI\n",),
        "dialect": ((REPO / "postproc" / "dialects" / "linuxcnc.toml").read_bytes(),
                    (REPO / "postproc" / "dialects" / "fanuc.toml").read_bytes()),
        "tbl": ((REPO / "fixtures" / "jobs" / "tools.tbl").read_bytes(),),
        "job": (_example_job(),),
        "meas": ((REPO / "fixtures" / "calibration" / "measured.csv").read_bytes(),
                 (REPO / "fixtures" / "calibration" / "validate.csv").read_bytes()),
    }


def _example_job() -> bytes:
    """The example job with absolute paths (the fuzzed copy is written elsewhere)."""
    jobs = REPO / "fixtures" / "jobs"
    text = (jobs / "example.toml").read_text(encoding="utf-8")
    text = text.replace('"../parts/twofaces.stl"', f'"{jobs.parent / "parts" / "twofaces.stl"}"')
    return text.replace('"tools.tbl"', f'"{jobs / "tools.tbl"}"').encode()


def _ascii_box() -> bytes:
    """A 40 x 40 x 20 mm wedge-topped block as ASCII STL (text to mutate, unlike the binary fixtures)."""
    v = [(0, 0, 0), (40, 0, 0), (40, 40, 0), (0, 40, 0), (0, 0, 20), (40, 0, 10), (40, 40, 10), (0, 40, 20)]
    faces = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5),
             (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]
    lines = ["solid box"]
    for face in faces:
        lines += ["  facet normal 0 0 0", "    outer loop",
                  *(f"      vertex {v[i][0]} {v[i][1]} {v[i][2]}" for i in face), "    endloop", "  endfacet"]
    return ("\n".join([*lines, "endsolid box", ""])).encode()


#: Text that parsers trip on, inserted into the files.
TOKENS = ("nan", "inf", "-", "1e400", "1_0", "\n", "\r\n", "(", ")", ";", "%", "G1", "X", "F0", "N", "=", '"',
          "[", "]", "solid", "endsolid", "vertex", "facet", "\x00", "é", "\ufeff", "0" * 40, ",")


@st.composite
def mutated(draw: st.DrawFn, kind: str) -> bytes:
    """One of the kind's files, with 0 to 3 mutations (half of them unmutated-or-once, so that the
    deeper code runs too)."""
    data = bytearray(draw(st.sampled_from(originals()[kind])))
    for _ in range(draw(st.sampled_from((0, 0, 0, 1, 1, 2, 3)))):
        size = len(data)
        at = draw(st.integers(0, max(size - 1, 0)))
        operation = draw(st.sampled_from(("flip", "truncate", "insert", "delete", "duplicate", "token")))
        if operation == "flip" and size:
            data[at] = draw(st.integers(0, 255))
        elif operation == "truncate":
            del data[at:]
        elif operation == "insert":
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
        elif operation == "delete":
            del data[at:at + draw(st.integers(1, 80))]
        elif operation == "duplicate":
            data[at:at] = data[at:at + draw(st.integers(1, 200))]
        else:
            data[at:at] = draw(st.sampled_from(TOKENS)).encode()
    return bytes(data)


# ----------------------------------------------------------------------------- option values

HOSTILE_NUMBERS = ("nan", "-inf", "1e308", "-1e308", "1e-320", "1_0", "", " 1", "0x10", "٣", "1,2", "--", "-",
                   "1e6", "-1e6", "999999", "0", "-0", "1" + "0" * 300)


def number_text() -> st.SearchStrategy[str]:
    """Mostly numbers a user might give, one time in five a hostile one."""
    sensible = st.floats(-200, 200, allow_nan=False).map(lambda x: f"{x:.4g}")
    small = st.floats(0.01, 20).map(lambda x: f"{x:.3f}")
    return st.one_of(sensible, small, small, st.sampled_from(HOSTILE_NUMBERS), st.integers(-10**6, 10**6).map(str))


def numbers_text(count: int) -> st.SearchStrategy[str]:
    right = st.lists(number_text(), min_size=count, max_size=count).map(",".join)
    return st.one_of(right, right, right, st.lists(number_text(), max_size=count + 2).map(",".join))


def input_file(kind: str, name: str) -> st.SearchStrategy[tuple[str, bytes] | str]:
    """A mutated file of ``kind`` (written as ``name`` in the input folder); rarely a path that is no file."""
    file = mutated(kind).map(lambda data: (name, data))
    return st.one_of(file, file, file, file, st.sampled_from(("missing.stl", ".", "/dev/null")))


#: What each path parameter reads: (kind, file name).
INPUTS = {
    "part": [("stl", "part.stl")], "part_path": [("stl", "part.stl")], "program_path": [("ngc", "prog.ngc")],
    "batch_path": [("csv", "poses.csv")], "against_path": [("stl", "against.stl"), ("csv", "against.csv")],
    "tool_table": [("tbl", "tools.tbl")], "job_path": [("job", "job.toml")],
    "inputs": [("cl", "c.cls"), ("ngc", "p.nc")],
    "measurements_path": [("meas", "measured.csv")], "validate_path": [("meas", "validate.csv")],
}
#: Output names: mostly good ones for the command, sometimes a folder, a missing folder or an input.
GOOD_OUTPUTS = {"preview": ("out/o.png", "out/o.svg"), "preview_path": ("out/o.png", "out/o.svg"),
                "ik": ("out/o.csv", "-"), "run": ("out/o.ngc", "-"), "demo": ("out/o.ngc", "-"),
                "job": ("out/o.ngc", "-"), "identify": ("out/o.toml", "-"), "plan": ("out/poses.csv", "-"),
                "report_path": ("out/r.json", "-"), "export": ("out/o.cls", "out/o.csv", "-"),
                "out_dir": ("out/sim",), "screenshot": ("out/o.png",)}
BAD_OUTPUTS = ("out/", "out/missing/o.png", "in/part.stl", "in/prog.ngc", "in/poses.csv", "out/o.txt", "")


def value_for(param: click.Parameter, command: str) -> st.SearchStrategy[Any]:
    """Values for one parameter: text for the command line, or (name, bytes) for an input file."""
    kind = param.type
    if param.name in INPUTS:
        return st.one_of(*(input_file(k, n) for k, n in INPUTS[param.name]))
    if isinstance(kind, OutputPath):
        good = st.sampled_from(GOOD_OUTPUTS.get(param.name or "", GOOD_OUTPUTS.get(command, ("out/o.ngc",))))
        return st.one_of(good, good, good, st.sampled_from(BAD_OUTPUTS))
    if param.name == "machine_name":
        return st.one_of(st.sampled_from(("patel2020", "patel2020-head", "nope")), input_file("machine", "m.toml"))
    if param.name == "dialect_name":
        return st.one_of(st.sampled_from(("linuxcnc", "fanuc", "nope")), input_file("dialect", "d.toml"))
    if param.name == "outdir":                      # convert's folder: the outputs' folder, the inputs', a file
        return st.sampled_from(("out", "out", "out", "in", "in/c.cls"))
    if param.name == "face_choice":
        return st.sampled_from(("auto", "auto", "0", "4", "5", "6", "99", "-1", "x", "²", ""))
    if isinstance(kind, click.Choice):
        return st.sampled_from([*(str(c) for c in kind.choices)] * 4 + ["bogus"])
    if isinstance(kind, Numbers):
        return numbers_text(kind.count)
    if isinstance(kind, (Decimal, click.types.FloatParamType)):
        return number_text()
    if isinstance(kind, (Integer, click.types.IntParamType, click.IntRange)):
        return st.one_of(st.integers(-5, 100_000).map(str), st.integers(0, 20).map(str),
                         st.sampled_from(("1e20", "10" * 20, "1_0", "x", "")))
    return st.text(max_size=12)


#: Parameters that go together: when a draw includes one, it includes the others (ik's pose).
TOGETHER = {"tip": ("axis",), "axis": ("tip",)}


# ----------------------------------------------------------------------------- running


def _arguments(draw: Any, command: click.Command, folder: Path) -> list[str]:
    """A command line for ``command``: its required parameters and up to MAX_OPTIONS others."""
    params = [p for p in command.params if p.name not in ("help",)]
    required = [p for p in params if p.required]
    optional = [p for p in params if not p.required]
    chosen = required + draw(st.lists(st.sampled_from(optional), max_size=MAX_OPTIONS, unique_by=lambda p: p.name)
                             if optional else st.just([]))
    names = {p.name for p in chosen}
    chosen += [p for p in optional if p.name not in names and names & set(TOGETHER.get(p.name or "", ()))]
    args: list[str] = [command.name or ""]
    for param in chosen:
        if isinstance(param, click.Option) and param.is_flag:
            args.append(draw(st.sampled_from([*param.opts, *param.secondary_opts])))
            continue
        value = draw(value_for(param, command.name or ""), label=param.name)
        if isinstance(value, tuple):                 # an input file: write it
            name, data = value
            (folder / "in" / name).write_bytes(data)
            value = f"in/{name}"
        args += [value] if isinstance(param, click.Argument) else [param.opts[0], value]
    return args


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in (folder / "in").iterdir() if p.is_file()}


def check_command(name: str, data: st.DataObject, monkeypatch: pytest.MonkeyPatch) -> None:
    command = main.commands[name]
    group: list[str] = []
    if isinstance(command, click.Group):             # calibrate: one of its commands (identify, plan)
        group = [name]
        command = command.commands[data.draw(st.sampled_from(sorted(command.commands)))]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "in").mkdir()
        (folder / "out").mkdir()
        monkeypatch.chdir(folder)
        if name == "sim":      # a run in LinuxCNC takes seconds: all up to it is fuzzed, the run itself is not
            monkeypatch.setattr("prs3_post.app.sim.linuxcnc_launcher", _no_linuxcnc)
        args = group + _arguments(data.draw, command, folder)
        inputs = _snapshot(folder)
        result = CliRunner().invoke(main, args, prog_name="prs3-post")
        context = f"prs3-post {' '.join(args)}\nstdout: {result.stdout[-2000:]}\nstderr: {result.stderr[-2000:]}"
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            trace = "".join(traceback.format_exception(result.exception))
            pytest.fail(f"traceback from {context}\n{trace}")
        assert result.exit_code in (0, 1, 2), context
        written = sorted(p.name for p in (folder / "out").iterdir())
        assert not [n for n in written if n.endswith(".tmp")], context
        if (result.exit_code == 2 and name != "convert") or (result.exit_code == 1 and name not in ("ik", "convert")):
            assert written == [], context
        if result.exit_code in (1, 2) and name == "convert":   # its one file failed (2: as bad input; or bad
            # options, before any work): at most the batch's report is written
            report = args[args.index("--report") + 1] if "--report" in args else None
            assert [f"out/{n}" for n in written] in ([], [report]), context
        now = _snapshot(folder)
        assert {name: now.get(name) for name in inputs} == inputs, context      # outputs may be new files


def _no_linuxcnc() -> str:
    raise MissingDependency("LinuxCNC is left out of the fuzzing")


FUZZ = settings(deadline=None, derandomize=True, database=None, print_blob=False,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


def _fuzz(name: str):
    @settings(FUZZ, max_examples=EXAMPLES[name])
    @given(data=st.data())
    def test(data: st.DataObject, monkeypatch: pytest.MonkeyPatch) -> None:
        check_command(name, data, monkeypatch)

    test.__name__ = f"test_fuzz_{name}"
    return test


def test_every_command_is_fuzzed() -> None:
    assert set(EXAMPLES) == set(main.commands)


test_fuzz_run = _fuzz("run")
test_fuzz_demo = _fuzz("demo")
test_fuzz_faces = _fuzz("faces")
test_fuzz_ik = _fuzz("ik")
test_fuzz_fk = _fuzz("fk")
test_fuzz_verify = _fuzz("verify")
test_fuzz_preview = _fuzz("preview")
test_fuzz_machines = _fuzz("machines")
test_fuzz_sources = _fuzz("sources")
test_fuzz_job = _fuzz("job")
test_fuzz_convert = _fuzz("convert")
test_fuzz_calibrate = _fuzz("calibrate")
test_fuzz_accuracy = _fuzz("accuracy")
test_fuzz_export = _fuzz("export")
test_fuzz_linuxcnc_config = _fuzz("linuxcnc-config")
test_fuzz_sim = _fuzz("sim")
