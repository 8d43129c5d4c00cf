"""glTF 2.0 import: a file's node hierarchy, meshes, materials, cameras and lights as raylume
sees them (DESIGN.md section 6, "Instances and glTF scenes").

The result is a `GltfScene`: each mesh primitive once, in its own frame (`GltfPart.mesh`), with
the world matrices of every node (and EXT_mesh_gpu_instancing instance) that uses it; materials
as model `Material`s; cameras and KHR_lights_punctual lights in raylume's world; base colour
textures decoded to linear texels. The compiler turns parts into triangles (compile/objects.py).

Handedness: glTF is right-handed (+y up, +z out of the screen, a camera looks along its -z);
raylume is left-handed. Every world matrix starts with HANDEDNESS = diag(1, 1, -1): glTF's
(x, y, z) is raylume's (x, y, -z). A mirror of the whole scene, cameras included, shows the
same image: a camera's right vector r = cross(up, forward) flips with the mirror exactly as the
handedness does, so what a glTF viewer shows on the left stays on the left. Mirrored matrices
(negative determinant) reverse triangle winding, so normals stay outward.

Materials (pbrMetallicRoughness onto raylume's path-mode materials; roughness r is GGX alpha
r^2; trace mode uses each type's approximation, compile.trace_approximation):
* KHR_materials_transmission >= 0.5: `dielectric` (ior from KHR_materials_ior, default 1.5;
  the base colour as its transmittance tint);
* else metallic >= 0.5: `conductor` (the base colour as its specular reflectance, no eta/k);
* else `plastic` (the base colour under a coating of the material's ior, default 1.5), or
  `diffuse` at roughness 1 (the coating's reflection, a few percent, spread over the
  hemisphere: taken as Lambertian).
Approximated: metallic between 0 and 1 is rounded to the nearer type (raylume has no blend);
baseColorTexture is multiplied by baseColorFactor and replaces the colour (sampled with
TEXCOORD_0, repeating); metallicRoughnessTexture and emissiveTexture scale their factors by the
texture's mean (raylume's materials have no per-texel metallic, roughness or emission);
normalTexture is the normal map (its scale the strength; tangents from the UVs, not the
TANGENT attribute); alphaMode MASK is the alpha map (baseColorTexture's alpha times
baseColorFactor's, kept in `images` as its own coverage image, cut below alphaCutoff), BLEND a
mask at 0.5 with a warning (raylume has no partial transparency), and an emissive material
keeps its emission without the mask (a warning); occlusion textures and samplers' wrap modes
are ignored; every surface is two-sided.

Lights (KHR_lights_punctual, colour times intensity): a point or spot light's intensity in
candela becomes raylume's radiant intensity (W/sr) one to one, a directional light's
illuminance in lux raylume's irradiance one to one, as the Khronos sample viewer and three.js
treat them (no 683 lm/W photometric factor: images come out as bright as in those viewers).
`range` is ignored (raylume's lights fall off as 1/r^2 without cutoff). Spot cones: outer and
inner cone angles (radians) become `angle` and `inner_angle` (degrees).
"""

from __future__ import annotations

import math
import os
import warnings
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .checks import SceneWarning
from .gltf_file import GltfError, GltfFile
from .mesh import MeshData, _apply, _smooth_normals, object_matrix_of, strips_to_triangles
from .model import Material, parse_material

HANDEDNESS = np.diag([1.0, 1.0, -1.0, 1.0])
SUPPORTED_EXTENSIONS = (
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_mesh_quantization",  # integer and normalized attributes: the accessor reader takes any type
    "EXT_mesh_gpu_instancing",
)
TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = 4, 5, 6
_DEGENERATE_SIN2 = 1e-20  # as scene/mesh.py: zero area up to float64 rounding


@dataclass(frozen=True)
class GltfPart:
    """One mesh primitive: its triangles in the mesh's own frame, its material, and the
    matrices (N, 4, 4) that place it in raylume's world (one per node or GPU instance using it,
    column vectors, HANDEDNESS included)."""

    mesh: MeshData
    material: int
    matrices: np.ndarray
    name: str


@dataclass(frozen=True)
class GltfCamera:
    name: str
    position: tuple
    look_at: tuple
    up: tuple
    fov: float  # vertical, degrees
    aspect: float | None  # width / height, when the file gives it
    node_name: str | None = None  # its node's name, which --camera also takes


