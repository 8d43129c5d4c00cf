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
* The OBJ reader takes face index 0 (invalid: OBJ counts from 1) as the first element,
  and drops all texture coordinates when a ``vt`` index is past the end, both silently.
  Where that shows (only zero-area faces, an IndexError, no UVs from a file with ``vt``
  lines) the file is scanned for the line at fault (``_obj_problem``, which also names a
  number that is not one, or a ``v`` line of two numbers that the reader takes as 2D); an index 0
  among valid faces is not found, as scanning every OBJ would add a quarter to its load.
* STL has no shared vertices (every triangle has its own three), so exactly
  coincident STL vertices are merged here (memory would otherwise triple).
* Computed (area-weighted) normals are accumulated over all vertices at the
  same position, so vertices split only because of UV seams do not crease.
* trimesh reads only a PLY's ``face`` element; a PLY that stores its surface as
  triangle strips (``element tristrips`` with a ``vertex_indices`` list, -1
  restarting a strip, as the Cyberware/Stanford scans such as igea.ply do) loads
  as a point cloud. Such files are read by the small PLY reader below instead.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .generated import generator_hint
from .procedural import vertex_normals as _area_weighted_normals
from .serialized import read_serialized

__all__ = [
    "SUPPORTED_EXTENSIONS",
    "MeshData",
    "MeshError",
    "load_mesh",
    "object_matrix_of",
    "place_mesh",
    "strips_to_triangles",
    "transform_matrix",
]

# Extension -> trimesh file type. Anything else is refused before trimesh is asked.
SUPPORTED_EXTENSIONS = {".obj": "obj", ".ply": "ply", ".stl": "stl", ".off": "off", ".gltf": "gltf", ".glb": "glb"}
SUPPORTED_EXTENSIONS[".serialized"] = "serialized"  # Mitsuba's own format (scene/serialized.py)

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


def object_matrix_of(t) -> np.ndarray:
    """4x4 float64 object-to-world matrix of a model Transform: its `matrix` when it has one,
    else ``T @ Rz @ Ry @ Rx @ S`` of its translate, rotate and scale."""
    if getattr(t, "matrix", None) is not None:
        return np.array(t.matrix, dtype=np.float64)
    return transform_matrix(t.translate, t.rotate, t.scale3)


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
        raise MeshError(f"Mesh file {path} does not exist{generator_hint(path)}.")
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
    if isinstance(exc, KeyError):  # a reader looking up a property or element the file lacks
        return f"it has no {exc.args[0]!r} where the format needs one" if exc.args else "a required field is missing"
    # Text readers meeting binary bytes: trimesh then needs the optional
    # charset_normalizer module, so a missing module means "not text" here too.
    if isinstance(exc, (UnicodeError, ModuleNotFoundError)):
        return "it holds binary data where text was expected"
    return (str(exc) or type(exc).__name__).rstrip(".!")


