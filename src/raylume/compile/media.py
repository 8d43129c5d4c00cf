"""Compile stage: participating media. The scene's [media] as the kernels' medium table (one row
per medium, kernels/shading/media/table.py), the grids' densities and majorant cells, and the
interface table: for each object, the medium inside and outside its surface. Bad input (a grid
file missing, not 3-D, negative or not finite; an interior on a mesh that is not closed) is a
SceneError naming the key.

Which medium lies outside an object is not written in the scene: it is the inside of the
innermost other object that holds it (the `interior` of a closed shape, or clear for a closed
dielectric without one), else the scene's outer medium, `[render] medium`. An object without
an interior is filled with what surrounds it, except a dielectric, which is a solid: clear
inside (so a glass in fog has no fog in it)."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import SceneError
from ..kernels.geometry.shapes import ANALYTIC
from ..kernels.geometry.transform import transform_point
from ..kernels.shading.materials.registry import is_solid
from ..kernels.shading.media import grid, homogeneous
from ..kernels.shading.media.table import MED_KIND, MED_WIDTH
from ..scene.checks import warn
from ..scene.generated import generator_hint
from ..scene.model import GridMedium, Mesh, Scene
from .objects import ANALYTIC_MODELS, object_matrix

NONE = -1  # no medium: clear space
MAX_DENSITY_VALUES = 1 << 28  # 1 GiB of float32 densities at most


class MediaTables(NamedTuple):
    data: np.ndarray  # float64 (K, MED_WIDTH)
    density: np.ndarray  # float32 (D,): every grid's densities, z-major
    majorants: np.ndarray  # float64 (C,): every grid's majorant cells
    interface: np.ndarray  # int32 (objects, 2): medium inside, outside (-1: none)
    camera: int  # the medium the camera sits in
    present: bool  # any medium at all
    pass_through: bool  # shadow rays must pass null boundaries and media (kernels' transmittance)


def build_media(scene: Scene, geometry, material_kinds: dict, source: str) -> MediaTables:
    """The media tables of `scene`; `geometry` is the objects stage's SceneGeometry (for the
    meshes' triangles) and `material_kinds` maps each object index to its material's type."""
    names = list(scene.media)
    index = {name: i for i, name in enumerate(names)}
    data = np.zeros((max(len(names), 1), MED_WIDTH), dtype=np.float64)
    densities: list[np.ndarray] = []
    majorants: list[np.ndarray] = []
    d_offset = c_offset = 0
    for i, name in enumerate(names):
        medium = scene.media[name]
        if isinstance(medium, GridMedium):
            density = load_density(medium, scene.base_dir, source, f"media.{name}.density")
            data[i, MED_KIND] = grid.KIND
            cells = grid.pack(medium, data[i], density, d_offset, c_offset)
            densities.append(density.ravel())
            majorants.append(cells.ravel())
            d_offset += density.size
            c_offset += cells.size
        else:
            data[i, MED_KIND] = homogeneous.KIND
            homogeneous.pack(medium, data[i])
    outer = NONE if scene.render.medium is None else index[scene.render.medium]
    null_boundaries = "null" in material_kinds.values()
    present = bool(names)
    if present:
        interface, solids = _interfaces(scene, geometry, index, outer, source)
        _check_camera(scene, solids, names, outer)
    else:
        interface = np.full((max(len(scene.objects), 1), 2), outer, dtype=np.int32)
    return MediaTables(
        data=data,
        density=np.concatenate(densities).astype(np.float32) if densities else np.zeros(1, np.float32),
        majorants=np.concatenate(majorants) if majorants else np.zeros(1, np.float64),
        interface=interface,
        camera=outer,
        present=present,
        pass_through=present or null_boundaries,
    )


def load_density(medium: GridMedium, base_dir: Path, source: str, where: str) -> np.ndarray:
    """The grid's density array from its .npy file, checked: 3-D, finite, not negative."""
    path = Path(medium.density)
    if not path.is_absolute():
        path = Path(base_dir) / path
    if path.suffix.lower() != ".npy":
        raise SceneError(f"{source}: {where}: a density grid is a .npy file, got {path.name!r}")
    try:
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise SceneError(f"{source}: {where}: no such file: {path}{generator_hint(path)}") from None
    except (OSError, ValueError) as exc:
        raise SceneError(f"{source}: {where}: cannot read {path} as a .npy array ({exc})") from None
    if array.ndim != 3 or min(array.shape) < 1:
        raise SceneError(f"{source}: {where}: the density grid must be 3-D (nz, ny, nx), got shape {array.shape}")
    if array.size > MAX_DENSITY_VALUES:
        raise SceneError(f"{source}: {where}: {array.size} voxels is more than the {MAX_DENSITY_VALUES} allowed")
    if not np.issubdtype(array.dtype, np.number) or np.issubdtype(array.dtype, np.complexfloating):
        raise SceneError(f"{source}: {where}: the density grid must hold real numbers, got {array.dtype}")
    array = np.ascontiguousarray(array, dtype=np.float32)
    if not np.isfinite(array).all():
        raise SceneError(f"{source}: {where}: the density grid has values that are not finite (NaN or inf)")
    if (array < 0).any():
        raise SceneError(f"{source}: {where}: the density grid has negative values (smallest {array.min():g})")
    return array


