"""A mesh object of the scene model read from its file and placed in the world.

Placement, in order: `handedness = "right"` mirrors x (a right-handed file into raylume's
left-handed frame, the same as a scale of [-1, 1, 1] applied first), then the transform's
scale, rotate and translate (scene/mesh.py), or, with `fit`, rotate and then a uniform scale and
a move that put the bounding box's centre at `fit.center` and its largest side at `fit.size`.

Framing a mesh file (autoframe.py) needs the placed mesh before the scene is compiled; the mesh
it reads is kept here until the compiler asks for the same object, so the file is read once.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .mesh import MeshData, load_mesh, object_matrix_of, place_mesh
from .model import Mesh

# At most one placed mesh, waiting for the compiler: {key: MeshData}. Any later read empties it.
_handoff: dict = {}


def mesh_path(obj: Mesh, base_dir: Path) -> Path:
    """The object's file, relative paths taken from the scene file's folder."""
    path = Path(obj.file)
    return path if path.is_absolute() else Path(base_dir) / path


def load_mesh_object(obj: Mesh, base_dir: Path, keep: bool = False) -> MeshData:
    """The object's mesh in world space. `keep` holds it for the next call asking for the same
    object and unchanged file (the compiler after framing). Raises MeshError."""
    if obj.file is None:
        return _place_inline(obj)
    path = mesh_path(obj, base_dir)
    key = _key(path, obj)
    mesh = _handoff.pop(key, None) if key is not None else None
    _handoff.clear()
    if mesh is None:
        mesh = _place(path, obj)
    if keep and key is not None:
        _handoff[key] = mesh
    return mesh


def _key(path: Path, obj: Mesh):
    """What identifies a placed mesh: the file (and its version) and how it is placed."""
    try:
        stat = os.stat(path)
    except OSError:
        return None  # load_mesh will say what is wrong with the file
    return (
        str(path.resolve()),
        stat.st_mtime_ns,
        stat.st_size,
        obj.transform,
        obj.handedness,
        obj.smooth,
        obj.shape_index,
    )


def _place(path: Path, obj: Mesh) -> MeshData:
    t = obj.transform
    sx, sy, sz = t.scale3
    if obj.handedness == "right":
        sx = -sx  # mirrored first, in the file's own frame; load_mesh keeps normals and winding right
    matrix = None if t.matrix is None else np.array(t.matrix, dtype=np.float64)
    mesh = load_mesh(
        path,
        translate=t.translate,
        rotate=t.rotate,
        scale=(sx, sy, sz),
        smooth=obj.smooth,
        matrix=matrix,
        shape_index=obj.shape_index,
    )
    if t.fit is not None:
        mesh = fit_into_box(mesh, t.fit.center, t.fit.size)
    return mesh


def _place_inline(obj: Mesh) -> MeshData:
    """An inline mesh (vertices, faces, normals, uvs in the object itself), placed as a file's."""
    m = object_matrix_of(obj.transform)
    if obj.handedness == "right":
        m = m @ np.diag([-1.0, 1.0, 1.0, 1.0])
    mesh = place_mesh(obj.vertices, obj.faces, obj.normals, obj.uvs, m, obj.smooth, "Inline mesh")
    if obj.transform.fit is not None:
        mesh = fit_into_box(mesh, obj.transform.fit.center, obj.transform.fit.size)
    return mesh


def bounds(mesh: MeshData) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box (lo, hi) of the vertices that faces use."""
    from .mesh_faces import used_bounds  # Numba, loaded when a mesh is placed

    return used_bounds(mesh.vertices, mesh.faces)


def fit_into_box(mesh: MeshData, center, size: float) -> MeshData:
    """The mesh scaled uniformly so that its bounding box's largest side is `size`, and moved so
    that the box's centre is `center`. (A uniform positive scale leaves normals and winding.)"""
    lo, hi = bounds(mesh)
    factor = float(size) / float((hi - lo).max())
    vertices = (mesh.vertices - 0.5 * (lo + hi)) * factor + np.asarray(center, dtype=np.float64)
    return mesh._replace(vertices=vertices)
