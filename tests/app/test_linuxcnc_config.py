"""`linuxcnc-config`: the LinuxCNC configuration's values are the machine file's, exactly.

The INI is read back with a small reader (LinuxCNC's INI repeats keys, which configparser refuses) and,
where LinuxCNC is installed, with LinuxCNC's own INI reader under the system Python.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from prs3_post.app.linuxcnc_config import config_files, tool_table_text, write_config
from prs3_post.core.errors import ConfigError, FieldError, InputError
from prs3_post.machine.loading import load_machine
from prs3_post.readers.tooltable import read_tool_table

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "fixtures" / "jobs" / "tools.tbl"
MACHINES = REPO / "postproc" / "machines"


def read_ini(path: Path) -> dict[str, dict[str, list[str]]]:
    """{section: {key: [values in order]}} of a LinuxCNC INI file (comments skipped)."""
    sections: dict[str, dict[str, list[str]]] = {}
    current: dict[str, list[str]] = {}
    for raw in path.read_text(encoding="utf-8").splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("["):
            current = sections.setdefault(line.strip("[]"), {})
            continue
        key, _, value = line.partition("=")
        current.setdefault(key.strip(), []).append(value.strip())
    return sections


def value(ini: dict[str, dict[str, list[str]]], section: str, key: str) -> str:
    (found,) = ini[section][key]
    return found


def test_the_ini_has_the_machine_s_joints_limits_and_speeds(tmp_path: Path) -> None:
    config = write_config("patel2020", str(tmp_path / "sim"), vismach=False)
    assert config.ini == tmp_path / "sim" / "patel2020.ini"
    assert sorted(config.files) == ["patel2020.hal", "patel2020.ini", "prs3.var", "tool.tbl"]
    ini = read_ini(config.ini)
    assert value(ini, "KINS", "KINEMATICS") == "trivkins coordinates=XYUVW"
    assert value(ini, "KINS", "JOINTS") == "5"
    assert value(ini, "TRAJ", "COORDINATES") == "XYUVW"
    assert value(ini, "TRAJ", "LINEAR_UNITS") == "mm"
    assert value(ini, "DISPLAY", "DISPLAY") == "axis"
    assert value(ini, "DISPLAY", "MAX_FEED_OVERRIDE") == "2.000"
    assert value(ini, "EMCIO", "TOOL_TABLE") == "tool.tbl"
    assert value(ini, "RS274NGC", "PARAMETER_FILE") == "prs3.var"
    assert ini["HAL"]["HALFILE"] == ["patel2020.hal"]
    machine = load_machine("patel2020")
    assert machine.dynamics is not None
    expected = {"X": (machine.stage.travel_x, machine.dynamics.stage_speed, machine.dynamics.stage_accel),
                "Y": (machine.stage.travel_y, machine.dynamics.stage_speed, machine.dynamics.stage_accel)}
    expected |= dict.fromkeys("UVW", (machine.limits.stroke, machine.dynamics.stroke_speed,
                                      machine.dynamics.stroke_accel))
    for joint, letter in enumerate("XYUVW"):
        (low, high), speed, accel = expected[letter]
        for section in (f"AXIS_{letter}", f"JOINT_{joint}"):
            assert float(value(ini, section, "MIN_LIMIT")) == low
            assert float(value(ini, section, "MAX_LIMIT")) == high
            assert float(value(ini, section, "MAX_VELOCITY")) == speed / 60.0      # mm/min → mm/s
            assert float(value(ini, section, "MAX_ACCELERATION")) == accel
        assert value(ini, f"JOINT_{joint}", "HOME_SEQUENCE") == "0"
        assert value(ini, f"JOINT_{joint}", "HOME_SEARCH_VEL") == "0"
        assert float(value(ini, f"JOINT_{joint}", "HOME")) == 0.0
    # the values themselves, as written
    assert (value(ini, "AXIS_U", "MIN_LIMIT"), value(ini, "AXIS_U", "MAX_LIMIT")) == ("-100.000", "400.000")
    assert value(ini, "AXIS_U", "MAX_VELOCITY") == "83.33333333333333"
    assert value(ini, "AXIS_X", "MAX_VELOCITY") == "166.66666666666666"
    # every axis at its top speed at once: sqrt(2·166.67² + 3·83.33²)
    assert value(ini, "TRAJ", "MAX_LINEAR_VELOCITY") == "276.3853991962833"
    assert value(ini, "TRAJ", "MAX_LINEAR_ACCELERATION") == "1658.3123951777"


def test_the_hal_file_loops_every_joint_back(tmp_path: Path) -> None:
    config = write_config("patel2020", str(tmp_path / "sim"))
    lines = [line for line in (config.folder / "patel2020.hal").read_text().splitlines()
             if line and not line.startswith("#")]
    assert lines == [
        "loadrt [KINS]KINEMATICS",
        "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
        "addf motion-command-handler servo-thread",
        "addf motion-controller servo-thread",
        "net x-pos-cmd joint.0.motor-pos-cmd => joint.0.motor-pos-fb",
        "net y-pos-cmd joint.1.motor-pos-cmd => joint.1.motor-pos-fb",
        "net u-pos-cmd joint.2.motor-pos-cmd => joint.2.motor-pos-fb",
        "net v-pos-cmd joint.3.motor-pos-cmd => joint.3.motor-pos-fb",
        "net w-pos-cmd joint.4.motor-pos-cmd => joint.4.motor-pos-fb",
        "net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in",
        "net tool-prepare-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared",
        "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed",
    ]


def test_a_head_without_a_stage_has_three_joints(tmp_path: Path) -> None:
    config = write_config("patel2020-head", str(tmp_path / "head"))
    ini = read_ini(config.ini)
    assert value(ini, "KINS", "KINEMATICS") == "trivkins coordinates=UVW"
    assert value(ini, "KINS", "JOINTS") == "3"
    assert [axis.letter for axis in config.axes] == ["U", "V", "W"]
    assert "AXIS_X" not in ini and "JOINT_3" not in ini
    assert float(value(ini, "JOINT_0", "MIN_LIMIT")) == -100.0


def test_the_tool_table_is_the_given_one_or_the_machine_s_tool(tmp_path: Path) -> None:
    given = write_config("patel2020", str(tmp_path / "given"), tool_table=str(TOOLS))
    assert (given.folder / "tool.tbl").read_text() == (
        "T1 P1 D6.000 Z52.300 ;6 mm drill\n"
        "T2 P2 D8.000 Z71.250 ;8 mm end mill\n"
        "T7 P7 D10.000 Z80.000 ;10 mm end mill, not used by the example\n")
    own = write_config("patel2020", str(tmp_path / "own"))
    assert (own.folder / "tool.tbl").read_text() == (
        "T1 P1 D6.000 Z55.000 ;the machine's tool: tool_length_mm - gauge_offset_mm of patel2020\n")
    # read back by our reader (LinuxCNC's format): the same tools
    back = read_tool_table(str(given.folder / "tool.tbl"))
    assert [(t.number, t.pocket, t.diameter, t.length) for t in back.tools] == [
        (1, 1, 6.0, 52.3), (2, 2, 8.0, 71.25), (7, 7, 10.0, 80.0)]


def test_a_tool_without_a_pocket_gets_its_number(tmp_path: Path) -> None:
    table = tmp_path / "t.tbl"
    table.write_text("T5 D3 Z40.125\n")
    assert tool_table_text(read_tool_table(str(table)).tools) == "T5 P5 D3.000 Z40.125\n"


def test_a_machine_without_dynamics_gets_the_nominal_speeds(tmp_path: Path) -> None:
    text = (MACHINES / "patel2020.toml").read_text()
    start = text.index("[dynamics]")
    end = text.index("[holder]")
    machine = tmp_path / "slow.toml"
    machine.write_text(text[:start] + text[end:])
    config = write_config(str(machine), str(tmp_path / "sim"))
    ini = read_ini(config.ini)
    assert value(ini, "AXIS_U", "MAX_VELOCITY") == "83.33333333333333"      # 5000 mm/min
    assert value(ini, "AXIS_X", "MAX_VELOCITY") == "83.33333333333333"
    assert value(ini, "AXIS_X", "MAX_ACCELERATION") == "500.000"
    assert "no [dynamics] in the machine file: the nominal 5000 mm/min and 500 mm/s²" in config.ini.read_text()


def test_options_reach_the_ini(tmp_path: Path) -> None:
    config = write_config("patel2020", str(tmp_path / "sim"), display="/opt/run/display.py --quiet",
                          max_feed_override=10.0)
    ini = read_ini(config.ini)
    assert value(ini, "DISPLAY", "DISPLAY") == "/opt/run/display.py --quiet"
    assert value(ini, "DISPLAY", "MAX_FEED_OVERRIDE") == "10.000"


def test_the_joints_home_where_asked_within_their_limits(tmp_path: Path) -> None:
    """`sim` homes the joints at a program's first point: the controller starts there."""
    config = write_config("patel2020", str(tmp_path / "sim"), home=(1.708, -312.5, 27.2803, 161.4444, 480.0))
    ini = read_ini(config.ini)
    assert [value(ini, f"JOINT_{j}", "HOME") for j in range(5)] == ["1.708", "-300.000", "27.2803", "161.4444",
                                                                    "400.000"]
    assert [value(ini, f"JOINT_{j}", "HOME_OFFSET") for j in range(5)] == [
        value(ini, f"JOINT_{j}", "HOME") for j in range(5)]
    assert [axis.home for axis in config.axes] == [1.708, -300.0, 27.2803, 161.4444, 400.0]


