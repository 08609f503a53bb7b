"""A progress bar on standard error, for the long commands (convert, verify, preview): drawn only when
standard error is a terminal, so that nothing of it reaches a log, a pipe or a test's captured output.

The library's loops tell a :data:`~prs3_post.core.types.Progress` callback ``(done, total)`` in bytes
read or rows replayed; the bar redraws one line (``\\r``) when the whole percent changes, so that a
million-line file costs some hundred writes. It may be told from another thread (a conversion's reading
thread): a lock keeps two draws from mixing.
"""

from __future__ import annotations

import sys
import threading
from types import TracebackType
from typing import TextIO

#: Characters of the bar itself (between the brackets).
BAR_WIDTH = 30


class ProgressBar:
    """``label [#########.....]  47%`` on one line of ``stream`` (standard error), while it is open.

    Call it as a :data:`~prs3_post.core.types.Progress`; :meth:`phase` starts another labelled sweep;
    ``after`` names the step that follows 100 % and reports nothing (preview: ``drawing``, after the
    replay); :meth:`close` ends the line. Nothing is drawn when the stream is not a terminal (or
    ``enabled`` is False).
    """

    def __init__(self, label: str, *, after: str | None = None, stream: TextIO | None = None,
                 enabled: bool | None = None):
        self.stream = sys.stderr if stream is None else stream
        self.enabled = _is_terminal(self.stream) if enabled is None else enabled
        self.label, self.after = label, after
        self.shown: int | None = None                   # the percent on the line (None: none drawn yet)
        self._lock = threading.Lock()

    def __call__(self, done: float, total: float) -> None:
        if not self.enabled:
            return
        percent = 100 if total <= 0 else max(0, min(100, int(100.0 * done / total)))
        if percent == self.shown:
            return
        with self._lock:
            self.shown = percent
            filled = BAR_WIDTH * percent // 100
            self._write(f"\r{self.label} [{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {percent:3d}%")
        if percent == 100 and self.after is not None:
            after, self.after = self.after, None
            self.phase(after, measured=False)

    def phase(self, label: str, *, measured: bool = True) -> None:
        """Start a sweep called ``label`` (the line is redrawn from 0 %; ``measured`` False: a step
        that reports no progress, shown by its label alone)."""
        if not self.enabled:
            return
        with self._lock:
            if self.shown is not None:
                self._write("\n")
            self.label, self.shown = label, None
            if not measured:
                self._write(f"{label} ...")
                self.shown = -1
        if measured:
            self(0.0, 1.0)

    def close(self) -> None:
        """End the bar's line (the next message starts on its own)."""
        if self.enabled and self.shown is not None:
            with self._lock:
                self._write("\n")
                self.shown = None

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):                   # a terminal gone: the command's work goes on
            self.enabled = False

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.close()


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
