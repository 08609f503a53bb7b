"""Which triangles of a mesh hang together: connected components, coplanar groups (facets), bodies (numpy, pure).

trimesh answers these questions through a graph library (networkx here: it builds a Python object per
triangle and per adjacency, 15 s and several hundred MB for a million triangles). The answers are plain
array work: the connected components of a graph given as an edge list are found by hooking and pointer
jumping (:func:`component_labels`), a few dozen array passes whatever the mesh.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.types import BoolArray, IntArray

if TYPE_CHECKING:
    import trimesh

__all__ = ["body_labels", "component_labels", "coplanar_pairs", "facet_labels"]


def component_labels(count: int, pairs: IntArray) -> IntArray:
    """(count,) int: the connected component of each node of a graph, numbered 0.. in the order of each
    component's smallest node.

    Parameters
    ----------
    count : int — nodes 0 .. count − 1
    pairs : (E, 2) int — the edges (node pairs; repeats and loops are harmless)

    Each node points at a node of smaller number in its component (at first, itself). A round hooks
    the root of every edge's larger end under the other end's root (the least one offered), then
    jumps every pointer to its root; the roots that remain are the components' smallest nodes. Edges
    whose ends share a root are dropped as they settle, so the work shrinks round by round.

    >>> component_labels(6, np.array([[4, 1], [1, 3], [5, 2]])).tolist()
    [0, 1, 2, 1, 1, 2]
    """
    parent = np.arange(count, dtype=np.int64)
    edges = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    first, second = edges[:, 0], edges[:, 1]
    while len(first):
        root_a, root_b = parent[first], parent[second]
        apart = root_a != root_b
        first, second, root_a, root_b = first[apart], second[apart], root_a[apart], root_b[apart]
        if not len(first):
            break
        np.minimum.at(parent, np.maximum(root_a, root_b), np.minimum(root_a, root_b))
        while True:                                     # pointer jumping: every node straight to its root
            above = parent[parent]
            if np.array_equal(above, parent):
                break
            parent = above
    labels: IntArray = np.unique(parent, return_inverse=True)[1].astype(np.int64)
    return labels


def coplanar_pairs(mesh: trimesh.Trimesh, *, facet_threshold: float | None = None) -> BoolArray:
    """(P,) bool: which of ``mesh.face_adjacency``'s pairs trimesh's ``facets`` takes as coplanar.

    trimesh's own test (``trimesh.graph.facets``), unchanged: the radius of the circle through the two
    triangles' far corners, divided by their span across the shared edge, squared, above
    ``facet_threshold`` (default ``trimesh.tol.facet_threshold``); a pair with no span is coplanar.
    """
    from trimesh.constants import tol

    threshold = tol.facet_threshold if facet_threshold is None else facet_threshold
    radii = mesh.face_adjacency_radius
    span = mesh.face_adjacency_span
    parallel = np.ones(len(radii), dtype=bool)
    nonzero = np.abs(span) > tol.zero
    parallel[nonzero] = (radii[nonzero] / span[nonzero]) ** 2 > threshold
    return parallel


def facet_labels(mesh: trimesh.Trimesh) -> IntArray:
    """(T,) int: each triangle's facet, the group of edge-connected coplanar triangles it belongs to
    (the triangles of trimesh's ``mesh.facets``, each with its own number), or −1 for a triangle that
    is in no facet (no coplanar neighbour). Facets are numbered by their smallest triangle."""
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    labels = component_labels(len(mesh.faces), pairs[coplanar_pairs(mesh)])
    size = np.bincount(labels)
    grouped = size[labels] >= 2
    out = np.full(len(labels), -1, dtype=np.int64)
    out[grouped] = np.unique(labels[grouped], return_inverse=True)[1]
    return out


def body_labels(mesh: trimesh.Trimesh) -> IntArray:
    """(T,) int: each triangle's body (the triangles connected to it through shared edges), numbered 0..
    by their smallest triangle."""
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    return component_labels(len(mesh.faces), pairs)
