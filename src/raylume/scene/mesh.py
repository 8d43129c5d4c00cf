"""Triangle-mesh import (OBJ, PLY, STL, OFF, glTF/GLB) through trimesh.

Coordinate conventions
----------------------
raylume's world is left-handed, +y up, as in pbrt. Rotations use the standard
matrices (the same ones pbrt's RotateX/Y/Z build)::

    Rx = [[1, 0, 0], [0, c, -s], [0, s, c]]
    Ry = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    Rz = [[c, -s, 0], [s, c, 0], [0, 0, 1]]

so, for example, rotating 90 degrees about y maps +x to -z and +z to +x. A
positive angle turns clockwise when looking from the positive axis towards the
origin (the left-hand rule in a left-handed frame). ``rotate`` is applied about
x, then y, then z, and the object-to-world matrix is ``M = T @ Rz @ Ry @ Rx @ S``.

What trimesh 5.x does and how this module copes
-----------------------------------------------
* ``process=False`` keeps vertices unmerged and unsorted, but the OBJ reader
  still drops vertices no face uses and splits a vertex whose corners carry
  different ``vt``/``vn`` indices (it must, to store one normal and one UV per
  vertex). Vertices stay in file order otherwise, so face indices equal the
  file's ``v`` indices only for an OBJ without unused vertices and without
  per-corner attributes. Face order is always the file's. (Its
  ``maintain_order=True`` keeps the indices but gives each vertex the median
  of its corners' UVs/normals, which is wrong at seams, so it is not used.)
* File vertex normals (OBJ ``vn``, PLY ``nx ny nz``, glTF ``NORMAL``) exist only
  as ``'vertex_normals'`` in the freshly loaded geometry's cache: asking for
  ``mesh.vertex_normals`` without them silently computes angle-weighted ones,
  and ``Trimesh.copy()`` -- used by ``Scene.dump()``/``to_mesh()``, hence by
  ``trimesh.load(force='mesh')`` -- drops them. So this module loads a Scene,
  reads the cache before anything copies the geometry, and bakes node
  transforms itself.
* UVs come from ``geometry.visual.uv`` (a ``TextureVisuals``), one per vertex.
* STL has no shared vertices (every triangle has its own three), so exactly
  coincident STL vertices are merged here (memory would otherwise triple).
* Computed (area-weighted) normals are accumulated over all vertices at the
  same position, so vertices split only because of UV seams do not crease.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .procedural import vertex_normals as _area_weighted_normals

__all__ = ["MeshError", "MeshData", "load_mesh", "transform_matrix", "SUPPORTED_EXTENSIONS"]

# Extension -> trimesh file type. Anything else is refused before trimesh is asked.
SUPPORTED_EXTENSIONS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".off": "off", ".gltf": "gltf", ".glb": "glb"}

# A face is degenerate when sin(angle at v0)^2 is below this: zero area up to
# float64 rounding, including faces that repeat a vertex index.
_DEGENERATE_SIN2 = 1e-20


class MeshError(ValueError):
    """A mesh file is missing, unreadable, malformed or holds no usable triangles."""


class MeshData(NamedTuple):
    vertices: np.ndarray  # float64 (V, 3), world space
    faces: np.ndarray  # int32 (F, 3), cross(v1 - v0, v2 - v0) points to the front
    normals: np.ndarray | None  # float32 (V, 3) unit world-space vertex normals, None = flat shading
    uvs: np.ndarray | None  # float32 (V, 2) texture coordinates, None when the file has none
    degenerate: int  # number of zero-area faces dropped


def _vec3(value, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape == ():
        arr = np.full(3, float(arr))
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be a finite number or 3-vector, got {value!r}")
    return arr


def transform_matrix(translate=(0.0, 0.0, 0.0), rotate=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    """4x4 float64 object-to-world matrix ``T @ Rz @ Ry @ Rx @ S``.

    ``scale`` is a number or a 3-vector (applied first), ``rotate`` holds
    degrees about x, then y, then z (see the module docstring for the
    convention), ``translate`` is a 3-vector (applied last).
    """
    t = _vec3(translate, "translate")
    ax, ay, az = np.radians(_vec3(rotate, "rotate"))
    s = _vec3(scale, "scale")
    (cx, sx), (cy, sy), (cz, sz) = ((np.cos(a), np.sin(a)) for a in (ax, ay, az))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx @ np.diag(s)
    m[:3, 3] = t
    return m


def _apply(m: np.ndarray, v: np.ndarray, f: np.ndarray, n: np.ndarray | None):
    """Transform positions by m, normals by its inverse transpose; a mirroring
    m (det < 0) reverses the winding so cross(v1 - v0, v2 - v0) still faces out.
    (The inverse transpose already keeps vertex normals pointing out.)"""
    a = m[:3, :3]
    v = v @ a.T + m[:3, 3]
    if n is not None:
        n = n @ np.linalg.inv(a)  # == (inv(a).T @ n.T).T
    if np.linalg.det(a) < 0:
        f = f[:, ::-1]
    return v, f, n


def _check_file(path: Path) -> str:
    """Fail early, with a plain message, on problems trimesh reports obscurely."""
    if not path.exists():
        raise MeshError(f"Mesh file {path} does not exist.")
    if path.is_dir():
        raise MeshError(f"Mesh file {path} is a directory, not a file.")
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        known = ", ".join(SUPPORTED_EXTENSIONS)
        raise MeshError(f"Mesh file {path} has unsupported extension {ext or '(none)'!r}; use one of {known}.")
    try:
        with open(path, "rb") as fh:
            empty = not fh.read(1)
    except OSError as exc:
        raise MeshError(f"Mesh file {path} cannot be read: {exc.strerror or exc}.") from exc
    if empty:
        raise MeshError(f"Mesh file {path} is empty.")
    return SUPPORTED_EXTENSIONS[ext]


def _why(exc: Exception) -> str:
    """Turn the exception trimesh raised while parsing into a plain reason."""
    if isinstance(exc, json.JSONDecodeError):
        return "it is not valid JSON"
    if isinstance(exc, FileNotFoundError):
        return f"a file it refers to does not exist ({exc})"
    if isinstance(exc, IndexError):
        return "a face refers to a vertex, normal or UV index that does not exist"
    # Text readers meeting binary bytes: trimesh then needs the optional
    # charset_normalizer module, so a missing module means "not text" here too.
    if isinstance(exc, (UnicodeError, ModuleNotFoundError)):
        return "it holds binary data where text was expected"
    return (str(exc) or type(exc).__name__).rstrip(".!")


def _read_parts(path: Path, file_type: str):
    """Every triangle mesh instance in the file as (vertices, faces, normals|None,
    uvs|None) with its scene-graph transform baked in."""
    import trimesh  # imported here: it is slow to import and only meshes need it

    try:
        if file_type == "gltf":
            # trimesh answers invalid JSON with a baffling "model.gltf" lookup error.
            json.loads(path.read_bytes())
        scene = trimesh.load_scene(str(path), file_type=file_type, process=False)
    except Exception as exc:  # trimesh raises anything from ValueError to ModuleNotFoundError
        raise MeshError(f"Mesh file {path} could not be parsed as {file_type.upper()}: {_why(exc)}.") from exc

    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geom = scene.geometry[name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue  # point clouds, paths
        v = np.asarray(geom.vertices, dtype=np.float64)
        f = np.asarray(geom.faces, dtype=np.int64)
        if f.min() < 0 or f.max() >= len(v):
            raise MeshError(f"Mesh file {path} has a face index outside the range of its {len(v)} vertices.")
        # Read the cache dict directly (as trimesh's own OBJ exporter does): the
        # property would invent normals the file lacks.
        n = getattr(geom._cache, "cache", {}).get("vertex_normals")
        n = None if n is None else np.asarray(n, dtype=np.float64)
        uv = getattr(geom.visual, "uv", None)
        uv = np.asarray(uv, dtype=np.float64) if uv is not None and len(uv) == len(v) else None
        transform = np.asarray(transform, dtype=np.float64)
        if not np.array_equal(transform, np.eye(4)):
            v, f, n = _apply(transform, v, f, n)
        parts.append((v, f, n, uv))
    if not parts:
        raise MeshError(f"Mesh file {path} contains no triangles.")
    return parts


def _concatenate(parts):
    """One mesh from several parts. A part lacking normals gets NaN ones (filled
    with computed normals later); a part lacking UVs gets (0, 0)."""
    offsets = np.cumsum([0] + [len(p[0]) for p in parts])
    v = np.concatenate([p[0] for p in parts])
    f = np.concatenate([p[1] + off for p, off in zip(parts, offsets)])
    n = uv = None
    if any(p[2] is not None for p in parts):
        n = np.concatenate([p[2] if p[2] is not None else np.full((len(p[0]), 3), np.nan) for p in parts])
    if any(p[3] is not None for p in parts):
        uv = np.concatenate([p[3] if p[3] is not None else np.zeros((len(p[0]), 2)) for p in parts])
    return v, f, n, uv


def _weld(*arrays):
    """Group rows that are bit-identical across all given per-vertex arrays.

    Returns (keep, remap): ``keep`` indexes the first row of each group, in
    order of first appearance, and ``remap`` maps every row to its group.
    Rows are grouped by a 64-bit hash (sorting uint64 is ~10x faster than
    sorting raw rows); a hash collision is detected and falls back to exact rows.
    """
    # "+ 0.0" turns -0.0 into 0.0 so the two compare equal bitwise.
    key = np.ascontiguousarray(np.concatenate([a for a in arrays if a is not None], axis=1) + 0.0)
    bits = key.view(np.uint64)
    h = np.zeros(len(bits), dtype=np.uint64)
    for col in bits.T:  # splitmix64-style mixing, wrapping uint64 arithmetic
        h ^= col
        h ^= h >> np.uint64(31)
        h *= np.uint64(0x9E3779B97F4A7C15)
        h ^= h >> np.uint64(29)
    _, first, inverse = np.unique(h, return_index=True, return_inverse=True)
    if not np.array_equal(bits[first][inverse], bits):
        rows = bits.view(np.dtype((np.void, bits.itemsize * bits.shape[1]))).ravel()
        _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return first[order], rank[inverse.ravel()]


def _smooth_normals(v, f):
    """Area-weighted normals shared by all vertices at the same position, so
    vertices split only for UV seams (or STL/glTF duplicates) do not crease."""
    keep, remap = _weld(v)
    return _area_weighted_normals(v[keep], remap[f])[remap]


def load_mesh(path, translate=(0.0, 0.0, 0.0), rotate=(0.0, 0.0, 0.0), scale=(1.0, 1.0, 1.0), smooth=None) -> MeshData:
    """Load a triangle mesh file and place it in the world.

    ``translate``/``rotate``/``scale`` are as in :func:`transform_matrix`.
    ``smooth``: True -> vertex normals from the file, else computed
    area-weighted; False -> ``normals`` is None (flat shading); None -> the
    file's normals when it has them, else None. Zero-area faces are dropped
    and counted. Every problem with the file raises :class:`MeshError`.
    """
    path = Path(os.fspath(path))
    try:
        m = transform_matrix(translate, rotate, scale)
    except ValueError as exc:
        raise MeshError(f"Mesh {path} cannot be placed: {exc}.") from exc
    if np.linalg.det(m[:3, :3]) == 0:
        raise MeshError(f"Mesh {path} cannot be placed: its scale has a zero component.")

    file_type = _check_file(path)
    v, f, n, uv = _concatenate(_read_parts(path, file_type))
    if not np.all(np.isfinite(v)):
        raise MeshError(f"Mesh file {path} has vertex coordinates that are NaN or infinite.")
    if file_type == "stl":
        keep, remap = _weld(v, n, uv)
        v, f = v[keep], remap[f]
        n, uv = (None if a is None else a[keep] for a in (n, uv))
    if len(v) > np.iinfo(np.int32).max:
        raise MeshError(f"Mesh file {path} has more vertices than int32 face indices can address.")

    if not np.array_equal(m, np.eye(4)):
        v, f, n = _apply(m, v, f, n)

    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    cross = np.cross(e1, e2)
    area2 = np.einsum("ij,ij->i", cross, cross)
    scale2 = np.einsum("ij,ij->i", e1, e1) * np.einsum("ij,ij->i", e2, e2)
    good = area2 > _DEGENERATE_SIN2 * scale2
    del e1, e2, cross, area2, scale2
    degenerate = int(len(f) - np.count_nonzero(good))
    if degenerate == len(f):
        raise MeshError(f"Mesh file {path} has only zero-area (degenerate) faces.")
    f = np.ascontiguousarray(f[good] if degenerate else f, dtype=np.int32)

    normals = None
    if smooth is not False and n is not None:
        length = np.linalg.norm(n, axis=1)
        bad = ~((length > 0) & np.isfinite(length))  # missing (NaN) or broken file normals
        normals = n / np.where(bad, 1.0, length)[:, None]
        if bad.any():
            normals[bad] = _smooth_normals(v, f)[bad]
        normals = normals.astype(np.float32)
    elif smooth:
        normals = _smooth_normals(v, f)
    return MeshData(
        vertices=np.ascontiguousarray(v, dtype=np.float64),
        faces=f,
        normals=normals,
        uvs=None if uv is None else uv.astype(np.float32),
        degenerate=degenerate,
    )
