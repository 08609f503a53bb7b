"""The vismach model's script runs under the system Python LinuxCNC uses and draws what our FK says.

The script is run as LinuxCNC runs it (``/usr/bin/python3``, a clean environment, no prs3-post on its
path) with ``--pose``, which prints its scene without a display; the scene must equal the one this
environment computes with :func:`vismach_scene` (our forward kinematics), to the last bit of JSON.
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from prs3_post.app.linuxcnc_config import write_config
from prs3_post.app.linuxcnc_vismach import package_folder
from prs3_post.check.machine_pose import machine_pose
from prs3_post.check.vismach_scene import vismach_scene
from prs3_post.machine.loading import load_machine

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "fixtures" / "jobs" / "tools.tbl"
SYSTEM_PYTHON = "/usr/bin/python3"
CLEAN_ENV = {"PATH": "/usr/bin:/bin", "LANG": "C.UTF-8"}


@pytest.fixture(scope="module")
def system_python() -> str:
    """The system Python with numpy (LinuxCNC's packages depend on python3-numpy); skipped without it
    except in CI."""
    ok = os.path.exists(SYSTEM_PYTHON) and subprocess.run(
        [SYSTEM_PYTHON, "-c", "import numpy"], capture_output=True, check=False, env=CLEAN_ENV).returncode == 0
    if not ok:
        if os.environ.get("CI"):
            pytest.fail("the system Python with numpy must be there in CI (apt-get install linuxcnc-uspace)")
        pytest.skip("no system Python with numpy (LinuxCNC is not installed)")
    return SYSTEM_PYTHON


def _pose(python: str, script: Path, *args: str) -> dict[str, object]:
    done = subprocess.run([python, str(script), "--pose", *args], capture_output=True, text=True, check=False,
                          env=CLEAN_ENV, cwd="/")
    assert done.returncode == 0, done.stderr
    result: dict[str, object] = json.loads(done.stdout)
    return result


def test_the_model_draws_our_fk_under_the_system_python(tmp_path: Path, system_python: str) -> None:
    config = write_config("patel2020", str(tmp_path / "sim"), tool_table=str(TOOLS))
    script = config.folder / "prs3_vismach.py"
    assert os.access(script, os.X_OK)
    strokes, stage = np.array([36.2244, 170.3886, 88.9519]), np.array([-2.7639, 12.0703])
    drawn = _pose(system_python, script, *map(str, strokes), *map(str, stage), "--tool", "2")
    machine = load_machine("patel2020")
    with_tool = machine.with_tool_length(machine.geometry.gauge_offset + 71.25)      # T2 of the table
    expected = vismach_scene(with_tool, strokes, stage, tool_diameter=8.0).as_dict()
    assert drawn.keys() == expected.keys()
    assert drawn["kinds"] == expected["kinds"]
    for key in ("cylinders", "radii", "spheres", "platform", "boxes", "tip", "work"):
        assert_allclose(np.array(drawn[key]), np.array(expected[key]), atol=1e-9, err_msg=key)
    # the links end where machine_pose puts the sliders and the spherical joints
    pose = machine_pose(machine, strokes[None], stage[None])
    links = np.array(drawn["cylinders"])[[kind == "link" for kind in drawn["kinds"]]]  # type: ignore[union-attr]
    assert_allclose(links[:, 0], pose.sliders[0], atol=1e-9)
    assert_allclose(links[:, 1], pose.spherical[0], atol=1e-9)


def test_a_tool_not_in_the_table_is_the_machine_s(tmp_path: Path, system_python: str) -> None:
    config = write_config("patel2020-head", str(tmp_path / "sim"))
    drawn = _pose(system_python, config.folder / "prs3_vismach.py", "300", "300", "300", "--tool", "9")
    expected = vismach_scene(load_machine("patel2020-head"), np.array([300.0, 300.0, 300.0])).as_dict()
    assert_allclose(np.array(drawn["tip"]), np.array(expected["tip"]), atol=1e-9)
    assert drawn["box_kinds"] == ["bed"]


def test_the_script_names_the_package_it_uses(tmp_path: Path, system_python: str) -> None:
    config = write_config("patel2020", str(tmp_path / "sim"))
    script = config.folder / "prs3_vismach.py"
    text = script.read_text()
    assert f"PACKAGE = {str(package_folder())!r}\n" in text
    assert (package_folder() / "check" / "vismach_scene.py").is_file()
    script.write_text(text.replace(f"PACKAGE = {str(package_folder())!r}", "PACKAGE = '/nonexistent/prs3_post'"))
    done = subprocess.run([system_python, str(script), "--pose", "300", "300", "300"], capture_output=True,
                          text=True, check=False, env=CLEAN_ENV)
    assert (done.returncode, done.stdout) == (1, "")
    assert done.stderr == ("prs3_vismach.py: prs3-post's package is not at /nonexistent/prs3_post any more: write "
                           "the configuration again (prs3-post linuxcnc-config)\n")


def test_the_hal_file_feeds_the_model(tmp_path: Path) -> None:
    config = write_config("patel2020", str(tmp_path / "sim"))
    assert sorted(config.files) == ["patel2020.hal", "patel2020.ini", "patel2020.toml", "prs3.var",
                                    "prs3_vismach.py", "tool.tbl", "vismach.hal"]
    lines = [line for line in (config.folder / "vismach.hal").read_text().splitlines() if not line.startswith("#")]
    assert lines == [
        "loadusr -Wn prs3-vismach /usr/bin/python3 prs3_vismach.py",
        "net x-pos-fb joint.0.pos-fb => prs3-vismach.stage-x",
        "net y-pos-fb joint.1.pos-fb => prs3-vismach.stage-y",
        "net u-pos-fb joint.2.pos-fb => prs3-vismach.t1",
        "net v-pos-fb joint.3.pos-fb => prs3-vismach.t2",
        "net w-pos-fb joint.4.pos-fb => prs3-vismach.t3",
        "net tool-in-spindle iocontrol.0.tool-number => prs3-vismach.tool-number",
    ]
    assert "\nHALFILE = patel2020.hal\nHALFILE = vismach.hal\n" in config.ini.read_text()
    assert (config.folder / "patel2020.toml").read_text() == (REPO / "postproc" / "machines" /
                                                              "patel2020.toml").read_text()
    without = write_config("patel2020", str(tmp_path / "plain"), vismach=False)
    assert sorted(without.files) == ["patel2020.hal", "patel2020.ini", "prs3.var", "tool.tbl"]


def test_the_model_runs_in_linuxcnc(linuxcnc: None, tmp_path: Path) -> None:
    """LinuxCNC starts the configuration with its model (under Xvfb, through `sim --screenshot`), and the
    picture shows the machine: the orange links, the blue sliders and the green platform. Optional like the
    screenshot itself: skipped without xvfb-run."""
    import shutil

    from click.testing import CliRunner
    from PIL import Image

    from prs3_post.cli.main import main

    if shutil.which("xvfb-run") is None:
        pytest.skip("no xvfb-run (apt-get install xvfb)")
    shot = tmp_path / "end.png"
    program = REPO / "fixtures" / "golden" / "wedge-hole-case2a.ngc"
    result = CliRunner().invoke(main, ["sim", str(program), "--feed-override", "10", "--screenshot", str(shot)])
    assert result.exit_code == 0, result.output
    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    red, green, blue = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    assert ((red > 150) & (green > 60) & (green < 180) & (blue < 70)).sum() > 100          # links
    assert ((blue > 150) & (red < 100)).sum() > 100                                       # sliders
    assert ((green > 120) & (red < 120) & (blue < 120)).sum() > 50                        # platform


def test_a_machine_name_cannot_end_the_script_s_docstring(tmp_path: Path) -> None:
    name = 'x"""\nopen("PWNED", "w")\n"""'                    # a file name: the machine's name
    shutil.copy(REPO / "postproc" / "machines" / "patel2020.toml", tmp_path / f"{name}.toml")
    config = write_config(str(tmp_path / f"{name}.toml"), str(tmp_path / "sim"))
    tree = ast.parse((config.folder / "prs3_vismach.py").read_text(encoding="utf-8"))
    assert ast.get_docstring(tree, clean=False).startswith(  # type: ignore[union-attr]
        "The vismach model of the 3-PRS machine x''' open('PWNED', 'w') ''', written by prs3-post")
    assert [ast.unparse(node) for node in ast.walk(tree) if isinstance(node, ast.Call) and "PWNED" in ast.unparse(node)
            ] == ["os.path.join(HERE, 'x____open__PWNED____w______.toml')"]        # the machine file's copy only
    assert next(ast.literal_eval(node.value) for node in tree.body if isinstance(node, ast.Assign)
                and ast.unparse(node.targets[0]) == "NAME") == name
    hal = (config.folder / "vismach.hal").read_text(encoding="utf-8").splitlines()
    assert hal[0] == '# The vismach model of x""" open("PWNED", "w") """: a window showing the machine at the joints\''
