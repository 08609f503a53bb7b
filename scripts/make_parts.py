"""Write the demo and fixture STL parts (binary STL, byte-for-byte deterministic).

Run from the repository root:  python scripts/make_parts.py

Every part is a prism: a convex profile polygon in one coordinate plane, extruded along the third
axis. Caps are fan-triangulated, each side quad is two triangles, and each mesh is checked to be
closed, consistently wound and outward (positive volume) before it is written. trimesh's binary
export has an all-zero 80-byte header (no name, no timestamp), so the bytes depend only on the
geometry. The bad-input fixtures are written here too, so that every fixture has one source.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
TAN = math.tan
RAD = math.radians


def prism(profile: list[tuple[float, float]], extrude: tuple[float, float], axes: str) -> trimesh.Trimesh:
    """A closed prism: ``profile`` (P, 2) in the plane of ``axes[:2]``, extruded over ``extrude`` along ``axes[2]``.

    ``axes`` is a permutation of "xyz" naming the part axes of (profile a, profile b, extrusion).
    The profile must be convex (fan triangulation); its orientation does not matter: the winding is
    made outward from the sign of the volume.
    """
    ring = np.asarray(profile, dtype=np.float64)  # (P, 2)
    count = len(ring)
    column = {axis: i for i, axis in enumerate(axes)}
    vertices = np.zeros((2 * count, 3))
    for layer, depth in enumerate(extrude):
        block = np.column_stack([ring, np.full(count, depth)])  # (P, 3) in (a, b, extrusion)
        vertices[layer * count : (layer + 1) * count] = block[:, [column["x"], column["y"], column["z"]]]
    i = np.arange(count)
    j = (i + 1) % count
    caps_near = np.column_stack([np.zeros(count - 2, int), i[2:], i[1:-1]])
    caps_far = np.column_stack([np.full(count - 2, count), count + i[1:-1], count + i[2:]])
    sides = np.concatenate([np.column_stack([i, j, count + j]), np.column_stack([i, count + j, count + i])])
    faces = np.concatenate([caps_near, caps_far, sides])
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    if mesh.volume < 0:
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces[:, ::-1], process=False)
    if not (mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0):
        raise SystemExit(f"prism {profile} is not a closed outward mesh")
    return mesh


def wedge() -> trimesh.Trimesh:
    """The paper's wedge: x in [-50, 50], y in [150, 250], z from 0 up to 300 - x/2."""
    return prism([(-50.0, 0.0), (50.0, 0.0), (50.0, 275.0), (-50.0, 325.0)], (150.0, 250.0), "xzy")


def tilt35() -> trimesh.Trimesh:
    """Box x in [-50, 50], y in [150, 250], top z = 300 + (y - 200) tan 35° (normal (0, -sin 35°, cos 35°))."""
    top = lambda y: 300.0 + (y - 200.0) * TAN(RAD(35.0))  # noqa: E731
    return prism([(150.0, 0.0), (250.0, 0.0), (250.0, top(250.0)), (150.0, top(150.0))], (-50.0, 50.0), "yzx")


def twofaces() -> trimesh.Trimesh:
    """A ridge at x = 20, z = 300: face A (x < 20) inclined 20°, face B (x > 20) inclined 30°."""
    face_a = lambda x: 300.0 + (x - 20.0) * TAN(RAD(20.0))  # noqa: E731
    face_b = lambda x: 300.0 - (x - 20.0) * TAN(RAD(30.0))  # noqa: E731
    profile = [(-60.0, 0.0), (60.0, 0.0), (60.0, face_b(60.0)), (20.0, 300.0), (-60.0, face_a(-60.0))]
    return prism(profile, (150.0, 250.0), "xzy")


def wall30() -> trimesh.Trimesh:
    """A 30° face falling towards +x (x −50…50, y 150…250), and beside its low edge a wall 5 mm thick
    (x 50…55) rising 40 mm above that edge (the collision tests). The profile is not convex, but every
    point of it is seen from its first vertex (55, 0), so the fan from there triangulates it."""
    top = 275.0 + 100.0 * TAN(RAD(30.0))
    return prism([(55.0, 0.0), (55.0, 315.0), (50.0, 315.0), (50.0, 275.0), (-50.0, top), (-50.0, 0.0)],
                 (150.0, 250.0), "xzy")


def bracket() -> trimesh.Trimesh:
    """The tutorial's "own part", as a CAD system exports it: Y up, origin at a corner, a 25° face.

    x 0…60, y (up) 0…40 − x·tan 25° (so 12.02 at x = 60), z 0…40: with ``--up y`` its inclined face
    has the normal (sin 25°, 0, cos 25°) and the part lies at y −40…0 on the machine."""
    top = lambda x: 40.0 - x * TAN(RAD(25.0))  # noqa: E731
    return prism([(0.0, 0.0), (60.0, 0.0), (60.0, top(60.0)), (0.0, top(0.0))], (0.0, 40.0), "xyz")


def cube() -> trimesh.Trimesh:
    """An axis-aligned 50 mm cube: no inclined face."""
    return prism([(0.0, 0.0), (50.0, 0.0), (50.0, 50.0), (0.0, 50.0)], (0.0, 50.0), "xzy")


def downward() -> trimesh.Trimesh:
    """A 50 mm box whose only inclined face is a 10 mm, 45° chamfer on a bottom edge, facing down."""
    return prism([(10.0, 0.0), (50.0, 0.0), (50.0, 50.0), (0.0, 50.0), (0.0, 10.0)], (0.0, 50.0), "xzy")


def write(mesh: trimesh.Trimesh, *relative: str) -> None:
    data = trimesh.exchange.stl.export_stl(mesh)  # binary, zero header
    for name in relative:
        path = ROOT / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        print(f"wrote {name} ({len(data)} bytes, {len(mesh.faces)} triangles)")


def write_text(text: str, relative: str) -> None:
    path = ROOT / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="ascii", newline="\n")
    print(f"wrote {relative} ({len(text)} bytes, text)")


def main() -> None:
    write(wedge(), "postproc/parts/patel2020-wedge.stl", "fixtures/parts/wedge.stl")
    write(tilt35(), "fixtures/parts/tilt35.stl")
    write(twofaces(), "fixtures/parts/twofaces.stl")
    write(wall30(), "fixtures/parts/wall30.stl")
    write(bracket(), "fixtures/parts/bracket.stl")
    write(cube(), "fixtures/bad/cube.stl")
    write(downward(), "fixtures/bad/downward.stl")
    write(wedge().apply_scale(0.001), "fixtures/bad/tiny.stl")  # the wedge in metres: 0.1 x 0.1 x 0.3
    write_text(
        "This is a text file, not an STL.\nIt has no 'solid' line and no facets.\n", "fixtures/bad/not_an_stl.stl"
    )
    write_text("solid empty\nendsolid empty\n", "fixtures/bad/empty.stl")


if __name__ == "__main__":
    main()
