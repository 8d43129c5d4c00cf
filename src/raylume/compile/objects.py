"""Compile stage: objects. The scene's objects gathered into geometry, object by object: analytic
shapes packed by their modules (kernels/geometry/shape_*.py), world-space triangles of meshes
and glTF files, instanced meshes in their own space; and the materials they use, numbered."""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from ..errors import SceneError
from ..kernels.geometry.shapes import ANALYTIC, RAY_OFFSET, SHAPE_WIDTH, Shape, is_bounded
from ..kernels.geometry.shapes import bounds as shape_bounds
from ..scene.checks import warn
from ..scene.gltf import flatten, load_gltf_object
from ..scene.instances import InstanceError, instance_matrices
from ..scene.mesh import MeshData, MeshError, obj_uv_problem, object_matrix_of
from ..scene.model import (
    DEFAULT_MATERIAL,
    Cylinder,
    Disk,
    Gltf,
    ImageTexture,
    Material,
    Mesh,
    Plane,
    Quad,
    Scene,
    Sphere,
    Triangle,
    beyond_float32,
)
from ..scene.placement import load_mesh_object, mesh_path

# Model classes of the analytic shapes and their kinds (one line per shape).
ANALYTIC_MODELS = {
    Sphere: Shape.SPHERE,
    Plane: Shape.PLANE,
    Disk: Shape.DISK,
    Quad: Shape.QUAD,
    Cylinder: Shape.CYLINDER,
}


def object_matrix(obj) -> np.ndarray:
    """4x4 object-to-world matrix of an analytic shape's `transform` (the identity for shapes
    without one): what its module's `pack` applies."""
    t = getattr(obj, "transform", None)
    return np.eye(4) if t is None else object_matrix_of(t)


# float32 rounding of a mesh's corners, relative to its size, that is worth a warning: about a
# tenth of a pixel where the object fills a 100-pixel part of the image
ROUNDING_WARNED = 1e-3


def _moved_too_far(lo: np.ndarray, hi: np.ndarray, moved_at) -> tuple[float, float, float] | None:
    """(its distance from the origin, its size, how far `moved_at(distance)` moves it) of an
    object of box (lo, hi) that this moves by a visible part of its size, else None."""
    size = float(np.linalg.norm(hi - lo))
    farthest = float(max(np.abs(lo).max(), np.abs(hi).max()))
    by = moved_at(farthest)
    return (farthest, size, by) if size > 0 and by > ROUNDING_WARNED * size else None


def rounded_too_far(lo: np.ndarray, hi: np.ndarray) -> tuple[float, float, float] | None:
    """_moved_too_far by float32's rounding, which stores triangles: an object far from the origin
    for its size (a 1-unit box 1e5 units away is rounded by 0.4% of it, and at 1e7 it vanishes).
    Spheres and the other analytic shapes are stored in float64 and keep their shape."""
    return _moved_too_far(lo, hi, lambda farthest: float(np.spacing(np.float32(farthest))) / 2)


def offset_too_far(lo: np.ndarray, hi: np.ndarray) -> tuple[float, float, float] | None:
    """_moved_too_far by the offset of the rays that leave an analytic shape (shapes.offset_epsilon's):
    a 1 cm sphere 1e5 units out has its shadows and terminator moved by 1 cm."""
    return _moved_too_far(lo, hi, lambda farthest: RAY_OFFSET * farthest)


def _named(found: dict[int, tuple[float, float, float]]) -> tuple[str, bool, int]:
    """(the objects named for a warning, whether they are one, the worst: moved by the largest
    part of its size) of what _moved_too_far found (a scene of loose triangles may have hundreds)."""
    worst = max(found, key=lambda k: found[k][2] / found[k][1])
    names = [f"objects[{k}]" for k in sorted(found)]
    which = " and ".join(names) if len(names) <= 2 else f"{names[0]}, {names[1]} and {len(names) - 2} more"
    return which, len(names) == 1, worst


def _far_for_their_size(which: str, one: bool) -> str:
    return f"{which} {'lies' if one else 'lie'} far from the origin for {'its size' if one else 'their sizes'}"


