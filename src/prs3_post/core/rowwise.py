"""Row-wise arithmetic on (N, 3) arrays, bit for bit numpy's, without its reductions along a short axis.

``np.linalg.norm(v, axis=1)``, ``mask.all(axis=1)`` and ``mask.any(axis=1)`` reduce a few values per
row one row at a time, which costs several times the arithmetic itself. The functions here do the same operations
column by column, in the same order (numpy sums a row of three as ``(x² + y²) + z²``), so they give
the same bits (tests/test_rows.py compares them with numpy's on generated rows).
"""

from __future__ import annotations

import numpy as np

from prs3_post.core.types import BoolArray, FloatArray

__all__ = ["row_all", "row_any", "row_lengths", "same_rows"]


def row_lengths(vectors: FloatArray) -> FloatArray:
    """(N,) float — the Euclidean length of each row of ``vectors`` (N, 3): ``np.linalg.norm(vectors,
    axis=1)``, bit for bit.

    >>> row_lengths(np.array([[3.0, 4.0, 12.0], [0.0, 0.0, -2.0]])).tolist()
    [13.0, 2.0]
    """
    squares = vectors * vectors
    return np.sqrt(squares[:, 0] + squares[:, 1] + squares[:, 2])


def row_all(mask: BoolArray) -> BoolArray:
    """(N,) bool — ``mask.all(axis=1)`` of a boolean (N, K) array, K ≥ 1, a column at a time.

    >>> row_all(np.array([[True, True], [True, False]])).tolist()
    [True, False]
    """
    out = mask[:, 0].copy()
    for column in range(1, mask.shape[1]):
        out &= mask[:, column]
    return out


def row_any(mask: BoolArray) -> BoolArray:
    """(N,) bool — ``mask.any(axis=1)`` of a boolean (N, K) array, K ≥ 1, a column at a time.

    >>> row_any(np.array([[False, True], [False, False]])).tolist()
    [True, False]
    """
    out = mask[:, 0].copy()
    for column in range(1, mask.shape[1]):
        out |= mask[:, column]
    return out


def same_rows(values: FloatArray) -> bool:
    """Whether every row of ``values`` (N, K) float64, K ≥ 1, has the bits of row 0 (True for N ≤ 1).

    Bits, not ``==``: a row computed once and repeated is then each row's own result, NaN, inf and
    the sign of a zero included. Each value is compared with the one K places before it, on one
    flat view (a comparison of (N, K) with a broadcast row costs several times more).

    >>> same_rows(np.array([[0.0, 1.0], [0.0, 1.0]])), same_rows(np.array([[0.0, 1.0], [-0.0, 1.0]]))
    (True, False)
    """
    width = values.shape[1]
    flat = np.ascontiguousarray(values, dtype=np.float64).view(np.int64).reshape(-1)
    return bool((flat[width:] == flat[:-width]).all())
