"""Pictures of a calibration: each measured pose's tip error before and after (``calibrate --preview``),
and the tool's uncertainty over the tool axis's directions (``accuracy --preview``).

matplotlib is optional (``pip install 'prs3-post[plot]'``) and imported here, when a picture is asked for.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from prs3_post.check.preview import figure_bytes
from prs3_post.core.errors import MissingDependency
from prs3_post.core.types import FloatArray, IntArray

__all__ = ["accuracy_figure", "residual_figure"]


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
    Figure, FigureCanvasAgg = _matplotlib("calibrate --preview")
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


def accuracy_figure(tilt_deg: FloatArray, azimuth_deg: FloatArray, tip: FloatArray, *, title: str, fmt: str) -> bytes:
    """The tip's uncertainty (T, A) mm over tilts (T,) and azimuths (A,) deg as a polar map: the
    azimuth around, the tilt outward (blank where a pose is outside a limit).

    Parameters
    ----------
    tilt_deg : (T,) float; azimuth_deg : (A,) float
    tip : (T, A) float — mm, NaN outside the limits
    title : str
    fmt : str — ``png`` or ``svg``
    """
    Figure, FigureCanvasAgg = _matplotlib("accuracy --preview")
    fig = Figure(figsize=(6.5, 5.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1, projection="polar")
    step_a = float(azimuth_deg[1] - azimuth_deg[0]) if len(azimuth_deg) > 1 else 360.0
    step_t = float(tilt_deg[1] - tilt_deg[0]) if len(tilt_deg) > 1 else 1.0
    edges_a = np.radians(np.append(azimuth_deg - step_a / 2, azimuth_deg[-1] + step_a / 2))
    edges_t = np.append(np.maximum(tilt_deg - step_t / 2, 0.0), tilt_deg[-1] + step_t / 2)
    mesh = ax.pcolormesh(edges_a, edges_t, np.ma.masked_invalid(tip), cmap="viridis", shading="flat")
    fig.colorbar(mesh, ax=ax, label="tip uncertainty, mm (1σ)")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("tool axis azimuth (around), tilt deg (outward)")
    fig.tight_layout()
    return figure_bytes(fig, fmt)


def _matplotlib(what: str) -> tuple[Any, Any]:
    """matplotlib's Figure and Agg canvas, or an error saying how to install them."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise MissingDependency(f"{what} needs matplotlib: pip install 'prs3-post[plot]'") from exc
    return Figure, FigureCanvasAgg
