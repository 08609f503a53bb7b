"""Read a part from an STL file into a closed, outward-wound ``trimesh.Trimesh`` in mm.

Formats
-------
- Binary STL: an 80-byte header, a little-endian uint32 triangle count, then 50 bytes per triangle.
  A file is read as binary when its length is exactly ``84 + 50 * count``, whatever its header says:
  many CAD exporters (SolidWorks among them) start the *binary* header with ``solid`` too.
- ASCII STL: ``solid [name]``, then ``facet normal nx ny nz / outer loop / vertex x y z (3x) /
  endloop / endfacet`` records, then ``endsolid [name]``; several solids in one file are joined.
  Lines end in LF, CRLF or CR alike (line numbers in messages count each), or the whole solid is on
  one line; a leading UTF-8 byte-order mark is read as nothing.

Why not just ``trimesh.load``: trimesh 5.2's STL loader is lenient. A text file, random bytes, an
empty file and a truncated ASCII STL all come back as an *empty mesh* without an error, and a bad
number in an ASCII STL ends its number parse quietly. This module checks the bytes itself, strictly,
and hands trimesh only triangles it has validated (``trimesh.Trimesh(..., process=True)`` then merges
the duplicated vertices, exactly as ``trimesh.load`` would).

Up axis
-------
Many CAD systems export Y-up. ``up`` names the file's axis that points up on the machine; the part is
turned by a quarter or half turn so that this axis becomes +z (a proper rotation, right-handed, so
the winding and the outward side are kept):

    up = z   unchanged
    up = y   +90° about x   (y → z, z → −y)
    up = -y  −90° about x   (−y → z, z → y)
    up = x   −90° about y   (x → z, z → −x)
    up = -x  +90° about y   (−x → z, z → x)
    up = -z  180° about x   (−z → z, y → −y)

Size
----
A part whose largest extent is under 1 mm is an error (wrong units, see the message); one under 2 mm
or over 2 m is loaded with a :class:`~prs3_post.core.errors.Prs3Warning` (is the file in inches?).

Orientation
-----------
Facet normals stored in the file are ignored: the outward side of each triangle comes from its vertex
order (right-hand rule). That is only well defined on a closed mesh, so the mesh must be closed (every
edge shared by exactly two triangles); inconsistent winding and inside-out bodies are then repaired
(``trimesh.repair.fix_normals``, per connected body).
"""

from __future__ import annotations

import os
import re
import warnings
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.defaults import MM_PER_INCH
from prs3_post.core.errors import InputError, Prs3Warning
from prs3_post.core.input_files import lf_line_ends, read_input
from prs3_post.core.types import FloatArray
from prs3_post.part.setup_transform import (
    UP_ROTATION,  # defined with the setup, so that the CLI's --up needs no STL reader
)

if TYPE_CHECKING:  # trimesh (with networkx and PIL) costs 200 ms: imported by the commands that read an STL
    import trimesh

UNIT_SCALE: dict[str, float] = {"mm": 1.0, "inch": MM_PER_INCH}
"""mm per file unit, for each accepted ``units`` value."""

MIN_EXTENT_MM = 1.0
"""A part whose largest extent is below this (mm) is taken to be in the wrong units (an error)."""
WARN_EXTENT_MM = (2.0, 2000.0)
"""A part whose largest extent is outside this range (mm) loads with a warning about its units."""

MAX_COORDINATE_MM = 1e6
"""A part's vertices must lie within ±this (mm, a kilometre): far larger ones overflow areas and outlines."""

