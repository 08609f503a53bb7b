"""Pictures of a calibration: each measured pose's tip error before and after (``calibrate --preview``).

matplotlib is optional (``pip install 'prs3-post[plot]'``) and imported here, when a picture is asked for.
"""

from __future__ import annotations

import numpy as np

from prs3_post.check.preview import figure_bytes
from prs3_post.core.errors import Prs3Error
from prs3_post.core.types import FloatArray, IntArray

__all__ = ["residual_figure"]


def residual_figure(line: IntArray, before: FloatArray, after: FloatArray, holdout: FloatArray | None, *,
                    title: str, fmt: str) -> bytes:
    """Each row's tip error (mm) with the nominal head and the calibrated one (and, when given, the
    calibrated head's hold-out error), against the file's line, on a log scale.

    Parameters
    ----------
    line : (N,) int — each row's line in the file
    before, after : (N,) float — mm
    holdout : (N,) float, optional — mm
    title : str
    fmt : str — ``png`` or ``svg``
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise Prs3Error("--preview needs matplotlib: pip install 'prs3-post[plot]'") from exc
    fig = Figure(figsize=(9, 4.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    floor = 1e-5                                          # mm: a log axis cannot show 0
    ax.semilogy(line, np.maximum(before, floor), "o", color="#d62728", label="nominal machine")
    ax.semilogy(line, np.maximum(after, floor), "o", color="#1f5fbf", label="calibrated (fitted rows)")
    if holdout is not None:
        ax.semilogy(line, np.maximum(holdout, floor), "x", color="#2ca02c", label="calibrated, held out (k-fold)")
    ax.set_xlabel("line of the measurement file")
    ax.set_ylabel("tip error, mm")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    return figure_bytes(fig, fmt)
