"""``--json`` on run, demo, job, machines and sources (issue 20 §2): one JSON object on standard output,
made from what the job itself found (its header's values, the margins tallied as it was posted), and
the program in the file -o names. Each value is checked against what the program's header or `verify`
says of the same program."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
JOB = REPO / "fixtures" / "jobs" / "example.toml"


def invoke(*args: str):
    return CliRunner().invoke(main, list(args), prog_name="prs3-post")


def _header(program: Path, key: str) -> str:
    """The value of a header entry: ``(key: value)``."""
    for line in program.read_text().splitlines():
        if line.startswith(f"({key}: "):
            return line[len(key) + 3:-1]
    raise AssertionError(f"no {key} entry")


def test_demo_json_states_what_the_header_states(tmp_path: Path) -> None:
    out = tmp_path / "sq.ngc"
    result = invoke("demo", "--profile", "square", "-o", str(out), "--json")
    assert result.exit_code == 0, result.stderr
    record = json.loads(result.stdout)
    text = out.read_text()
    assert record["program"] == {"path": str(out), "lines": text.count("\n"), "bytes": len(text.encode()), "moves": 20}
    assert (record["machine"], record["dialect"]) == ("patel2020", "linuxcnc")
    setup = _header(out, "setup")
    assert setup == "part origin at machine [-100.0000, -200.0000, -970.0000] mm, rotation 0.0000 deg about z"
    assert record["setup"] == {"part_origin_mm": [-100.0, -200.0, -970.0], "part_rotation_deg": 0.0, "chosen": None}
    face = record["faces"][0]
    assert (face["index"], face["asked"], round(face["inclination_deg"], 4)) == (4, "auto", 26.5651)
    assert _header(out, "face").startswith("4, chosen automatically: inclination 26.5651 deg")
    dynamics = _header(out, "dynamics")
    assert dynamics == "cycle time 1.214 min = 72.8 s, no feed slowed by the axis speed limits"
    assert record["header"]["dynamics"] == dynamics
    cycle = record["cycle_time"]
    assert f"{cycle['minutes']:.3f} min = {cycle['seconds']:.1f} s" == "1.214 min = 72.8 s"
    assert record["slowed_moves"] == 0
    assert record["collision"] == {"checked": True, "clearance_min_mm": 1.0, "closest": None}   # all beyond 11 mm
    assert record["header"]["collision"] == _header(out, "collision")
    assert "wrote" in result.stderr


def test_run_json_margins_are_verify_s_closest_approach(tmp_path: Path) -> None:
    """The strokes and the stage move linearly between rows: their closest approach is at a row, the
    one verify names, with the value the program prints (4 decimals)."""
    out = tmp_path / "hole.ngc"
    result = invoke("run", str(REPO / "postproc" / "parts" / "patel2020-wedge.stl"), "--profile", "hole",
                    "--at-xyz", "18.9736,221.2132,290.5135", "-o", str(out), "--json")
    assert result.exit_code == 0, result.stderr
    margins = {m["limit"]: m for m in json.loads(result.stdout)["margins"]}
    verified = invoke("verify", str(out), "--json")
    assert verified.exit_code == 0, verified.stderr
    lines = out.read_text().splitlines()
    for limit in json.loads(verified.stdout)["limits"]:
        mine = margins[limit["limit"]]
        assert (mine["unit"], mine["min"], mine["max"]) == (limit["unit"], limit["min"], limit["max"])
        if limit["unit"] == "mm":                      # strokes and stage: exact at the rows, to the printing
            assert mine["line"] == limit["line"]
            assert mine["value"] == pytest.approx(limit["value"], abs=5e-5)
            assert re.search(rf"\b[UVWXY]{mine['value']:.4f}\b", lines[mine["line"] - 1])
        else:                                          # angles, condition: verify samples between rows too
            assert mine["value"] == pytest.approx(limit["value"], abs=1e-3)
    assert margins["T1 stroke"]["margin"] == pytest.approx(margins["T1 stroke"]["value"] + 100.0, abs=1e-9)


def test_job_json_lists_every_face_and_the_tallied_margins(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    result = invoke("job", str(JOB), "-o", "job.ngc", "--json")
    assert result.exit_code == 0, result.stderr
    record = json.loads(result.stdout)
    text = (tmp_path / "job.ngc").read_text()
    assert [face["index"] for face in record["faces"]] == [int(n) for n in re.findall(
        r"^\(operation \d face: (\d+), ", text, flags=re.MULTILINE)] == [5, 6]
    assert "operation 2: clear of the part by at least 1.000 mm: tool 9.274 mm, " in _header(tmp_path / "job.ngc",
                                                                                             "collision")
    closest = record["collision"]["closest"]
    assert (closest["body"], round(closest["clearance_mm"], 3), closest["exact"]) == ("tool", 9.274, True)
    assert text.splitlines()[closest["line"] - 1].startswith("G")
    verified = json.loads(invoke("verify", "job.ngc", "--json").stdout)
    mine = {m["limit"]: m for m in record["margins"]}
    for limit in verified["limits"]:
        if limit["unit"] == "mm":
            assert mine[limit["limit"]]["value"] == pytest.approx(limit["value"], abs=5e-5), limit["limit"]


@pytest.mark.parametrize("args", [
    ["demo", "--profile", "hole", "--json"],
    ["demo", "--profile", "hole", "--json", "-o", "-"],
    ["job", str(JOB), "--json"],
])
def test_json_needs_the_program_in_a_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, args: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    result = invoke(*args)
    assert (result.exit_code, result.stdout) == (2, "")
    assert result.stderr.splitlines()[-1] == ("Error: --json prints its report on standard output: write the "
                                              "program to a file with -o FILE")
    assert list(tmp_path.iterdir()) == []


def test_json_errors_stay_text_on_standard_error(tmp_path: Path) -> None:
    """A limit failure: exit 1, the usual message, nothing on standard output, no program."""
    out = tmp_path / "far.ngc"
    result = invoke("demo", "--profile", "hole", "--part-origin", "0,0,-300", "-o", str(out), "--json")
    assert (result.exit_code, result.stdout) == (1, "")
    assert result.stderr.startswith("prs3-post: error: ")
    assert not out.exists()


def test_machines_and_sources_json() -> None:
    machines = invoke("machines", "--json")
    assert machines.exit_code == 0, machines.stderr
    listed = {m["name"]: m for m in json.loads(machines.stdout)}
    assert sorted(listed) == ["patel2020", "patel2020-head"]
    paper = listed["patel2020"]
    assert paper["stage"] is True and listed["patel2020-head"]["stage"] is False
    assert paper["kinematics"] == "3-prs"
    assert paper["geometry"]["link_length_mm"] == 482.0
    assert paper["geometry"]["tool_length_mm"] == 175.0
    assert paper["limits"]["stroke_mm"] == [-100.0, 400.0]
    assert paper["limits"]["max_tilt_deg"] == pytest.approx(45.0, abs=1e-12)
    assert paper["stage_travel_mm"] == {"x": [-300.0, 300.0], "y": [-300.0, 300.0]}
    text = invoke("machines").stdout.splitlines()
    assert [line.split()[0] for line in text] == sorted(listed)
    sources = invoke("sources", "--json")
    assert sources.exit_code == 0, sources.stderr
    found = json.loads(sources.stdout)
    assert [s["name"] for s in found] == [line.split()[0] for line in invoke("sources").stdout.splitlines()]
    for source in found:
        assert set(source) == {"name", "description", "words", "vector_words", "tcp_on", "tcp_off", "file"}
