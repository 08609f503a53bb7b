"""Planar faces of a part: find them, pick the one to machine, project points onto it.

A *face* is one planar region of the part's surface: a maximal set of edge-connected, coplanar
triangles (trimesh's ``Trimesh.facets``, grouped by :func:`prs3_post.part.meshgraph.facet_labels`), or a
single triangle that belongs to no such set (on a curved surface every triangle is its own small face).

Decisions
---------
- Coplanar but *disconnected* regions (two separate pads at the same height) are separate faces:
  that is how ``facets`` groups them (connected components of the coplanar-adjacency graph), and an
  operation placed on one of them must not straddle the gap to the other.
- ``facets`` decides coplanarity pair by pair, so a gently curved surface made of many thin triangles
  can chain into one "facet". Every group is therefore checked: if one of its vertices lies more than
  ``flatness_tol`` off the group's plane, the group is not planar and each of its triangles becomes
  its own face.
- Normal = area-weighted mean of the triangle normals; origin = area centroid. The boundary is the
  area enclosed by the face's boundary edges (those it shares with another face) projected onto its
  (u, v) plane (shapely's ``build_area``): the same polygon as the union of its projected triangles,
  with holes where the face has them, at a cost that grows with the outline, not with the triangles.
  Should floating-point noise still split it, the largest piece is the boundary (``area`` stays the
  exact triangle sum).
- Triangles with zero area have no normal: they add nothing to a group, and alone they are no face.
- A face is a *curved strip* (``Face.curved``) when it is one of the flat strips a tessellated curved
  surface (a fillet, a hole wall, a cone) is made of: neighbouring faces within ``STRIP_MAX_ANGLE_DEG``
  of it share at least ``STRIP_MIN_SHARE`` of its outline, and it is at most ``STRIP_MAX_AREA_RATIO``
  times the largest of them (a planar face between two tessellated fillets is much larger than their
  strips, so it stays a face of the design).
- ``Face.width`` is the diameter of the largest circle inside the outline (shapely's
  ``maximum_inscribed_circle``, to 0.1 % of the face's size): the widest tool that fits.

Automatic selection (:func:`select_face`) takes the largest *candidate*: facing up, inclined between 1°
and 89°, not a curved strip, and at least ``MIN_FACE_WIDTH_MM`` (or the tool) wide;
:func:`candidate_reason` says for each face why it is or is not one.

Order: faces are sorted by area, largest first; equal areas (to 9 significant digits) by normal
(z, then y, then x, larger first: upward faces first), then by origin (x, y, z, smaller first). Index
``i`` in the returned tuple is ``Face.index``.

Precondition: the mesh is closed and wound outward (:func:`prs3_post.part.stl.load_part` makes it so); all
lengths are mm.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.errors import FeatureError
from prs3_post.core.numbers import fixed
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.part.face import Face, frame_from_normal
from prs3_post.part.meshgraph import facet_labels

if TYPE_CHECKING:  # trimesh (200 ms) and shapely (60 ms) load only where a part is read
    import shapely
    import trimesh

INCLINED_MIN_DEG = 1.0
"""Automatic selection: a face must be inclined strictly more than this from horizontal (degrees)."""
INCLINED_MAX_DEG = 89.0
"""Automatic selection: ... and strictly less than this (degrees)."""
EQUAL_AREA_RTOL = 1e-6
"""Automatic selection: candidates whose areas differ by at most this fraction tie (reported)."""
UP_MIN_NORMAL_Z = 1e-9
"""A face whose normal z is at or below this does not face up: the tool cannot reach it from above."""
MIN_FACE_WIDTH_MM = 3.0
"""Automatic selection: the smallest tool assumed (mm); a narrower face (``Face.width``) is no candidate."""
STRIP_MAX_ANGLE_DEG = 20.0
"""Curved strips: neighbours whose normals are within this angle (degrees) of a face's count as smooth."""
STRIP_MIN_SHARE = 0.5
"""Curved strips: ... and must share at least this fraction of the face's outline length ..."""
STRIP_MAX_AREA_RATIO = 4.0
"""Curved strips: ... and the face is at most this many times the largest smooth neighbour's area."""