def warn_about_offsets(offset: dict[int, tuple[float, float, float]]) -> None:
    """One warning for the analytic shapes offset_too_far found, naming the worst."""
    if not offset:
        return
    which, one, worst = _named(offset)
    farthest, size, by = offset[worst]
    warn(
        f"{_far_for_their_size(which, one)}: rays that leave {'it' if one else f'objects[{worst}]'}, "
        f"{farthest:.3g} units out, start {by:.2g} off its surface ({100 * by / size:.3g}% of its {size:.3g} "
        "across), so its shading and shadows are off; move the scene nearer to the origin (or scale it up)"
    )


def warn_about_rounding(rounded: dict[int, tuple[float, float, float]]) -> None:
    """One warning for every object rounded_too_far found, naming the worst."""
    if not rounded:
        return
    which, one, worst = _named(rounded)
    farthest, size, rounding = rounded[worst]
    whose = "its corners" if one else f"the corners of objects[{worst}]"
    warn(
        f"{_far_for_their_size(which, one)}: float32, which stores triangles, rounds {whose}, {farthest:.3g} units "
        f"out, by up to {rounding:.2g} ({100 * rounding / size:.2g}% of its {size:.3g} across), so shapes and hits "
        "are off; move the scene nearer to the origin (or scale it up)"
    )


class OutOfRange(ValueError):
    """An object whose world-space coordinates float32 cannot hold (gather_objects names it)."""


def _check_extent(extent: float) -> None:
    # float32 holds the triangle table and the BVH's boxes: a coordinate beyond its range would
    # become inf there (and numpy would warn as it converted it)
    if (problem := beyond_float32(extent, " in world space")) is not None:
        raise OutOfRange(problem)


def _mesh_extent(lo: np.ndarray, hi: np.ndarray, instances: np.ndarray | None) -> float:
    """The largest coordinate magnitude of a mesh of box (lo, hi) in world space: of its
    vertices, or with `instances` ((N, 3, 4) matrices) of the box's corners through each matrix."""
    if instances is None:
        return float(max(-lo.min(), hi.max()))
    corners = np.array([[(hi if (c >> a) & 1 else lo)[a] for a in range(3)] + [1.0] for c in range(8)])
    return float(np.abs(np.asarray(instances)[:, :3, :] @ corners.T).max())


def _joined(arrays: list[np.ndarray]) -> np.ndarray:
    """The arrays one after another; one array itself (np.concatenate would copy it: a
    4M-triangle mesh's table is 144 MB, ~0.1-0.2 s with its pages faulted in, and the BVH's leaf
    order copies it again anyway)."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


class _TriangleSoup:
    """Triangles gathered object by object before the BVH reorders them."""

    def __init__(self):
        # (verts (F, 9) f32, normals (F, 9) f32 or None, material, object, its first face's `prim`)
        self.parts: list[tuple] = []
        self.uvs: list[np.ndarray | None] = []  # per part: (F, 6) f32 UVs, None when not needed
        self.degenerate = 0

    def add(
        self,
        vertices9: np.ndarray,
        normals9: np.ndarray | None,
        material: int,
        obj: int,
        uvs6: np.ndarray | None = None,
        first_face: int = 0,
    ):
        self.parts.append((vertices9, normals9, material, obj, first_face))
        self.uvs.append(uvs6)

    def uv_array(self) -> np.ndarray:
        """float32 (T, 6) UVs of every triangle (zeros where none are needed), or (1, 6)
        when no triangle needs UVs (no image texture on a triangle)."""
        if not any(uv is not None for uv in self.uvs):
            return np.zeros((1, 6), dtype=np.float32)
        return np.concatenate(
            [uv if uv is not None else np.zeros((len(p[0]), 6), np.float32) for uv, p in zip(self.uvs, self.parts)]
        ).astype(np.float32)

    def arrays(self):
        if not self.parts:
            empty9 = np.zeros((0, 9), dtype=np.float32)
            return empty9, np.zeros((1, 9), np.float32), np.zeros(0, bool), *(np.zeros(0, np.int32),) * 3
        verts = _joined([p[0] for p in self.parts])
        counts = [len(p[0]) for p in self.parts]
        any_smooth = any(p[1] is not None for p in self.parts)
        if any_smooth:
            normals = _joined([p[1] if p[1] is not None else np.zeros_like(p[0]) for p in self.parts])
        else:
            normals = np.zeros((1, 9), dtype=np.float32)
        smooth = np.concatenate([np.full(n, p[1] is not None) for n, p in zip(counts, self.parts)])
        material = np.concatenate([np.full(n, p[2], np.int32) for n, p in zip(counts, self.parts)])
        obj = np.concatenate([np.full(n, p[3], np.int32) for n, p in zip(counts, self.parts)])
        face = np.concatenate([np.arange(p[4], p[4] + n, dtype=np.int32) for n, p in zip(counts, self.parts)])
        return verts, normals, smooth, material, obj, face


def _load_mesh_object(scene: Scene, k: int, obj: Mesh, source):
    """The object's mesh in world space (handedness, transform, fit: scene/placement.py)."""
    try:
        return load_mesh_object(obj, scene.base_dir)
    except MeshError as exc:
        key = "file" if obj.file is not None else "vertices"
        raise SceneError(f"{source}: objects[{k}].{key}: {exc}") from None


