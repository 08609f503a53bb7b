"""The house's rules, checked on the source with ``ast`` (docs/architecture.md draws them).

Every module of ``src/prs3_post`` belongs to one package of a layer; a module imports only from its
own package or from a lower layer (function-level imports count as much as top-level ones), the
imports form no circle, no module is over 900 lines, and the command line (``cli/``) reaches the
library only through ``app/`` and ``core/``.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "prs3_post"

#: The packages, bottom to top; packages on one line are one layer and do not import each other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("machine",),
    ("kinematics", "part"),
    ("toolpaths", "post"),
    ("readers", "emit", "check"),
    ("app",),
    ("cli",),
)
LAYER_OF = {package: level for level, packages in enumerate(LAYERS) for package in packages}
MAX_LINES = 900


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports() -> dict[str, set[str]]:
    """Each module's imports of other prs3_post modules (``from prs3_post.x import y`` counts ``x.y``
    when that is a module, else ``x``)."""
    modules = {_module_name(path): path for path in SRC.rglob("*.py")}
    found: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "prs3_post":
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    targets.add(sub if sub in modules else node.module)
            elif isinstance(node, ast.Import):
                targets.update(a.name for a in node.names if a.name.split(".")[0] == "prs3_post")
        found[name] = {target for target in targets if target != name and target in modules}
    return found


def _package(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def test_every_package_has_a_layer() -> None:
    packages = {path.name for path in SRC.iterdir() if path.is_dir() and (path / "__init__.py").exists()}
    assert packages == set(LAYER_OF)


def test_no_import_reaches_up_or_sideways() -> None:
    wrong = []
    for module, targets in sorted(_imports().items()):
        here = _package(module)
        for target in sorted(targets):
            there = _package(target)
            if here is None or there is None or here == there:
                continue
            if LAYER_OF[there] >= LAYER_OF[here]:
                wrong.append(f"{module} -> {target}")
    assert wrong == []


def _circles(arrows: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected groups of more than one module (Tarjan's algorithm, without recursion)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups = []
    for root in sorted(arrows):
        if root in index:
            continue
        work = [(root, iter(sorted(arrows[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(arrows[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                group = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    group.append(member)
                    if member == node:
                        break
                if len(group) > 1:
                    groups.append(sorted(group))
    return groups


def test_the_circle_finder_finds_a_circle() -> None:
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_circles() -> None:
    assert _circles(_imports()) == []


def test_the_command_line_reaches_only_app_and_core() -> None:
    wrong = sorted(f"{module} -> {target}" for module, targets in _imports().items()
                   if _package(module) == "cli"
                   for target in targets if _package(target) not in ("cli", "app", "core", None))
    assert wrong == []


def test_no_module_is_over_900_lines() -> None:
    long = sorted(f"{path.relative_to(SRC)}: {n}" for path in SRC.rglob("*.py")
                  if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES)
    assert long == []
