"""Scene model -> flat arrays the kernels read, plus the BVH over spheres and triangles."""

from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .accel.bvh import BVH, build_bvh, bvh_depth, bvh_nbytes
from .errors import SceneError
from .kernels import layout as L
from .kernels.camera import camera_frame
from .kernels.scene import KernelScene
from .scene.mesh import MeshError, load_mesh
from .scene.model import DEFAULT_MATERIAL, ImageTexture, Material, Mesh, Plane, Scene, Sphere, Triangle


# BVH shape, measured on the seed scene and the bunny (benchmarks/bench_bvh.py): visiting a node
# (two box tests) costs about as much as two primitive tests, and scenes of a few primitives
# are fastest as a single leaf, with no box test at all.
BVH_MAX_LEAF = 4
BVH_TRAVERSAL_COST = 2.0
SMALL_SCENE = 8


class CompiledScene(NamedTuple):
    kernel: KernelScene
    camera: np.ndarray  # float64 (CAM_WIDTH,), see kernels/camera.py and kernels/layout.py
    stats: dict  # primitives, triangles, bvh_nodes, bvh_bytes, build_seconds, ...


def unit_vector(v) -> np.ndarray:
    """v / |v|, scaled first so that tiny but non-zero vectors (1e-200) do not underflow."""
    v = np.asarray(v, dtype=np.float64)
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def material_row(mat: Material, atlas: "TextureAtlas | None" = None, where: str = "material") -> np.ndarray:
    """The material's row of the materials array; image textures are added to `atlas`."""
    row = np.zeros(L.MAT_WIDTH, dtype=np.float64)
    row[L.MAT_COLOR : L.MAT_COLOR + 3] = mat.color
    row[L.MAT_SPECULAR] = mat.specular if mat.specular is not None else -1.0
    row[L.MAT_REFLECTIVE] = mat.reflective
    row[L.MAT_TRANSPARENCY] = mat.transparency
    row[L.MAT_IOR] = mat.ior
    row[L.MAT_ABSORPTION : L.MAT_ABSORPTION + 3] = mat.absorption
    if isinstance(mat.texture, ImageTexture):
        if atlas is None:
            raise ValueError("an image texture needs a TextureAtlas")
        offset, tex_w, tex_h, mean = atlas.add(mat.texture.file, f"{where}.texture.file")
        row[L.MAT_TEXTURE] = L.TEXTURE_IMAGE
        row[L.MAT_CHECK_A : L.MAT_CHECK_A + 3] = mean
        row[L.MAT_TEX_OFFSET] = offset
        row[L.MAT_TEX_WIDTH] = tex_w
        row[L.MAT_TEX_HEIGHT] = tex_h
        row[L.MAT_TEX_SCALE_U] = mat.texture.scale[0]
        row[L.MAT_TEX_SCALE_V] = mat.texture.scale[1]
    elif mat.texture is not None:
        row[L.MAT_TEXTURE] = L.TEXTURE_CHECKER
        row[L.MAT_CHECK_A : L.MAT_CHECK_A + 3] = mat.texture.colors[0]
        row[L.MAT_CHECK_B : L.MAT_CHECK_B + 3] = mat.texture.colors[1]
        row[L.MAT_CHECK_SCALE] = mat.texture.scale
    return row


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve, inverted (x in 0..1)."""
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


class TextureAtlas:
    """Image textures, decoded to linear float32 RGB and concatenated row by row into one
    (N, 3) array, so that the kernels get a single array (each material keeps its offset)."""

    MAX_TEXELS = 1 << 26  # 64 Mi texels (768 MiB): a guard against decompression bombs

    def __init__(self, base_dir: Path, source: str):
        self.base_dir = Path(base_dir)
        self.source = source
        self.parts: list[np.ndarray] = []
        self.size = 0
        self.loaded: dict[Path, tuple] = {}

    def add(self, file: str, where: str) -> tuple[int, int, int, np.ndarray]:
        """(offset, width, height, mean linear colour) of the image, loading it once."""
        path = Path(file)
        if not path.is_absolute():
            path = self.base_dir / path
        key = path.resolve()
        if key not in self.loaded:
            texels = self._load(path, where)
            h, w = texels.shape[:2]
            self.loaded[key] = (self.size, w, h, texels.reshape(-1, 3).mean(axis=0, dtype=np.float64))
            self.parts.append(texels.reshape(-1, 3))
            self.size += w * h
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

    def array(self) -> np.ndarray:
        if not self.parts:
            return np.zeros((1, 3), dtype=np.float32)
        return np.ascontiguousarray(np.concatenate(self.parts), dtype=np.float32)


def _lights(scene: Scene):
    kinds = np.zeros(len(scene.lights), dtype=np.int32)
    data = np.zeros((len(scene.lights), L.LIGHT_WIDTH), dtype=np.float64)
    for k, light in enumerate(scene.lights):
        data[k, 3:6] = light.intensity
        if light.type == "ambient":
            kinds[k] = L.LIGHT_AMBIENT
        elif light.type == "point":
            kinds[k] = L.LIGHT_POINT
            data[k, 0:3] = light.position
        elif light.type == "directional":
            kinds[k] = L.LIGHT_DIRECTIONAL
            data[k, 0:3] = unit_vector(light.direction)
        elif light.type == "quad":
            kinds[k] = L.LIGHT_QUAD
            data[k, 0:3] = light.position
            data[k, L.LIGHT_U : L.LIGHT_U + 3] = light.u
            data[k, L.LIGHT_V : L.LIGHT_V + 3] = light.v
            data[k, L.LIGHT_SAMPLES] = light.samples
        else:
            kinds[k] = L.LIGHT_SPHERE
            data[k, 0:3] = light.position
            data[k, L.LIGHT_RADIUS] = light.radius
            data[k, L.LIGHT_SAMPLES] = light.samples
    return kinds, data


class _TriangleSoup:
    """Triangles gathered object by object before the BVH reorders them."""

    def __init__(self):
        self.parts: list[tuple] = []  # (verts (F, 9) f32, normals (F, 9) f32 or None, material, object)
        self.uvs: list[np.ndarray | None] = []  # per part: (F, 6) f32 UVs, None when not needed
        self.degenerate = 0

    def add(self, vertices9: np.ndarray, normals9: np.ndarray | None, material: int, obj: int,
            uvs6: np.ndarray | None = None):
        self.parts.append((vertices9, normals9, material, obj))
        self.uvs.append(uvs6)

    def uv_array(self) -> np.ndarray:
        """float32 (T, 6) UVs of every triangle (zeros where none are needed), or (1, 6)
        when no triangle needs UVs (no image texture on a triangle)."""
        if not any(uv is not None for uv in self.uvs):
            return np.zeros((1, 6), dtype=np.float32)
        return np.concatenate([uv if uv is not None else np.zeros((len(p[0]), 6), np.float32)
                               for uv, p in zip(self.uvs, self.parts)]).astype(np.float32)

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
        prim = np.concatenate([np.arange(n, dtype=np.int32) for n in counts])
        return verts, normals, smooth, material, obj, prim


def _load_mesh_object(scene: Scene, k: int, obj: Mesh, source):
    path = Path(obj.file)
    if not path.is_absolute():
        path = scene.base_dir / path
    t = obj.transform
    try:
        return load_mesh(path, translate=t.translate, rotate=t.rotate, scale=t.scale3, smooth=obj.smooth)
    except MeshError as exc:
        raise SceneError(f"{source}: objects[{k}].file: {exc}") from None


def single_leaf_bvh(lo: np.ndarray, hi: np.ndarray) -> BVH:
    """A 'hierarchy' of one leaf holding every primitive: for small scenes (fastest so, and
    the BVH builder need not even be compiled) and for modes that never trace rays."""
    if len(lo):
        bounds = np.concatenate([lo.min(axis=0), hi.max(axis=0)]).astype(np.float32)[None, :]
    else:
        bounds = np.array([[np.inf] * 3 + [-np.inf] * 3], dtype=np.float32)
    n = len(lo)
    return BVH(bounds, np.array([[0, n]], dtype=np.int32), np.array([-1], dtype=np.int8), np.arange(n, dtype=np.int32))


def compile_scene(scene: Scene, width: int, height: int, source="<scene>", accelerate: bool = True) -> CompiledScene:
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

    spheres, sphere_mat, sphere_obj = [], [], []
    planes, plane_mat, plane_obj = [], [], []
    soup = _TriangleSoup()
    for k, obj in enumerate(scene.objects):
        m = material_index(obj, k)
        if isinstance(obj, Sphere):
            spheres.append((*obj.center, obj.radius))
            sphere_mat.append(m)
            sphere_obj.append(k)
        elif isinstance(obj, Plane):
            n = unit_vector(obj.normal)
            planes.append((*obj.point, *n))
            plane_mat.append(m)
            plane_obj.append(k)
        elif isinstance(obj, Triangle):
            uvs = np.array([[0, 0, 1, 0, 0, 1]], dtype=np.float32) if needs_uvs(obj) else None
            soup.add(np.asarray(obj.vertices, dtype=np.float32).reshape(1, 9), None, m, k, uvs)
        else:
            mesh = _load_mesh_object(scene, k, obj, source)
            verts = mesh.vertices.astype(np.float32)[mesh.faces].reshape(-1, 9)
            normals = None if mesh.normals is None else mesh.normals.astype(np.float32)[mesh.faces].reshape(-1, 9)
            uvs = None
            if needs_uvs(obj):
                if mesh.uvs is None:
                    raise SceneError(f"{source}: objects[{k}].file: the mesh has no texture coordinates (UVs), "
                                     "which its material's image texture needs")
                uvs = mesh.uvs.astype(np.float32)[mesh.faces].reshape(-1, 6)
            soup.add(verts, normals, m, k, uvs)
            soup.degenerate += mesh.degenerate

    sphere_arr = np.asarray(spheres, dtype=np.float64).reshape(-1, 4)
    tri, tri_n, tri_smooth, tri_mat, tri_obj, tri_prim = soup.arrays()
    tri_uv = soup.uv_array()
    n_spheres, n_tris = len(sphere_arr), len(tri)

    # Bounds of every BVH primitive: spheres first, then triangles (of the float32 vertices
    # the kernels intersect, so the boxes are exact).
    lo = np.empty((n_spheres + n_tris, 3), dtype=np.float64)
    hi = np.empty_like(lo)
    lo[:n_spheres] = sphere_arr[:, :3] - sphere_arr[:, 3:4]
    hi[:n_spheres] = sphere_arr[:, :3] + sphere_arr[:, 3:4]
    if n_tris:
        corners = tri.reshape(-1, 3, 3)
        lo[n_spheres:] = corners.min(axis=1)
        hi[n_spheres:] = corners.max(axis=1)
        del corners
    if accelerate and len(lo) > SMALL_SCENE:
        bvh = build_bvh(lo, hi, max_leaf_size=BVH_MAX_LEAF, c_trav=BVH_TRAVERSAL_COST)
        depth = bvh_depth(bvh)
    else:
        bvh = single_leaf_bvh(lo, hi)
        depth = 1
    if depth >= L.TRAVERSAL_STACK - 2:  # traversal stacks are fixed-size (no allocation per ray)
        raise SceneError(f"{source}: the BVH is {depth} levels deep, more than the {L.TRAVERSAL_STACK - 2} "
                         "traversal supports; the scene's primitives are pathologically arranged")

    # Reorder so that leaves read consecutive triangles (cache-friendly traversal).
    order = bvh.prim_order.astype(np.int64)
    is_tri = order >= n_spheres
    prim_type = np.where(is_tri, L.PRIM_TRIANGLE, L.PRIM_SPHERE).astype(np.int8)
    prim_id = order.astype(np.int32)
    tri_perm = order[is_tri] - n_spheres
    prim_id[is_tri] = np.arange(n_tris, dtype=np.int32)
    if n_tris:
        tri, tri_smooth, tri_mat, tri_obj, tri_prim = (a[tri_perm] for a in (tri, tri_smooth, tri_mat, tri_obj, tri_prim))
        if len(tri_n) == n_tris:
            tri_n = tri_n[tri_perm]
        if len(tri_uv) == n_tris:
            tri_uv = tri_uv[tri_perm]

    atlas = TextureAtlas(scene.base_dir, source)
    mat_rows = np.stack([material_row(m, atlas, material_where.get(m, "material")) for m in materials])
    finite_extent = [np.abs(lo).max() if len(lo) else 0.0, np.abs(hi).max() if len(hi) else 0.0]
    if planes:
        finite_extent.append(np.abs(np.asarray(planes)[:, :3]).max())
    finite_extent.append(np.abs(scene.camera.position).max())
    kinds, data = _lights(scene)
    kernel = KernelScene(
        materials=mat_rows,
        light_kind=kinds,
        light_data=data,
        spheres=sphere_arr,
        sphere_material=np.asarray(sphere_mat, dtype=np.int32),
        sphere_object=np.asarray(sphere_obj, dtype=np.int32),
        planes=np.asarray(planes, dtype=np.float64).reshape(-1, 6),
        plane_material=np.asarray(plane_mat, dtype=np.int32),
        plane_object=np.asarray(plane_obj, dtype=np.int32),
        triangles=np.ascontiguousarray(tri),
        triangle_normals=np.ascontiguousarray(tri_n),
        triangle_smooth=tri_smooth,
        triangle_material=tri_mat,
        triangle_object=tri_obj,
        triangle_prim=tri_prim,
        node_bounds=bvh.node_bounds,
        node_index=bvh.node_index,
        prim_type=prim_type,
        prim_id=prim_id,
        has_transparency=bool((mat_rows[:, L.MAT_TRANSPARENCY] > 0).any()),
        epsilon_floor=float(max(1e-3 * max(finite_extent), 1e-30)),
        triangle_uvs=np.ascontiguousarray(tri_uv),
        textures=atlas.array(),
    )
    cam = scene.camera
    camera = camera_frame(cam.position, cam.look_at, cam.up, cam.fov, width, height,
                          aperture=cam.aperture, focus_distance=cam.focus, pixel_filter=scene.render.filter)
    stats = {
        "primitives": n_spheres + n_tris + len(planes),
        "triangles": n_tris,
        "degenerate_triangles": soup.degenerate,
        "bvh_nodes": int(len(bvh.node_index)),
        "bvh_depth": int(depth),
        "bvh_bytes": int(bvh_nbytes(bvh) + prim_type.nbytes + prim_id.nbytes),
        "build_seconds": time.perf_counter() - start,
    }
    return CompiledScene(kernel, camera, stats)
