"""A toolpath's program, post-processed and emitted a chunk at a time (the streaming conversion).

:func:`program_text` feeds each chunk through a :class:`~prs3_post.post.pipeline.PostStream` and
writes its rows with one :class:`~prs3_post.emit.gcode.ProgramEmitter`, so a program of any length
is held one chunk at a time; :func:`emitted_text` does the emitting alone, for chunks posted already.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from prs3_post.core.toolpath import JointProgram, Toolpath
from prs3_post.emit.gcode import ProgramEmitter
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.dialect import Dialect
from prs3_post.machine.model import Machine
from prs3_post.part.setup_transform import Setup
from prs3_post.post.pipeline import PostStream

__all__ = ["emitted_text", "program_text"]

def program_text(machine: Machine, chunks: Iterable[Toolpath], setup: Setup, dialect: Dialect, *,
                 header: tuple[tuple[str, str], ...] = (), tolerance: float,
                 angle_tolerance: float, line_numbers: bool | None = None,
                 line_start: int | None = None, line_step: int | None = None,
                 stream: PostStream | None = None) -> Iterator[str]:
    """The program of a toolpath given in chunks, as chunks of G-code text (begin, one per chunk, end).

    The concatenation is byte for byte the program of the whole toolpath post-processed in one piece
    (:func:`~prs3_post.post.pipeline.post_process` with ``length_decimals`` = the dialect's) and emitted with
    :func:`~prs3_post.emit.gcode.emit_program`. Lazy: a chunk is read, checked and formatted when
    its text is asked for, so ``write_atomic(path, program_text(...))`` holds one chunk at a time
    and leaves no file when a chunk raises.

    Parameters
    ----------
    machine, setup, tolerance, angle_tolerance : as :func:`~prs3_post.post.pipeline.post_process`
    chunks : iterable of Toolpath — the part-frame toolpath, in order (placed already when ``stream`` is ``placed``)
    dialect, header, line_numbers, line_start, line_step : as :func:`~prs3_post.emit.gcode.emit_program`
    stream : PostStream, optional — the stream to feed (made here when None); pass one to read its
        :meth:`~prs3_post.post.pipeline.PostStream.finish` counts afterwards (it must use the dialect's length decimals)

    Raises
    ------
    ReachError, LimitError
        As :meth:`~prs3_post.post.pipeline.PostStream.feed` and :func:`~prs3_post.emit.gcode.emit_program`,
        when the text of the chunk concerned is asked for.
    """
    if stream is None:
        stream = PostStream(machine, setup, tolerance=tolerance, angle_tolerance=angle_tolerance,
                            length_decimals=dialect.decimals.length)
    fed = stream
    return emitted_text(machine, (fed.feed(chunk).program for chunk in chunks), dialect, header=header,
                        line_numbers=line_numbers, line_start=line_start, line_step=line_step)


def emitted_text(machine: Machine, programs: Iterable[JointProgram], dialect: Dialect, *,
                 header: tuple[tuple[str, str], ...] = (), line_numbers: bool | None = None,
                 line_start: int | None = None, line_step: int | None = None) -> Iterator[str]:
    """:func:`program_text` of the chunks post-processed already (``programs``, in order): its begin,
    one text per program, its end."""
    emitter = ProgramEmitter(dialect, stage=machine.stage.present, line_numbers=line_numbers,
                             line_start=line_start, line_step=line_step, kinematics=kinematics_of(machine))
    yield emitter.begin(header)
    for program in programs:
        yield emitter.rows(program)
    yield emitter.end()