def _read_parts(path: Path, file_type: str, shape_index: int = 0):
    """Every triangle mesh instance in the file as (vertices, faces, normals|None,
    uvs|None) with its scene-graph transform baked in (of a .serialized file, the mesh
    `shape_index`)."""
    if file_type == "serialized":
        try:
            return [read_serialized(path, shape_index)]
        except (ValueError, struct.error) as exc:
            raise MeshError(f"Mesh file {path} could not be read as a Mitsuba serialized mesh: {exc}.") from exc
    if file_type == "ply":
        strips = _read_strip_ply(path)
        if strips is not None:
            return [strips]
    import trimesh  # imported here: it is slow to import and only meshes need it

    try:
        if file_type == "gltf":
            # trimesh answers invalid JSON with a baffling "model.gltf" lookup error.
            json.loads(path.read_bytes())
        scene = trimesh.load_scene(str(path), file_type=file_type, process=False)
    except Exception as exc:  # trimesh raises anything from ValueError to ModuleNotFoundError
        if file_type == "ply" and _ply_polygons_mixed(path):
            # trimesh's binary PLY reader takes faces of one size only (a mesh of quads and
            # triangles, as Blender writes, is "unexpected length"): read by the module's own
            return [_read_own_ply(path)]
        why = _format_problem(path, file_type) or _why(exc)
        raise MeshError(f"Mesh file {path} could not be parsed as {file_type.upper()}: {why}.") from exc

    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geom = scene.geometry[name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue  # point clouds, paths
        v = np.asarray(geom.vertices, dtype=np.float64)
        f = np.asarray(geom.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:  # trimesh's OBJ reader takes a short `v` line so
            why = _format_problem(path, file_type) or "its vertices are not 3D points"
            raise MeshError(f"Mesh file {path} could not be parsed as {file_type.upper()}: {why}.")
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
        short = _stl_truncated(path) if file_type == "stl" else None
        if short is not None:
            raise MeshError(f"Mesh file {path} could not be parsed as STL: {short}.")
        raise MeshError(f"Mesh file {path} contains no triangles.")
    return parts


def _format_problem(path: Path, file_type: str) -> str | None:
    """What raylume's own look at a file trimesh could not parse finds wrong with it, or None."""
    if file_type == "obj":
        return _obj_problem(path)
    if file_type == "stl":
        return _stl_truncated(path)
    return None


def _stl_truncated(path: Path) -> str | None:
    """Why a binary STL file is cut short, or None: trimesh reads such a file as an
    ASCII STL, which finds no triangles (trimesh 4) or fails to decode it (trimesh 5.2)."""
    data = path.read_bytes()
    if len(data) < 84 or data[:5].lower() == b"solid" and b"facet" in data[:1024]:
        return None  # too short to be binary, or text
    count = struct.unpack_from("<I", data, 80)[0]
    needed = 84 + 50 * count
    if len(data) >= needed:
        return None
    return f"its header counts {count} triangles, which take {needed} bytes, but the file has {len(data)} (cut short?)"


# ---------------------------------------------------------------- PLY triangle strips

_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_PLY_FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}


class _PlyElement(NamedTuple):
    name: str
    count: int
    # (name, type) for a scalar, (name, (count type, item type)) for a list; numpy type codes
    properties: list


def _ply_header(data: bytes):
    """(format, elements, body offset) of a PLY file; raises ValueError on a malformed header."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ValueError("it has no PLY header")
    body = data.index(b"\n", end) + 1
    fmt, elements = None, []
    for line in data[:end].decode("ascii", "replace").splitlines()[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) >= 2 and words[1] in _PLY_FORMATS:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append(_PlyElement(words[1], int(words[2]), []))
        elif (
            words[0] == "property"
            and elements
            and len(words) == 5
            and words[1] == "list"
            and words[2] in _PLY_TYPES
            and words[3] in _PLY_TYPES
        ):
            elements[-1].properties.append((words[4], (_PLY_TYPES[words[2]], _PLY_TYPES[words[3]])))
        elif words[0] == "property" and elements and len(words) == 3 and words[1] in _PLY_TYPES:
            elements[-1].properties.append((words[2], _PLY_TYPES[words[1]]))
        else:
            raise ValueError(f"its header has a line PLY does not define: {line.strip()!r}")
    if fmt is None:
        raise ValueError("its header names no known format (ascii, binary_little_endian, binary_big_endian)")
    return fmt, elements, body


class _PlyBody:
    """Reads one element after another from a PLY body, ASCII or binary. An element of
    scalars comes back as a structured array (one vectorised read); an element with lists
    as a list of rows, each a dict of property -> scalar or 1D array."""

    def __init__(self, data: bytes, fmt: str, offset: int):
        self.endian = _PLY_FORMATS[fmt]
        self.ascii = fmt == "ascii"
        self.data, self.pos = data, offset
        if self.ascii:
            self.tokens, self.pos = data[offset:].split(), 0

    def read(self, element: _PlyElement):
        if all(isinstance(t, str) for _, t in element.properties):
            return self._scalars(element)
        return [self._row(element.properties) for _ in range(element.count)]

    def _scalars(self, element: _PlyElement) -> np.ndarray:
        dtype = np.dtype([(name, self.endian + t) for name, t in element.properties])
        if self.ascii:
            n = element.count * len(element.properties)
            if self.pos + n > len(self.tokens):
                raise ValueError(f"its {element.name} element ends early")
            values = np.array(self.tokens[self.pos : self.pos + n], dtype=np.float64).reshape(element.count, -1)
            self.pos += n
            out = np.empty(element.count, dtype=dtype)
            for k, (name, _) in enumerate(element.properties):
                out[name] = values[:, k]
            return out
        if self.pos + element.count * dtype.itemsize > len(self.data):
            raise ValueError(f"its {element.name} element ends early")
        out = np.frombuffer(self.data, dtype=dtype, count=element.count, offset=self.pos)
        self.pos += element.count * dtype.itemsize
        return out

    def _row(self, properties) -> dict:
        row = {}
        for name, kind in properties:
            if isinstance(kind, str):
                row[name] = self._take(kind, 1)[0]
            else:
                count = int(self._take(kind[0], 1)[0])
                if count < 0:
                    raise ValueError(f"a {name} list has a negative length")
                row[name] = self._take(kind[1], count)
        return row

    def _take(self, kind: str, n: int) -> np.ndarray:
        if self.ascii:
            if self.pos + n > len(self.tokens):
                raise ValueError("its data ends early")
            out = np.array(self.tokens[self.pos : self.pos + n], dtype=np.float64).astype(kind)
            self.pos += n
            return out
        dtype = np.dtype(self.endian + kind)
        if self.pos + n * dtype.itemsize > len(self.data):
            raise ValueError("its data ends early")
        out = np.frombuffer(self.data, dtype=dtype, count=n, offset=self.pos)
        self.pos += n * dtype.itemsize
        return out


def strips_to_triangles(strips) -> np.ndarray:
    """Triangle strips -> (F, 3) triangles, as OpenGL's GL_TRIANGLE_STRIP: the k-th triangle
    of a strip s is (s[k], s[k+1], s[k+2]) for even k and (s[k+1], s[k], s[k+2]) for odd k,
    so all face the same way. -1 ends a strip and starts a new one (k counts from 0 again).
    Triangles that repeat an index (the zero-area joins between strips) are dropped."""
    parts = [np.append(np.asarray(s, dtype=np.int64).ravel(), -1) for s in strips]
    seq = np.concatenate(parts) if parts else np.zeros(0, np.int64)
    if len(seq) < 3:
        return np.zeros((0, 3), np.int64)
    if (seq < -1).any():
        raise ValueError("a triangle strip has a negative vertex index other than the -1 restart marker")
    at = np.arange(len(seq))
    last_restart = np.maximum.accumulate(np.where(seq == -1, at, -1))
    odd = ((at - last_restart - 1)[:-2] % 2) == 1  # position of each triangle inside its strip
    a, b, c = seq[:-2], seq[1:-1], seq[2:]
    tri = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)
    keep = (a >= 0) & (b >= 0) & (c >= 0) & (a != b) & (b != c) & (a != c)
    return tri[keep]


def _fan(polygons) -> np.ndarray:
    """PLY face lists (any vertex count >= 3) -> triangles (v0, vk, vk+1)."""
    tris = [[p[0], p[k], p[k + 1]] for p in polygons for k in range(1, len(p) - 1)]
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def _list_of(rows, element: _PlyElement):
    """The vertex_indices (or vertex_index) list of each row of a face/tristrips element."""
    names = [name for name, kind in element.properties if not isinstance(kind, str)]
    name = next((n for n in ("vertex_indices", "vertex_index") if n in names), None)
    if name is None:
        raise ValueError(f"its {element.name} element has no vertex_indices list")
    return [row[name] for row in rows]


def _read_strip_ply(path: Path):
    """The part (vertices, faces, normals|None, uvs|None) of a PLY file with a `tristrips`
    element, or None for any other PLY (trimesh reads those)."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    if b"tristrips" not in head.split(b"end_header")[0]:
        return None  # the usual case, decided without reading the whole file
    try:
        if "tristrips" not in {e.name for e in _ply_header(path.read_bytes())[1]}:
            return None
    except (ValueError, OverflowError) as exc:
        raise MeshError(f"Mesh file {path} could not be parsed as PLY: {_why(exc)}.") from exc
    return _read_own_ply(path)


def _ply_polygons_mixed(path: Path) -> bool:
    """Whether a PLY file that trimesh refused is binary with a face list (whose rows may differ
    in length): the own reader's case. Anything else keeps trimesh's answer."""
    try:
        fmt, elements, _ = _ply_header(path.read_bytes())
    except (ValueError, OverflowError, OSError):
        return False
    face = next((e for e in elements if e.name == "face"), None)
    return fmt != "ascii" and face is not None and any(not isinstance(kind, str) for _, kind in face.properties)


def _read_own_ply(path: Path):
    """The part (vertices, faces, normals|None, uvs|None) of a PLY file read by this module:
    faces of any size (fanned into triangles) and triangle strips."""
    try:
        data = path.read_bytes()
        fmt, elements, offset = _ply_header(data)
        body, found = _PlyBody(data, fmt, offset), {}
        wanted = {"vertex", "face", "tristrips"} & {e.name for e in elements}
        for element in elements:
            if wanted <= found.keys():
                break  # what follows (edges, materials, ...) is not needed
            found[element.name] = (element, body.read(element))
        if "vertex" not in found or not {"x", "y", "z"} <= set(found["vertex"][1].dtype.names or ()):
            raise ValueError("it has no vertex element with x, y and z")
        vertex = found["vertex"][1]
        faces = []
        if "face" in found:
            faces.append(_fan(_list_of(found["face"][1], found["face"][0])))
        if "tristrips" in found:
            faces.append(strips_to_triangles(_list_of(found["tristrips"][1], found["tristrips"][0])))
    except (ValueError, OverflowError) as exc:
        raise MeshError(f"Mesh file {path} could not be parsed as PLY: {_why(exc)}.") from exc
    v = np.column_stack([vertex[c] for c in "xyz"]).astype(np.float64)
    f = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    if len(f) == 0:
        raise MeshError(f"Mesh file {path} contains no triangles.")
    if f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"Mesh file {path} has a face index outside the range of its {len(v)} vertices.")
    names = set(vertex.dtype.names)
    n = (
        np.column_stack([vertex[c] for c in ("nx", "ny", "nz")]).astype(np.float64)
        if {"nx", "ny", "nz"} <= names
        else None
    )
    uv_names = next((pair for pair in (("u", "v"), ("s", "t"), ("texture_u", "texture_v")) if set(pair) <= names), None)
    uv = None if uv_names is None else np.column_stack([vertex[c] for c in uv_names]).astype(np.float64)
    return v, f, n, uv


