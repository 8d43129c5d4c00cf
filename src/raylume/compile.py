"""Scene model -> the flat arrays the kernels read (kernels/scene.py), plus the BVH.

The compiled scene holds no camera and no file paths: geometry, materials, textures, lights
and the BVH only, so one compilation renders through any camera (Session) and can be pickled
and shipped (a cluster's workers never read the scene's files).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .accel.bvh import build_bvh, triangle_bounds
from .accel.wide import collapse, mark_sphere_leaves, mark_triangle_leaves, single_leaf, wide_depth, wide_nbytes
from .compile_instances import build_instances, join_triangles, place_instanced
from .errors import SceneError
from .kernels.frame_stack import roomy_frame_stack
from .kernels.geometry.shape_triangle import TRIANGLES_PER_TEST
from .kernels.geometry.shapes import (
    ANALYTIC,
    PRIM_FACE,
    PRIM_KIND,
    PRIM_LIGHT,
    PRIM_MATERIAL,
    PRIM_OBJECT,
    PRIM_ROW,
    PRIM_WIDTH,
    SHAPE_WIDTH,
    Shape,
    is_bounded,
)
from .kernels.geometry.shapes import bounds as shape_bounds
from .kernels.geometry.wide_nodes import BVH_WIDTH, TRAVERSAL_STACK, stack_needed
from .kernels.scene import KernelScene
from .kernels.shading import materials as M
from .kernels.shading import textures as X
from .lights_table import build_light_table, scene_environment
from .scene.gltf import flatten, load_gltf_object
from .scene.instances import InstanceError, instance_matrices
from .scene.mesh import MeshData, MeshError, transform_matrix
from .scene.model import (
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
)
from .scene.placement import load_mesh_object

# BVH shape, measured on the seed scene and the bunny (benchmarks/bench_bvh.py): visiting a node
# (two box tests) costs about as much as two primitive tests, and scenes of a few primitives
# are fastest as a single leaf, with no box test at all.
BVH_MAX_LEAF = 4
BVH_TRAVERSAL_COST = 2.0
# A leaf of up to 4 triangles or spheres is one vector test (kernels/traverse.py intersect_leaf),
# so the heuristic counts a leaf's cost in blocks of 4: a leaf of 1 costs as much as one of 4.
# Hit rays on a 1M-triangle mesh ~3% faster, the bunny ~1.5% (benchmarks/bench_hits.py).
BVH_LEAF_BLOCK = TRIANGLES_PER_TEST
BVH_OPTIONS = {"max_leaf_size": BVH_MAX_LEAF, "c_trav": BVH_TRAVERSAL_COST, "leaf_block": BVH_LEAF_BLOCK}
SMALL_SCENE = 8

# Model classes of the analytic shapes and their kinds (one line per shape).
ANALYTIC_MODELS = {
    Sphere: Shape.SPHERE,
    Plane: Shape.PLANE,
    Disk: Shape.DISK,
    Quad: Shape.QUAD,
    Cylinder: Shape.CYLINDER,
}


class CompiledScene(NamedTuple):
    kernel: KernelScene  # epsilon_floor left at the geometry's own; see with_camera
    extent: float  # largest coordinate magnitude of the geometry (for ray offsets)
    stats: dict  # primitives, triangles, bvh_nodes, bvh_bytes, build_seconds, ...

    def for_camera(self, position) -> KernelScene:
        """The kernel scene with the ray-offset floor for a camera at `position`: a tiny
        fraction of the extent of the scene and the camera together."""
        extent = max(self.extent, float(np.abs(np.asarray(position, dtype=np.float64)).max()))
        return self.kernel._replace(epsilon_floor=float(max(1e-3 * extent, 1e-30)))


def object_matrix(obj) -> np.ndarray:
    """4x4 object-to-world matrix of an analytic shape's `transform` (the identity for shapes
    without one): what its module's `pack` applies."""
    t = getattr(obj, "transform", None)
    return np.eye(4) if t is None else transform_matrix(t.translate, t.rotate, t.scale3)


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve, inverted (x in 0..1)."""
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def mip_levels(texels: np.ndarray) -> list[np.ndarray]:
    """The image (float32 (H, W, 3)) and its mip-map: each level the area average of the one
    before at half its size (rounded down, at least 1), down to 1 x 1."""
    from PIL import Image as PILImage

    levels = [texels]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        h, w = levels[-1].shape[:2]
        size = (max(1, w // 2), max(1, h // 2))
        channels = [
            np.asarray(
                PILImage.fromarray(np.ascontiguousarray(levels[-1][:, :, c]), mode="F").resize(size, PILImage.BOX)
            )
            for c in range(3)
        ]
        levels.append(np.stack(channels, axis=-1).astype(np.float32))
    return levels


class TextureTable:
    """Rows of the texture table, and image textures decoded to linear float32 RGB and
    concatenated row by row into one texel atlas (each row keeps its offset), each followed by
    its mip-map levels (textures.py)."""

    MAX_TEXELS = 1 << 26  # 64 Mi texels (768 MiB): a guard against decompression bombs

    def __init__(self, base_dir: Path, source: str, images: dict[str, np.ndarray] | None = None):
        self.base_dir = Path(base_dir)
        self.source = source
        self.images = images or {}  # decoded images by ImageTexture.file (a glTF file's textures)
        self.rows: list[np.ndarray] = []
        self.parts: list[np.ndarray] = []
        self.size = 0
        self.loaded: dict[Path, tuple] = {}

    def add(self, texture, where: str) -> int:
        """The row of a model texture (checker or image)."""
        row = np.zeros(X.TEX_WIDTH, dtype=np.float64)
        if isinstance(texture, ImageTexture):
            offset, tex_w, tex_h, levels, mean = self._image(texture.file, f"{where}.texture.file")
            row[X.TEX_KIND] = X.IMAGE
            row[X.TEX_COLOR_A : X.TEX_COLOR_A + 3] = mean
            row[X.TEX_OFFSET] = offset
            row[X.TEX_WIDTH_PX] = tex_w
            row[X.TEX_HEIGHT_PX] = tex_h
            row[X.TEX_LEVELS] = levels
            row[X.TEX_SCALE_U] = texture.scale[0]
            row[X.TEX_SCALE_V] = texture.scale[1]
        else:
            row[X.TEX_KIND] = X.CHECKER
            row[X.TEX_COLOR_A : X.TEX_COLOR_A + 3] = texture.colors[0]
            row[X.TEX_COLOR_B : X.TEX_COLOR_B + 3] = texture.colors[1]
            row[X.TEX_CELL] = texture.scale
        self.rows.append(row)
        return len(self.rows) - 1

    def _image(self, file: str, where: str) -> tuple[int, int, int, int, np.ndarray]:
        """(offset, width, height, mip levels, mean linear colour) of the image, loading it once."""
        path = Path(file)
        if not path.is_absolute():
            path = self.base_dir / path
        key = path.resolve()
        if key not in self.loaded:
            texels = self.images[file] if file in self.images else self._load(path, where)
            h, w = texels.shape[:2]
            levels = mip_levels(texels)
            self.loaded[key] = (self.size, w, h, len(levels), texels.reshape(-1, 3).mean(axis=0, dtype=np.float64))
            for level in levels:
                self.parts.append(level.reshape(-1, 3))
                self.size += level.shape[0] * level.shape[1]
        return self.loaded[key]

    def _load(self, path: Path, where: str) -> np.ndarray:
        from PIL import Image as PILImage

        def fail(why: str):
            raise SceneError(f"{self.source}: {where}: {why}")

        if not path.exists():
            fail(f"texture file {path} does not exist")
        if path.is_dir():
            fail(f"texture file {path} is a folder")
        try:
            with PILImage.open(path) as im:
                if im.width * im.height > self.MAX_TEXELS:
                    fail(f"texture {path} is {im.width} x {im.height}, more than {self.MAX_TEXELS} texels")
                rgb = np.asarray(im.convert("RGB"), dtype=np.float32) / np.float32(255.0)
        except SceneError:
            raise
        except (OSError, ValueError, PILImage.DecompressionBombError) as exc:
            fail(f"cannot read texture {path} as an image (PNG or JPEG): {exc}")
        return srgb_to_linear(rgb).astype(np.float32)

    def table(self) -> np.ndarray:
        if not self.rows:
            return np.zeros((1, X.TEX_WIDTH), dtype=np.float64)
        return np.stack(self.rows)

    def texels(self) -> np.ndarray:
        if not self.parts:
            return np.zeros((1, 3), dtype=np.float32)
        return np.ascontiguousarray(np.concatenate(self.parts), dtype=np.float32)


def material_row(mat: Material, textures: TextureTable | None = None, where: str = "material") -> np.ndarray:
    """The material's row of the materials table: the columns of its kind, packed by the kind's
    module (its trace-mode approximation in the phong columns), then those every kind has;
    its texture is added to `textures`."""
    row = np.zeros(M.MAT_WIDTH, dtype=np.float64)
    M.kind_module(mat.type).pack(mat, row)
    row[M.MAT_COLOR : M.MAT_COLOR + 3] = mat.color
    row[M.MAT_EMISSION : M.MAT_EMISSION + 3] = mat.emission
    row[M.MAT_TEXTURE] = -1
    if mat.texture is not None:
        if textures is None:
            raise ValueError("a textured material needs a TextureTable")
        row[M.MAT_TEXTURE] = textures.add(mat.texture, where)
    return row


class _TriangleSoup:
    """Triangles gathered object by object before the BVH reorders them."""

    def __init__(self):
        self.parts: list[tuple] = []  # (verts (F, 9) f32, normals (F, 9) f32 or None, material, object)
        self.uvs: list[np.ndarray | None] = []  # per part: (F, 6) f32 UVs, None when not needed
        self.degenerate = 0

    def add(
        self,
        vertices9: np.ndarray,
        normals9: np.ndarray | None,
        material: int,
        obj: int,
        uvs6: np.ndarray | None = None,
    ):
        self.parts.append((vertices9, normals9, material, obj))
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
        verts = np.concatenate([p[0] for p in self.parts])
        counts = [len(p[0]) for p in self.parts]
        any_smooth = any(p[1] is not None for p in self.parts)
        if any_smooth:
            normals = np.concatenate([p[1] if p[1] is not None else np.zeros_like(p[0]) for p in self.parts])
        else:
            normals = np.zeros((1, 9), dtype=np.float32)
        smooth = np.concatenate([np.full(n, p[1] is not None) for n, p in zip(counts, self.parts)])
        material = np.concatenate([np.full(n, p[2], np.int32) for n, p in zip(counts, self.parts)])
        obj = np.concatenate([np.full(n, p[3], np.int32) for n, p in zip(counts, self.parts)])
        face = np.concatenate([np.arange(n, dtype=np.int32) for n in counts])
        return verts, normals, smooth, material, obj, face


def _load_mesh_object(scene: Scene, k: int, obj: Mesh, source):
    """The object's mesh in world space (handedness, transform, fit: scene/placement.py)."""
    try:
        return load_mesh_object(obj, scene.base_dir)
    except MeshError as exc:
        raise SceneError(f"{source}: objects[{k}].file: {exc}") from None