@dataclass
class GltfScene:
    path: Path
    parts: list[GltfPart]
    materials: list[Material]
    images: dict[str, np.ndarray]  # ImageTexture.file key -> linear float32 texels (H, W, 3)
    cameras: list[GltfCamera]
    lights: list[dict]  # light tables of the scene model
    warnings: list[str] = field(default_factory=list)

    def placed(self, matrix: np.ndarray) -> GltfScene:
        """The scene moved by `matrix` (4x4, applied after the file's own world matrices);
        cameras and lights are not moved (an object in a TOML scene imports neither)."""
        parts = [GltfPart(p.mesh, p.material, matrix @ p.matrices, p.name) for p in self.parts]
        return GltfScene(self.path, parts, self.materials, self.images, self.cameras, self.lights, self.warnings)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """A box around every placed triangle (each part's box corners, transformed)."""
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for part in self.parts:
            v = part.mesh.vertices[np.unique(part.mesh.faces)]
            a, b = v.min(axis=0), v.max(axis=0)
            corners = np.array([[x, y, z, 1.0] for x in (a[0], b[0]) for y in (a[1], b[1]) for z in (a[2], b[2])])
            world = np.einsum("nij,cj->nci", part.matrices, corners)[..., :3].reshape(-1, 3)
            lo, hi = np.minimum(lo, world.min(axis=0)), np.maximum(hi, world.max(axis=0))
        return lo, hi


def flatten(part: GltfPart):
    """The part's world-space copies, one MeshData per matrix (what the compiler adds until
    instances are compiled as such). Matrices that flatten the mesh (det 0) are skipped."""
    m = part.mesh
    for matrix in part.matrices:
        if np.linalg.det(matrix[:3, :3]) == 0:
            continue
        v, f, n = _apply(matrix, m.vertices, m.faces, None if m.normals is None else m.normals.astype(np.float64))
        if n is not None:
            n = (n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]).astype(np.float32)
        yield MeshData(v, np.ascontiguousarray(f, dtype=np.int32), n, m.uvs, m.degenerate)


# ---------------------------------------------------------------------- reading, cached

_cache: dict = {}  # at most one read file: {(path, mtime, size): GltfScene}


def read_gltf(path: str | Path) -> GltfScene:
    """The file's scene (raising GltfError). The last file read is kept, so that framing the
    scene and compiling it read it once; its warnings are issued when it is read."""
    path = Path(os.fspath(path))
    try:
        stat = os.stat(path)
        key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    except OSError:
        key = None
    if key is not None and key in _cache:
        return _cache[key]
    file = GltfFile(path)
    try:
        scene = _Importer(file).run()
    except GltfError:
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError) as exc:
        # a value of the wrong JSON type where the reader does not check it by name
        raise GltfError(f"glTF file {path}: it does not follow the glTF 2.0 schema ({exc}).") from None
    for message in scene.warnings:
        warnings.warn(message, SceneWarning, stacklevel=2)
    _cache.clear()
    if key is not None:
        _cache[key] = scene
    return scene


def load_gltf_object(obj, base_dir: Path) -> GltfScene:
    """A `type = "gltf"` object's scene, placed by its transform (scale, rotate, translate)."""
    path = Path(obj.file)
    path = path if path.is_absolute() else Path(base_dir) / path
    t = obj.transform
    return read_gltf(path).placed(object_matrix_of(t))


# ---------------------------------------------------------------------- the importer


def _srgb_to_linear(x: np.ndarray) -> np.ndarray:
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _quaternion_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of unit quaternions (N, 4) stored x, y, z, w."""
    x, y, z, w = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def _trs(t: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(N, 4, 4) matrices T @ R @ S from translations (N, 3), quaternions (N, 4), scales (N, 3)."""
    length = np.linalg.norm(r, axis=1, keepdims=True)
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = _quaternion_matrices(r / np.where(length > 0, length, 1.0)) * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