_NOT_STL = "not an STL file (expected ASCII 'solid ...' or binary STL): "
_BINARY_HEADER_BYTES = 84
_BINARY_RECORD = np.dtype(
    [("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attributes", "<u2")]
)  # itemsize 50
_BINARY_RECORD_BYTES = _BINARY_RECORD.itemsize
# One ASCII facet record as whitespace-separated tokens; None marks a number.
_ASCII_RECORD: tuple[str | None, ...] = (
    "facet", "normal", None, None, None, "outer", "loop",
    "vertex", None, None, None, "vertex", None, None, None, "vertex", None, None, None,
    "endloop", "endfacet",
)  # fmt: skip
_ASCII_VERTEX_COLUMNS = (8, 9, 10, 12, 13, 14, 16, 17, 18)
_SOLID_LINE = re.compile(r"^[ \t]*(end)?solid\b[^\n]*", re.MULTILINE)
#: A solid or endsolid line whose facet records share its line (a file on one line): its name ends
#: before them, and an endsolid may follow an endfacet. Three times slower than _SOLID_LINE: used
#: only where that finds records on a solid line, or solids that do not pair up.
_SOLID_INLINE = re.compile(
    r"(?:^[ \t]*|(?<=endfacet)[ \t]+)(end)?solid\b(?:(?![ \t]+(?:facet[ \t]+normal|endsolid)\b)[^\n])*", re.MULTILINE
)
_RECORD_ON_SOLID_LINE = re.compile(r"solid\b.*?[ \t](?:facet[ \t]+normal|endsolid)\b")
_BOM = "\xef\xbb\xbf"  # a UTF-8 byte-order mark, its bytes read as Latin-1


def up_rotation(up: str) -> FloatArray:
    """(3, 3) float — the proper rotation that turns the file axis ``up`` into +z (see ``UP_ROTATION``).

    >>> (up_rotation("y") @ [0.0, 1.0, 0.0]).tolist()
    [0.0, 0.0, 1.0]
    """
    return np.array(UP_ROTATION[up][1], dtype=np.float64)


def load_part(path: str | os.PathLike[str], *, units: str = "mm", up: str = "z") -> trimesh.Trimesh:
    """Load an STL part: closed, wound outward, in mm, turned so that ``up`` is +z (part coordinates).

    Parameters
    ----------
    path : str or path-like — the STL file (binary or ASCII)
    units : {"mm", "inch"} — length unit of the file's coordinates; "inch" scales by 25.4
    up : {"z", "y", "x", "-x", "-y", "-z"} — the file's axis that points up (see the module docstring)

    Returns
    -------
    trimesh.Trimesh
        Merged vertices ``(V, 3)`` float mm and triangles ``(F, 3)`` int, every edge shared by exactly
        two triangles, each triangle wound counter-clockwise seen from outside the material.

    Raises
    ------
    InputError
        With ``path``: unknown ``units`` or ``up``; file not found or unreadable; not an STL; a malformed ASCII
        STL (with the line); no triangles; a non-finite coordinate; a part smaller than 1 mm (wrong
        units); a mesh that is not closed.

    Warns
    -----
    Prs3Warning
        The part's largest extent is under 2 mm or over 2 m (``WARN_EXTENT_MM``): wrong units?
    """
    where = os.fspath(path)
    if units not in UNIT_SCALE:
        raise InputError(f"unknown units {units!r} (valid: {', '.join(UNIT_SCALE)})", path=where)
    if up not in UP_ROTATION:
        raise InputError(f"unknown up axis {up!r} (valid: {', '.join(UP_ROTATION)})", path=where)
    triangles = _triangles_from_bytes(read_input(where, "an STL file"), where)  # (F, 3, 3) file units
    if up != "z":  # entries 0 and ±1: exact, so vertex merging is unaffected
        triangles = triangles @ up_rotation(up).T
    count = len(triangles)
    if count == 0:
        raise InputError("STL has no triangles", path=where)
    reach = float(np.abs(triangles).max()) * UNIT_SCALE[units]
    if reach > MAX_COORDINATE_MM:
        raise InputError(f"coordinates reach {reach:.3g} mm: beyond ±{MAX_COORDINATE_MM:g} mm, the largest part "
                         "this tool handles (is the STL in the right units?)", path=where)
    import trimesh

    try:
        mesh = trimesh.Trimesh(
            vertices=triangles.reshape(-1, 3),
            faces=np.arange(3 * count, dtype=np.int64).reshape(count, 3),
            process=True,  # merge the per-triangle copies of each vertex, so that edges are shared
        )
    except (ValueError, IndexError) as exc:  # not expected for validated triangles; never a traceback
        raise InputError(f"trimesh cannot build a mesh from the triangles: {exc}", path=where) from exc
    # Triangles that collapsed to a repeated vertex have no area and no outward side; their only
    # effect would be bogus edges in the closedness check.
    faces = mesh.faces
    distinct = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    if not distinct.all():
        mesh.update_faces(distinct)
        mesh.remove_unreferenced_vertices()
        if len(mesh.faces) == 0:
            raise InputError("STL has no triangles with three distinct vertices", path=where)
    if not (mesh.area_faces > 0.0).any():
        raise InputError("STL has no triangle with an area (all are flat slivers): it encloses no solid", path=where)
    if UNIT_SCALE[units] != 1.0:
        mesh.apply_scale(UNIT_SCALE[units])
    _check_size(mesh, units, where)
    _orient_outward(mesh, where)
    return mesh


