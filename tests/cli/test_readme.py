"""The README shows real output: its program excerpt is what the main command prints today."""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

from prs3_post.cli.main import main

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_program_excerpt_is_the_demo_output():
    """The program the README shows begins exactly as the demo's does (its first lines, up to the first
    ``...``, line for line; tests/docs/test_docs_commands.py checks the lines after it in order)."""
    text = README.read_text(encoding="utf-8")
    block = re.search(r"```console\n\$ prs3-post demo --profile square\n(.*?)\n```", text, re.S)
    assert block is not None, "README lost its program excerpt"
    shown = block.group(1).splitlines()
    head = shown[: shown.index("...")]
    assert len(head) >= 6
    result = CliRunner().invoke(main, ["demo", "--profile", "square"])
    assert result.exit_code == 0
    assert result.stdout.splitlines()[: len(head)] == head


def test_readme_has_the_two_setup_commands_ci_runs():
    text = README.read_text(encoding="utf-8")
    setup = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    commands = [line.strip() for line in setup.splitlines() if line.startswith("    ")]
    assert len(commands) == 2
    assert "prs3-post demo" in commands[0]
    ci = (README.parent / ".ci" / "run").read_text(encoding="utf-8")
    assert commands[1] in ci.splitlines()     # CI runs the README's test command verbatim


def test_readme_stays_short():
    """The README is the front page (a picture, what the tool is, set-up, commands, exit codes, where
    next): at most 200 lines; the rest belongs in docs/."""
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines: move sections to docs/"
    assert lines[2].startswith("![")                    # the picture comes first