@pytest.mark.parametrize(("kwargs", "field", "message"), [
    ({"display": ""}, "display", "give the display program on one line, printable (like 'axis'), got ''"),
    ({"display": "axis\nDISPLAY = x"}, "display",
     "give the display program on one line, printable (like 'axis'), got 'axis\\nDISPLAY = x'"),
    ({"max_feed_override": 0.5}, "max_feed_override", "expected 1 to 100 (1 = 100 %), got 0.5"),
    ({"max_feed_override": float("inf")}, "max_feed_override", "expected 1 to 100 (1 = 100 %), got inf"),
    ({"home": (1.0, 2.0)}, "home", "expected 5 positions (one per joint: XYUVW), got 2"),
])
def test_bad_options_are_refused(kwargs: dict[str, object], field: str, message: str) -> None:
    with pytest.raises(FieldError) as caught:
        config_files(load_machine("patel2020"), "", **kwargs)  # type: ignore[arg-type]
    assert (caught.value.field, str(caught.value)) == (field, message)


def test_a_rotary_letter_is_refused(tmp_path: Path) -> None:
    dialect = tmp_path / "rotary.toml"
    dialect.write_text((REPO / "postproc" / "dialects" / "linuxcnc.toml").read_text()
                       .replace('t1 = "U"', 't1 = "A"'))
    with pytest.raises(ConfigError) as caught:
        write_config("patel2020", str(tmp_path / "sim"), dialect=str(dialect))
    assert str(caught.value) == (
        f"{dialect}: axes: the dialect writes stroke T1 as 'A', which LinuxCNC treats as a rotary axis in degrees: "
        "give a dialect that writes the stage and the strokes with X Y Z U V W")
    assert not (tmp_path / "sim").exists()


