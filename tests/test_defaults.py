"""Defaults once: the library's default values live in :mod:`prs3_post.core.defaults` (or in a machine file),
and a new copy of one of them elsewhere in the package is a test failure, not a drift found later.

The package is read with ``ast`` (not grep: docstrings and messages that quote a default are words, not
values). Flagged: a number equal to one of :data:`KNOWN` anywhere in the code, and ``1.0`` where it is a
clearance (a parameter's default, a keyword argument, a field or a fallback named for one).
"""

from __future__ import annotations

import ast
from pathlib import Path

import prs3_post
from prs3_post.core import defaults

PACKAGE = Path(prs3_post.__file__).parent

#: The values a default has been repeated with (the tolerance, the angle and circle tolerances, the nominal
#: rapid rate, the inch), and the name each is defined under.
KNOWN = {defaults.DEFAULT_TOLERANCE: "DEFAULT_TOLERANCE", defaults.DEFAULT_ANGLE_TOLERANCE_DEG:
         "DEFAULT_ANGLE_TOLERANCE_DEG or DEFAULT_CIRCLE_TOLERANCE", defaults.NOMINAL_RAPID_RATE: "NOMINAL_RAPID_RATE",
         defaults.MM_PER_INCH: "MM_PER_INCH"}

#: The constant or function a number is in (in whichever module): why that number is not one of the defaults.
ALLOWED = {
    "FLAT_KEY_MM": "a hash cell size of the collision scan, not a tolerance anyone sets",
    "TRANSLATION_SPREAD": "how alike the three stroke changes of a replayed move are for a translation",
    "TOOL_DIAMETER_RANGE": "the smallest tool diameter accepted, a range bound",
    "render_preview": "a label's offset in the preview's bar chart (a fraction of the axes)",
    "project_onto_face": "how far a job's point may be off its face, a check of that input",
}


def _owner(stack: list[ast.AST]) -> str:
    """The innermost function or module-level constant a node is in ("" at module level otherwise)."""
    for node in reversed(stack):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            return node.name
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            return node.targets[0].id
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            return node.target.id
    return ""


def _owners(tree: ast.AST) -> dict[int, str]:
    """Each constant's owner (:func:`_owner`), by the constant's id."""
    owners: dict[int, str] = {}
    todo: list[tuple[ast.AST, list[ast.AST]]] = [(tree, [])]
    while todo:
        node, stack = todo.pop()
        stack = [*stack, node]
        if isinstance(node, ast.Constant):
            owners[id(node)] = _owner(stack)
        todo += [(child, stack) for child in ast.iter_child_nodes(node)]
    return owners


def _names(node: ast.AST) -> set[str]:
    """Every name and attribute a node mentions."""
    found = set()
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            found.add(sub.id)
        elif isinstance(sub, ast.Attribute):
            found.add(sub.attr)
        elif isinstance(sub, ast.arg):
            found.add(sub.arg)
        elif isinstance(sub, ast.keyword) and sub.arg:
            found.add(sub.arg)
        elif isinstance(sub, ast.Constant) and isinstance(sub.value, str):
            found.add(sub.value)
    return found


def _clearance_ones(tree: ast.AST) -> list[ast.Constant]:
    """``1.0`` as a clearance: a default of a parameter, a keyword argument, a field, a fallback or an
    argument of a call whose name says clearance."""
    found: list[ast.Constant] = []

    def one(node: ast.AST | None) -> bool:
        return isinstance(node, ast.Constant) and type(node.value) is float and node.value == 1.0

    def clearance(names: set[str] | str) -> bool:
        return any("clearance" in name for name in ([names] if isinstance(names, str) else names))

    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            positional = args.posonlyargs + args.args
            pairs = list(zip(positional[len(positional) - len(args.defaults):], args.defaults, strict=True))
            pairs += [(a, d) for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True) if d is not None]
            found += [d for a, d in pairs if one(d) and clearance(a.arg)]
        elif isinstance(node, ast.keyword) and node.arg and one(node.value) and clearance(node.arg):
            found.append(node.value)                                   # type: ignore[arg-type]
        elif isinstance(node, ast.AnnAssign) and one(node.value) and clearance(_names(node.target)):
            found.append(node.value)                                   # type: ignore[arg-type]
        elif isinstance(node, ast.Assign) and one(node.value) and clearance(_names(node.targets[0])):
            found.append(node.value)                                   # type: ignore[arg-type]
        elif isinstance(node, ast.IfExp) and clearance(_names(node.test)):
            found += [b for b in (node.body, node.orelse) if one(b)]   # type: ignore[misc]
        elif isinstance(node, ast.Call) and clearance(_names(node)):   # .get("clearance_min", 1.0), an option's default
            found += [a for a in [*node.args, *(k.value for k in node.keywords)] if one(a)]   # type: ignore[misc]
    return found


def repeated_defaults(root: Path = PACKAGE) -> list[str]:
    """``module:line: value (use NAME)`` for each copy of a default outside core/defaults.py."""
    problems = []
    for path in sorted(root.rglob("*.py")):
        module = path.relative_to(root).as_posix()
        if module == "core/defaults.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        owners = _owners(tree)
        flagged = {id(node): (node, "DEFAULT_CLEARANCE_MIN") for node in _clearance_ones(tree)}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and type(node.value) in (int, float) and node.value in KNOWN
                    and owners.get(id(node), "") not in ALLOWED):
                flagged[id(node)] = (node, KNOWN[node.value])
        problems += [f"{module}:{node.lineno}: {node.value!r} (use core.defaults.{name})"
                     for node, name in sorted(flagged.values(), key=lambda pair: (pair[0].lineno, pair[0].col_offset))]
    return problems


def test_no_default_is_repeated_outside_core_defaults():
    assert repeated_defaults() == []


def test_each_allowed_number_is_still_there():
    """An entry of ALLOWED whose number went away is removed, so the list stays the reasons that hold."""
    seen = set()
    for path in PACKAGE.rglob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        owners = _owners(tree)
        seen |= {owners[id(node)] for node in ast.walk(tree) if isinstance(node, ast.Constant)
                 and type(node.value) in (int, float) and node.value in KNOWN and owners[id(node)] in ALLOWED}
    assert seen == set(ALLOWED)


def test_the_check_finds_a_copy(tmp_path):
    """The check itself: each kind of copy it is for is found, and a docstring quoting a value is not."""
    (tmp_path / "core").mkdir()
    (tmp_path / "core" / "defaults.py").write_text("TOLERANCE = 0.002\n")
    (tmp_path / "m.py").write_text(
        '"""(tolerance: 0.002 mm)"""\n'
        "def f(x, *, tolerance=0.002, clearance_min=1.0, scale=1.0):\n"
        "    return g(x, rate=5000.0, clearance_min=1.0, inch=25.4)\n"
        "option('--clearance-min', default=1.0, show_default=True)\n"
        "def h(clearance_min=None):\n"
        "    return 1.0 if clearance_min is None else clearance_min\n"
        "class C:\n"
        "    clearance_min: float = 1.0\n"
        "    circle_tolerance: float = 0.01\n")
    found = repeated_defaults(tmp_path)
    assert [entry.split(" (")[0] for entry in found] == [
        "m.py:2: 0.002", "m.py:2: 1.0", "m.py:3: 5000.0", "m.py:3: 1.0", "m.py:3: 25.4", "m.py:4: 1.0",
        "m.py:6: 1.0", "m.py:8: 1.0", "m.py:9: 0.01"]
