"""The command line is a thin front end: its modules import only the use cases (``app``) and the
core, and each stays a readable size."""

from __future__ import annotations

import ast
from pathlib import Path

CLI = Path(__file__).resolve().parents[1] / "src" / "prs3_post" / "cli"
#: What the command line may import from the package.
ALLOWED = ("prs3_post.app", "prs3_post.core", "prs3_post.cli")


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every module of the package ``path`` imports (anywhere: top level, functions, TYPE_CHECKING), with its line."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] if node.module != "prs3_post" else [f"prs3_post.{a.name}" for a in node.names]
            found += [(node.lineno, name) for name in names]
        elif isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            found.append((node.lineno, "prs3_post.cli"))        # relative: within cli/
    return [(line, name) for line, name in found if name.split(".")[0] == "prs3_post"]


def test_the_cli_imports_only_app_and_core():
    wrong = [f"{path.name}:{line}: {name}" for path in sorted(CLI.glob("*.py")) for line, name in _imports(path)
             if name != "prs3_post" and not name.startswith(tuple(p + "." for p in ALLOWED)) and name not in ALLOWED]
    assert wrong == []


def test_the_cli_modules_are_under_900_lines():
    sizes = {path.name: len(path.read_text(encoding="utf-8").splitlines()) for path in CLI.glob("*.py")}
    assert {name: size for name, size in sizes.items() if size >= 900} == {}