def _triangles_from_bytes(data: bytes, where: str) -> FloatArray:
    """Validate and decode STL bytes into triangles ``(F, 3, 3)`` float64, file units."""
    size = len(data)
    if size == 0:
        raise InputError(_NOT_STL + "the file is empty (0 bytes)", path=where)
    declared = None
    if size >= _BINARY_HEADER_BYTES:
        declared = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0])
        if size == _BINARY_HEADER_BYTES + _BINARY_RECORD_BYTES * declared:
            return _triangles_from_binary(data, declared, where)
    if not _looks_like_text(data[:4096]):
        if declared is None:
            reason = f"{size} bytes of binary data, shorter than a binary STL header (84 bytes)"
        else:
            expected = _BINARY_HEADER_BYTES + _BINARY_RECORD_BYTES * declared
            reason = (
                f"binary data whose header declares {declared} triangles ({expected} bytes), "
                f"but the file has {size} bytes"
            )
        raise InputError(_NOT_STL + reason, path=where)
    # latin-1 maps every byte to one character, so it cannot fail and keeps positions.
    text = lf_line_ends(data.decode("latin-1").removeprefix(_BOM))
    stripped = text.strip()
    if not stripped:
        raise InputError(_NOT_STL + "the file contains only whitespace", path=where)
    first_line = stripped.splitlines()[0].strip()
    if first_line.split()[0].lower() != "solid":
        shown = first_line.encode("latin-1").decode("utf-8", "replace")    # as the user's editor shows it
        raise InputError(_NOT_STL + f"text starting with {_quote(shown)} instead of 'solid'", path=where)
    return _triangles_from_ascii(text, where)


def _looks_like_text(head: bytes) -> bool:
    """True when ``head`` has no control bytes other than tab, newline, form feed and carriage return."""
    codes = np.frombuffer(head, dtype=np.uint8)
    control = (codes < 32) & ~np.isin(codes, (9, 10, 12, 13))
    return not bool(control.any())


def _quote(text: str, limit: int = 40) -> str:
    return f"'{text[:limit]}...'" if len(text) > limit else f"'{text}'"


def _as_written(text: str, line: int, token: str) -> str:
    """``token``, a word of line ``line`` of the lowered ``text`` (the file's bytes read as Latin-1), as the file has
    it, its bytes read as UTF-8 as the user's editor shows them (``'١'``, not ``'ù¡'``)."""
    start = 0
    for _ in range(line - 1):                          # only on an error: a loop over the newlines is fine
        start = text.index("\n", start) + 1
    end = text.find("\n", start)
    words = text[start:end if end >= 0 else len(text)].split()
    written = next((word for word in words if word.lower() == token), token)
    return written.encode("latin-1").decode("utf-8", "replace")