# --- which medium lies on each side of each object -------------------------------------------


class _Solid(NamedTuple):
    """A closed object that decides the medium inside it."""

    obj: int
    inside: int
    volume: float  # its own, or a mesh's bounding box's: the innermost holder of a point is the smallest
    contains: object  # (3,) point -> bool


def _interfaces(scene: Scene, geometry, index: dict, outer: int, source: str) -> np.ndarray:
    triangles = _object_triangles(geometry)
    solids = []
    for k, obj in enumerate(scene.objects):
        solid = is_solid(scene.material_of(obj))
        interior = getattr(obj, "interior", None)
        if interior is None and not solid:
            continue
        test = _containment(obj, triangles.get(k))
        if test is None:
            continue  # an open shape: nothing inside to fill (interior on one is a model error)
        contains, volume, closed = test
        if not closed:
            if interior is not None:
                raise SceneError(
                    f"{source}: objects[{k}].interior: the mesh is not closed (watertight), so it has no "
                    "inside to fill; close its holes, or use a closed shape"
                )
            continue  # an open solid's mesh: a sheet, no inside
        solids.append(_Solid(k, NONE if interior is None else index[interior], volume, contains))
    interface = np.full((max(len(scene.objects), 1), 2), outer, dtype=np.int32)
    for k, obj in enumerate(scene.objects):
        point = _surface_point(obj, triangles.get(k))
        holder = None if point is None else _innermost(solids, point, other_than=k)
        around = holder.inside if holder is not None else outer
        mine = next((s for s in solids if s.obj == k), None)
        interface[k] = (mine.inside if mine is not None else around, around)
    return interface, solids


def _innermost(solids: list[_Solid], point: np.ndarray, other_than: int = -1) -> _Solid | None:
    """The smallest of the solids (but object `other_than`) that holds `point`, or None."""
    holders = [s for s in solids if s.obj != other_than and s.contains(point)]
    return min(holders, key=lambda s: s.volume) if holders else None


def _check_camera(scene: Scene, solids: list[_Solid], names: list[str], outer: int) -> None:
    """Warn where the camera is inside an object filled with another medium than the outer one:
    the camera sits in the outer medium (DESIGN 7), so its rays see none of the medium around it
    and path and bdpt disagree there (a light subpath's medium is found from the geometry)."""
    cameras = [("", scene.camera.position)]
    if scene.animation is not None and scene.animation.camera:  # and every frame's of an animation
        from ..scene.camera_path import camera_at

        for k in range(scene.animation.frames):
            try:
                cameras.append((f" (frame {k} of the animation)", camera_at(scene, k).position))
            except SceneError:  # an invalid frame: said when the frames are rendered, not here
                break

    inside = ((when, position, _innermost(solids, np.asarray(position, np.float64))) for when, position in cameras)
    found = next(((w, p, s) for w, p, s in inside if s is not None and s.inside != outer), None)
    if found is None:
        return
    when, position, solid = found

    def name(i: int) -> str:
        return "none" if i == NONE else repr(names[i])

    x, y, z = (f"{c:g}" for c in position)
    warn(
        f"the camera at ({x}, {y}, {z}){when} is inside objects[{solid.obj}] (medium: {name(solid.inside)}), "
        f"but a camera sits in the medium outside every object ([render] medium: {name(outer)}), and its "
        "rays start there; move the camera out of the object"
    )


