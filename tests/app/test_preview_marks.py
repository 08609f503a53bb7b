"""app/preview.py: where a program's text marks its tool changes and operations."""

from __future__ import annotations

from pathlib import Path

from prs3_post.app.preview import program_marks
from prs3_post.app.verify import open_program
from prs3_post.check.timeline import MarkKind

GOLDEN = Path(__file__).resolve().parents[2] / "fixtures" / "golden"


def _marks(name: str) -> list[tuple[int, int, str, str]]:
    context = open_program(str(GOLDEN / name))
    return [(m.row, m.line, m.kind.value, m.label)
            for m in program_marks(context.program, context.header, context.dialect)]


def test_a_main_jobs_operation_begins_at_its_title():
    assert _marks("wedge-hole-case2a.ngc") == [(0, 20, "tool change", "T1 D6.000 mm tool"),
                                               (0, 18, "operation", "drill 1 hole D6.000 on face 4")]


def test_a_converted_programs_tool_changes_begin_its_operations():
    """A converted CL file: its one tool (the comment the converter wrote before the M6 names its TLDATA)."""
    label = "T1 tool 1: TLDATA/MILL,30.0000,0.0000,75.0000,0.0000,0.0000"
    assert _marks("convert-mech491_APT_SimpleMillPlane.ngc") == [(0, 18, "tool change", label),
                                                                 (0, 18, "operation", label)]


def test_a_fanuc_program_is_read_with_its_comment_style():
    marks = _marks("twofaces-face6-round-fanuc.nc")
    assert [m[2] for m in marks] == [MarkKind.TOOL_CHANGE.value, MarkKind.OPERATION.value]
    assert marks[1][3].lower().startswith("round") and marks[1][3].lower().endswith("on face 6")
