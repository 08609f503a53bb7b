"""`prs3-post sim`: a program run in LinuxCNC's own motion controller.

The runs in LinuxCNC (fixture ``linuxcnc``: skipped where it is not installed, a failure in CI) take
real time, as the machine would: the demo hole and the example job at feed override 10 must pass, stop
within 0.001 mm of their last line's words, and take the header's model's time at that override
within 10 %; a move out of the stroke range comes back as a failure naming its line; Ctrl-C stops
LinuxCNC in order. Each run must leave no process and no folder behind. The runs take turns (the
command's own lock), also under several pytest processes.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import prs3_post.app.sim as sim_module
from prs3_post.app.linuxcnc_config import config_axes
from prs3_post.app.sim import (
    POSITION_TOLERANCE_MM,
    ControllerMessage,
    estimate_minutes,
    simulate,
)
from prs3_post.app.verify import open_program
from prs3_post.cli.main import main
from prs3_post.core.errors import FieldError
from prs3_post.machine.loading import load_machine

REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "golden"
DEMO = GOLDEN / "wedge-hole-case2a.ngc"            # prs3-post demo --profile hole
EXAMPLE = GOLDEN / "twofaces-job-example.ngc"      # prs3-post job fixtures/jobs/example.toml
#: The feed override of the runs: the demo's one plunge 10 times faster; rapids are at top speed anyway.
OVERRIDE = 10.0
#: How close the controller's motion time must be to the model's at the override.
TIME_TOLERANCE = 0.10
CONSOLE = "from prs3_post.cli.entry import main; main()"


def invoke(*args: object):
    return CliRunner().invoke(main, [str(a) for a in args], prog_name="prs3-post")


# -- without LinuxCNC ---------------------------------------------------------------------------------

@pytest.mark.parametrize(("program", "minutes"), [(DEMO, 0.082), (EXAMPLE, 1.287)])
def test_the_estimate_at_100_percent_is_the_headers(program: Path, minutes: float) -> None:
    context = open_program(str(program))
    assert context.machine.dynamics is not None
    assert round(estimate_minutes(context.machine.dynamics, context.program.moves), 3) == minutes


def test_the_estimate_at_an_override_speeds_the_feeds_up_to_the_axes_top_speeds() -> None:
    context = open_program(str(DEMO))
    dynamics, moves = context.machine.dynamics, context.program.moves
    assert dynamics is not None
    # the plunge (7 mm at 100 mm/min: 4.2 s) 10 times faster; the four rapids (0.702 s) as they were
    assert estimate_minutes(dynamics, moves, 10.0) * 60 == pytest.approx(1.15213, abs=1e-5)
    # far beyond: the strokes' 6.261 mm of the plunge as fast as they accelerate (500 mm/s², never reaching
    # their 5000 mm/min): 2·√(6.261 / 500) = 0.2238 s, and the rapids
    assert estimate_minutes(dynamics, moves, 1000.0) * 60 == pytest.approx(0.92612, abs=1e-5)
    example = open_program(str(EXAMPLE))
    assert estimate_minutes(dynamics, example.program.moves, 10.0) * 60 == pytest.approx(38.420, abs=1e-3)


def test_without_linuxcnc_it_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sim_module.shutil, "which", lambda name: None)
    result = invoke("sim", DEMO)
    assert result.exit_code == 2
    assert result.output == ("prs3-post: error: sim runs the program in LinuxCNC, which is not installed (the "
                             "linuxcnc launcher is not on PATH): apt-get install linuxcnc-uspace\n")


def test_a_screenshot_without_xvfb_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setattr(sim_module, "linuxcnc_launcher", lambda: "/usr/bin/linuxcnc")
    monkeypatch.setattr(sim_module.shutil, "which", lambda name: None)
    result = invoke("sim", DEMO, "--screenshot", tmp_path / "end.png")
    assert result.exit_code == 2
    assert result.output == ("prs3-post: error: --screenshot needs a virtual X display (xvfb-run), which is not "
                             "installed: apt-get install xvfb\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("shot", ["end.jpg", "-"])
def test_a_screenshot_is_a_png_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, shot: str) -> None:
    monkeypatch.chdir(tmp_path)                        # refused before LinuxCNC is looked for
    monkeypatch.setattr(sim_module, "linuxcnc_launcher", lambda: pytest.fail("LinuxCNC was started"))
    result = invoke("sim", DEMO, "--screenshot", shot)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == (f"Error: Invalid value for '--screenshot': the screenshot must end in "
                                              f".png, got '{shot}'")
    assert list(tmp_path.iterdir()) == []


def test_a_screenshot_without_a_vismach_model_says_so(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import prs3_post.app.linuxcnc_config as config_module

    def no_model(*args: object) -> str:
        raise NotImplementedError("no model of this kinematics")

    monkeypatch.setattr(sim_module, "linuxcnc_launcher", lambda: "/usr/bin/linuxcnc")
    monkeypatch.setattr(sim_module.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setattr(config_module, "vismach_hal", no_model)
    runs = tmp_path / "runs"
    runs.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(runs))
    result = invoke("sim", DEMO, "--screenshot", tmp_path / "end.png")
    assert result.exit_code == 2
    assert result.output == ("prs3-post: error: --screenshot needs a vismach model of machine patel2020, which "
                             "linuxcnc-config cannot write (no model of this kinematics): run without --screenshot\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"] and list(runs.iterdir()) == []


@pytest.mark.parametrize("value", ["0", "-1", "100.5", "nan"])
def test_a_feed_override_out_of_range_is_refused(value: str) -> None:
    result = invoke("sim", DEMO, "--feed-override", value)
    assert result.exit_code == 2
    assert "Invalid value for '--feed-override'" in result.output


def test_the_library_refuses_a_feed_override_out_of_range() -> None:
    with pytest.raises(FieldError, match=r"expected more than 0 and at most 100 \(1 = 100 %\), got 0"):
        simulate(str(DEMO), feed_override=0.0)


def test_a_file_that_is_not_a_program_is_refused_before_linuxcnc(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sim_module, "linuxcnc_launcher", lambda: pytest.fail("LinuxCNC must not be looked for"))
    result = invoke("sim", REPO / "fixtures" / "jobs" / "example.toml")
    assert result.exit_code == 2
    assert result.output.startswith("prs3-post: error: ")
    assert "example.toml:" in result.output


def test_a_linuxcnc_that_does_not_start_is_reported_with_its_output(monkeypatch: pytest.MonkeyPatch,
                                                                   tmp_path: Path) -> None:
    fake = tmp_path / "linuxcnc"
    fake.write_text("#!/bin/sh\necho 'Starting LinuxCNC...'\necho 'HAL: ERROR: no such pin'\nexit 1\n",
                    encoding="utf-8")
    fake.chmod(0o755)
    runs = tmp_path / "runs"
    runs.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(runs))
    monkeypatch.setattr(sim_module, "linuxcnc_launcher", lambda: str(fake))
    monkeypatch.setattr(sim_module, "can_isolate", lambda: False)   # (a namespace's /tmp would hide the fake)
    monkeypatch.setattr(sim_module, "_wait_for_other_linuxcnc", lambda tell: None)
    monkeypatch.setattr(sim_module, "_check_reachable", lambda folder: None)     # (no realtime part to run)
    result = invoke("sim", DEMO)
    assert result.exit_code == 1
    assert result.output == ("prs3-post: error: LinuxCNC did not run the program: Starting LinuxCNC...; HAL: "
                             "ERROR: no such pin\n")
    assert list(runs.iterdir()) == []


def test_runs_take_turns_on_one_lock() -> None:
    """Another process holding the lock (another sim running): this one says it waits, then goes on."""
    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, os, sys, time; from prs3_post.app.sim import SIM_LOCK\n"
        "fd = os.open(SIM_LOCK, os.O_RDONLY | os.O_CREAT, 0o666); fcntl.flock(fd, fcntl.LOCK_EX)\n"
        "print('held', flush=True); time.sleep(1.0)")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        told: list[str] = []
        started = time.monotonic()
        with sim_module._sim_lock(told.append):
            waited = time.monotonic() - started
    finally:
        holder.wait(timeout=30)
    assert told == ["waiting for another prs3-post sim to finish"]
    assert waited > 0.5


def test_the_joints_are_in_the_configurations_order() -> None:
    """Stage X, Y, then the strokes; a machine without a stage has the strokes alone (as its configuration)."""
    context = open_program(str(DEMO))
    moves = context.program.moves
    np.testing.assert_allclose(sim_module.config_joints(context.machine, moves, -1),
                               [1.708, 12.0703, 27.2803, 161.4444, 80.0078])
    head = load_machine("patel2020-head")
    np.testing.assert_allclose(sim_module.config_joints(head, moves, 0), [27.2803, 161.4444, 80.0078])
    axes = config_axes(head)
    assert sim_module._start_move(axes, sim_module.config_joints(head, moves, 0)) == (
        "G90 G0 U27.280300 V161.444400 W80.007800")


def test_an_error_without_a_line_belongs_to_the_one_before_it() -> None:
    moves = open_program(str(DEMO)).program.moves
    result = {"errors": [
        {"kind": "error", "text": "Linear move on line 27 would exceed V's positive limit", "line": 27, "named": True,
         "stage": "run"},
        {"kind": "error", "text": "invalid params in linear command", "line": 25, "named": False, "stage": "run"},
    ], "messages": [{"kind": "text", "text": "hello", "line": 24, "named": False, "stage": "run"}]}
    assert sim_module._messages(result, moves) == (
        ControllerMessage("error", "Linear move on line 27 would exceed V's positive limit", 27),
        ControllerMessage("error", "invalid params in linear command", 27),
        ControllerMessage("text", "hello", 24),
    )
    first = {"errors": [{"kind": "error", "text": "would exceed", "line": None, "named": False,
                         "stage": "first point"}]}
    assert sim_module._messages(first, moves) == (ControllerMessage("error", "would exceed", 24),)
    assert sim_module.message_text(ControllerMessage("error", "Linear move on line 27 would exceed V", 27)) == (
        "Linear move would exceed V")


# -- in LinuxCNC --------------------------------------------------------------------------------------

def _run_processes(folder: Path) -> list[int]:
    """Processes of the runs whose folders are in ``folder`` (LinuxCNC's carry PRS3_SIM_RUN in their
    environment)."""
    found = []
    marker = f"PRS3_SIM_RUN={folder}".encode()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                if marker in (entry / "environ").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


@pytest.fixture
def run_folder(linuxcnc: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The temporary folder the runs are made in; afterwards nothing of them is left, in it or running."""
    folder = tmp_path / "runs"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    yield folder
    assert _run_processes(folder) == []
    assert list(folder.iterdir()) == []


