"""Connected components, facets and bodies of a mesh (part/meshgraph.py) against plain oracles and trimesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from prs3_post.part.meshgraph import body_labels, component_labels, facet_labels
from prs3_post.part.stl import load_part

REPO = Path(__file__).resolve().parents[2]
PARTS = REPO / "fixtures" / "parts"


def _union_find(count: int, pairs: np.ndarray) -> list[int]:
    """The components, one edge at a time (the oracle), numbered in the order of their smallest node."""
    parent = list(range(count))

    def root(x: int) -> int:
        while parent[x] != x:
            x = parent[x]
        return x

    for a, b in pairs.tolist():
        ra, rb = root(a), root(b)
        parent[max(ra, rb)] = min(ra, rb)
    roots = [root(x) for x in range(count)]
    number = {r: k for k, r in enumerate(sorted(set(roots)))}
    return [number[r] for r in roots]


@pytest.mark.parametrize(("count", "edges"), [(0, 0), (1, 0), (1, 3), (5000, 3000), (5000, 6000), (5000, 20000)])
def test_component_labels_match_a_union_find(count: int, edges: int) -> None:
    rng = np.random.default_rng(count + edges)
    pairs = rng.integers(0, max(count, 1), size=(edges, 2)) if count else np.zeros((0, 2), dtype=np.int64)
    labels = component_labels(count, pairs)
    assert labels.shape == (count,)
    assert labels.tolist() == _union_find(count, pairs)


def test_component_labels_of_a_long_path_numbered_backwards() -> None:
    """A path whose nodes are numbered against its order: every hook moves one step, the jumps do the rest."""
    order = np.arange(100_000)[::-1]
    labels = component_labels(100_000, np.column_stack([order[:-1], order[1:]]))
    assert labels.tolist() == [0] * 100_000


@pytest.mark.parametrize("name", ["wedge", "wall30", "tilt35", "twofaces"])
def test_facet_labels_are_trimeshs_facets(name: str) -> None:
    mesh = load_part(PARTS / f"{name}.stl").subdivide()
    labels = facet_labels(mesh)
    ours = sorted(np.flatnonzero(labels == g).tolist() for g in range(labels.max() + 1))
    assert ours == sorted(sorted(int(t) for t in facet) for facet in mesh.facets)
    assert (labels >= 0).all()                             # every triangle of these planar parts is in a facet


def test_a_lone_triangle_is_in_no_facet_and_bodies_are_counted() -> None:
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    tetra = trimesh.creation.icosahedron()
    tetra.apply_translation((5.0, 0.0, 0.0))
    both = trimesh.util.concatenate([box, tetra])
    labels = facet_labels(both)
    assert sorted(np.flatnonzero(labels == g).tolist() for g in range(6)) == sorted(
        sorted(int(t) for t in facet) for facet in box.facets)
    assert (labels[12:] == -1).all()                       # an icosahedron's triangles have no coplanar neighbour
    assert body_labels(both).tolist() == [0] * 12 + [1] * 20