def find_faces(mesh: trimesh.Trimesh, *, flatness_tol: float = 1e-3) -> tuple[Face, ...]:
    """Group a part's triangles into planar faces, largest first.

    Parameters
    ----------
    mesh : trimesh.Trimesh — closed, wound outward, mm, part coordinates (see ``load_part``)
    flatness_tol : float — mm, largest distance of a vertex from its face's plane; a coplanar group
        that exceeds it is split into single-triangle faces

    Returns
    -------
    tuple of Face
        Sorted by area (largest first, ties as in the module docstring), ``faces[i].index == i``.
        Empty for a mesh without triangles.

    >>> import trimesh
    >>> faces = find_faces(trimesh.creation.box(extents=(2.0, 3.0, 4.0)))
    >>> [(f.index, round(f.area, 6)) for f in faces]
    [(0, 12.0), (1, 12.0), (2, 8.0), (3, 8.0), (4, 6.0), (5, 6.0)]
    >>> faces[2].normal.tolist(), round(math.degrees(faces[2].inclination), 6)
    ([0.0, 1.0, 0.0], 90.0)
    """
    triangles = np.asarray(mesh.triangles, dtype=np.float64)  # (T, 3, 3) mm
    if len(triangles) == 0:
        return ()
    area_tri = np.asarray(mesh.area_faces, dtype=np.float64)  # (T,) mm²
    normal_tri = np.asarray(mesh.face_normals, dtype=np.float64)  # (T, 3); zeros where degenerate
    labels = _labels_from_facets(facet_labels(mesh), area_tri)
    if not (labels >= 0).any():  # only zero-area triangles
        return ()
    area, normal, origin = _group_stats(labels, triangles, area_tri, normal_tri)

    # A group whose vertices leave its plane is a curved patch that trimesh chained together.
    kept = labels >= 0
    offset_tri = np.abs(
        np.einsum("tkj,tj->tk", triangles[kept] - origin[labels[kept]][:, None, :], normal[labels[kept]])
    )  # (T_kept, 3) mm, each vertex's distance from its group's plane
    worst = np.zeros(len(area))
    np.maximum.at(worst, labels[kept], offset_tri.max(axis=1))
    curved = kept & (worst[np.maximum(labels, 0)] > flatness_tol)
    if curved.any():
        labels = labels.copy()
        labels[curved] = labels.max() + 1 + np.arange(np.count_nonzero(curved))
        labels = _drop_degenerate_singletons(labels, area_tri)
        area, normal, origin = _group_stats(labels, triangles, area_tri, normal_tri)

    # Renumber the groups in face order, so that group g is face g.
    order = _face_order(area, normal, origin)  # (G,) group ids, largest face first
    rank = np.zeros(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    labels = np.where(labels >= 0, rank[np.maximum(labels, 0)], -1)
    area, normal, origin = area[order], normal[order], origin[order]
    u, v = frame_from_normal(normal)  # (G, 3) each
    inclination = np.arccos(np.clip(normal[:, 2], -1.0, 1.0))  # clip: |n_z| may round past 1
    boundaries = _boundaries(mesh, labels, triangles, area_tri, origin, u, v)
    members = _members(labels, len(area))
    width = _widths(boundaries)
    curved = _curved_strips(mesh, labels, area, normal)
    # Faces hold read-only row views of these (G, 3) arrays: one Python object per face, no copies.
    normal, origin, u, v = (_frozen(a) for a in (normal, origin, u, v))
    return tuple(
        Face(
            index=g,
            area=float(area[g]),
            normal=normal[g],
            origin=origin[g],
            u=u[g],
            v=v[g],
            inclination=float(inclination[g]),
            boundary=boundaries[g],
            triangles=members[g],
            width=float(width[g]),
            curved=bool(curved[g]),
        )
        for g in range(len(area))
    )


def _labels_from_facets(facet: IntArray, area_tri: FloatArray) -> IntArray:
    """Group label of each triangle ``(T,)``: facets first (``facet``: each triangle's, −1 for none), then one
    label per lone triangle, -1 = none."""
    labels = facet.copy()
    lone = labels < 0
    labels[lone] = int(facet.max(initial=-1)) + 1 + np.arange(np.count_nonzero(lone))
    return _drop_degenerate_singletons(labels, area_tri)


def _drop_degenerate_singletons(labels: IntArray, area_tri: FloatArray) -> IntArray:
    """Label -1 for groups without area (a lone zero-area triangle, or a facet of only such: they have
    no normal); then number groups 0..G-1."""
    group_area = np.bincount(labels[labels >= 0], weights=area_tri[labels >= 0])
    labels = np.where((labels >= 0) & (group_area[np.maximum(labels, 0)] <= 0.0), -1, labels)
    kept = labels >= 0
    compact = np.full(len(labels), -1, dtype=np.int64)
    compact[kept] = np.unique(labels[kept], return_inverse=True)[1]
    return compact


def _group_stats(
    labels: IntArray, triangles: FloatArray, area_tri: FloatArray, normal_tri: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per group: area ``(G,)`` mm², unit normal ``(G, 3)``, area centroid ``(G, 3)`` mm."""
    kept = labels >= 0
    groups = int(labels.max()) + 1
    lab, weight = labels[kept], area_tri[kept]
    # numpy types bincount as int
    area: FloatArray = np.bincount(lab, weights=weight, minlength=groups).astype(np.float64)
    normal = np.zeros((groups, 3))
    centroid = np.zeros((groups, 3))
    np.add.at(normal, lab, normal_tri[kept] * weight[:, None])
    np.add.at(centroid, lab, triangles[kept].mean(axis=1) * weight[:, None])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return area, normal, centroid / area[:, None]


def _members(labels: IntArray, groups: int) -> list[IntArray]:
    """Triangle indices of each group, ascending, read-only ``[(K_g,) int]``."""
    order = _frozen(np.argsort(labels, kind="stable").astype(np.int64))
    starts = np.searchsorted(labels[order], np.arange(groups + 1))
    return [order[starts[g] : starts[g + 1]] for g in range(groups)]


def _face_order(area: FloatArray, normal: FloatArray, origin: FloatArray) -> IntArray:
    """Group ids in face order ``(G,)``: area to 9 significant digits, largest first; ties by normal
    z, y, x (larger first, to 1e-9), then origin x, y, z (smaller first, to 1e-6 mm); then stable."""
    scale = 10.0 ** (8.0 - np.floor(np.log10(area)))  # area > 0: zero-area groups were dropped
    area_key = np.rint(area * scale) / scale
    n = np.round(normal, 9) + 0.0  # + 0.0 turns -0.0 into 0.0
    o = np.round(origin, 6) + 0.0
    return np.lexsort((o[:, 2], o[:, 1], o[:, 0], -n[:, 0], -n[:, 1], -n[:, 2], -area_key))


def _boundaries(
    mesh: trimesh.Trimesh, labels: IntArray, triangles: FloatArray, area_tri: FloatArray, origin: FloatArray,
    u: FloatArray, v: FloatArray,
) -> list[shapely.Polygon]:
    """Outline of each group in its face coordinates (u, v) mm: exterior CCW, holes CW.

    A face of one triangle (with area) is that triangle. A larger face is the area its boundary edges
    enclose (shapely's ``build_area``): the edges between one of its triangles and a triangle of
    another face, a few per face however finely it is cut, where a union of all its triangles would
    grow with them.

    Parameters
    ----------
    mesh : trimesh.Trimesh — the part (its triangles' corners and edge adjacency)
    labels : (T,) int — group of each triangle, -1 for none
    triangles : (T, 3, 3) float — mm, part coordinates
    area_tri : (T,) float — mm²
    origin, u, v : (G, 3) float — each group's frame

    Returns
    -------
    list of shapely.Polygon, one per group
    """
    import shapely

    groups = len(origin)
    basis = np.stack([u, v], axis=2)  # (G, 3, 2)

    def projected(rows: IntArray) -> FloatArray:
        """(K, 3, 2) mm: the corners of triangles ``rows`` in their face's (u, v)."""
        group = labels[rows]
        out: FloatArray = np.einsum("kij,kjc->kic", triangles[rows] - origin[group][:, None, :], basis[group])
        return out

    solid = (labels >= 0) & (area_tri > 0.0)  # zero-area triangles outline nothing
    count = np.bincount(labels[solid], minlength=groups)  # (G,) triangles with area
    outlines = np.full(groups, None, dtype=object)
    lone = np.flatnonzero(solid & (count[np.maximum(labels, 0)] == 1))
    outlines[labels[lone]] = shapely.polygons(projected(lone))
    # The boundary edges: the sides of an adjacent pair of triangles on two faces, seen from each face.
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)  # (P, 2) triangles sharing an edge
    ends = np.asarray(mesh.face_adjacency_edges, dtype=np.int64).reshape(-1, 2)  # (P, 2) that edge's vertices
    across = labels[pairs[:, 0]] != labels[pairs[:, 1]]
    side = pairs[across].ravel()  # (2B,) a triangle on each side of each boundary edge
    ends = np.repeat(ends[across], 2, axis=0)  # (2B, 2)
    mine = (labels[side] >= 0) & (count[np.maximum(labels[side], 0)] >= 2)
    side, ends = side[mine], ends[mine]
    corners = np.asarray(mesh.faces, dtype=np.int64)[side]  # (S, 3) vertex ids
    first = np.argmax(corners == ends[:, :1], axis=1)  # (S,) the corner at the edge's first end
    second = np.argmax(corners == ends[:, 1:], axis=1)
    forward = second == (first + 1) % 3  # the triangle runs first -> second: its winding, kept
    start, stop = np.where(forward, first, second), np.where(forward, second, first)
    corner_uv = projected(side)  # (S, 3, 2)
    rows = np.arange(len(side))
    segments = np.stack([corner_uv[rows, start], corner_uv[rows, stop]], axis=1)  # (S, 2, 2)
    group = labels[side]
    by_group = np.argsort(group, kind="stable")
    shared = np.unique(group)
    lines = shapely.multilinestrings(shapely.linestrings(segments[by_group]), indices=np.searchsorted(
        shared, group[by_group]))
    outlines[shared] = [_main_polygon(area) for area in shapely.build_area(lines)]
    return list(shapely.orient_polygons(outlines, exterior_cw=False))


def _widths(boundaries: list[shapely.Polygon]) -> FloatArray:
    """Diameter of the largest inscribed circle of each outline ``(G,)`` mm (0 for an empty one)."""
    import shapely

    outlines = np.array(boundaries, dtype=object)
    width = np.zeros(len(outlines))
    solid = np.flatnonzero(shapely.area(outlines) > 0.0) if len(outlines) else np.zeros(0, dtype=np.int64)
    # default tolerance: 1/1000 of each outline's size (45 ms for 844 faces; 1 µm would take 0.4 s)
    width[solid] = 2.0 * shapely.length(shapely.maximum_inscribed_circle(outlines[solid]))
    return width


def _curved_strips(mesh: trimesh.Trimesh, labels: IntArray, area: FloatArray, normal: FloatArray) -> BoolArray:
    """Which faces are strips of a tessellated curved surface ``(G,)`` (rule in the module docstring).

    Parameters
    ----------
    mesh : trimesh.Trimesh — the part (its triangle adjacency and vertices, mm)
    labels : (T,) int — face of each triangle, -1 for none
    area : (G,) float — mm²; normal : (G, 3) float — unit, per face
    """
    groups = len(area)
    pairs = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)  # (P, 2) triangles sharing an edge
    ends = np.asarray(mesh.face_adjacency_edges, dtype=np.int64).reshape(-1, 2)  # (P, 2) that edge's vertices
    a, b = labels[pairs[:, 0]], labels[pairs[:, 1]]
    between = (a != b) & (a >= 0) & (b >= 0)  # edges on the outline between two faces
    a, b, ends = a[between], b[between], ends[between]
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    length = np.linalg.norm(vertices[ends[:, 0]] - vertices[ends[:, 1]], axis=1)  # (E,) mm
    smooth = np.einsum("ij,ij->i", normal[a], normal[b]) >= math.cos(math.radians(STRIP_MAX_ANGLE_DEG))
    outline = np.bincount(a, length, groups) + np.bincount(b, length, groups)  # (G,) mm
    shared = np.bincount(a[smooth], length[smooth], groups) + np.bincount(b[smooth], length[smooth], groups)
    largest = np.zeros(groups)  # (G,) mm², the largest smooth neighbour
    np.maximum.at(largest, a[smooth], area[b[smooth]])
    np.maximum.at(largest, b[smooth], area[a[smooth]])
    return (shared > 0.0) & (shared >= STRIP_MIN_SHARE * outline) & (area <= STRIP_MAX_AREA_RATIO * largest)


def _main_polygon(geometry: shapely.Geometry) -> shapely.Polygon:
    """The polygon itself, or the largest polygon of a collection (numerical slivers only)."""
    import shapely

    if isinstance(geometry, shapely.Polygon):
        return geometry
    if not isinstance(geometry, (shapely.MultiPolygon, shapely.GeometryCollection)):
        return shapely.Polygon()
    polygons = [g for g in geometry.geoms if isinstance(g, shapely.Polygon)]
    return max(polygons, key=lambda piece: piece.area) if polygons else shapely.Polygon()


def _frozen(array: np.ndarray) -> np.ndarray:
    out = np.array(array, copy=True)
    out.flags.writeable = False
    return out


def _degrees(face: Face) -> float:
    return math.degrees(face.inclination)


def face_kind(face: Face) -> str:
    """How a face sits, in words: 'horizontal up', 'inclined up', 'vertical', 'inclined down' or 'horizontal down'.

    Horizontal means within 1° of horizontal, vertical within 1° of vertical; 'inclined up' faces are
    exactly the candidates of automatic selection.
    """
    degrees = _degrees(face)
    if degrees <= INCLINED_MIN_DEG:
        return "horizontal up"
    if degrees < INCLINED_MAX_DEG:
        return "inclined up"
    if degrees <= 180.0 - INCLINED_MAX_DEG:
        return "vertical"
    if degrees < 180.0 - INCLINED_MIN_DEG:
        return "inclined down"
    return "horizontal down"


_ORIENTATION_REASON = {
    "horizontal up": "horizontal",
    "vertical": "vertical",
    "inclined down": "faces down",
    "horizontal down": "faces down",
}


def candidate_reason(face: Face, *, min_width: float = MIN_FACE_WIDTH_MM) -> tuple[bool, str]:
    """Whether automatic selection may take ``face``, and why (or why not), in a few words.

    A candidate faces up, is inclined strictly between 1° and 89°, is not a strip of a curved surface
    (``face.curved``) and is at least ``min_width`` mm wide (``face.width``).

    >>> import trimesh
    >>> faces = find_faces(trimesh.creation.box(extents=(2.0, 3.0, 4.0)))
    >>> [candidate_reason(f) for f in faces[4:]]
    [(False, 'horizontal'), (False, 'faces down')]
    """
    kind = face_kind(face)
    if kind != "inclined up":
        return False, _ORIENTATION_REASON[kind]
    if face.curved:
        return False, "strip of a curved surface"
    if face.width < min_width:
        return False, f"too narrow: {fixed(face.width, 2)} mm < {min_width:g} mm"
    return True, f"inclined up, {fixed(face.width, 2)} mm wide"


def select_face(
    faces: tuple[Face, ...], choice: int | None, *, min_width: float = MIN_FACE_WIDTH_MM,
    reachable: Callable[[FloatArray], BoolArray] | None = None,
) -> tuple[Face, str]:
    """Pick the face to machine: automatically (``choice=None``) or by index.

    Automatic: the largest candidate (:func:`candidate_reason`): a planar face that faces up, is
    inclined strictly between 1° and 89° from horizontal, is not a strip of a tessellated curved
    surface and is at least ``min_width`` wide. Candidates whose areas agree within
    ``EQUAL_AREA_RTOL`` (relative) tie; the lowest index wins and the note says so. A face given by
    index only has to face up.

    Parameters
    ----------
    faces : tuple of Face — as returned by :func:`find_faces` (``faces[i].index == i``)
    choice : int or None — a face index, or None for automatic selection
    min_width : float — mm, the narrowest face automatic selection takes (the smallest tool, or the
        operation's tool diameter where it is known)
    reachable : callable, optional — (K, 3) unit normals → (K,) bool, the tool axes the machine can take:
        where no face is a candidate, a face another up axis would make one is named (as a hint that
        must lead somewhere) only when its normal, turned so, is one of them (None: any)

    Returns
    -------
    face : Face
    note : str — one line saying how the face was picked, for the program header and the log

    Raises
    ------
    FeatureError
        No faces; ``choice`` out of range (lists the valid indexes); the chosen face does not face up;
        automatic selection finds no candidate (the message says why, and counts what was found).
    """
    if not faces:
        raise FeatureError("the part has no faces")
    if choice is not None:
        if not 0 <= choice < len(faces):
            valid = "0" if len(faces) == 1 else f"0 to {len(faces) - 1}"
            raise FeatureError(f"face {choice} does not exist (valid: {valid})")
        face = faces[choice]
        if face.normal[2] <= UP_MIN_NORMAL_Z:
            raise FeatureError(
                f"face {face.index} does not face up (normal z = {fixed(face.normal[2], 4)}, "
                f"inclination {fixed(_degrees(face), 1)}°): the tool cannot reach it from above"
            )
        return face, f"face {face.index} as requested ({_describe(face)})"

    candidates = [f for f in faces if candidate_reason(f, min_width=min_width)[0]]
    if not candidates:
        raise FeatureError(_no_candidate(faces, min_width, reachable))
    largest = max(f.area for f in candidates)
    tied = sorted(f.index for f in candidates if largest - f.area <= EQUAL_AREA_RTOL * largest)
    face = faces[tied[0]]
    note = f"auto: face {face.index} is the largest upward-facing inclined face ({_describe(face)})"
    if len(tied) > 1:
        names = ", ".join(str(i) for i in tied[:-1]) + f" and {tied[-1]}"
        note += (
            f"; faces {names} have equal area {fixed(face.area, 1)} mm²; picked {face.index} (lower index)"
        )
    skipped = [f for f in faces[: face.index] if face_kind(f) == "inclined up"]
    if skipped:
        strips = sum(f.curved for f in skipped)
        why = [f"{strips} {'strip' if strips == 1 else 'strips'} of curved surfaces"] if strips else []
        if len(skipped) > strips:
            why.append(f"{len(skipped) - strips} narrower than {min_width:g} mm")
        note += f"; skipped larger inclined faces: {', '.join(why)}"
    return face, note


def _describe(face: Face) -> str:
    return f"inclination {fixed(_degrees(face), 4)}°, area {fixed(face.area, 1)} mm²"


def _no_candidate(faces: tuple[Face, ...], min_width: float,
                  reachable: Callable[[FloatArray], BoolArray] | None = None) -> str:
    """Why automatic selection found nothing, in plain words, with what was found."""
    planar = [f for f in faces if not f.curved]
    up = [f for f in planar if face_kind(f) == "inclined up"]  # all narrower than min_width here
    down = [f for f in planar if face_kind(f) == "inclined down"]
    if down and not up:
        if len(down) == 1:
            f = down[0]
            head = (
                f"the only inclined planar face, face {f.index} ({fixed(180.0 - _degrees(f), 1)}° from horizontal, "
                f"area {fixed(f.area, 1)} mm²), faces down (normal z = {fixed(f.normal[2], 4)}): "
                "the tool cannot reach it from above"
            )
        else:
            names = ", ".join(str(f.index) for f in down[:-1]) + f" and {down[-1].index}"
            head = (
                f"all {len(down)} inclined planar faces (faces {names}) face down: "
                "the tool cannot reach them from above"
            )
        return (f"{head}; found {_count_faces(faces, min_width=min_width, down_said=True)}"
                + _other_up(faces, min_width, reachable))
    if up:
        head = f"no upward-facing inclined planar face at least {min_width:g} mm wide"
    else:
        head = (
            f"no upward-facing inclined face ({INCLINED_MIN_DEG:g}° < inclination < {INCLINED_MAX_DEG:g}°, "
            "normal z > 0)"
        )
    return f"{head}: found {_count_faces(faces, min_width=min_width)}" + _other_up(faces, min_width, reachable)


def _other_up(faces: tuple[Face, ...], min_width: float,
              reachable: Callable[[FloatArray], BoolArray] | None = None) -> str:
    """The largest face that would be a candidate with another of the part's axes up, as a hint naming
    the ``{up}`` key (or ''); with ``reachable``, only a face whose turned normal the machine can take.

    Turning the part changes only which way its faces point, not their widths or whether they are
    curved strips: the candidate test runs on each face's normal component along that axis.
    """
    from prs3_post.part.stl import UP_ROTATION, up_rotation

    usable = [f for f in faces if not f.curved and f.width >= min_width]
    if not usable:
        return ""
    normal = np.array([f.normal for f in usable])  # (K, 3)
    area = np.array([f.area for f in usable])  # (K,)
    low, high = (math.cos(math.radians(d)) for d in (INCLINED_MAX_DEG, INCLINED_MIN_DEG))
    best: tuple[float, str, int, float] | None = None  # area, axis, face, inclination in degrees
    beyond: tuple[float, str, int, float] | None = None  # the same of a face the machine cannot take
    for axis in UP_ROTATION:
        if axis == "z":
            continue
        up_z = normal @ up_rotation(axis)[2]  # (K,) normal z once `axis` points up (row 2 of the turn)
        fits = np.flatnonzero((up_z > low) & (up_z < high))
        if reachable is not None and len(fits):
            taken = reachable(normal[fits] @ up_rotation(axis).T)
            if not taken.all():
                k = int(fits[~taken][np.argmax(area[fits[~taken]])])
                if beyond is None or area[k] > beyond[0]:
                    beyond = (float(area[k]), axis, usable[k].index, math.degrees(math.acos(float(up_z[k]))))
            fits = fits[taken]
        if len(fits):
            k = int(fits[np.argmax(area[fits])])
            if best is None or area[k] > best[0]:
                best = (float(area[k]), axis, usable[k].index, math.degrees(math.acos(float(up_z[k]))))
    if best is None:
        if beyond is None:
            return ""
        _, axis, index, inclination = beyond
        return (f"; no other up axis gives a face this machine can take: with the part's {axis} axis up, face "
                f"{index} would be inclined {fixed(inclination, 1)}°, beyond its tilt, link angle or condition "
                "number limits")
    found_area, axis, index, inclination = best
    return (
        f"; if the part's {axis} axis (as read) points up ({{up}} {axis}), face {index} (inclination "
        f"{fixed(inclination, 1)}°, area {fixed(found_area, 1)} mm²) is a candidate"
    )


def _count_faces(faces: tuple[Face, ...], *, min_width: float, down_said: bool = False) -> str:
    """'6 faces: 2 horizontal up, 1 horizontal down, 2 vertical, 1 inclined 45.0° facing down (...)'.

    Strips of curved surfaces are counted apart, at the end; upward inclined planar faces are counted
    as narrower than ``min_width`` (the caller found no candidate).
    """
    planar = [f for f in faces if not f.curved]
    kinds = [face_kind(f) for f in planar]
    parts = [
        f"{kinds.count(kind)} {kind}" + (f" narrower than {min_width:g} mm" if kind == "inclined up" else "")
        for kind in ("horizontal up", "inclined up", "horizontal down", "vertical")
        if kind in kinds
    ]
    # Facing down: report the slope from horizontal (180° - inclination), grouped by its rounded text.
    slopes = sorted(
        (fixed(180.0 - _degrees(f), 1) for f, k in zip(planar, kinds, strict=True) if k == "inclined down"), key=float
    )
    for slope in dict.fromkeys(slopes):
        parts.append(f"{slopes.count(slope)} inclined {slope}° facing down")
    if slopes and not down_said:
        parts[-1] += " (cannot be reached from above)"
    strips = len(faces) - len(planar)
    if strips:
        parts.append(f"{strips} {'strip' if strips == 1 else 'strips'} of curved surfaces")
    noun = "face" if len(faces) == 1 else "faces"
    return f"{len(faces)} {noun}: " + ", ".join(parts)


def project_onto_face(face: Face, xyz_part: FloatArray, *, max_offset: float | None = 0.01) -> FloatArray:
    """Face coordinates (u, v) of part points, dropped perpendicularly onto the face's plane.

    Whether the result lies inside ``face.boundary`` is for the operation to check.

    Parameters
    ----------
    face : Face
    xyz_part : (N, 3) or (3,) float — mm, part coordinates
    max_offset : float or None — mm, largest allowed distance of a point from the face's plane
        (None: no check)

    Returns
    -------
    uv : (N, 2) float — mm, face coordinates

    Raises
    ------
    FeatureError
        A point lies farther than ``max_offset`` from the plane (the first such point is named).
    """
    xyz = np.asarray(xyz_part, dtype=np.float64).reshape(-1, 3)
    uvw = face.from_part(xyz)  # (N, 3)
    if max_offset is not None and len(uvw):
        off = np.abs(uvw[:, 2])
        far = np.flatnonzero(off > max_offset)
        if len(far):
            i = int(far[0])
            which = "point" if len(xyz) == 1 else f"point {i + 1} of {len(xyz)}"
            coords = ", ".join(fixed(c, 4) for c in xyz[i])
            raise FeatureError(
                f"{which} ({coords}) is {fixed(off[i], 4)} mm off the plane of face {face.index} "
                f"(allowed: {fixed(max_offset, 4)} mm)"
            )
    return np.array(uvw[:, :2])


def face_table(faces: tuple[Face, ...], *, min_width: float = MIN_FACE_WIDTH_MM) -> list[dict[str, object]]:
    """The faces as JSON-ready rows (plain ints, floats, bools, strings and lists; -0.0 written as 0.0).

    Returns
    -------
    list of dict
        One per face, in index order, with keys ``index`` (int), ``area_mm2`` (float), ``normal``
        (3 floats, unit), ``inclination_deg`` (float, from +z), ``origin`` (3 floats, mm, part coordinates),
        ``width_mm`` (float, ``Face.width``), ``curved`` (bool, a strip of a curved surface),
        ``candidate`` (bool, automatic selection may take it, with ``min_width``) and ``reason`` (str, why
        or why not: :func:`candidate_reason`).
    """
    rows: list[dict[str, object]] = []
    for f in faces:
        candidate, reason = candidate_reason(f, min_width=min_width)
        rows.append({
            "index": int(f.index),
            "area_mm2": float(f.area) + 0.0,
            "normal": [float(c) + 0.0 for c in f.normal],
            "inclination_deg": _degrees(f) + 0.0,
            "origin": [float(c) + 0.0 for c in f.origin],
            "width_mm": float(f.width) + 0.0,
            "curved": bool(f.curved),
            "candidate": candidate,
            "reason": reason,
        })
    return rows


_TABLE_COLUMNS = (
    ("face", ">"), ("area mm²", ">"), ("width mm", ">"), ("incl °", ">"),
    ("normal x", ">"), ("normal y", ">"), ("normal z", ">"),
    ("origin x", ">"), ("origin y", ">"), ("origin z", ">"), ("kind", "<"), ("candidate", "<"), ("reason", "<"),
)  # fmt: skip


def format_face_table(faces: tuple[Face, ...], *, min_width: float = MIN_FACE_WIDTH_MM) -> str:
    """Plain-text table of the faces, one line per face, fixed decimals, ending in a newline.

    Area 3 decimals (mm²), width 2 (mm), inclination 4 (degrees from +z), normal 6, origin 4 (mm); then
    the kind, whether automatic selection may take the face (yes/no) and why (:func:`candidate_reason`).
    """
    rows = [[header for header, _ in _TABLE_COLUMNS]]
    for f in faces:
        candidate, reason = candidate_reason(f, min_width=min_width)
        rows.append(
            [str(f.index), fixed(f.area, 3), fixed(f.width, 2), fixed(_degrees(f), 4)]
            + [fixed(c, 6) for c in f.normal]
            + [fixed(c, 4) for c in f.origin]
            + [face_kind(f), "yes" if candidate else "no", reason]
        )
    widths = [max(len(row[c]) for row in rows) for c in range(len(_TABLE_COLUMNS))]
    lines = [
        "  ".join(
            f"{cell:{align}{width}}" for cell, (_, align), width in zip(row, _TABLE_COLUMNS, widths, strict=True)
        ).rstrip()
        for row in rows
    ]
    return "\n".join(lines) + "\n"
