"""Every command the README and docs/ show is run here, and what they show it printing is checked.

The convention (docs/README.md states it for writers):

- A fenced block marked ``console`` holds commands, each on a line that starts with ``$ ``, and below
  each command the lines it prints (standard output and standard error as a terminal shows them),
  or nothing when the output is not the point.
- A shown line must equal a line of the output, except that ``...`` inside it stands for any text;
  a line that is ``...`` alone stands for any number of lines. The shown lines (between ``...``
  lines) must appear in the output in that order, each run of them on consecutive lines.
- A command exits 0 unless it ends with ``# exit N``.
- In a table whose header has an ``example`` column, that column's code spans that start with
  ``prs3-post `` are commands too (exit 0, output not checked): the README's table of commands gives
  one runnable example per command.

The commands of one page run in order in one fresh folder, where ``fixtures/`` and ``postproc/``
(and ``scripts/``) are the repository's (so a page can use the files an earlier command wrote). ``prs3-post`` commands
run in this process through click's test runner; anything else (a pipe, a redirection, ``eval``,
an environment variable, another program) runs in ``bash`` with this environment's ``prs3-post``
first on the PATH. A command of another program that is not installed here is skipped, unless the
``CI`` environment variable is set (then it fails); so is ``prs3-post sim`` where LinuxCNC is not.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from prs3_post.cli.main import main

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted([REPO / "README.md", *(REPO / "docs").rglob("*.md")])
_FENCE = re.compile(r"^```(\S*)\s*$")
_EXIT = re.compile(r"\s+#\s*exit\s+(\d+)\s*$")
_TABLE_COMMAND = re.compile(r"`(prs3-post [^`]+)`")
_SHELL = re.compile(r"[|<>;&$`()*?~]|^\w+=")


@dataclass
class Command:
    page: Path
    line: int
    text: str
    exit_code: int
    shown: list[str]

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO)}:{self.line}"


def commands_of(page: Path) -> list[Command]:
    """The commands of a page, in order: each console block's ``$`` lines and each table's ``prs3-post`` spans."""
    found: list[Command] = []
    fence: str | None = None
    example_column: int | None = None          # in a table: the index of its "example" column
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), start=1):
        opened = _FENCE.match(line)
        if fence is None and opened and line.strip() != "```":
            fence = opened.group(1)
            continue
        if fence is not None and line.strip() == "```":
            fence = None
            continue
        if fence == "console":
            if line.startswith("$ "):
                text = line[2:]
                code = _EXIT.search(text)
                found.append(Command(page, number, text[: code.start()] if code else text,
                                     int(code.group(1)) if code else 0, []))
            elif found and found[-1].line < number:
                found[-1].shown.append(line)
        elif fence is None and line.lstrip().startswith("|"):
            cells = [cell.strip() for cell in line.strip().strip("|").split("|")]
            if example_column is None and "example" in cells:
                example_column = cells.index("example")
            elif example_column is not None and example_column < len(cells):
                found.extend(Command(page, number, span, 0, [])
                             for span in _TABLE_COMMAND.findall(cells[example_column]))
        elif fence is None:
            example_column = None
    return found


def _pattern(shown: str) -> re.Pattern[str]:
    return re.compile(".*".join(re.escape(piece) for piece in shown.split("...")) + r"\Z")


def shown_problem(shown: list[str], output: str) -> str | None:
    """None when the shown lines appear in the output (see the module's docstring), else what is missing."""
    lines = output.splitlines()
    runs: list[list[str]] = [[]]
    for line in shown:
        if line.strip() == "...":
            runs.append([])
        else:
            runs[-1].append(line)
    at = 0
    for run in (r for r in runs if r):
        patterns = [_pattern(line) for line in run]
        start = next((i for i in range(at, len(lines) - len(run) + 1)
                      if all(p.match(lines[i + k]) for k, p in enumerate(patterns))), None)
        if start is None:
            return f"these lines (in this order, one after the other) are not in the output: {run}"
        at = start + len(run)
    return None


def _program(text: str) -> str:
    """The program a shell command line runs (past ``VAR=value`` assignments and ``eval``)."""
    words = [word for word in re.split(r"[\s\"'()$]+", text) if word]
    return next(word for word in words if not re.match(r"\w+=", word) and word not in ("eval", "source"))


def _installed(program: str) -> bool:
    if program == "scripts/rs274-check":          # needs LinuxCNC's interpreter (Debian's linuxcnc-uspace)
        return subprocess.run(["/usr/bin/python3", "-c", "import gcode"], capture_output=True,
                              check=False).returncode == 0 if Path("/usr/bin/python3").exists() else False
    return program == "prs3-post" or program.startswith("scripts/") or shutil.which(program) is not None


def _linuxcnc_installed() -> bool:
    """`prs3-post sim` runs LinuxCNC: its launcher and Debian's python3 with the linuxcnc module."""
    return shutil.which("linuxcnc") is not None and Path("/usr/bin/python3").exists() and subprocess.run(
        ["/usr/bin/python3", "-c", "import linuxcnc"], capture_output=True, check=False).returncode == 0


def _run(command: Command, folder: Path) -> tuple[int, str]:
    if command.text.startswith("prs3-post sim ") and not _linuxcnc_installed():
        if os.environ.get("CI"):
            pytest.fail(f"{command.where}: LinuxCNC is not installed (apt-get install linuxcnc-uspace)")
        return command.exit_code, "\n".join(command.shown)          # not run here: nothing to compare
    if command.text.startswith("prs3-post ") and not _SHELL.search(command.text):
        args = shlex.split(command.text)[1:]
        result = CliRunner().invoke(main, args, prog_name="prs3-post", catch_exceptions=True)
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            raise result.exception
        return result.exit_code, result.output
    program = _program(command.text)
    if not _installed(program):
        if os.environ.get("CI"):
            pytest.fail(f"{command.where}: {program} cannot run here")
        return command.exit_code, "\n".join(command.shown)          # not run here: nothing to compare
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    done = subprocess.run(["bash", "-c", command.text], cwd=folder, env=env, capture_output=True, text=True,
                          timeout=120, check=False)
    return done.returncode, done.stdout + done.stderr


def _page_id(page: Path) -> str:
    return str(page.relative_to(REPO))


@pytest.mark.parametrize("page", [p for p in PAGES if commands_of(p)], ids=_page_id)
def test_every_command_of_the_page_runs_as_shown(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ("fixtures", "postproc", "scripts"):
        (tmp_path / name).symlink_to(REPO / name)
    monkeypatch.chdir(tmp_path)
    for command in commands_of(page):
        code, output = _run(command, tmp_path)
        assert code == command.exit_code, (
            f"{command.where}: `{command.text}` exited {code}, the page says {command.exit_code}:\n{output[-3000:]}")
        problem = shown_problem(command.shown, output)
        assert problem is None, f"{command.where}: `{command.text}`: {problem}\noutput:\n{output[-3000:]}"


def test_the_pages_show_commands() -> None:
    """The convention is in use: the README and the tutorial show commands (and the finder finds them)."""
    assert len(commands_of(REPO / "README.md")) >= 12
    assert len(commands_of(REPO / "docs" / "tutorial.md")) >= 8


def test_the_shown_output_matcher() -> None:
    output = "a\nb 12.5 s\nc\nd\n"
    assert shown_problem(["a", "b ... s"], output) is None
    assert shown_problem(["a", "...", "d"], output) is None
    assert shown_problem(["a", "c"], output) is not None           # not one after the other
    assert shown_problem(["c", "...", "a"], output) is not None    # not in this order
    assert shown_problem(["b"], output) is not None                # a line is matched whole
