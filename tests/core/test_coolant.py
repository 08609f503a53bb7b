"""The coolant is one enum (toolpath.Coolant) that ops, the job file, the readers and the emitter share."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import prs3_post
from prs3_post import toolpaths as ops
from prs3_post.core import toolpath
from prs3_post.core.toolpath import Coolant, Event, EventKind

SRC = Path(prs3_post.__file__).parent


def test_one_coolant_enum() -> None:
    assert ops.Coolant is toolpath.Coolant
    assert [(c.name, c.value) for c in Coolant] == [("FLOOD", "flood"), ("MIST", "mist"), ("OFF", "off")]


def test_m_codes_both_ways() -> None:
    assert [Coolant.from_m_code(code) for code in (7, 8)] == [Coolant.MIST, Coolant.FLOOD]
    assert [Coolant.MIST.m_word, Coolant.FLOOD.m_word] == ["M7", "M8"]
    with pytest.raises(ValueError, match="no M word turns coolant 'off' on"):
        _ = Coolant.OFF.m_word


def test_event_coolant() -> None:
    assert Event(0, EventKind.COOLANT_ON, text="mist").coolant is Coolant.MIST
    assert Event(0, EventKind.COOLANT_ON).coolant is Coolant.FLOOD


def test_no_coolant_names_as_text_in_code() -> None:
    """No module but toolpath.py spells 'mist' or 'flood' as a string constant (docstrings may say them)."""
    found = []
    for path in sorted(SRC.rglob("*.py")):
        name = path.relative_to(SRC).as_posix()
        if name == "core/toolpath.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and node.value in ("mist", "flood"):
                found.append(f"{name}:{node.lineno}: {node.value!r}")
    assert found == []