def _object_triangles(geometry) -> dict[int, np.ndarray]:
    """World-space triangles (F, 3, 3) of each mesh object (an instanced mesh: its first instance)."""
    parts: dict[int, list] = {}
    for verts, _normals, _material, obj, _first_face in geometry.soup.parts:
        parts.setdefault(int(obj), []).append(np.asarray(verts, dtype=np.float64).reshape(-1, 3, 3))
    for inst in geometry.instanced:
        tris = np.asarray(inst.triangles, dtype=np.float64).reshape(-1, 3, 3)
        m = inst.matrices[0]
        parts.setdefault(int(inst.obj), []).append(tris @ m[:, :3].T + m[:, 3])
    return {k: np.concatenate(v) for k, v in parts.items()}


def _analytic_solid(obj):
    """(point -> inside?, a point of its surface, volume) of a closed analytic shape, from its
    module's `solid` (a sphere, a capped cylinder); None for other objects and open shapes."""
    kind = ANALYTIC_MODELS.get(type(obj))
    solid = None if kind is None else getattr(ANALYTIC[kind], "solid", None)
    return None if solid is None else solid(ANALYTIC[kind].pack(obj, object_matrix(obj)))


def _containment(obj, triangles):
    """(point -> inside?, volume, closed) of a closed object; None for open shapes."""
    if ANALYTIC_MODELS.get(type(obj)) is not None:
        found = _analytic_solid(obj)
        return None if found is None else (found[0], found[2], True)
    if isinstance(obj, Mesh) and triangles is not None and len(triangles):
        lo, hi = triangles.reshape(-1, 3).min(0), triangles.reshape(-1, 3).max(0)
        return (lambda p: _inside_mesh(triangles, p)), float(np.prod(np.maximum(hi - lo, 1e-300))), _closed(triangles)
    return None


def _surface_point(obj, triangles) -> np.ndarray | None:
    """A point on the object's surface (a mesh's first vertex) to find what holds it: not its
    centre, which a smaller object inside it may hold."""
    found = _analytic_solid(obj)
    if found is not None:
        return np.asarray(found[1], dtype=np.float64)
    if triangles is not None and len(triangles):
        return triangles[0, 0]
    m = object_matrix(obj)  # the point as placed in the world
    for key in ("position", "center", "point", "p0"):
        if hasattr(obj, key):
            return transform_point(m, getattr(obj, key))
    if hasattr(obj, "vertices") and obj.vertices:
        return transform_point(m, obj.vertices[0])
    return None


def _closed(triangles: np.ndarray) -> bool:
    """Watertight: every edge (vertices welded where they coincide) shared by exactly two faces."""
    vertices, inverse = np.unique(triangles.reshape(-1, 3), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(len(counts)) and bool((counts == 2).all())


def _inside_mesh(triangles: np.ndarray, p: np.ndarray) -> bool:
    """Parity of a ray's crossings of the (closed) mesh: odd inside. The ray's direction is an
    irrational-looking one, so that it meets no edge or vertex exactly."""
    d = np.array([0.5773502691896258, 0.5773502691896257, 0.5773502691896258]) + np.array([1e-3, -2e-3, 3e-3])
    d /= np.linalg.norm(d)
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    h = np.cross(d, e2)
    a = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(a) > 1e-300
    f = np.where(ok, 1.0 / np.where(ok, a, 1.0), 0.0)
    s = p - v0
    u = f * np.einsum("ij,ij->i", s, h)
    q = np.cross(s, e1)
    v = f * (q @ d)
    t = f * np.einsum("ij,ij->i", e2, q)
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return bool(hits.sum() % 2)
