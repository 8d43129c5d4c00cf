"""Mitsuba's `serialized` mesh files, as its documentation describes the format: a file holds
one or more meshes, each a little-endian header (uint16 0x041C, uint16 version 3 or 4) and a
zlib stream of: uint32 flags, (version 4) the shape's name ending in a NUL byte, uint64 vertex
and triangle counts, positions, then normals, texture coordinates and colours where the flags
say so, then the triangles' indices (uint32, or uint64 past 2^32 vertices). After the last
mesh, a table of each mesh's byte offset (uint64 in version 4, uint32 in version 3) and the
uint32 number of meshes end the file.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

MAGIC = 0x041C
HAS_NORMALS, HAS_TEXCOORDS, HAS_COLORS, FACE_NORMALS = 0x0001, 0x0002, 0x0008, 0x0010
SINGLE, DOUBLE = 0x1000, 0x2000


class SerializedError(ValueError):
    pass


def shape_count(data: bytes) -> int:
    if len(data) < 8:
        raise SerializedError("too short to be a serialized mesh file")
    return struct.unpack_from("<I", data, len(data) - 4)[0]


def _offset(data: bytes, index: int) -> int:
    count = shape_count(data)
    if not 0 <= index < count:
        raise SerializedError(f"shape_index {index} is out of range: the file holds {count} mesh(es)")
    version = struct.unpack_from("<H", data, 2)[0]
    width = 8 if version >= 4 else 4
    table = len(data) - 4 - width * count
    if table < 0:
        raise SerializedError("its table of mesh offsets is cut short")
    return struct.unpack_from("<Q" if width == 8 else "<I", data, table + width * index)[0]


def read_serialized(path: Path, index: int = 0):
    """(vertices (N, 3), faces (M, 3), normals or None, uvs or None) of mesh `index` in the file."""
    data = Path(path).read_bytes()
    start = _offset(data, index)
    if start + 4 > len(data):
        raise SerializedError(f"mesh {index} starts past the end of the file")
    magic, version = struct.unpack_from("<HH", data, start)
    if magic != MAGIC or version not in (3, 4):
        raise SerializedError(f"mesh {index} has no serialized-mesh header (0x041C, version 3 or 4)")
    try:
        body = zlib.decompressobj().decompress(data[start + 4 :])
    except zlib.error as exc:
        raise SerializedError(f"mesh {index}: its compressed data is damaged ({exc})") from None
    return _parse(body, version, index)


def _parse(body: bytes, version: int, index: int):
    pos = 4
    (flags,) = struct.unpack_from("<I", body, 0)
    if version == 4:
        end = body.find(b"\0", pos)
        if end < 0:
            raise SerializedError(f"mesh {index}: its name is not terminated")
        pos = end + 1
    n_vertices, n_triangles = struct.unpack_from("<QQ", body, pos)
    pos += 16
    real = np.dtype("<f8") if flags & DOUBLE else np.dtype("<f4")

    def take(count: int, dtype: np.dtype) -> np.ndarray:
        nonlocal pos
        size = count * dtype.itemsize
        if pos + size > len(body):
            raise SerializedError(f"mesh {index}: its data ends early ({n_vertices} vertices, {n_triangles} triangles)")
        array = np.frombuffer(body, dtype=dtype, count=count, offset=pos)
        pos += size
        return array

    vertices = take(3 * n_vertices, real).reshape(-1, 3).astype(np.float64)
    normals = take(3 * n_vertices, real).reshape(-1, 3).astype(np.float64) if flags & HAS_NORMALS else None
    uvs = take(2 * n_vertices, real).reshape(-1, 2).astype(np.float64) if flags & HAS_TEXCOORDS else None
    if flags & HAS_COLORS:
        take(3 * n_vertices, real)  # vertex colours: raylume has no use for them
    index_type = np.dtype("<u8") if n_vertices > 0xFFFFFFFF else np.dtype("<u4")
    faces = take(3 * n_triangles, index_type).reshape(-1, 3).astype(np.int64)
    if len(faces) and faces.max() >= n_vertices:
        raise SerializedError(f"mesh {index}: a triangle refers to a vertex that does not exist")
    if flags & FACE_NORMALS:
        normals = None  # the file asks for flat shading
    return vertices, faces, normals, uvs