def _load_gltf_object(scene: Scene, k: int, obj: Gltf, source):
    try:
        return load_gltf_object(obj, scene.base_dir)
    except MeshError as exc:
        raise SceneError(f"{source}: objects[{k}].file: {exc}") from None


def _reads_uvs(material) -> bool:
    """Whether a material reads its surface's UVs: an image texture, a normal, bump or alpha map."""
    maps = material.normal_map is not None or material.bump_map is not None or material.alpha_map is not None
    return isinstance(material.texture, ImageTexture) or maps


def _add_gltf_part(geometry: SceneGeometry, part, m: int, k: int, needs_uvs: bool, source="<scene>") -> None:
    """A glTF mesh primitive (UVs where its material's texture needs them; a mesh without UVs
    then reads UV (0, 0), with a warning): placed once, its world-space triangles; used by
    several nodes or GPU instances, one stored mesh and an instance per matrix (those that
    flatten it skipped)."""
    mesh = part.mesh
    if needs_uvs and mesh.uvs is None:
        warn(
            f"{source}: objects[{k}]: {part.name} has no texture coordinates (TEXCOORD_0), which its material's "
            "texture or maps read: they read UV (0, 0) everywhere"
        )
        mesh = mesh._replace(uvs=np.zeros((len(mesh.vertices), 2), np.float32))
    if len(part.matrices) == 1:
        for placed in flatten(part):
            geometry.add_mesh(placed._replace(uvs=mesh.uvs), m, k, uvs=needs_uvs)
        return
    a = np.asarray(part.matrices, dtype=np.float64)[:, :3, :]
    keep = np.flatnonzero(np.abs(np.linalg.det(a[:, :, :3])) > 0)
    if len(keep):
        geometry.add_mesh(mesh, m, k, a[keep], uvs=needs_uvs, instance_ids=keep)


def _instance_matrices(scene: Scene, k: int, obj: Mesh, source) -> np.ndarray | None:
    try:
        return instance_matrices(obj, scene.base_dir)
    except InstanceError as exc:
        raise SceneError(f"{source}: objects[{k}].instances: {exc}") from None


class _InstancedMesh(NamedTuple):
    """A mesh stored once in object space, and the matrices placing its copies."""

    triangles: np.ndarray  # float32 (F, 9)
    normals: np.ndarray | None  # float32 (F, 9) vertex normals, None for flat shading
    uvs: np.ndarray | None  # float32 (F, 6)
    material: int
    obj: int
    matrices: np.ndarray  # float64 (N, 3, 4) object to world
    ids: np.ndarray  # int32 (N,): each instance's index within its object (the `instance` AOV)
    first_face: int  # the `prim` AOV of its first triangle (after the object's other meshes')


