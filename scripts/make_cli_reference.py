"""Write docs/reference/cli.md from the click command tree: every command, its usage, its help text
and every option with its value and default, exactly as `prs3-post COMMAND --help` gives them.

Run from anywhere:  python scripts/make_cli_reference.py        (--check: exit 1 if the file is stale)

tests/docs/test_docs_reference.py fails when the file differs from what this script writes, so the
reference never drifts from the code: after changing an option, run this and commit the result.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from prs3_post.cli.main import main as group

ROOT = Path(__file__).resolve().parents[1]
TARGET = ROOT / "docs" / "reference" / "cli.md"
WIDTH = 100

HEAD = """# Command reference

Every command and option, generated from the command-line code by `scripts/make_cli_reference.py`
(a test fails when this page is stale). `prs3-post COMMAND --help` prints the same. The options'
spellings across commands follow one scheme: the part is the positional `PART` where it is the
command's subject (`run`, `faces`) and `--part` where it is an extra input; `-o/--output` is one
file. Every command takes `-q/--quiet` (errors only on standard error), `-v/--verbose` (the setup,
face, files and settings used, and each stage's time) and `-h/--help`; `prs3-post -V` prints the
version. [The main job's options by group](main-job.md) and [the exit codes](exit-codes.md)
explain them in words.
"""


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _command(name: str, command: click.Command, parent: click.Context) -> str:
    ctx = click.Context(command, info_name=name, parent=parent, terminal_width=WIDTH, max_content_width=WIDTH)
    formatter = ctx.make_formatter()
    command.format_usage(ctx, formatter)
    command.format_help_text(ctx, formatter)
    lines = [f"## `prs3-post {name}`", "", "```text", formatter.getvalue().rstrip(), "```", ""]
    records = [(param, param.get_help_record(ctx)) for param in command.get_params(ctx)]
    rows = [record for param, record in records if isinstance(param, click.Option) and record is not None]
    if rows:
        lines += ["| option | meaning |", "|---|---|"]
        lines += [f"| `{_cell(names)}` | {_cell(meaning)} |" for names, meaning in rows]
        lines.append("")
    return "\n".join(lines)


def render() -> str:
    settings = {**group.context_settings, "terminal_width": WIDTH, "max_content_width": WIDTH}
    root = click.Context(group, info_name="prs3-post", **settings)
    parts = [HEAD, _command_group(root)]
    for name in sorted(group.list_commands(root)):
        command = group.get_command(root, name)
        if command is not None and not command.hidden:
            parts.append(_command(name, command, root))
            if isinstance(command, click.Group):          # calibrate: its commands too (identify, plan)
                parts += [_command(f"{name} {sub}", command.commands[sub], root) for sub in sorted(command.commands)]
    return "\n".join(parts).rstrip() + "\n"


def _command_group(root: click.Context) -> str:
    formatter = root.make_formatter()
    group.format_help(root, formatter)
    return "\n".join(["## `prs3-post`", "", "```text", formatter.getvalue().rstrip(), "```", ""])


def main(argv: list[str]) -> int:
    text = render()
    if "--check" in argv:
        if TARGET.read_text(encoding="utf-8") != text:
            print(f"{TARGET.relative_to(ROOT)} is stale: run python scripts/make_cli_reference.py", file=sys.stderr)
            return 1
        return 0
    TARGET.write_text(text, encoding="utf-8")
    print(f"wrote {TARGET.relative_to(ROOT)} ({len(text.splitlines())} lines)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