def test_a_dialect_s_letters_name_the_joints(tmp_path: Path) -> None:
    dialect = tmp_path / "swapped.toml"
    dialect.write_text((REPO / "postproc" / "dialects" / "linuxcnc.toml").read_text()
                       .replace('t1 = "U"', 't1 = "Z"'))
    config = write_config("patel2020", str(tmp_path / "sim"), dialect=str(dialect))
    ini = read_ini(config.ini)
    assert value(ini, "KINS", "KINEMATICS") == "trivkins coordinates=XYZVW"
    assert float(value(ini, "AXIS_Z", "MAX_LIMIT")) == 400.0


def test_a_full_folder_is_kept_unless_forced(tmp_path: Path) -> None:
    folder = tmp_path / "sim"
    folder.mkdir()
    (folder / "mine.txt").write_text("keep")
    with pytest.raises(InputError) as caught:
        write_config("patel2020", str(folder))
    assert str(caught.value) == f"{folder}: exists and is not empty: give a new or empty folder, or --force to " \
                                "replace it"
    assert sorted(p.name for p in folder.iterdir()) == ["mine.txt"]
    write_config("patel2020", str(folder), force=True)
    assert sorted(p.name for p in folder.iterdir()) == ["patel2020.hal", "patel2020.ini", "patel2020.toml", "prs3.var",
                                                        "prs3_vismach.py", "tool.tbl", "vismach.hal"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sim"]                  # no temp folder left


def test_an_empty_folder_is_filled(tmp_path: Path) -> None:
    (tmp_path / "sim").mkdir()
    write_config("patel2020", str(tmp_path / "sim"))
    assert (tmp_path / "sim" / "patel2020.ini").is_file()


def test_a_folder_holding_an_input_is_not_replaced(tmp_path: Path) -> None:
    folder = tmp_path / "sim"
    folder.mkdir()
    tools = folder / "tools.tbl"
    shutil.copy(TOOLS, tools)
    with pytest.raises(InputError) as caught:
        write_config("patel2020", str(folder), tool_table=str(tools), force=True)
    assert str(caught.value) == (f"{folder}: holds the input {tools}: replacing the folder would destroy it "
                                 "(give another folder)")
    assert tools.read_text() == TOOLS.read_text()


def test_machine_file_errors_write_nothing(tmp_path: Path) -> None:
    bad = REPO / "fixtures" / "bad" / "machines" / "cannot_assemble.toml"
    with pytest.raises(ConfigError) as caught:
        write_config(str(bad), str(tmp_path / "sim"))
    assert str(caught.value) == bad.read_text().splitlines()[0].removeprefix("# expect: ").replace(
        "machines/cannot_assemble.toml", str(bad))
    assert not (tmp_path / "sim").exists()


def test_the_ini_reads_in_linuxcnc(tmp_path: Path) -> None:
    """LinuxCNC's own INI reader (its Python module, under the system Python) finds what we wrote."""
    probe = subprocess.run(["/usr/bin/python3", "-c", "import linuxcnc"], capture_output=True, check=False) \
        if os.path.exists("/usr/bin/python3") else None
    if probe is None or probe.returncode != 0:
        if os.environ.get("CI"):
            pytest.fail("LinuxCNC's Python module must be installed in CI (apt-get install linuxcnc-uspace)")
        pytest.skip("LinuxCNC is not installed")
    config = write_config("patel2020", str(tmp_path / "sim"), vismach=False)
    script = ("import linuxcnc, sys; ini = linuxcnc.ini(sys.argv[1]); "
              "print(ini.find('KINS', 'JOINTS'), ini.find('TRAJ', 'COORDINATES'), ini.find('JOINT_2', 'MAX_LIMIT'), "
              "ini.findall('HAL', 'HALFILE'))")
    done = subprocess.run(["/usr/bin/python3", "-c", script, str(config.ini)], capture_output=True, text=True,
                          check=True)
    assert done.stdout == "5 XYUVW 400.000 ['patel2020.hal']\n"


def test_file_names_have_no_blanks(tmp_path: Path) -> None:
    machine = tmp_path / "my machine (2).toml"
    shutil.copy(MACHINES / "patel2020.toml", machine)
    config = write_config(str(machine), str(tmp_path / "sim"))
    assert sorted(config.files) == ["my_machine__2_.hal", "my_machine__2_.ini", "my_machine__2_.toml", "prs3.var",
                                    "prs3_vismach.py", "tool.tbl", "vismach.hal"]
    assert read_ini(config.ini)["HAL"]["HALFILE"] == ["my_machine__2_.hal", "vismach.hal"]


def test_a_name_or_description_with_a_newline_stays_on_its_line(tmp_path: Path) -> None:
    machine = tmp_path / "a\n[EMC]\nb.toml"                     # each would start a section of its own
    text = (MACHINES / "patel2020.toml").read_text(encoding="utf-8")
    machine.write_text(text.replace('description = "', 'description = "x\\n[HAL]\\nHALFILE = evil.hal\\r '),
                       encoding="utf-8")
    config = write_config(str(machine), str(tmp_path / "sim"))
    ini = read_ini(config.ini)
    assert (ini["EMC"]["MACHINE"], ini["HAL"]["HALFILE"]) == (["prs3-post a [EMC] b"],
                                                                ["a__EMC__b.hal", "vismach.hal"])
    lines = Path(config.ini).read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("# LinuxCNC configuration of the machine a [EMC] b (x [HAL] HALFILE = evil.hal  Patel")
    assert [ln for ln in lines if ln.startswith("[")].count("[EMC]") == 1
    hal = (tmp_path / "sim" / "a__EMC__b.hal").read_text(encoding="utf-8").splitlines()
    assert hal[0].startswith("# Simulated drives of a [EMC] b: the motion controller")
    tools = (tmp_path / "sim" / "tool.tbl").read_text(encoding="utf-8").splitlines()
    assert [ln for ln in tools if not ln.startswith("T")] == []
