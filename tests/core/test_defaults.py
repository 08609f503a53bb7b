"""Defaults once: the library's default values live in :mod:`prs3_post.core.defaults` (or in a machine file),
and a new copy of one of them elsewhere in the package is a test failure, not a drift found later.

The package is read with ``ast`` (not grep: docstrings and messages that quote a default are words, not
values). Flagged: a number equal to one of :data:`KNOWN` anywhere in the code, and ``1.0`` where it is a
clearance (a parameter's default, a keyword argument, a field or a fallback named for one).
"""

from __future__ import annotations

import ast
import functools
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
    "_margin_panel": "a label's offset in the preview's bar chart (a fraction of the axes)",
    "project_onto_face": "how far a job's point may be off its face, a check of that input",
    "POLL_S": "seconds between two status reads of `sim`'s display program (outside the package's imports)",
    "WAIT_POLL_S": "seconds between two status reads of `sim`'s display program while it waits for a step",
}


@functools.cache
def _parsed(path: Path) -> tuple[list[tuple[ast.Constant, str]], list[ast.Constant]]:
    """A module read once (one walk of its tree): each number equal to one of :data:`KNOWN` with its owner
    (the innermost function or constant it is in, "" where none) and each ``1.0`` used as a clearance."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    spans: list[tuple[int, int, str]] = []              # (first line, last line, name)
    known: list[ast.Constant] = []
    ones: list[ast.Constant] = []
    for node in ast.walk(tree):
        name = (node.name if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else
                node.targets[0].id if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name) else
                node.target.id if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) else None)
        if name is not None:
            spans.append((node.lineno, node.end_lineno or node.lineno, name))
        if isinstance(node, ast.Constant) and type(node.value) in (int, float) and node.value in KNOWN:
            known.append(node)
        ones += _clearance_ones(node)

    def owner(node: ast.Constant) -> str:
        around = [(last - first, name) for first, last, name in spans if first <= node.lineno <= last]
        return min(around)[1] if around else ""

    return [(node, owner(node)) for node in known], ones


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


def _one(node: ast.AST | None) -> bool:
    return isinstance(node, ast.Constant) and type(node.value) is float and node.value == 1.0


def _clearance(names: set[str] | str) -> bool:
    return any("clearance" in name for name in ([names] if isinstance(names, str) else names))


def _clearance_ones(node: ast.AST) -> list[ast.Constant]:
    """``1.0`` as a clearance in ``node`` itself (not its children): a default of a parameter, a keyword
    argument, a field, a fallback or an argument of a call whose name says clearance."""
    found: list[ast.Constant] = []
    one, clearance = _one, _clearance
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
        args = node.args
        positional = args.posonlyargs + args.args
        pairs = list(zip(positional[len(positional) - len(args.defaults):], args.defaults, strict=True))
        pairs += [(a, d) for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True) if d is not None]
        found += [d for a, d in pairs if one(d) and clearance(a.arg)]
    elif isinstance(node, ast.keyword) and node.arg and one(node.value) and clearance(node.arg):
        found.append(node.value)
    elif isinstance(node, ast.AnnAssign) and one(node.value) and clearance(_names(node.target)):
        found.append(node.value)
    elif isinstance(node, ast.Assign) and one(node.value) and clearance(_names(node.targets[0])):
        found.append(node.value)
    elif isinstance(node, ast.IfExp) and clearance(_names(node.test)):
        found += [b for b in (node.body, node.orelse) if one(b)]
    elif isinstance(node, ast.Call):                   # .get("clearance_min", 1.0), an option's default
        ones = [a for a in [*node.args, *(k.value for k in node.keywords)] if one(a)]
        found += ones if ones and clearance(_names(node)) else []
    return found


def repeated_defaults(root: Path = PACKAGE) -> list[str]:
    """``module:line: value (use NAME)`` for each copy of a default outside core/defaults.py."""
    problems = []
    for path in sorted(root.rglob("*.py")):
        module = path.relative_to(root).as_posix()
        if module == "core/defaults.py":
            continue
        known, ones = _parsed(path)
        flagged = {id(node): (node, "DEFAULT_CLEARANCE_MIN") for node in ones}
        flagged |= {id(node): (node, KNOWN[node.value]) for node, owner in known if owner not in ALLOWED}
        problems += [f"{module}:{node.lineno}: {node.value!r} (use core.defaults.{name})"
                     for node, name in sorted(flagged.values(), key=lambda pair: (pair[0].lineno, pair[0].col_offset))]
    return problems


def test_no_default_is_repeated_outside_core_defaults():
    assert repeated_defaults() == []


def test_each_allowed_number_is_still_there():
    """An entry of ALLOWED whose number went away is removed, so the list stays the reasons that hold."""
    seen = set()
    for path in PACKAGE.rglob("*.py"):
        seen |= {owner for _, owner in _parsed(path)[0] if owner in ALLOWED}
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