def _load_gltf_object(scene: Scene, k: int, obj: Gltf, source):
    try:
        return load_gltf_object(obj, scene.base_dir)
    except MeshError as exc:
        raise SceneError(f"{source}: objects[{k}].file: {exc}") from None


def _add_gltf_part(geometry: SceneGeometry, part, m: int, k: int, needs_uvs: bool) -> None:
    """A glTF mesh primitive (UVs where its material's texture needs them; a mesh without UVs
    then reads texel (0, 0)): placed once, its world-space triangles; used by several nodes or
    GPU instances, one stored mesh and an instance per matrix (those that flatten it skipped)."""
    mesh = part.mesh
    if needs_uvs and mesh.uvs is None:
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


class _Analytic:
    """Analytic shapes gathered in object order: their rows and their primitive-table columns."""

    def __init__(self):
        self.rows: list[np.ndarray] = []
        self.kinds: list[int] = []
        self.materials: list[int] = []
        self.objects: list[int] = []

    def add(self, kind: Shape, row, material: int, obj: int) -> None:
        padded = np.zeros(SHAPE_WIDTH, dtype=np.float64)
        padded[: len(row)] = row
        self.rows.append(padded)
        self.kinds.append(int(kind))
        self.materials.append(material)
        self.objects.append(obj)

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
        self.instanced: list[_InstancedMesh] = []

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
        the materials table. The `prim` AOV is the face's index in `mesh.faces`.

        Without `instances`, the mesh's vertices are in world space and its triangles join the
        world BVH with every other primitive. With `instances`, float (N, 3, 4) or (N, 4, 4)
        object-to-world matrices (column vectors, p' = M @ [p, 1]; finite and invertible, see
        scene/instances.check_matrices), the mesh is stored once, in its own space, with its
        own BVH (a BLAS), and each instance costs its inverse matrix, two indices and its share
        of the top-level BVH. `instance_ids` (int (N,), default 0..N-1) are the `instance` AOV's
        values. `uvs`: keep the mesh's texture coordinates (mesh.uvs must exist)."""
        tris = mesh.vertices.astype(np.float32)[mesh.faces].reshape(-1, 9)
        normals = None if mesh.normals is None else mesh.normals.astype(np.float32)[mesh.faces].reshape(-1, 9)
        uv6 = mesh.uvs.astype(np.float32)[mesh.faces].reshape(-1, 6) if uvs else None
        self.soup.degenerate += mesh.degenerate
        if instances is None:
            self.soup.add(tris, normals, material, obj, uv6)
            return
        m = np.asarray(instances, dtype=np.float64)
        m = np.ascontiguousarray(m[:, :3, :])
        ids = np.arange(len(m), dtype=np.int32) if instance_ids is None else np.asarray(instance_ids, np.int32)
        self.instanced.append(_InstancedMesh(tris, normals, uv6, material, obj, m, ids))