def _triangles_from_binary(data: bytes, count: int, where: str) -> FloatArray:
    records = np.frombuffer(data, dtype=_BINARY_RECORD, count=count, offset=_BINARY_HEADER_BYTES)
    triangles = records["vertices"].astype(np.float64)  # (F, 3, 3)
    finite = np.isfinite(triangles).all(axis=(1, 2))
    if not finite.all():
        first = int(np.argmin(finite))
        value = float(triangles[first][~np.isfinite(triangles[first])][0])
        raise InputError(
            f"triangle {first + 1} of {count} has a non-finite vertex coordinate ({value})", path=where
        )
    return triangles


def _triangles_from_ascii(text: str, where: str) -> FloatArray:
    """Parse an ASCII STL strictly; every error names the line."""
    lowered = text.lower()
    # 1. solid / endsolid lines must alternate, starting with solid and ending with endsolid.
    solid = _SOLID_LINE
    matches = list(solid.finditer(lowered))
    opened = sum(match.group(1) is None for match in matches)
    if 2 * opened != len(matches) or any(_RECORD_ON_SOLID_LINE.search(m.group()) for m in matches):
        solid = _SOLID_INLINE                          # records on a solid's line (or an error: said as before)
        matches = list(solid.finditer(lowered))
    open_line = None
    for match in matches:
        line = lowered.count("\n", 0, match.start()) + 1
        if match.group(1) is None:  # solid
            if open_line is not None:
                raise InputError(
                    f"'solid' inside the solid opened on line {open_line} (missing 'endsolid')",
                    path=where,
                    line=line,
                )
            open_line = line
        else:
            if open_line is None:
                raise InputError("'endsolid' without a matching 'solid'", path=where, line=line)
            open_line = None
    if open_line is not None:
        raise InputError(
            "'solid' has no matching 'endsolid' (is the file truncated?)", path=where, line=open_line
        )
    # 2. What is left (solid lines blanked, newlines kept for line numbers) must be whole facet records.
    body = solid.sub("", lowered)
    tokens = np.array(body.split(), dtype=object)
    per_record = len(_ASCII_RECORD)
    count = -(-len(tokens) // per_record)  # records, the last one possibly incomplete
    padded = np.full(count * per_record, None, dtype=object)
    padded[: len(tokens)] = tokens
    records = padded.reshape(count, per_record)
    # The first token out of place: a wrong keyword, or a keyword where a number belongs.
    keywords = np.array(sorted({k for k in _ASCII_RECORD if k}), dtype=object)
    first_bad = len(tokens)
    for column, keyword in enumerate(_ASCII_RECORD):
        cells = records[:, column]
        present = cells != None  # noqa: E711 (elementwise on an object array)
        wrong = (cells != keyword) if keyword else np.isin(cells, keywords)
        bad = np.flatnonzero(present & wrong)
        if len(bad):
            first_bad = min(first_bad, int(bad[0]) * per_record + column)
    if first_bad < len(tokens):
        expected = _ASCII_RECORD[first_bad % per_record]
        line = _line_of_token(body, first_bad)
        found = _as_written(text, line, str(tokens[first_bad]))
        raise InputError(
            f"expected {repr(expected) if expected else 'a number'}, found {_quote(found, 20)}", path=where, line=line
        )
    if len(tokens) % per_record:
        expected = _ASCII_RECORD[len(tokens) % per_record]
        line = _line_of_token(body, len(tokens) - 1)
        raise InputError(
            f"facet ends early: expected {repr(expected) if expected else 'a number'} "
            f"after {_quote(_as_written(text, line, str(tokens[-1])), 20)}",
            path=where,
            line=line,
        )
    # 3. Numbers: the facet normal is checked (strictness) but not used; the vertices are the data.
    # float() also takes '1_0' (10) and other scripts' digits ('١'): only plain decimals are numbers here.
    odd = _NOT_IN_A_NUMBER.search(body)
    if odd is not None:
        start = max(body.rfind(blank, 0, odd.start()) for blank in " \t\r\n\f\v") + 1
        token = re.match(r"\S+", body[start:])
        line = body.count("\n", 0, odd.start()) + 1
        shown = _as_written(text, line, token.group() if token else odd.group())
        raise InputError(f"{_quote(shown, 20)} is not a plain decimal number (like -12.5 or 1.25e+01)", path=where,
                         line=line)
    numeric = [column for column, keyword in enumerate(_ASCII_RECORD) if keyword is None]
    try:
        values = records[:, numeric].astype(np.float64)  # (F, 12)
    except ValueError as exc:
        row, col = _first_non_number(records[:, numeric])
        line = _line_of_token(body, row * per_record + numeric[col])
        found = _as_written(text, line, str(records[row, numeric[col]]))
        raise InputError(f"expected a number, found {_quote(found, 20)}", path=where, line=line) from exc
    vertex_cols = [numeric.index(column) for column in _ASCII_VERTEX_COLUMNS]
    triangles = values[:, vertex_cols].reshape(count, 3, 3)
    finite = np.isfinite(values)
    if not finite.all():
        row, col = (int(i) for i in np.argwhere(~finite)[0])
        line = _line_of_token(body, row * per_record + numeric[col])
        shown = _as_written(text, line, str(records[row, numeric[col]]))
        raise InputError(f"{_quote(shown, 20)} is not a finite number", path=where, line=line)
    return triangles


#: A character that is in no keyword of a facet record and in no plain decimal number.
_NOT_IN_A_NUMBER = re.compile(r"[^a-z0-9+\-.\s]")


def _first_non_number(cells: np.ndarray) -> tuple[int, int]:
    """(row, column) of the first cell of an object array of strings that float() rejects."""
    for (row, col), cell in np.ndenumerate(cells):  # error path only
        try:
            float(cell)
        except ValueError:
            return row, col
    return 0, 0  # unreachable when astype(float) failed


def _line_of_token(body: str, index: int) -> int:
    """1-based line of the ``index``-th whitespace-separated token of ``body`` (error path only)."""
    for number, match in enumerate(re.finditer(r"\S+", body)):
        if number == index:
            return body.count("\n", 0, match.start()) + 1
    return body.count("\n") + 1


def _check_size(mesh: trimesh.Trimesh, units: str, where: str) -> None:
    extents = mesh.extents  # (3,) mm
    largest = float(extents.max())
    dims = _dims(extents)
    low, high = WARN_EXTENT_MM
    if largest > high or MIN_EXTENT_MM <= largest < low:
        warnings.warn(Prs3Warning(f"{where}: {_size_doubt(extents, units)}", names_keys=("units",)), stacklevel=3)
    if largest >= MIN_EXTENT_MM:
        return
    if units == "mm":
        message = (
            f"part is only {dims} mm (largest extent under {MIN_EXTENT_MM:g} mm): "
            f"if the file is in inches, use {{units}} inch ({_dims(extents * MM_PER_INCH)} mm); "
            f"if it is in metres, scale it by 1000 ({_dims(extents * 1000.0)} mm)"
        )
    else:
        message = (
            f"part is only {dims} mm even in inches (largest extent under {MIN_EXTENT_MM:g} mm): "
            f"if the file is in metres, scale it by 1000 and load it with {{units}} mm "
            f"({_dims(extents / UNIT_SCALE[units] * 1000.0)} mm)"
        )
    raise InputError(message, path=where, names_keys=("units",))


def _size_doubt(extents: FloatArray, units: str) -> str:
    """Why a part of these extents (mm) is suspicious, and the likely fix (``WARN_EXTENT_MM``)."""
    low, high = WARN_EXTENT_MM
    small = float(extents.max()) < low
    size = f"only {_dims(extents)} mm (largest extent under {low:g} mm)" if small else (
        f"{_dims(extents)} mm (largest extent over {high / 1000.0:g} m)"
    )
    fixes = {
        (True, "mm"): f"is this STL in inches? use {{units}} inch ({_dims(extents * MM_PER_INCH)} mm)",
        (True, "inch"): f"is this STL in metres? scale it by 1000 and use {{units}} mm "
                        f"({_dims(extents / MM_PER_INCH * 1000.0)} mm)",
        (False, "mm"): f"is this STL in micrometres? scale it by 1/1000 ({_dims(extents / 1000.0)} mm)",
        (False, "inch"): f"is this STL in mm? use {{units}} mm ({_dims(extents / MM_PER_INCH)} mm)",
    }
    return f"part is {size}: {fixes[small, units]}"


def _dims(extents: FloatArray) -> str:
    """'0.1 x 0.1 x 0.3': each extent to 3 significant digits, never in exponent notation."""
    return " x ".join(
        np.format_float_positional(float(e), precision=3, unique=True, fractional=False, trim="-")
        for e in extents
    )


def _orient_outward(mesh: trimesh.Trimesh, where: str) -> None:
    """Require a closed mesh, then make its winding consistent and outward (in place).

    Each edge, as the pair of its vertex numbers, is counted in one sort of integer keys (not a
    unique over rows): used once, it is open; more than twice, shared too widely. Where every edge is
    used once each way (the winding agrees) and every body encloses a positive volume (as an export
    normally is), nothing changes; otherwise trimesh repairs it (``trimesh.repair.fix_normals``,
    per connected body).
    """
    edges = np.asarray(mesh.edges, dtype=np.int64)  # (3T, 2) each triangle's edges in its winding
    count = np.int64(len(mesh.vertices))
    directed = np.sort(edges[:, 0] * count + edges[:, 1])
    undirected = np.sort(edges.min(axis=1) * count + edges.max(axis=1))
    starts = np.flatnonzero(np.diff(undirected, prepend=-1))  # (E,) first use of each edge
    uses = np.diff(np.append(starts, len(undirected)))
    open_edges = int(np.count_nonzero(uses == 1))
    shared_edges = int(np.count_nonzero(uses > 2))
    if open_edges or shared_edges:
        found = []
        if open_edges:
            found.append(f"{open_edges} {'edge belongs' if open_edges == 1 else 'edges belong'} to only one triangle")
        if shared_edges:
            found.append(
                f"{shared_edges} {'edge is' if shared_edges == 1 else 'edges are'} shared by more than two triangles"
            )
        raise InputError(
            f"mesh is not closed ({', '.join(found)}): its outward side is undefined; "
            "repair the STL (close its holes) and export it again",
            path=where,
        )
    if not (directed[1:] == directed[:-1]).any() and (_body_volumes(mesh) >= 0.0).all():
        return                                          # wound consistently and outward already
    import trimesh.repair

    trimesh.repair.fix_normals(mesh, multibody=True)
    if not mesh.is_winding_consistent:
        raise InputError(
            "the triangles cannot be wound consistently (self-intersecting or non-orientable surface)",
            path=where,
        )


def _body_volumes(mesh: trimesh.Trimesh) -> FloatArray:
    """(B,) mm³: the signed volume each body of a closed, consistently wound mesh encloses (positive:
    wound outward), by the divergence theorem over its triangles as trimesh's ``mass_properties`` has it."""
    from prs3_post.part.meshgraph import body_labels

    corner = np.asarray(mesh.triangles, dtype=np.float64)  # (T, 3, 3) mm
    ab, ac = corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]
    cross_x = ab[:, 1] * ac[:, 2] - ab[:, 2] * ac[:, 1]  # (T,) x of the triangle's doubled area vector
    volume: FloatArray = np.bincount(body_labels(mesh), weights=cross_x * corner[:, :, 0].sum(axis=1)) / 6.0
    return volume
