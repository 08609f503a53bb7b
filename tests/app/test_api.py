"""The Python API: ``prs3_post`` re-exports the use cases, cheaply, and docs/api.md's example runs as shown."""

from __future__ import annotations

import contextlib
import inspect
import io
import json
import re
import subprocess
import sys
from pathlib import Path

import prs3_post

REPO = Path(__file__).resolve().parents[2]
API_DOC = REPO / "docs" / "api.md"


def _blocks(language: str) -> list[str]:
    """The fenced ``language`` blocks of docs/api.md, in order."""
    return re.findall(rf"```{language}\n(.*?)```", API_DOC.read_text(), flags=re.DOTALL)


def test_the_documented_example_prints_the_documented_program():
    """The example is run verbatim from the markdown, and prints the program shown below it."""
    (example,), (shown,) = _blocks("python"), _blocks("text")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(example, str(API_DOC), "exec"), {"__name__": "api_example"})
    assert printed.getvalue() == shown


def test_every_public_name_resolves_with_a_docstring_and_typed_parameters():
    for name in prs3_post.__all__:
        value = getattr(prs3_post, name)
        if name == "__version__":
            continue
        assert inspect.getdoc(value), name
        if inspect.isfunction(value):
            signature = inspect.signature(value)
            assert signature.return_annotation is not inspect.Signature.empty, name
            assert all(p.annotation is not inspect.Parameter.empty for p in signature.parameters.values()), name


def test_an_unknown_name_is_an_attribute_error():
    try:
        prs3_post.no_such_thing  # noqa: B018
    except AttributeError as error:
        assert "no_such_thing" in str(error)
    else:
        raise AssertionError("no AttributeError")


def test_importing_the_package_loads_nothing_else():
    """The use cases load when first used: ``import prs3_post`` costs no numpy, no click."""
    probe = "import json, sys; import prs3_post; print(json.dumps(sorted(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    loaded = set(json.loads(done.stdout))
    assert {name for name in loaded if name.startswith("prs3_post")} == {"prs3_post", "prs3_post.core",
                                                                         "prs3_post.core.version"}
    assert not loaded & {"numpy", "click"}


def test_ik_and_fk_on_arrays_round_trip():
    tip = [[-81.0264, 21.2132, -679.4865], [0.0, 0.0, -680.0]]
    axis = [[0.447214, 0.0, 0.894427], [0.0, 0.0, 1.0]]
    ik = prs3_post.inverse_kinematics(tip, axis)
    assert ik.strokes.shape == (2, 3) and ik.reachable.all()
    fk = prs3_post.forward_kinematics(ik.strokes, ik.stage)
    import numpy as np

    np.testing.assert_allclose(fk.tip, np.array(tip), atol=1e-6)


def test_verify_program_file_checks_a_program_with_its_header_tolerance(tmp_path):
    from click.testing import CliRunner

    from prs3_post.cli.main import main

    program = tmp_path / "hole.ngc"
    made = CliRunner().invoke(main, ["demo", "--profile", "hole", "--tolerance", "0.005", "-o", str(program)])
    assert made.exit_code == 0, made.output
    report = prs3_post.verify_program_file(str(program))
    assert report.ok
    assert report.tolerance == 0.005


def test_post_part_is_the_main_job():
    from click.testing import CliRunner

    from prs3_post.cli.main import main
    from prs3_post.cli.options import demo_part

    made = CliRunner().invoke(main, ["demo", "--profile", "round", "--diameter", "20", "--depth", "1.5"])
    assert made.exit_code == 0, made.output
    posted = prs3_post.post_part(str(demo_part()), profile="round", operation={"diameter": 20.0, "depth": 1.5})
    assert posted == made.stdout