class _Analytic:
    """Analytic shapes gathered in object order: their rows and their primitive-table columns."""

    def __init__(self):
        self.rows: list[np.ndarray] = []
        self.kinds: list[int] = []
        self.materials: list[int] = []
        self.objects: list[int] = []

    def add(self, kind: Shape, row, material: int, obj: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Add a shape; returns its box (lo, hi), None for an unbounded one (a plane)."""
        padded = np.zeros(SHAPE_WIDTH, dtype=np.float64)
        padded[: len(row)] = row
        box = None
        if is_bounded(kind):
            lo, hi = shape_bounds(kind, padded[None])
            _check_extent(float(max(np.abs(lo).max(), np.abs(hi).max())))
            box = (lo[0], hi[0])
        self.rows.append(padded)
        self.kinds.append(int(kind))
        self.materials.append(material)
        self.objects.append(obj)
        return box

    def table(self) -> np.ndarray:
        return np.asarray(self.rows, dtype=np.float64).reshape(-1, SHAPE_WIDTH)

    def bounded(self) -> np.ndarray:
        return np.array([is_bounded(Shape(k)) for k in self.kinds], dtype=bool)

    def bounds(self, rows: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lo = np.empty((len(which), 3))
        hi = np.empty((len(which), 3))
        kinds = np.asarray(self.kinds, dtype=np.int64)[which]
        for kind in np.unique(kinds):
            sel = kinds == kind
            lo[sel], hi[sel] = shape_bounds(Shape(int(kind)), rows[which[sel]])
        return lo, hi


class SceneGeometry:
    """The geometry of a scene as it is gathered, object by object, before the BVHs are built:
    analytic shapes, world-space triangles, and instanced meshes."""

    def __init__(self):
        self.analytic = _Analytic()
        self.soup = _TriangleSoup()
        self.rounded: dict[int, tuple[float, float, float]] = {}  # objects float32 rounds visibly
        self.offset: dict[int, tuple[float, float, float]] = {}  # analytic shapes the ray offset moves visibly
        self.instanced: list[_InstancedMesh] = []
        self.faces_of: dict[int, int] = {}  # triangles added so far to each object (a glTF's meshes)

    def add_mesh(
        self,
        mesh: MeshData,
        material: int,
        obj: int,
        instances: np.ndarray | None = None,
        *,
        uvs: bool = False,
        instance_ids: np.ndarray | None = None,
    ) -> None:
        """Add a triangle mesh of scene object `obj` (the `object` AOV) with row `material` of
        the materials table. The `prim` AOV is the face's index in `mesh.faces`, after the faces of
        the object's meshes added before (a glTF object's meshes number its triangles in turn).

        Without `instances`, the mesh's vertices are in world space and its triangles join the
        world BVH with every other primitive. With `instances`, float (N, 3, 4) or (N, 4, 4)
        object-to-world matrices (column vectors, p' = M @ [p, 1]; finite and invertible, see
        scene/instances.check_matrices), the mesh is stored once, in its own space, with its
        own BVH (a BLAS), and each instance costs its inverse matrix, two indices and its share
        of the top-level BVH. `instance_ids` (int (N,), default 0..N-1) are the `instance` AOV's
        values. `uvs`: keep the mesh's texture coordinates (mesh.uvs must exist)."""

        def corners(per_vertex):  # float32 (F, 3 x its width): each face's three rows, by np.take
            # (rows copied whole, ~2x faster than indexing at 4M triangles)
            rows = np.take(per_vertex.astype(np.float32), mesh.faces, axis=0)
            return rows.reshape(-1, 3 * per_vertex.shape[1])

        if len(mesh.vertices):
            lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)  # (no (V, 3) temporary of np.abs)
            _check_extent(_mesh_extent(lo, hi, instances))
            if instances is None and (found := rounded_too_far(lo, hi)) is not None:
                self.rounded[obj] = found  # (an instanced mesh is stored in its own space)
        tris = corners(mesh.vertices)
        normals = None if mesh.normals is None else corners(mesh.normals)
        uv6 = corners(mesh.uvs) if uvs else None
        self.soup.degenerate += mesh.degenerate
        first_face = self.faces_of.get(obj, 0)
        self.faces_of[obj] = first_face + len(mesh.faces)
        if instances is None:
            self.soup.add(tris, normals, material, obj, uv6, first_face)
            return
        m = np.asarray(instances, dtype=np.float64)
        m = np.ascontiguousarray(m[:, :3, :])
        ids = np.arange(len(m), dtype=np.int32) if instance_ids is None else np.asarray(instance_ids, np.int32)
        self.instanced.append(_InstancedMesh(tris, normals, uv6, material, obj, m, ids, first_face))


