"""The reference pages that are generated from the code are current, and the hand-written ones name
every key the loaders read."""

from __future__ import annotations

import importlib.util
import re
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
REFERENCE = REPO / "docs" / "reference"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_command_reference_is_current() -> None:
    """docs/reference/cli.md is what scripts/make_cli_reference.py writes from the click commands now."""
    script = _script("make_cli_reference")
    assert script.TARGET.read_text(encoding="utf-8") == script.render(), (
        "docs/reference/cli.md is stale: run python scripts/make_cli_reference.py and commit it")


def test_the_command_reference_has_every_command_and_option() -> None:
    from prs3_post.cli.main import main as group

    text = (REFERENCE / "cli.md").read_text(encoding="utf-8")
    for name, command in group.commands.items():
        assert f"## `prs3-post {name}`" in text
        for param in command.params:
            for opt in getattr(param, "opts", []):
                if opt.startswith("-") and not getattr(param, "hidden", False):
                    assert opt in text, f"{name} {opt}"


def test_the_cam_word_reference_is_current() -> None:
    script = _script("make_cam_reference")
    assert script.TARGET.read_text(encoding="utf-8") == script.render(), (
        "docs/reference/cam-words.md is stale: run python scripts/make_cam_reference.py and commit it")


def _keys(table: dict, prefix: str = "") -> set[str]:
    found = set()
    for key, value in table.items():
        if isinstance(value, dict):
            found |= _keys(value, f"{prefix}{key}.")
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for item in value:
                found |= _keys(item, f"{prefix}{key}.")
        else:
            found.add(f"{prefix}{key}")
    return found


def _documented(page: str) -> str:
    return (REFERENCE / page).read_text(encoding="utf-8")


def test_every_key_of_the_shipped_files_is_documented() -> None:
    """Each key of every shipped machine, dialect and source file (and the example machine files of
    fixtures/machines/) is named on its reference page (as `key`)."""
    missing = []
    for folder, page in (("machines", "machine-file.md"), ("dialects", "dialect-file.md"),
                         ("sources", "source-file.md")):
        text = _documented(page)
        examples = sorted((REPO / "fixtures" / folder).glob("*.toml")) if folder == "machines" else []
        for path in [*sorted((REPO / "postproc" / folder).glob("*.toml")), *examples]:
            for key in _keys(tomllib.loads(path.read_text(encoding="utf-8"))):
                if folder == "dialects" and key.startswith("comments.replace."):
                    continue                      # its keys are data (characters)
                leaf = key.rsplit(".", 1)[-1]
                if not re.search(rf"`{re.escape(leaf)}`", text):
                    missing.append(f"{page}: {key} (from {path.name})")
    assert missing == []


def test_every_job_file_key_is_documented() -> None:
    from prs3_post.readers.jobfile import OPERATION_KEYS, TOP_KEYS

    text = _documented("job-file.md")
    missing = [key for key in (*TOP_KEYS, *OPERATION_KEYS, "part_origin", "part_rotation_deg")
               if f"`{key}`" not in text and f"`[[{key}]]`" not in text and f"`[{key}]`" not in text]
    assert missing == []
