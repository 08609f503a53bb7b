"""G-code output: a :class:`~prs3_post.toolpath.JointProgram` and a dialect → program text (no I/O)."""

from prs3_post.emit.gcode import emit_program, format_word, sanitize_comment

__all__ = ["emit_program", "format_word", "sanitize_comment"]