def _check_pass(report: sim_module.SimReport) -> None:
    assert report.stage == "done"
    assert report.errors == ()
    assert report.applied_override == OVERRIDE
    deviation = report.deviation
    assert deviation is not None
    assert float(deviation.max()) <= POSITION_TOLERANCE_MM
    assert report.passed
    ratio = report.time_ratio
    assert ratio is not None
    assert abs(ratio - 1.0) <= TIME_TOLERANCE, (report.motion_s, report.estimate_s)


def test_the_demo_hole_runs_in_linuxcnc(run_folder: Path, tmp_path: Path) -> None:
    demo = tmp_path / "demo.ngc"
    assert invoke("demo", "--profile", "hole", "-o", demo).exit_code == 0
    report = simulate(str(demo), feed_override=OVERRIDE)
    _check_pass(report)
    np.testing.assert_allclose(report.expected, [-17.2655, -9.1429, 17.7936, 151.9577, 70.5211])   # line 29
    assert report.last_line == 29
    assert report.header_minutes == 0.082


def test_the_example_job_runs_in_linuxcnc(run_folder: Path) -> None:
    report = simulate(str(EXAMPLE), feed_override=OVERRIDE)
    _check_pass(report)                      # with its tool change to T2 (the header's tools in the table)
    assert report.last_line == 661
    assert report.header_minutes == 1.287


