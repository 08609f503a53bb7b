"""What the CAM readers share: joining a stream's chunks, and the limits of a record and a feed."""

from __future__ import annotations

import numpy as np

from prs3_post.core.defaults import FEED_RANGE_MM_MIN
from prs3_post.core.toolpath import Event, Toolpath

#: mm/min, the fastest feed per minute a CAM file may ask for (a kilometre a minute, as the command line's
#: feeds): more is a typo, and would make a program whose moves the controller cannot follow.
MIN_FEED_MM_MIN, MAX_FEED_MM_MIN = FEED_RANGE_MM_MIN
#: Characters of a record (continuation lines joined) at most: far more than any CAM system writes
#: (a GOTO/ of six 20-digit numbers is about 130), few enough that a bad file is refused at once. The
#: CAM G-code reader holds a block (its code, without comments) to the same.
MAX_RECORD_CHARS = 65_536
#: Why a tool change's range is the program's: the output names the tool in a T word of its dialect.
DIALECT_TOOLS = ", the largest the output dialect takes: its words.tool_number_max"


def join_toolpaths(parts: list[Toolpath]) -> Toolpath:
    """One toolpath of consecutive chunks (each chunk's events count rows from its own start)."""
    events: list[Event] = []
    rows = 0
    for part in parts:
        events += [Event(before=e.before + rows, kind=e.kind, value=e.value, text=e.text) for e in part.events]
        rows += len(part)
    if not parts:
        return Toolpath(kind=np.zeros(0, dtype=np.int64), tip=np.zeros((0, 3)), axis=np.zeros((0, 3)),
                        feed=np.zeros(0), source=np.zeros(0, dtype=np.int64))
    return Toolpath(kind=np.concatenate([p.kind for p in parts]), tip=np.concatenate([p.tip for p in parts]),
                    axis=np.concatenate([p.axis for p in parts]), feed=np.concatenate([p.feed for p in parts]),
                    source=np.concatenate([p.source for p in parts]), events=tuple(events),
                    source_file=parts[0].source_file)
