"""Mesh files bounded before they are parsed: counts read cheaply from the bytes.

trimesh spends seconds and gigabytes on a file crafted to be costly (an OBJ face line of six
million indices, an OBJ of four million vertices and one face, an upper-case ``FACET`` STL, a
PLY whose header is larger than the part read for the count): :func:`mesh_bytes_problem`
bounds the triangles (after fanning polygons), the vertices and the PLY header from C-speed
byte counts first, with memory of the order of the file. Used by the engine's mesh loader and
by the job service's uploads (which answer 413).
"""
from __future__ import annotations

import re
from typing import Optional

# a triangle mesh has no use for more vertices than three per triangle
VERTICES_PER_TRIANGLE = 3
MAX_PLY_HEADER_BYTES = 64 * 1024  # a real header is a few hundred bytes

# blanks to " ", anything else to "x": a token starts at each " x"
_TOKEN_STARTS = bytes(32 if b in b" \t\r" else 120 for b in range(256))


def _binary_stl(data: bytes) -> bool:
    if len(data) < 84:
        return False
    n = int.from_bytes(data[80:84], "little")
    if 84 + 50 * n == len(data):
        return True
    return not data[:512].lstrip().lower().startswith(b"solid")


def mesh_counts(data: bytes, fmt: str, max_lines: int = 10**7) -> dict:
    """Upper bounds read without parsing: ``triangles`` (a polygon counts as its fan of
    n - 2; for an OBJ of more than ``max_lines`` faces, the face count), ``vertices``
    (None when the format gives no cheap count) and, for PLY, ``header_bytes``. ValueError
    for a PLY without a readable header."""
    fmt = fmt.lower()
    if fmt == "stl":
        if _binary_stl(data):
            return {"triangles": int.from_bytes(data[80:84], "little"), "vertices": None}
        lower = data.lower()  # any case: "FACET" is a facet too
        return {"triangles": lower.count(b"facet") - lower.count(b"endfacet"),
                "vertices": None}
    if fmt == "obj":
        # C-speed byte counts (a regex anchored at every line start, or one substituting
        # at every line, took seconds on millions of lines); faces are the lines starting
        # "f", as trimesh reads them; vertices are bounded by every "v" followed by a blank
        text = data.replace(b"\r", b" ") if b"\r" in data else data
        n_faces = (text.count(b"\nf ") + text.count(b"\nf\t")
                   + (text.startswith(b"f ") or text.startswith(b"f\t")))
        if n_faces > max_lines:  # already too many: nothing more need be read
            return {"triangles": n_faces, "vertices": None}
        n_vertices = text.count(b"v ") + text.count(b"v\t")
        text = b"\n" + text  # (fewer than max_lines faces: a copy is cheap next to parsing)
        lines, start = [], 0
        for marker in (b"\nf ", b"\nf\t"):
            start = text.find(marker)
            while start >= 0:
                end = text.find(b"\n", start + 1)
                lines.append(text[start + 1:end if end >= 0 else len(text)].strip())
                start = text.find(marker, end) if end >= 0 else -1
        # the indices of the face lines, counted as the tokens after "f" (a byte map and a
        # count); a face of n indices is a fan of n - 2 triangles
        indices = b"\n".join(lines).translate(_TOKEN_STARTS).count(b" x")
        return {"triangles": max(0, indices - 2 * len(lines)), "vertices": n_vertices}
    if fmt == "ply":
        end = data.find(b"end_header", 0, MAX_PLY_HEADER_BYTES)
        if not data.startswith(b"ply") or end < 0:
            long = len(data) > MAX_PLY_HEADER_BYTES and data.startswith(b"ply")
            raise ValueError(f"a PLY header longer than {MAX_PLY_HEADER_BYTES} bytes" if long
                             else "no PLY header (a file starting 'ply', ending 'end_header')")
        header = data[:end]
        faces = re.search(rb"element\s+face\s+(\d+)", header)
        verts = re.search(rb"element\s+vertex\s+(\d+)", header)
        return {"triangles": int(faces.group(1)) if faces else 0,
                "vertices": int(verts.group(1)) if verts else 0, "header_bytes": end}
    raise ValueError(f"unknown mesh format {fmt!r}")


def mesh_bytes_problem(data: bytes, fmt: str, max_triangles: int) -> Optional[str]:
    """Why the mesh file ``data`` (format ``fmt``: stl, obj or ply) is too large to parse
    with at most ``max_triangles`` triangles, or None. For PLY the face count is the header's
    (a face of n vertices is checked after parsing, with the fan it makes)."""
    try:
        counts = mesh_counts(data, fmt, max_lines=max_triangles)
    except ValueError as exc:
        return str(exc)
    if counts["triangles"] > max_triangles:
        return (f"has {counts['triangles']} triangles (counted before parsing, polygons as "
                f"their fans); at most {max_triangles} are allowed (decimate the mesh)")
    vertices = counts.get("vertices")
    if vertices is not None and vertices > VERTICES_PER_TRIANGLE * max_triangles:
        return (f"has {vertices} vertices (counted before parsing); at most "
                f"{VERTICES_PER_TRIANGLE * max_triangles} ({VERTICES_PER_TRIANGLE} per allowed "
                f"triangle) are accepted")
    return None