class Gathered(NamedTuple):
    """What the objects stage found: the geometry, the materials in use (model -> row, the
    default first) with the key path of each, images decoded from glTF files, and the seconds
    spent reading mesh files."""

    geometry: SceneGeometry
    materials: dict[Material, int]
    material_where: dict[Material, str]
    images: dict[str, np.ndarray]
    mesh_seconds: float


def gather_objects(scene: Scene, source: str) -> Gathered:
    """Every object of the scene into a SceneGeometry, and the materials they use."""
    materials: dict[Material, int] = {DEFAULT_MATERIAL: 0}
    material_where: dict[Material, str] = {}  # key path of each material, for error messages

    def material_index(obj, k) -> int:
        mat = scene.material_of(obj)
        ref = obj.material
        material_where.setdefault(mat, f"materials.{ref}" if isinstance(ref, str) else f"objects[{k}].material")
        return materials.setdefault(mat, len(materials))

    def needs_uvs(obj) -> bool:
        return _reads_uvs(scene.material_of(obj))

    geometry = SceneGeometry()
    analytic, soup = geometry.analytic, geometry.soup
    images: dict[str, np.ndarray] = {}  # textures decoded from glTF files
    mesh_seconds = 0.0  # reading mesh files: part of the build, reported apart
    for k, obj in enumerate(scene.objects):
        try:
            m = material_index(obj, k)
            kind = ANALYTIC_MODELS.get(type(obj))
            if isinstance(obj, Gltf):  # a glTF file's meshes with their own materials (scene/gltf.py)
                loading = time.perf_counter()
                imported = _load_gltf_object(scene, k, obj, source)
                mesh_seconds += time.perf_counter() - loading
                images.update(imported.images)
                for part in imported.parts:
                    mat = imported.materials[part.material]
                    material_where.setdefault(mat, f"objects[{k}].file")
                    m = materials.setdefault(mat, len(materials))
                    _add_gltf_part(geometry, part, m, k, _reads_uvs(mat), source)
            elif kind is not None:
                box = analytic.add(kind, ANALYTIC[kind].pack(obj, object_matrix(obj)), m, k)
                if box is not None and (found := offset_too_far(*box)) is not None:
                    geometry.offset[k] = found
            elif isinstance(obj, Triangle):
                uvs = np.array([[0, 0, 1, 0, 0, 1]], dtype=np.float32) if needs_uvs(obj) else None
                corners = np.asarray(obj.vertices, dtype=np.float64)
                matrix = object_matrix(obj)
                if not np.array_equal(matrix, np.eye(4)):
                    corners = corners @ matrix[:3, :3].T + matrix[:3, 3]
                    _check_extent(float(np.abs(corners).max()))
                if (found := rounded_too_far(corners.min(axis=0), corners.max(axis=0))) is not None:
                    geometry.rounded[k] = found
                soup.add(corners.astype(np.float32).reshape(1, 9), None, m, k, uvs)
            else:
                matrices = _instance_matrices(scene, k, obj, source)  # before the (slower) mesh file
                loading = time.perf_counter()
                mesh = _load_mesh_object(scene, k, obj, source)
                mesh_seconds += time.perf_counter() - loading
                if needs_uvs(obj) and mesh.uvs is None:
                    problem = obj_uv_problem(mesh_path(obj, scene.base_dir)) if obj.file is not None else None
                    why = f"; {problem}" if problem else ""  # an OBJ's bad vt index, say
                    key = "file" if obj.file is not None else "uvs"  # an inline mesh's UVs are its `uvs`
                    raise SceneError(
                        f"{source}: objects[{k}].{key}: the mesh has no texture coordinates (UVs), "
                        f"which its material's image texture or map (normal, bump, alpha) needs{why}"
                    )
                geometry.add_mesh(mesh, m, k, matrices, uvs=needs_uvs(obj))
        except OutOfRange as exc:
            raise SceneError(f"{source}: objects[{k}]: {exc}") from None
    warn_about_rounding(geometry.rounded)
    warn_about_offsets(geometry.offset)
    return Gathered(geometry, materials, material_where, images, mesh_seconds)