@roomy_frame_stack  # the BVH builder's kernels compile on first use (frame_stack.py)
def compile_scene(scene: Scene, source="<scene>", accelerate: bool = True) -> CompiledScene:
    """Flatten the scene into arrays. `accelerate=False` skips the BVH (the rasterizer needs
    none: at 4M triangles that saves about 9 s)."""
    start = time.perf_counter()
    materials: dict[Material, int] = {DEFAULT_MATERIAL: 0}
    material_where: dict[Material, str] = {}  # key path of each material, for error messages

    def material_index(obj, k) -> int:
        mat = scene.material_of(obj)
        ref = obj.material
        material_where.setdefault(mat, f"materials.{ref}" if isinstance(ref, str) else f"objects[{k}].material")
        return materials.setdefault(mat, len(materials))

    def needs_uvs(obj) -> bool:
        return isinstance(scene.material_of(obj).texture, ImageTexture)

    geometry = SceneGeometry()
    analytic, soup = geometry.analytic, geometry.soup
    images: dict[str, np.ndarray] = {}  # textures decoded from glTF files
    mesh_seconds = 0.0  # reading mesh files: part of the build, reported apart
    for k, obj in enumerate(scene.objects):
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
                _add_gltf_part(geometry, part, m, k, mat.texture is not None)
        elif kind is not None:
            analytic.add(kind, ANALYTIC[kind].pack(obj, object_matrix(obj)), m, k)
        elif isinstance(obj, Triangle):
            uvs = np.array([[0, 0, 1, 0, 0, 1]], dtype=np.float32) if needs_uvs(obj) else None
            soup.add(np.asarray(obj.vertices, dtype=np.float32).reshape(1, 9), None, m, k, uvs)
        else:
            matrices = _instance_matrices(scene, k, obj, source)  # before the (slower) mesh file
            loading = time.perf_counter()
            mesh = _load_mesh_object(scene, k, obj, source)
            mesh_seconds += time.perf_counter() - loading
            if needs_uvs(obj) and mesh.uvs is None:
                raise SceneError(
                    f"{source}: objects[{k}].file: the mesh has no texture coordinates (UVs), "
                    "which its material's image texture needs"
                )
            geometry.add_mesh(mesh, m, k, matrices, uvs=needs_uvs(obj))

    shapes = analytic.table()
    bounded = analytic.bounded()
    in_bvh = np.flatnonzero(bounded)  # analytic rows in the BVH, in object order
    unbounded = np.flatnonzero(~bounded)
    tri, tri_n, tri_smooth, tri_mat, tri_obj, tri_face = soup.arrays()
    tri_uv = soup.uv_array()
    inst = build_instances(geometry.instanced, accelerate)
    n_analytic, n_tris = len(in_bvh), len(tri)

    # Bounds of every BVH primitive: bounded analytic shapes first, then triangles (of the
    # float32 vertices the kernels intersect, so the boxes are exact).
    lo = np.empty((n_analytic + n_tris, 3), dtype=np.float64)
    hi = np.empty_like(lo)
    lo[:n_analytic], hi[:n_analytic] = analytic.bounds(shapes, in_bvh)
    if n_tris:
        triangle_bounds(tri, lo[n_analytic:], hi[n_analytic:])
    if accelerate and len(lo) > SMALL_SCENE:
        # the binned-SAH binary tree, collapsed into BVH_WIDTH-wide nodes (accel/wide.py)
        bvh = collapse(build_bvh(lo, hi, **BVH_OPTIONS), BVH_WIDTH)
        depth = wide_depth(bvh)
    else:
        bvh = single_leaf(lo, hi, BVH_WIDTH)
        depth = 1
    if stack_needed(depth) > TRAVERSAL_STACK:  # traversal stacks are fixed-size (no allocation per ray)
        raise SceneError(
            f"{source}: the BVH is {depth} levels deep, more than the traversal supports; "
            "the scene's primitives are pathologically arranged"
        )

    # Reorder so that leaves read consecutive triangles (cache-friendly traversal).
    order = bvh.prim_order.astype(np.int64)
    is_tri = order >= n_analytic
    tri_perm = order[is_tri] - n_analytic
    if n_tris:
        tri, tri_smooth, tri_mat, tri_obj, tri_face = (
            a[tri_perm] for a in (tri, tri_smooth, tri_mat, tri_obj, tri_face)
        )
        if len(tri_n) == n_tris:
            tri_n = tri_n[tri_perm]
        if len(tri_uv) == n_tris:
            tri_uv = tri_uv[tri_perm]

    # The primitive table: the world BVH's primitives in leaf order, the instanced meshes'
    # (each in its BLAS's leaf order), then the unbounded shapes.
    n_world = len(order)
    n_bounded = n_world + len(inst.prims)
    prims = np.zeros((n_bounded + len(unbounded), PRIM_WIDTH), dtype=np.int32)
    prims[:, PRIM_LIGHT] = -1  # no primitive emits light yet (path tracing's emitters will)
    shape_rows = np.concatenate([in_bvh[order[~is_tri]], unbounded])
    shape_slots = np.concatenate([np.flatnonzero(~is_tri), np.arange(n_bounded, len(prims))])
    _fill_prims(prims, shape_slots, shape_rows, analytic)
    tri_slots = np.flatnonzero(is_tri)
    prims[tri_slots, PRIM_KIND] = Shape.TRIANGLE
    prims[tri_slots, PRIM_ROW] = np.arange(n_tris, dtype=np.int32)
    prims[tri_slots, PRIM_MATERIAL] = tri_mat
    prims[tri_slots, PRIM_OBJECT] = tri_obj
    prims[tri_slots, PRIM_FACE] = tri_face
    if accelerate and n_tris:
        mark_triangle_leaves(bvh, is_tri)  # leaves of triangles alone are tested 4 at a time
    mark_sphere_leaves(bvh, prims[:n_world, PRIM_KIND] == Shape.SPHERE)  # and of spheres alone
    if len(inst.prims):  # the instanced meshes' rows and triangles follow the world's
        place_instanced(inst, n_world, n_tris)
        prims[n_world:n_bounded] = inst.prims
        tri, tri_n, tri_smooth, tri_uv = join_triangles(
            (tri, tri_n, tri_smooth, tri_uv), (inst.triangles, inst.normals, inst.smooth, inst.uvs)
        )
    if inst.stack > TRAVERSAL_STACK:  # a BLAS walk runs on the stack above the TLAS walk's
        raise SceneError(
            f"{source}: the instances' BVHs are too deep together for the traversal; "
            "the instances or an instanced mesh are pathologically arranged"
        )

    textures = TextureTable(scene.base_dir, source, images)
    mat_rows = np.stack([material_row(m, textures, material_where.get(m, "material")) for m in materials])
    extent = [np.abs(lo).max() if len(lo) else 0.0, np.abs(hi).max() if len(hi) else 0.0, inst.extent]
    for r in unbounded:  # an unbounded shape's size is that of its defining point
        extent.append(np.abs(shapes[r, :3]).max())
    environment = scene_environment(scene, source)
    # instanced meshes' triangles (stored in object space) are sampled per mesh, through its
    # instances (lights_table.instanced_emitters), not one row per triangle
    world = np.ones(len(prims), dtype=bool)
    world[n_world:n_bounded] = False
    lights = build_light_table(
        scene, prims, shapes, tri, mat_rows, environment, float(max(extent)), candidates=world, instances=inst
    )
    kernel = KernelScene(
        prims=prims,
        n_bounded=n_bounded,
        shapes=shapes,
        triangles=np.ascontiguousarray(tri),
        triangle_normals=np.ascontiguousarray(tri_n),
        triangle_smooth=tri_smooth,
        triangle_uvs=np.ascontiguousarray(tri_uv),
        node_bounds=bvh.node_bounds,
        node_index=bvh.node_index,
        materials=mat_rows,
        textures=textures.table(),
        texels=textures.texels(),
        light_kind=lights.kind,
        light_data=lights.data,
        light_order=lights.order,
        light_cdf=lights.cdf,
        light_dist=lights.dist,
        n_area_lights=lights.n_area,
        environment_row=lights.environment_row,
        ambient_row=lights.ambient_row,
        env_image=environment.image,
        env_marginal_cdf=environment.marginal_cdf,
        env_conditional_cdf=environment.conditional_cdf,
        env_rotation=environment.rotation,
        env_present=environment.present,
        has_transparency=bool((mat_rows[:, M.MAT_TRANSPARENCY] > 0).any()),
        basic_shapes=bool(np.isin(prims[:, PRIM_KIND], (Shape.SPHERE, Shape.TRIANGLE)).all()),
        inst_node_bounds=inst.node_bounds,
        inst_node_index=inst.node_index,
        instance_inverse=inst.inverse,
        instance_index=inst.index,
        epsilon_floor=1e-30,
    )
    stats = {
        "primitives": len(prims),
        "triangles": len(tri),  # stored: an instanced mesh's once (instanced_triangles: as drawn)
        "degenerate_triangles": soup.degenerate,
        # without acceleration (the rasterizer's scenes) there is no BVH to report, only the
        # placeholder leaf that keeps the kernels' arrays typed alike
        "bvh_nodes": int(len(bvh.node_index)) if accelerate else 0,  # BVH_WIDTH-wide nodes
        "bvh_depth": int(depth) if accelerate else 0,
        # nodes, and the two columns of the primitive table that traversal reads (kind, row)
        "bvh_bytes": int(wide_nbytes(bvh) + 8 * len(prims) + inst.node_bytes) if accelerate else 0,
        "build_seconds": time.perf_counter() - start,
        "mesh_load_seconds": mesh_seconds,
        **inst.stats,
    }
    return CompiledScene(kernel, float(max(extent)), stats)


def _fill_prims(prims: np.ndarray, slots: np.ndarray, rows: np.ndarray, analytic: _Analytic) -> None:
    """Primitive-table rows `slots` for the analytic shapes of `rows`."""
    for column, values in (
        (PRIM_KIND, analytic.kinds),
        (PRIM_MATERIAL, analytic.materials),
        (PRIM_OBJECT, analytic.objects),
    ):
        prims[slots, column] = np.asarray(values, dtype=np.int32)[rows] if len(rows) else 0
    prims[slots, PRIM_ROW] = rows  # PRIM_FACE stays 0: an analytic shape is one face