def _concatenate(parts):
    """One mesh from several parts. A part lacking normals gets NaN ones (filled
    with computed normals later); a part lacking UVs gets (0, 0). One part is itself (a copy
    of a large mesh's arrays costs ~0.3 s at 4M triangles, its pages faulted in)."""
    if len(parts) == 1:
        return parts[0]
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


def load_mesh(
    path,
    translate=(0.0, 0.0, 0.0),
    rotate=(0.0, 0.0, 0.0),
    scale=(1.0, 1.0, 1.0),
    smooth=None,
    matrix: np.ndarray | None = None,
    shape_index: int = 0,
) -> MeshData:
    """Load a triangle mesh file and place it in the world.

    ``translate``/``rotate``/``scale`` are as in :func:`transform_matrix`;
    ``matrix`` (4x4, column vectors), when given, is applied after them.
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
    if matrix is not None:
        m = np.asarray(matrix, dtype=np.float64) @ m
    if np.linalg.det(m[:3, :3]) == 0:
        raise MeshError(f"Mesh {path} cannot be placed: its scale has a zero component.")

    file_type = _check_file(path)
    v, f, n, uv = _concatenate(_read_parts(path, file_type, shape_index))
    if not np.all(np.isfinite(v)):
        raise MeshError(f"Mesh file {path} has vertex coordinates that are NaN or infinite.")
    if file_type == "stl":
        keep, remap = _weld(v, n, uv)
        v, f = v[keep], remap[f]
        n, uv = (None if a is None else a[keep] for a in (n, uv))
    if len(v) > np.iinfo(np.int32).max:
        raise MeshError(f"Mesh file {path} has more vertices than int32 face indices can address.")
    try:
        mesh = place_mesh(v, f, n, uv, m, smooth, f"Mesh file {path}")
    except MeshError:  # only zero-area faces: an OBJ's index 0, which trimesh reads as 1, may be why
        problem = _obj_problem(path) if file_type == "obj" else None
        if problem is None:
            raise
        raise MeshError(f"Mesh file {path} could not be parsed as OBJ: {problem}.") from None
    return mesh


# ---------------------------------------------------------------- OBJ face indices

_OBJ_ELEMENTS = {b"v": "vertex", b"vt": "texture coordinate", b"vn": "normal"}
_OBJ_CORNER = (b"v", b"vt", b"vn")  # the order of a face corner's v/vt/vn indices


# How many numbers each OBJ element line takes: v x y z [w | r g b], vt u [v [w]], vn x y z.
_OBJ_NUMBERS = {b"v": (3, 4, 6, 7), b"vt": (1, 2, 3), b"vn": (3,)}


def _obj_problem(path: Path) -> str | None:
    """The first line of an OBJ file at fault, in words, or None: a number that is not one,
    a vertex of too few coordinates, or a face index that does not exist (a slow Python pass
    over the file, read only when trimesh's result shows that something is wrong)."""
    lines = path.read_bytes().splitlines()
    return _obj_number_problem(lines) or _obj_index_problem(lines)


def _obj_number_problem(lines: list[bytes]) -> str | None:
    for number, line in enumerate(lines, 1):
        words = line.split(b"#", 1)[0].split()
        if not words or words[0] not in _OBJ_NUMBERS:
            continue
        shown = line.split(b"#", 1)[0].strip().decode("utf-8", "replace")[:60]
        name = _OBJ_ELEMENTS[words[0]]
        for word in words[1:]:
            try:
                float(word)
            except ValueError:
                return f"line {number} ({shown}): {word.decode('utf-8', 'replace')!r} is not a number"
        if len(words) - 1 not in _OBJ_NUMBERS[words[0]]:
            *most, last = (str(c) for c in _OBJ_NUMBERS[words[0]])
            counts = f"{', '.join(most)} or {last}" if most else last
            return f"line {number} ({shown}): a {name} takes {counts} numbers, not {len(words) - 1}"
    return None


def _obj_index_problem(lines: list[bytes]) -> str | None:
    """The first face index of an OBJ file's `lines` that is 0 or past the end of its list, in
    words, or None. trimesh (5.x) reads index 0 as the first element and drops the texture
    coordinates of a file with a vt index past the end, saying nothing."""
    totals = dict.fromkeys(_OBJ_ELEMENTS, 0)
    for line in lines:
        words = line.split(b"#", 1)[0].split()
        if words and words[0] in totals:
            totals[words[0]] += 1
    seen = dict.fromkeys(_OBJ_ELEMENTS, 0)  # a negative index counts back from the elements before it
    for number, line in enumerate(lines, 1):
        words = line.split(b"#", 1)[0].split()
        if words and words[0] in seen:
            seen[words[0]] += 1
        if not words or words[0] != b"f":
            continue
        for corner in words[1:]:
            for key, text in zip(_OBJ_CORNER, corner.split(b"/")):
                problem = _obj_bad_index(text, totals[key], seen[key], _OBJ_ELEMENTS[key], key.decode())
                if problem is not None:
                    shown = line.split(b"#", 1)[0].strip().decode("utf-8", "replace")[:60]
                    return f"line {number} ({shown}): {problem}"
    return None


def _obj_bad_index(text: bytes, total: int, before: int, name: str, key: str) -> str | None:
    if not text:
        return None  # "1//3": no texture coordinate
    try:
        i = int(text)
    except ValueError:
        return f"{name} index {text.decode('utf-8', 'replace')!r} is not a whole number"
    if i == 0:
        return f"{name} index 0 is invalid (OBJ indices start at 1)"
    if i > total:
        return f"{name} index {i} is out of range (the file has {total} {key} lines)"
    if i < 0 and -i > before:
        return f"{name} index {i} is out of range (only {before} {key} lines come before it)"
    return None


def obj_uv_problem(path: Path) -> str | None:
    """Why an OBJ file loaded without texture coordinates although it has vt lines, or None:
    asked only where a texture needs them (it reads the file again)."""
    if path.suffix.lower() != ".obj":
        return None
    try:
        data = path.read_bytes()
    except OSError:
        return None
    if b"vt" not in data:  # the common case, a file without texture coordinates: no slow pass
        return None
    problem = _obj_index_problem(data.splitlines())
    if problem is not None:
        return f"its texture coordinates could not be used: {problem}"
    return "its texture coordinates could not be used (the faces do not refer to them)"


def place_mesh(v, f, n, uv, m: np.ndarray, smooth, what: str) -> MeshData:
    """Vertices (V, 3), faces (F, 3), optional normals (V, 3) and uvs (V, 2) in object space,
    placed by the 4x4 matrix `m` (zero-area faces dropped, `smooth` as in load_mesh). `what`
    names the mesh in MeshErrors ("Mesh file x.ply")."""
    v = np.asarray(v, dtype=np.float64)
    f = np.asarray(f, dtype=np.int64)
    n = None if n is None else np.asarray(n, dtype=np.float64)
    if not np.array_equal(m, np.eye(4)):
        v, f, n = _apply(m, v, f, n)

    from .mesh_faces import nondegenerate_faces  # Numba, loaded when a mesh is placed

    # e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]; c = np.cross(e1, e2):
    # good = (c * c).sum(1) > _DEGENERATE_SIN2 * (e1 * e1).sum(1) * (e2 * e2).sum(1)
    good, outside = nondegenerate_faces(v, f, _DEGENERATE_SIN2)
    if outside:
        raise MeshError(f"{what} has a face index outside the range of its {len(v)} vertices.")
    degenerate = int(len(f) - np.count_nonzero(good))
    if degenerate == len(f):
        raise MeshError(f"{what} has only zero-area (degenerate) faces.")
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
        uvs=None if uv is None else np.asarray(uv, dtype=np.float32),
        degenerate=degenerate,
    )
