"""The README shows real output: its program excerpt is what the main command prints today."""

from __future__ import annotations

import re
from pathlib import Path

from click.testing import CliRunner

from prs3_post.cli.main import main

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_program_excerpt_is_the_demo_output():
    text = README.read_text(encoding="utf-8")
    block = re.search(r"writes:\n\n```\n(.*?)\n```", text, re.S)
    assert block is not None, "README lost its program excerpt"
    shown = block.group(1).splitlines()
    assert shown[-1] == "..."
    result = CliRunner().invoke(main, ["demo", "--profile", "square"])
    assert result.exit_code == 0
    assert result.stdout.splitlines()[: len(shown) - 1] == shown[:-1]


def test_readme_has_the_two_setup_commands_ci_runs():
    text = README.read_text(encoding="utf-8")
    setup = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    commands = [line.strip() for line in setup.splitlines() if line.startswith("    ")]
    assert len(commands) == 2
    assert "prs3-post demo" in commands[0]
    ci = (README.parent / ".ci" / "run").read_text(encoding="utf-8")
    assert commands[1] in ci.splitlines()     # CI runs the README's test command verbatim