def test_without_namespaces_it_runs_alone_on_the_host(run_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where LinuxCNC cannot have namespaces of its own (not root), it runs as the host's one instance."""
    running = sim_module.linuxcnc_processes()
    if running:
        pytest.skip(f"another LinuxCNC runs on this host: {running}")
    monkeypatch.setattr(sim_module, "can_isolate", lambda: False)
    if os.geteuid() == 0:                    # rtapi_app runs as nobody, and must reach its FIFO in the run
        with pytest.raises(sim_module.SimError, match=r"cannot be entered by the user LinuxCNC's realtime part"):
            simulate(str(DEMO), feed_override=OVERRIDE)          # pytest's temporary folders are the owner's
        monkeypatch.setattr(tempfile, "tempdir", "/tmp")
    _check_pass(simulate(str(DEMO), feed_override=OVERRIDE))
    assert not Path("/tmp/linuxcnc.lock").exists()


def test_a_move_out_of_range_fails_naming_its_line(run_folder: Path, tmp_path: Path) -> None:
    """The demo's plunge sent to V474.8608 (the strokes end at 400 mm), after a program stop (M0) that the
    display resumes as an operator's cycle start would."""
    text = DEMO.read_text(encoding="utf-8")
    bad = tmp_path / "bad.ngc"
    bad.write_text(text.replace("G93\nG1 X-5.0002 U40.6968 V174.8608", "M0\nG93\nG1 X-5.0002 U40.6968 V474.8608"),
                   encoding="utf-8")
    result = invoke("sim", bad, "--feed-override", OVERRIDE)
    assert result.exit_code == 1, result.output
    lines = result.output.splitlines()
    assert lines[0] == "bad.ngc in LinuxCNC (machine patel2020, feed override 10 = 1000 %)"
    assert "  controller note: line 25: program stop after this line's move: resumed (cycle start)" in lines
    assert "  controller: line 28: Linear move would exceed V's positive limit" in lines
    assert "    line 28: G1 X-5.0002 U40.6968 V474.8608 W93.4242 F14.2857" in lines
    assert lines[-1].startswith("FAIL: the controller stopped the program at line 28 (")


def test_ctrl_c_stops_linuxcnc_in_order(run_folder: Path) -> None:
    env = {**os.environ, "TMPDIR": str(run_folder)}
    process = subprocess.Popen([sys.executable, "-c", CONSOLE, "sim", str(EXAMPLE), "-v"], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert process.stderr is not None
        said = process.stderr.readline()                    # (another sim may hold the lock: it waits)
        while said.startswith("prs3-post: waiting"):
            said = process.stderr.readline()
        assert said.startswith("prs3-post: starting LinuxCNC"), said
        time.sleep(2.0)                                      # under way: homed, on its way to the first point
        assert _run_processes(run_folder)
        stopped = time.monotonic()
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert time.monotonic() - stopped < 15
    assert process.returncode == 130, err
    assert err == "prs3-post: interrupted\n"
    assert out == ""
