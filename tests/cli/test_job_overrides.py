"""`prs3-post job` takes the main job's machine, dialect, setup, preview and collision options: the job
file and the command line build the same request, and an option replaces what the file says."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.app.requests import job_request
from prs3_post.app.run import run_job_file
from prs3_post.cli.main import main
from prs3_post.core.errors import FieldError

REPO = Path(__file__).resolve().parents[2]
JOBS = REPO / "fixtures" / "jobs"
EXAMPLE = JOBS / "example.toml"


def _job(tmp_path: Path, *args: str, text: str | None = None) -> str:
    """The program of `prs3-post job` on the example (or on ``text``, a job file beside it) with ``args``."""
    job = EXAMPLE
    if text is not None:
        job = JOBS / f"_override_{tmp_path.name}.toml"
        job.write_text(text, encoding="utf-8")
    out = tmp_path / "out.ngc"
    try:
        result = CliRunner().invoke(main, ["job", str(job), "-o", str(out), *args])
    finally:
        if text is not None:
            job.unlink()
    assert result.exit_code == 0, result.output
    return out.read_text(encoding="utf-8")


EDITS = {
    "--dialect": ("fanuc", ('tool_table = "tools.tbl"\n', 'tool_table = "tools.tbl"\ndialect = "fanuc"\n')),
    "--part-origin": ("-90,-200,-970", ("part_origin = [-100.0, -200.0, -970.0]",
                                        "part_origin = [-90.0, -200.0, -970.0]")),
    "--part-rotation": ("2", ("part_rotation_deg = 0.0", "part_rotation_deg = 2.0")),
}


@pytest.mark.parametrize("flag", list(EDITS))
def test_an_override_makes_the_program_of_the_job_file_that_says_it(tmp_path: Path, flag: str) -> None:
    value, (old, new) = EDITS[flag]
    text = EXAMPLE.read_text(encoding="utf-8")
    assert old in text
    overridden = _job(tmp_path, f"{flag}={value}")
    assert overridden == _job(tmp_path, text=text.replace(old, new, 1))
    assert overridden != _job(tmp_path)


def test_the_dialect_override_changes_the_header(tmp_path: Path) -> None:
    lines = _job(tmp_path, "--dialect", "fanuc").splitlines()
    assert any(line.startswith("(dialect: fanuc") or line.startswith("(DIALECT: FANUC") for line in lines)


def test_no_collision_check_is_said_in_the_header(tmp_path: Path) -> None:
    checked, skipped = _job(tmp_path), _job(tmp_path, "--no-collision-check")
    assert checked != skipped
    assert "(collision: not checked [asked not to])" in skipped.splitlines()


def test_the_machine_override_is_the_machine_used(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["job", str(EXAMPLE), "--machine", "patel2020-head", "-o",
                                       str(tmp_path / "out.ngc")])
    assert result.exit_code != 0                  # the head alone cannot make this job: its limits said so
    assert "patel2020-head" in result.output


def test_the_preview_override_draws_the_job(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    image = tmp_path / "job.svg"
    _job(tmp_path, "--preview", str(image))
    assert image.read_text(encoding="utf-8").lstrip().startswith("<?xml")


def test_the_api_runs_a_job_file_with_the_same_overrides(tmp_path: Path) -> None:
    assert run_job_file(str(EXAMPLE), dialect="fanuc") == _job(tmp_path, "--dialect", "fanuc")


def test_a_request_names_the_key_of_a_bad_value() -> None:
    data = {"part": "p.stl", "operation": [{"profile": "hole"}, {"profile": "round", "depth": "deep"}]}
    with pytest.raises(FieldError) as caught:
        job_request(data)
    assert (caught.value.field, caught.value.operation) == ("depth", 2)
    assert str(caught.value) == "expected a number, got 'deep'"