class _Importer:
    def __init__(self, file: GltfFile):
        self.file = file
        self.warnings: list[str] = []
        self.images: dict[str, np.ndarray] = {}
        self.materials: list[Material] = []
        self.material_rows: dict[int | None, int] = {}
        self.mesh_parts: dict[int, list[tuple[MeshData, int | None, str]]] = {}

    def warn(self, message: str) -> None:
        self.warnings.append(f"glTF file {self.file.path}: {message}")

    def run(self) -> GltfScene:
        self._extensions()
        placements, cameras, lights = self._walk()
        parts = []
        for mesh_index, matrices in placements.items():
            for data, material, name in self._mesh(mesh_index):
                parts.append(GltfPart(data, self._material(material), np.stack(matrices), name))
        if not parts:
            self.file.fail("it contains no triangles (no node of its scene has a mesh of triangles)")
        return GltfScene(self.file.path, parts, self.materials, self.images, cameras, lights, self.warnings)

    def _extensions(self) -> None:
        doc, f = self.file.doc, self.file
        for key in ("extensionsRequired", "extensionsUsed"):
            if not all(isinstance(e, str) for e in f.items(key)):
                f.fail(f"{key} must be a list of extension names")
        required = [e for e in doc.get("extensionsRequired", []) if e not in SUPPORTED_EXTENSIONS]
        if required:
            f.fail(
                f"it requires the extension{'s' if len(required) > 1 else ''} {', '.join(required)}, which raylume "
                f"cannot honour (supported: {', '.join(SUPPORTED_EXTENSIONS)})"
            )
        ignored = [e for e in doc.get("extensionsUsed", []) if e not in SUPPORTED_EXTENSIONS]
        if ignored:
            self.warn(
                f"ignores the optional extension{'s' if len(ignored) > 1 else ''} {', '.join(ignored)} "
                "(the image may differ from a glTF viewer's)"
            )

    # -------------------------------------------------------------- the node hierarchy

    def _roots(self) -> list[tuple[int, str]]:
        """(node index, the key path that names it) of the scene's root nodes."""
        f = self.file
        scenes = f.items("scenes")
        if scenes:
            index = f.doc.get("scene", 0)
            nodes = f.item("scenes", index, "scene").get("nodes", [])
            if not isinstance(nodes, list):
                f.fail(f"scenes[{index}].nodes is not a list")
            return [(n, f"scenes[{index}].nodes[{k}]") for k, n in enumerate(nodes)]
        children = set()
        for node in f.items("nodes"):
            if isinstance(node, dict) and isinstance(node.get("children"), list):
                children.update(c for c in node["children"] if isinstance(c, int))  # others fail in _walk
        return [(n, f"nodes[{n}]") for n in range(len(f.items("nodes"))) if n not in children]

    def _local(self, node: dict, where: str) -> np.ndarray:
        f = self.file
        if "matrix" in node:
            return f.numbers(node["matrix"], 16, f"{where}.matrix").reshape(4, 4).T  # stored column by column
        t = f.numbers(node.get("translation"), 3, f"{where}.translation", (0, 0, 0))
        r = f.numbers(node.get("rotation"), 4, f"{where}.rotation", (0, 0, 0, 1))
        s = f.numbers(node.get("scale"), 3, f"{where}.scale", (1, 1, 1))
        if not np.any(r):
            f.fail(f"{where}.rotation is the zero quaternion")
        return _trs(t[None], r[None], s[None])[0]

    def _walk(self):
        """(mesh -> list of world matrices, cameras, lights), depth first in the scene's order."""
        f = self.file
        placements: dict[int, list[np.ndarray]] = defaultdict(list)
        cameras: list[tuple[int, GltfCamera]] = []
        lights: list[dict] = []
        stack = [(n, HANDEDNESS, (), where) for n, where in reversed(self._roots())]
        while stack:
            index, parent, ancestors, where = stack.pop()
            node = f.item("nodes", index, where)
            here = f"nodes[{index}]"
            if index in ancestors:
                f.fail(f"{here} is its own ancestor (the node hierarchy has a cycle)")
            world = parent @ self._local(node, here)
            if node.get("mesh") is not None:
                f.item("meshes", node["mesh"], f"{here}.mesh")
                placements[node["mesh"]].extend(world @ self._gpu_instances(node, here))
            if node.get("camera") is not None:
                camera = self._camera(node["camera"], node, world, here)
                if camera is not None:
                    cameras.append((node["camera"], camera))
            light = (node.get("extensions") or {}).get("KHR_lights_punctual")
            if isinstance(light, dict) and light.get("light") is not None:
                lights.append(self._light(light["light"], world, f"{here}.extensions.KHR_lights_punctual.light"))
            children = node.get("children", [])
            if not isinstance(children, list):
                f.fail(f"{here}.children is not a list")
            for k, child in reversed(list(enumerate(children))):
                stack.append((child, world, (*ancestors, index), f"{here}.children[{k}]"))
        cameras.sort(key=lambda c: c[0])  # the file's first camera first, then in node order
        return placements, [c for _, c in cameras], lights

    def _gpu_instances(self, node: dict, where: str) -> np.ndarray:
        """EXT_mesh_gpu_instancing's per-instance matrices (N, 4, 4), or the identity (1, 4, 4)."""
        ext = (node.get("extensions") or {}).get("EXT_mesh_gpu_instancing")
        if not isinstance(ext, dict):
            return np.eye(4)[None]
        where = f"{where}.extensions.EXT_mesh_gpu_instancing.attributes"
        attributes = ext.get("attributes") or {}
        columns = {}
        for name, width in (("TRANSLATION", 3), ("ROTATION", 4), ("SCALE", 3)):
            if name in attributes:
                values = self.file.accessor(attributes[name], f"{where}.{name}")
                if values.shape[1] != width or not np.all(np.isfinite(values)):
                    self.file.fail(f"{where}.{name} must hold finite {width}-vectors")
                columns[name] = values.astype(np.float64)
        counts = {len(v) for v in columns.values()}
        if len(counts) > 1:
            self.file.fail(f"{where}: TRANSLATION, ROTATION and SCALE hold different numbers of instances")
        n = counts.pop() if counts else 1
        t = columns.get("TRANSLATION", np.zeros((n, 3)))
        r = columns.get("ROTATION", np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))
        s = columns.get("SCALE", np.ones((n, 3)))
        return _trs(t, r, s)

    def _camera(self, index, node: dict, world: np.ndarray, where: str) -> GltfCamera | None:
        f = self.file
        cam = f.item("cameras", index, f"{where}.camera")
        here = f"cameras[{index}]"
        if cam.get("type") != "perspective":
            self.warn(f"{here} is {cam.get('type')!r}; only perspective cameras are imported")
            return None
        p = cam.get("perspective") or {}
        yfov = f.number(p.get("yfov"), f"{here}.perspective.yfov")
        if not 0 < yfov < math.pi:
            f.fail(f"{here}.perspective.yfov is {yfov}, not between 0 and pi radians")
        aspect = p.get("aspectRatio")
        aspect = None if aspect is None else f.number(aspect, f"{here}.perspective.aspectRatio")
        if aspect is not None and aspect <= 0:
            f.fail(f"{here}.perspective.aspectRatio is {aspect}, not > 0")
        linear = world[:3, :3]
        position = world[:3, 3]
        forward = linear @ np.array([0.0, 0.0, -1.0])  # a glTF camera looks along its -z
        up = linear @ np.array([0.0, 1.0, 0.0])
        if np.linalg.norm(forward) == 0 or np.linalg.norm(np.cross(forward, up)) == 0:
            f.fail(f"{where}'s transform leaves camera {here} without a viewing direction")
        forward = forward / np.linalg.norm(forward)
        name = cam.get("name") or node.get("name") or here
        return GltfCamera(
            node_name=None if node.get("name") is None else str(node.get("name")),
            name=str(name),
            position=tuple(position.tolist()),
            look_at=tuple((position + forward).tolist()),
            up=tuple((up / np.linalg.norm(up)).tolist()),
            fov=math.degrees(yfov),
            aspect=aspect,
        )

    def _light(self, index, world: np.ndarray, where: str) -> dict:
        f = self.file
        table = ((f.doc.get("extensions") or {}).get("KHR_lights_punctual") or {}).get("lights", [])
        if not f.index(index, where) < len(table):
            f.fail(f"{where} refers to light {index}, but the file's KHR_lights_punctual has {len(table)}")
        light = table[index]
        if not isinstance(light, dict):
            f.fail(f"extensions.KHR_lights_punctual.lights[{index}] is not an object")
        here = f"extensions.KHR_lights_punctual.lights[{index}]"
        colour = f.numbers(light.get("color"), 3, f"{here}.color", (1, 1, 1))
        intensity = f.number(light.get("intensity"), f"{here}.intensity", 1)
        if intensity < 0 or np.any(colour < 0):
            f.fail(f"{here}: color and intensity must not be negative")
        rgb = (colour * intensity).tolist()
        kind = light.get("type")
        position = world[:3, 3].tolist()

        def direction(z: float) -> list:
            d = world[:3, :3] @ np.array([0.0, 0.0, z])
            if not np.any(d):
                f.fail(f"{where}: the node's transform leaves the light without a direction")
            return (d / np.linalg.norm(d)).tolist()

        if kind == "point":
            return {"type": "point", "position": position, "intensity": rgb}
        if kind == "directional":  # shines along its -z; raylume's direction points towards the light
            return {"type": "directional", "direction": direction(1.0), "intensity": rgb}
        if kind == "spot":
            spot = light.get("spot") or {}
            outer = f.number(spot.get("outerConeAngle"), f"{here}.spot.outerConeAngle", math.pi / 4)
            inner = f.number(spot.get("innerConeAngle"), f"{here}.spot.innerConeAngle", 0)
            if not 0 <= inner < outer <= math.pi / 2:
                f.fail(f"{here}.spot: need 0 <= innerConeAngle < outerConeAngle <= pi/2, got {inner} and {outer}")
            return {
                "type": "spot",
                "position": position,
                "direction": direction(-1.0),
                "angle": math.degrees(outer),
                "inner_angle": math.degrees(inner),
                "intensity": rgb,
            }
        f.fail(f"{here}.type is {kind!r}, not point, spot or directional")

    # -------------------------------------------------------------- meshes

    def _mesh(self, index: int) -> list[tuple[MeshData, int | None, str]]:
        if index not in self.mesh_parts:
            mesh = self.file.item("meshes", index, "nodes[].mesh")
            parts = []
            for p, prim in enumerate(mesh.get("primitives", [])):
                where = f"meshes[{index}].primitives[{p}]"
                if prim.get("material") is not None:  # checked here, where its key path is known
                    self.file.item("materials", prim["material"], f"{where}.material")
                data = self._primitive(prim, where)
                if data is not None:
                    parts.append((data, prim.get("material"), f"{mesh.get('name') or f'meshes[{index}]'}/{p}"))
            self.mesh_parts[index] = parts
        return self.mesh_parts[index]

    def _attribute(self, attributes: dict, name: str, width: int, where: str) -> np.ndarray | None:
        if name not in attributes:
            return None
        values = self.file.accessor(attributes[name], f"{where}.attributes.{name}")
        if values.shape[1] != width:
            self.file.fail(f"{where}.attributes.{name} has {values.shape[1]} components, not {width}")
        if not np.all(np.isfinite(values)):
            self.file.fail(f"accessors[{attributes[name]}] ({where}.attributes.{name}) holds NaN or infinite values")
        return values.astype(np.float64)

    def _primitive(self, prim: dict, where: str) -> MeshData | None:
        f = self.file
        mode = prim.get("mode", TRIANGLES)
        if mode not in (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN):
            self.warn(f"{where} draws points or lines (mode {mode}); only triangles are imported")
            return None
        attributes = prim.get("attributes") or {}
        v = self._attribute(attributes, "POSITION", 3, where)
        if v is None:
            self.warn(f"{where} has no POSITION attribute; skipped")
            return None
        if prim.get("indices") is not None:
            idx = f.accessor(prim["indices"], f"{where}.indices").ravel().astype(np.int64)
            if len(idx) and (idx.min() < 0 or idx.max() >= len(v)):
                f.fail(f"accessors[{prim['indices']}] ({where}.indices) refers to vertex {idx.max()} of {len(v)}")
        else:
            idx = np.arange(len(v), dtype=np.int64)
        if mode == TRIANGLES:
            if len(idx) % 3:
                f.fail(f"{where} has {len(idx)} indices, not a multiple of 3 (mode TRIANGLES)")
            faces = idx.reshape(-1, 3)
        elif mode == TRIANGLE_STRIP:
            faces = strips_to_triangles([idx])
        else:
            faces = np.stack([np.full(max(len(idx) - 2, 0), idx[0] if len(idx) else 0), idx[1:-1], idx[2:]], 1)
        n = self._attribute(attributes, "NORMAL", 3, where)
        uv = self._attribute(attributes, "TEXCOORD_0", 2, where)
        if uv is not None:
            uv = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])  # glTF's v runs down the image, raylume's up
        e1, e2 = v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]
        cross = np.cross(e1, e2)
        good = np.einsum("ij,ij->i", cross, cross) > _DEGENERATE_SIN2 * np.einsum("ij,ij->i", e1, e1) * np.einsum(
            "ij,ij->i", e2, e2
        )
        faces = np.ascontiguousarray(faces[good], dtype=np.int32)
        if len(faces) == 0:
            return None
        normals = None
        if n is not None:
            length = np.linalg.norm(n, axis=1)
            bad = ~(length > 0)
            normals = n / np.where(bad, 1.0, length)[:, None]
            if bad.any():
                normals[bad] = _smooth_normals(v, faces)[bad]
            normals = normals.astype(np.float32)
        return MeshData(v, faces, normals, None if uv is None else uv.astype(np.float32), int(np.count_nonzero(~good)))

    # -------------------------------------------------------------- materials

    def _material(self, index: int | None) -> int:
        if index is not None:
            self.file.item("materials", index, "a primitive's material")
        if index not in self.material_rows:
            self.materials.append(self._convert(index))
            self.material_rows[index] = len(self.materials) - 1
        return self.material_rows[index]

    def _texture(self, info, where: str, alpha: bool = False) -> np.ndarray | None:
        """The image of a textureInfo as floats 0..1 (H, W, 3), with `alpha` (H, W, 4), or None."""
        if not isinstance(info, dict):
            return None
        f = self.file
        if info.get("texCoord", 0) != 0:
            self.warn(f"{where} uses TEXCOORD_{info['texCoord']}; raylume reads TEXCOORD_0")
        texture = f.item("textures", info.get("index"), f"{where}.index")
        source = texture.get("source")
        if source is None:
            self.warn(f"{where}: textures[{info.get('index')}] has no source image (an extension's format?); ignored")
            return None
        return f.image(source, f"textures[{info.get('index')}].source", alpha).astype(np.float64) / 255.0

    def _normal_map(self, info, here: str, table: dict) -> None:
        """normalTexture as the material's normal map: its texels as stored (glTF's normal maps
        are linear), its `scale` as the strength of x and y."""
        where = f"{here}.normalTexture"
        image = self._texture(info, where)
        if image is None:
            return
        strength = self.file.number(info.get("scale"), f"{where}.scale", 1)
        if strength < 0:  # the spec allows it (an inverted map); raylume's strength is >= 0
            self.warn(f"{where}.scale is {strength:g}; raylume reads normal maps at strength 0 or more, so 0")
            strength = 0.0
        key = f"{self.file.path.resolve()}#{where}"
        self.images[key] = image.astype(np.float32)
        table["normal_map"] = {"file": key, "strength": strength}

    def _alpha_map(self, mat: dict, here: str, alpha: float, image: np.ndarray | None, emissive: bool, table: dict):
        """alphaMode MASK (or BLEND, approximated by a mask) as the material's alpha map: the
        coverage baseColorTexture's alpha times baseColorFactor's (a 1 x 1 image of the factor's
        without a texture), cut below alphaCutoff (BLEND: 0.5). Nothing where nothing is cut."""
        f = self.file
        mode = mat.get("alphaMode", "OPAQUE")
        if mode == "OPAQUE":
            return  # alphaCutoff is ignored, as the spec has it
        if mode not in ("MASK", "BLEND"):
            f.fail(f"{here}.alphaMode is {mode!r}, not OPAQUE, MASK or BLEND")
        if mode == "MASK":
            cutoff = f.number(mat.get("alphaCutoff"), f"{here}.alphaCutoff", 0.5)
            if cutoff < 0:
                f.fail(f"{here}.alphaCutoff is {cutoff:g}, not >= 0")
        else:
            cutoff = 0.5
            self.warn(
                f"{here} ({mat.get('name') or 'unnamed'}) is alphaMode BLEND; raylume has no partial transparency, "
                "so it is cut as a mask at alpha 0.5 (solid above, a hole below)"
            )
        coverage = np.clip(alpha, 0.0, 1.0) * (image[..., 3] if image is not None else np.ones((1, 1)))
        if cutoff == 0 or coverage.min() >= cutoff:
            return  # no texel below the cutoff, and no bilinear lookup between them: no hole
        if emissive:
            self.warn(f"{here} emits light and is alphaMode {mode}; raylume's emitters take no mask: drawn whole")
            return
        if cutoff > 1:  # every coverage is below it: one hole
            coverage, cutoff = np.zeros((1, 1)), 1.0
        key = f"{f.path.resolve()}#{here}.alpha"
        self.images[key] = np.repeat(coverage[..., None], 3, axis=2).astype(np.float32)
        table["alpha_map"] = {"file": key, "cutoff": cutoff}

    def _convert(self, index: int | None) -> Material:
        """glTF material `index` (None: the spec's default material) as a raylume Material."""
        f = self.file
        mat = {} if index is None else f.item("materials", index, "a primitive's material")
        here = f"materials[{index}]"
        pbr = mat.get("pbrMetallicRoughness") or {}
        factor = f.numbers(pbr.get("baseColorFactor"), 4, f"{here}.baseColorFactor", (1, 1, 1, 1))
        base = np.clip(factor[:3], 0, 1)
        masked = mat.get("alphaMode", "OPAQUE") != "OPAQUE"
        metallic = float(np.clip(f.number(pbr.get("metallicFactor"), f"{here}.metallicFactor", 1), 0, 1))
        roughness = float(np.clip(f.number(pbr.get("roughnessFactor"), f"{here}.roughnessFactor", 1), 0, 1))
        table: dict = {}
        colours = self._texture(pbr.get("baseColorTexture"), f"{here}.pbrMetallicRoughness.baseColorTexture", masked)
        if colours is not None:
            key = f"{f.path.resolve()}#{here}.baseColorTexture"
            self.images[key] = (_srgb_to_linear(colours[..., :3]) * base).astype(np.float32)
            table["texture"] = {"type": "image", "file": key}
        where = f"{here}.pbrMetallicRoughness.metallicRoughnessTexture"
        image = self._texture(pbr.get("metallicRoughnessTexture"), where)
        if image is not None:  # green: roughness, blue: metallic; per-texel values are averaged
            roughness *= float(image[..., 1].mean())
            metallic *= float(image[..., 2].mean())
        self._normal_map(mat.get("normalTexture"), here, table)
        ext = mat.get("extensions") or {}
        emission = f.numbers(mat.get("emissiveFactor"), 3, f"{here}.emissiveFactor", (0, 0, 0))
        strength = (ext.get("KHR_materials_emissive_strength") or {}).get("emissiveStrength")
        emission = emission * f.number(strength, f"{here}.emissiveStrength", 1)
        image = self._texture(mat.get("emissiveTexture"), f"{here}.emissiveTexture")
        if image is not None:
            emission = emission * _srgb_to_linear(image).reshape(-1, 3).mean(axis=0)
        transmission = f.number(
            (ext.get("KHR_materials_transmission") or {}).get("transmissionFactor"), f"{here}.transmissionFactor", 0
        )
        ior = f.number((ext.get("KHR_materials_ior") or {}).get("ior"), f"{here}.ior", 1.5)
        ior = ior if ior >= 1 else 1.5  # 0 (a KHR_materials_ior special case) and < 1: the default
        emission = np.maximum(emission, 0)
        self._alpha_map(mat, here, float(factor[3]), colours if masked else None, bool(emission.any()), table)
        table.update(color=base.tolist(), emission=emission.tolist(), roughness=roughness**2)
        if transmission >= 0.5:
            table.update(type="dielectric", ior=ior)
        elif metallic >= 0.5:
            table.update(type="conductor")
        elif roughness >= 1:  # fully rough: its coating's few percent spread over the hemisphere
            table.update(type="diffuse")
            del table["roughness"]
        else:
            table.update(type="plastic", ior=ior)
        return parse_material(table)


def is_gltf_file(path: str | Path) -> bool:
    return Path(path).suffix.lower() in (".gltf", ".glb")


__all__ = [
    "GltfCamera",
    "GltfError",
    "GltfPart",
    "GltfScene",
    "flatten",
    "is_gltf_file",
    "load_gltf_object",
    "read_gltf",
]
