"""glTF 2.0 import (scene/gltf.py, gltf_file.py, gltf_scene.py), checked against files written
here byte by byte (JSON + a numpy buffer) and values computed by hand: where a vertex lands on
the image, a point light's irradiance on a diffuse plane, the materials' factors, the file's
orientation as a glTF viewer shows it, and the errors for broken files."""

from __future__ import annotations

import json
import math
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage
from test_cli import assert_refused
from test_cli import raylume as run_cli

import raylume
from raylume.cli import _resolve_scene
from raylume.compile import compile_scene
from raylume.errors import SceneError
from raylume.kernels.shading import materials as M
from raylume.scene.checks import SceneWarning
from raylume.scene.gltf import read_gltf
from raylume.scene.gltf_scene import gltf_scene
from raylume.scene.load import load_scene

FLOAT, USHORT = 5126, 5123


class Builder:
    """A glTF document and its one binary buffer, written as .glb or .gltf + .bin."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}], "nodes": []}
        self.blob = bytearray()

    def accessor(self, values, ctype=FLOAT, kind=None) -> int:
        values = np.asarray(values, dtype={FLOAT: np.float32, USHORT: np.uint16}[ctype])
        width = 1 if values.ndim == 1 else values.shape[1]
        kind = kind or {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}[width]
        self.blob += b"\0" * (-len(self.blob) % 4)
        views = self.doc.setdefault("bufferViews", [])
        views.append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": values.nbytes})
        self.blob += values.tobytes()
        accessors = self.doc.setdefault("accessors", [])
        accessors.append({"bufferView": len(views) - 1, "componentType": ctype, "count": len(values), "type": kind})
        return len(accessors) - 1

    def mesh(self, positions, indices=None, material=None, normals=None, uvs=None) -> int:
        prim = {"attributes": {"POSITION": self.accessor(positions)}}
        if indices is not None:
            prim["indices"] = self.accessor(np.ravel(indices), USHORT)
        if normals is not None:
            prim["attributes"]["NORMAL"] = self.accessor(normals)
        if uvs is not None:
            prim["attributes"]["TEXCOORD_0"] = self.accessor(uvs)
        if material is not None:
            prim["material"] = material
        self.doc.setdefault("meshes", []).append({"primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def quad(self, x0, x1, y0, y1, z=0.0, material=None) -> int:
        """A rectangle in a plane of constant z, facing +z (towards a default glTF camera)."""
        p = [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]
        return self.mesh(
            p, [[0, 1, 2], [0, 2, 3]], material, normals=[[0, 0, 1]] * 4, uvs=[[0, 1], [1, 1], [1, 0], [0, 0]]
        )

    def material(self, **table) -> int:
        self.doc.setdefault("materials", []).append(table)
        return len(self.doc["materials"]) - 1

    def node(self, root=True, **table) -> int:
        self.doc["nodes"].append(table)
        if root:
            self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def camera(self, yfov, aspect=None, name=None, **node) -> int:
        perspective = {"yfov": yfov, "znear": 0.01}
        if aspect is not None:
            perspective["aspectRatio"] = aspect
        cam = {"type": "perspective", "perspective": perspective}
        if name:
            cam["name"] = name
        self.doc.setdefault("cameras", []).append(cam)
        return self.node(camera=len(self.doc["cameras"]) - 1, **node)

    def light(self, light: dict, **node) -> int:
        ext = self.doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})
        ext["lights"].append(light)
        used = self.doc.setdefault("extensionsUsed", [])
        if "KHR_lights_punctual" not in used:
            used.append("KHR_lights_punctual")
        return self.node(extensions={"KHR_lights_punctual": {"light": len(ext["lights"]) - 1}}, **node)

    def glb(self, path):
        doc = {**self.doc, "buffers": [{"byteLength": len(self.blob)}]}
        text = json.dumps(doc).encode()
        text += b" " * (-len(text) % 4)
        blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
        chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
        path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
        return path

    def gltf(self, path):
        (path.parent / "buffer.bin").write_bytes(bytes(self.blob))
        doc = {**self.doc, "buffers": [{"byteLength": len(self.blob), "uri": "buffer.bin"}]}
        path.write_text(json.dumps(doc))
        return path


def rgb_of(path):
    return raylume.render(load_scene(path), mode="cast").rgb


def hits(image) -> np.ndarray:
    return image.aovs["object"] >= 0


# ------------------------------------------------------------------ camera and orientation


def two_squares(b: Builder):
    """A red square on the file's -x side and a blue one on its +x side, both at z = 0."""
    red = b.material(pbrMetallicRoughness={"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0})
    blue = b.material(pbrMetallicRoughness={"baseColorFactor": [0, 0, 1, 1], "metallicFactor": 0})
    b.node(mesh=b.quad(-1.5, -0.5, 0.2, 1.0, material=red))
    b.node(mesh=b.quad(0.5, 1.5, 0.2, 1.0, material=blue))


def test_a_vertex_lands_on_the_hand_computed_pixel_and_left_stays_left(tmp_path):
    # Camera at (0, 0, 5) looking along -z (glTF's default orientation), tan(yfov/2) = 0.5: at
    # distance 5 the image spans x, y in -2.5..2.5 over 40 x 40 pixels, 8 pixels per unit.
    b = Builder()
    two_squares(b)
    b.camera(2 * math.atan(0.5), aspect=1.0, translation=[0, 0, 5])
    b.light({"type": "directional", "intensity": 1})
    image = raylume.render(load_scene(b.glb(tmp_path / "squares.glb")), width=40, height=40, mode="cast")
    albedo = image.aovs["albedo"]
    column = lambda x: (x / 2.5 + 1) / 2 * 40  # noqa: E731  pixel edge of file coordinate x
    row = lambda y: (1 - y / 2.5) / 2 * 40  # noqa: E731
    centres = np.arange(40) + 0.5
    inside_y = (centres > row(1.0)) & (centres < row(0.2))
    red_x = (centres > column(-1.5)) & (centres < column(-0.5))
    blue_x = (centres > column(0.5)) & (centres < column(1.5))
    np.testing.assert_array_equal(hits(image), inside_y[:, None] & (red_x | blue_x)[None, :])
    # the file's -x (red) on the image's left, as a glTF viewer shows it: not mirrored
    assert (albedo[inside_y][:, red_x] == [1, 0, 0]).all() and (albedo[inside_y][:, blue_x] == [0, 0, 1]).all()
    depth = image.aovs["depth"][inside_y][:, red_x | blue_x]
    centre_ray = np.sqrt(
        1 + ((centres[red_x | blue_x] - 20) / 8 / 5)[None, :] ** 2 + ((20 - centres[inside_y]) / 8 / 5)[:, None] ** 2
    )
    np.testing.assert_allclose(depth, 5 * centre_ray, rtol=1e-5)


def test_a_turned_camera_node_and_a_parent_transform(tmp_path):
    # The camera node turned +90 degrees about y (quaternion) at x = 5 looks along the file's -x,
    # with the file's -z on its right. A parent node moves the red square from z = 0 to z = -1
    # (its child's matrix, column-major), to the image's right half.
    b = Builder()
    red = b.material(pbrMetallicRoughness={"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0})
    square = b.mesh([[0, -0.5, -0.5], [0, -0.5, 0.5], [0, 0.5, 0.5], [0, 0.5, -0.5]], [[0, 1, 2], [0, 2, 3]], red)
    child = b.node(root=False, mesh=square, matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -0.5, 1])
    b.node(children=[child], translation=[0, 0, -0.5])
    s = math.sin(math.pi / 4)
    b.camera(2 * math.atan(0.5), aspect=1.0, translation=[5, 0, 0], rotation=[0, s, 0, s])
    b.light({"type": "directional"})
    image = raylume.render(load_scene(b.glb(tmp_path / "turned.glb")), width=40, height=40, mode="cast")
    # the square spans file z -1.5..-0.5 -> image x 0.5..1.5 (right of centre), y -0.5..0.5
    centres = np.arange(40) + 0.5
    cols = (centres > (0.5 / 2.5 + 1) * 20) & (centres < (1.5 / 2.5 + 1) * 20)
    rows = (centres > (1 - 0.5 / 2.5) * 20) & (centres < (1 + 0.5 / 2.5) * 20)
    np.testing.assert_array_equal(hits(image), rows[:, None] & cols[None, :])


def test_camera_by_name_aspect_and_framing_without_a_camera(tmp_path):
    b = Builder()
    two_squares(b)
    b.camera(0.5, aspect=2.0, name="wide", translation=[0, 0, 9])
    b.camera(0.7, name="close", translation=[0, 0, 4])
    path = b.glb(tmp_path / "cams.glb")
    first = gltf_scene(path)
    assert first.camera.position == (0.0, 0.0, -9.0) and first.camera.look_at == (0.0, 0.0, -8.0)
    assert first.camera.fov == pytest.approx(math.degrees(0.5))
    assert (first.render.width, first.render.height) == (600, 300)
    assert first.lights[0].type == "ambient"  # no lights in the file: a uniform environment
    assert gltf_scene(path, camera="close").camera.position == (0.0, 0.0, -4.0)
    assert (gltf_scene(path, width=300).render.height, gltf_scene(path, height=100).render.width) == (150, 200)
    # a camera without aspectRatio: the viewport's, square by default, so one side given is both
    close = [gltf_scene(path, camera="close", **side).render for side in ({"width": 48}, {"height": 40})]
    assert [(r.width, r.height) for r in close] == [(48, 48), (40, 40)]
    both = gltf_scene(path, camera="close", width=48, height=20).render
    assert (both.width, both.height) == (600, 600)  # both given: the flags set them later, as for any scene
    with pytest.raises(SceneError, match="'nope'.*'wide', 'close'"):
        gltf_scene(path, camera="nope")
    with pytest.raises(SceneError, match="--camera close: chooses a camera of a glTF file"):
        _resolve_scene("seed", camera="close")
    b = Builder()
    two_squares(b)
    framed = gltf_scene(b.glb(tmp_path / "nocam.glb"))
    assert framed.camera.look_at == pytest.approx((0.0, 0.6, 0.0))
    assert framed.camera.position[2] < -1  # in front of the squares (the file's +z), looking at them


def test_camera_by_its_node_s_name_where_the_camera_has_one_too(tmp_path):
    """gltf.md: --camera NAME picks a camera by its own name or its node's."""
    b = Builder()
    two_squares(b)
    b.camera(0.5, name="main", translation=[0, 0, 9])
    b.doc["cameras"].append({"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01}, "name": "side"})
    b.node(camera=len(b.doc["cameras"]) - 1, name="sidenode", translation=[0, 0, 4])  # both named
    path = b.glb(tmp_path / "cams.glb")
    assert gltf_scene(path, camera="sidenode").camera.position == (0.0, 0.0, -4.0)
    assert gltf_scene(path, camera="side").camera.position == (0.0, 0.0, -4.0)


# ------------------------------------------------------------------ lights


def test_point_light_irradiance_on_a_diffuse_plane(tmp_path):
    # A white point light of 4 cd (raylume: 4 W/sr) at height 2 above a diffuse plane of base
    # colour 0.5 (roughness 1: raylume's diffuse). Radiance seen = albedo/pi * I cos(theta) / r^2.
    b = Builder()
    grey = b.material(pbrMetallicRoughness={"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0})
    b.node(mesh=b.quad(-20, 20, -20, 20, material=grey))
    b.light({"type": "point", "intensity": 4.0}, translation=[0, 0, 2])
    b.camera(2 * math.atan(0.5), aspect=1.0, translation=[0, 0, 10])
    scene = load_scene(b.glb(tmp_path / "lamp.glb"))
    image = raylume.render(scene, width=20, height=20, spp=1, mode="path", max_depth=2)
    # pixel (i, j) centre sees the plane point x = (i + 0.5 - 10) / 10 * 5, y likewise
    for i, j in [(10, 10), (14, 9), (2, 17)]:
        x, y = (i + 0.5 - 10) / 2, (10 - j - 0.5) / 2
        r2 = x * x + y * y + 4
        expected = 0.5 / math.pi * 4.0 * (2 / math.sqrt(r2)) / r2
        np.testing.assert_allclose(image.rgb[j, i], expected, rtol=2e-4)


def test_light_conversion(tmp_path):
    b = Builder()
    b.node(mesh=b.quad(0, 1, 0, 1))
    s = math.sin(math.pi / 4)
    b.light(
        {"type": "spot", "color": [1, 0.5, 0.25], "intensity": 8, "spot": {"outerConeAngle": 0.6}},
        translation=[1, 2, 3],
    )
    b.light({"type": "directional", "intensity": 3}, rotation=[-s, 0, 0, s])  # turned to shine along -y
    lights = gltf_scene(b.glb(tmp_path / "lights.glb")).lights
    assert lights[0].type == "spot" and lights[0].position == (1.0, 2.0, -3.0)
    assert lights[0].direction == pytest.approx((0, 0, 1))  # the file's -z, raylume's +z
    assert lights[0].intensity == (8.0, 4.0, 2.0)
    assert lights[0].angle == pytest.approx(math.degrees(0.6)) and lights[0].inner_angle == 0
    assert lights[1].type == "directional" and lights[1].direction == pytest.approx((0, 1, 0))  # towards the light


# ------------------------------------------------------------------ materials


def test_material_factors_map_onto_raylume_materials(tmp_path):
    b = Builder()
    mats = [
        b.material(
            pbrMetallicRoughness={"baseColorFactor": [0.8, 0.3, 0.1, 1], "metallicFactor": 0, "roughnessFactor": 0.5}
        ),
        b.material(
            pbrMetallicRoughness={"baseColorFactor": [0.9, 0.6, 0.2, 1], "metallicFactor": 1, "roughnessFactor": 0.2}
        ),
        b.material(
            pbrMetallicRoughness={"roughnessFactor": 0},
            extensions={"KHR_materials_transmission": {"transmissionFactor": 1}, "KHR_materials_ior": {"ior": 1.33}},
        ),
        b.material(
            pbrMetallicRoughness={"metallicFactor": 0},
            emissiveFactor=[1, 0.5, 0],
            extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 4}},
        ),
    ]
    for k, mat in enumerate(mats):
        b.node(mesh=b.quad(k, k + 0.9, 0, 1, material=mat))
    b.doc["extensionsUsed"] = ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_emissive_strength"]
    imported = read_gltf(b.glb(tmp_path / "mats.glb"))
    plastic, conductor, glass, lamp = imported.materials
    assert (plastic.type, plastic.color, plastic.roughness, plastic.ior) == ("plastic", (0.8, 0.3, 0.1), 0.25, 1.5)
    assert (conductor.type, conductor.color) == ("conductor", (0.9, 0.6, 0.2))
    assert conductor.roughness == pytest.approx(0.04)  # GGX alpha = roughness^2
    assert (glass.type, glass.ior, glass.roughness) == ("dielectric", 1.33, 0.0)
    assert lamp.type == "diffuse" and lamp.emission == (4.0, 2.0, 0.0)  # roughness 1 (the default): diffuse
    scene = gltf_scene(tmp_path / "mats.glb")
    rows = compile_scene(scene).kernel.materials
    kinds = {M.BY_NAME[name].KIND for name in ("plastic", "conductor", "dielectric", "diffuse")}
    assert {int(k) for k in rows[1:, M.MAT_KIND]} == kinds


def test_base_colour_factor_and_texture_reach_the_albedo(tmp_path):
    # left square: a factor alone; right square: a 4 x 1 sRGB texture (red, red, cyan, cyan) times
    # the factor, read without filtering: bilinear lookups inside a half read one colour only
    texels = np.array([[[255, 0, 0], [255, 0, 0], [0, 188, 255], [0, 188, 255]]], dtype=np.uint8)
    PILImage.fromarray(texels).save(tmp_path / "tex.png")
    b = Builder()
    plain = b.material(pbrMetallicRoughness={"baseColorFactor": [0.25, 0.5, 0.75, 1], "metallicFactor": 0})
    b.doc["images"] = [{"uri": "tex.png"}]
    b.doc["textures"] = [{"source": 0}]
    textured = b.material(
        pbrMetallicRoughness={"baseColorFactor": [0.5, 1, 1, 1], "baseColorTexture": {"index": 0}, "metallicFactor": 0}
    )
    b.node(mesh=b.quad(-2, -0.1, -1, 1, material=plain))
    b.node(mesh=b.quad(0.1, 2, -1, 1, material=textured))
    b.camera(2 * math.atan(0.5), aspect=1.0, translation=[0, 0, 5])
    scene = load_scene(b.gltf(tmp_path / "tex.gltf")).replace(render={"texture_filter": False})
    albedo = raylume.render(scene, width=40, height=40, mode="cast").aovs["albedo"]
    np.testing.assert_allclose(albedo[20, 10], [0.25, 0.5, 0.75], rtol=1e-6)
    # u runs from 0 at x = 0.1 to 1 at x = 2: column 25 (x 0.69) reads u 0.31, column 32 (x 1.56) u 0.77
    cyan = ((188 / 255 + 0.055) / 1.055) ** 2.4  # sRGB decoded
    np.testing.assert_allclose(albedo[20, 25], [0.5, 0, 0], rtol=1e-5)
    np.testing.assert_allclose(albedo[20, 32], [0, cyan, 1.0], rtol=1e-5)


def test_a_texture_on_a_primitive_without_uvs_reads_one_texel_with_a_warning(tmp_path):
    """No TEXCOORD_0 (invalid glTF, which exporters still write): the lookup at UV (0, 0)
    everywhere, as before, and now a warning that names the primitive (it was silent)."""
    PILImage.fromarray(np.array([[[255, 0, 0], [0, 0, 255]]], dtype=np.uint8)).save(tmp_path / "tex.png")
    b = Builder()
    b.doc["images"] = [{"uri": "tex.png"}]
    b.doc["textures"] = [{"source": 0}]
    textured = b.material(pbrMetallicRoughness={"baseColorTexture": {"index": 0}, "metallicFactor": 0})
    b.node(mesh=b.mesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[0, 1, 2]], textured))
    b.camera(2 * math.atan(0.5), aspect=1.0, translation=[0, 0, 3])
    scene = load_scene(b.gltf(tmp_path / "nouv.gltf")).replace(render={"texture_filter": False})
    with pytest.warns(SceneWarning, match=r"objects\[0\]: meshes\[0\]/0 has no texture coordinates \(TEXCOORD_0\)"):
        albedo = raylume.render(scene, width=16, height=16, mode="cast").aovs["albedo"]
    seen = albedo[np.isfinite(albedo).all(axis=2) & (albedo.sum(axis=2) > 0)]
    assert len(seen) > 20 and (seen == seen[0]).all()  # one lookup, at UV (0, 0), everywhere


def test_normal_texture_turns_the_normal_up_the_image_and_scale_is_its_strength(tmp_path):
    # glTF's normal textures: +x right (increasing u), +y up the image, linear texels, the
    # normal 2 t - 1 with x and y times `scale`. A quad facing +z with u along +x and v down
    # the image along -y: a texel tilted up the image tilts the normal towards +y; raylume's
    # world has z negated, so the face's normal there is -z.
    texel = np.array([128, 191, 238], dtype=np.uint8)
    PILImage.fromarray(np.tile(texel, (4, 4, 1))).save(tmp_path / "normal.png")
    b = Builder()
    b.doc["images"] = [{"uri": "normal.png"}]
    b.doc["textures"] = [{"source": 0}]
    bumpy = b.material(normalTexture={"index": 0, "scale": 0.5}, pbrMetallicRoughness={"metallicFactor": 0})
    b.node(mesh=b.quad(-1, 1, -1, 1, material=bumpy))
    b.camera(2 * math.atan(0.5), aspect=1.0, translation=[0, 0, 5])
    normal = raylume.render(load_scene(b.gltf(tmp_path / "bumpy.gltf")), width=9, height=9, mode="cast")
    n_t = (2 * texel.astype(np.float64) / 255 - 1) * [0.5, 0.5, 1]
    n_t /= np.linalg.norm(n_t)
    np.testing.assert_allclose(normal.aovs["normal"][4, 4], [n_t[0], n_t[1], -n_t[2]], atol=1e-6)


# ------------------------------------------------------------------ alpha: MASK, BLEND, OPAQUE


def half_alpha(path, colour=(255, 40, 40)):
    """An 8 x 8 RGBA image, opaque `colour` everywhere, its alpha 0 on the left half (u < 0.5),
    128 on the right."""
    pixels = np.zeros((8, 8, 4), dtype=np.uint8)
    pixels[..., :3] = colour
    pixels[:, 4:, 3] = 128
    PILImage.fromarray(pixels, mode="RGBA").save(path)


def masked_materials(b: Builder, textured: dict) -> dict:
    """Materials of every alpha case, by name."""
    cases = {
        "mask": {"alphaMode": "MASK", "alphaCutoff": 0.25, "pbr": {**textured, "baseColorFactor": [1, 1, 1, 0.8]}},
        "mask_default": {"alphaMode": "MASK", "pbr": textured},
        "blend": {"alphaMode": "BLEND", "pbr": textured},
        "opaque": {"alphaCutoff": 0.9, "pbr": textured},
        "faint": {"alphaMode": "MASK", "pbr": {"baseColorFactor": [1, 1, 1, 0.3]}},
        "firm": {"alphaMode": "MASK", "pbr": {"baseColorFactor": [1, 1, 1, 0.7]}},
        "lamp": {"alphaMode": "MASK", "emissiveFactor": [1, 1, 1], "pbr": textured},
    }
    out = {}
    for name, case in cases.items():
        extra = {k: v for k, v in case.items() if k != "pbr"}
        out[name] = b.material(name=name, pbrMetallicRoughness={"metallicFactor": 0, **case["pbr"]}, **extra)
    return out


def test_alpha_mask_is_the_alpha_map_blend_a_mask_at_a_half_and_opaque_nothing(tmp_path):
    half_alpha(tmp_path / "leaf.png")
    b = Builder()
    b.doc["images"] = [{"uri": "leaf.png"}]
    b.doc["textures"] = [{"source": 0}]
    materials = masked_materials(b, {"baseColorTexture": {"index": 0}})
    for k, index in enumerate(materials.values()):
        b.node(mesh=b.quad(k, k + 1, 0, 1, material=index))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        imported = read_gltf(b.gltf(tmp_path / "alpha.gltf"))
    warned = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    by_name = {}
    for part in imported.parts:
        by_name[next(n for n, i in materials.items() if part.name == f"meshes[{i}]/0")] = imported.materials[
            part.material
        ]
    coverage = lambda m: imported.images[m.alpha_map.file][..., 0]  # noqa: E731
    # MASK: the texture's alpha times the factor's, cut below alphaCutoff
    mask = by_name["mask"]
    assert mask.alpha_map.cutoff == 0.25 and mask.alpha_map.encoding == "linear"
    np.testing.assert_allclose(coverage(mask)[:, :4], 0.0)
    np.testing.assert_allclose(coverage(mask)[:, 4:], 128 / 255 * 0.8, rtol=1e-6)
    assert imported.images[mask.alpha_map.file].shape == (8, 8, 3)
    assert mask.texture is not None  # the colour stays the texture's
    assert by_name["mask_default"].alpha_map.cutoff == 0.5
    # BLEND: a mask at 0.5, with a warning naming the material
    assert by_name["blend"].alpha_map.cutoff == 0.5
    assert any("materials[2] (blend) is alphaMode BLEND" in w and "cut as a mask at alpha 0.5" in w for w in warned)
    assert by_name["opaque"].alpha_map is None  # OPAQUE (the default): alphaCutoff ignored
    # no texture: a factor alpha below the cutoff is a hole everywhere, one above it nothing
    faint = by_name["faint"]
    assert faint.alpha_map.cutoff == 0.5 and coverage(faint).shape == (1, 1) and coverage(faint)[0, 0] < 0.5
    assert by_name["firm"].alpha_map is None
    # an emitter keeps its emission, not its mask
    lamp = by_name["lamp"]
    assert lamp.alpha_map is None and max(lamp.emission) > 0
    assert any("materials[6] emits light and is alphaMode MASK" in w for w in warned), warned
    assert len(warned) == 2, warned


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"alphaMode": "CLIP"}, r"materials\[0\]\.alphaMode is 'CLIP', not OPAQUE, MASK or BLEND\."),
        ({"alphaMode": "MASK", "alphaCutoff": -0.5}, r"materials\[0\]\.alphaCutoff is -0\.5, not >= 0"),
    ],
)
def test_an_unknown_alpha_mode_or_a_negative_cutoff_is_an_error(tmp_path, table, message):
    b = Builder()
    b.node(mesh=b.quad(0, 1, 0, 1, material=b.material(**table)))
    with pytest.raises(SceneError, match=message):
        gltf_scene(b.glb(tmp_path / "bad_alpha.glb"))


def test_a_masked_gltf_quad_renders_as_the_toml_quad_with_its_alpha_map(tmp_path):
    """A quad whose texture's alpha is 0 on its left half, in front of a wall: rendered from the
    file, and as the same scene written with the alpha_map (raylume's z is the file's -z)."""
    half_alpha(tmp_path / "leaf.png")
    b = Builder()
    b.doc["images"] = [{"uri": "leaf.png"}]
    b.doc["textures"] = [{"source": 0}]
    leaf = b.material(alphaMode="MASK", pbrMetallicRoughness={"baseColorTexture": {"index": 0}, "metallicFactor": 0})
    wall = b.material(pbrMetallicRoughness={"baseColorFactor": [0.1, 0.2, 0.8, 1], "metallicFactor": 0})
    b.node(mesh=b.quad(-1, 1, -1, 1, material=leaf))
    b.node(mesh=b.quad(-3, 3, -3, 3, z=-1, material=wall))
    b.camera(2 * math.atan(0.5), aspect=2.0, translation=[0, 0, 5])
    scene = load_scene(b.glb(tmp_path / "leaf.glb")).replace(render={"mode": "trace", "spp": 1})

    def toml_scene(alpha_map: dict | None):
        quad = {"type": "diffuse", "texture": {"type": "image", "file": "leaf.png"}}
        if alpha_map is not None:
            quad["alpha_map"] = alpha_map
        return scene.replace(
            objects=[
                {
                    "type": "mesh",
                    "vertices": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
                    "faces": [[0, 2, 1], [0, 3, 2]],
                    "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]],
                    "material": quad,
                },
                {
                    "type": "mesh",
                    "vertices": [[-3, -3, 1], [3, -3, 1], [3, 3, 1], [-3, 3, 1]],
                    "faces": [[0, 2, 1], [0, 3, 2]],
                    "material": {"type": "diffuse", "color": [0.1, 0.2, 0.8]},
                },
            ]
        ).with_base_dir(tmp_path)

    a = raylume.render(scene, width=24, height=12, seed=2, aovs=False).rgb
    b_ = raylume.render(toml_scene({"file": "leaf.png"}), width=24, height=12, seed=2, aovs=False).rgb
    whole = raylume.render(toml_scene(None), width=24, height=12, seed=2, aovs=False).rgb
    np.testing.assert_allclose(a, b_, rtol=1e-5, atol=1e-6)
    assert np.abs(a - whole).max() > 0.05, "the mask changes nothing: the test would prove nothing"


# ------------------------------------------------------------------ the file against its TOML twin

TWIN = """
[render]
width = 48
height = 32
mode = "trace"
encoding = "srgb"
[camera]
position = [0.5, 1, -6]
look_at = [0.5, 1, -5]
up = [0, 1, 0]
fov = {fov}
[[lights]]
type = "point"
position = [2, 3, -4]
intensity = [5, 5, 5]
[[lights]]
type = "directional"
direction = [0, 0, -1]
intensity = [0.5, 0.5, 0.5]
[[objects]]
type = "gltf"
file = "twin.glb"
"""


def test_the_file_rendered_directly_equals_the_toml_scene_that_places_it(tmp_path):
    b = Builder()
    two_squares(b)
    b.camera(0.9, aspect=1.5, translation=[0.5, 1, 6])
    b.light({"type": "point", "intensity": 5}, translation=[2, 3, 4])
    b.light({"type": "directional", "intensity": 0.5})  # shines along the file's -z: towards raylume's -z
    b.glb(tmp_path / "twin.glb")
    (tmp_path / "twin.toml").write_text(TWIN.format(fov=math.degrees(0.9)))
    direct = raylume.render(load_scene(tmp_path / "twin.glb"), width=48, height=32, mode="trace", spp=1)
    placed = raylume.render(load_scene(tmp_path / "twin.toml"))
    np.testing.assert_array_equal(direct.rgb, placed.rgb)
    assert direct.rgb.max() > 0


def test_shared_meshes_and_gpu_instancing_place_every_copy(tmp_path):
    b = Builder()
    tri = b.mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    b.node(mesh=tri, translation=[10, 0, 0])
    b.node(mesh=tri, scale=[2, 2, 2])
    node = b.node(
        mesh=tri,
        extensions={
            "EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": b.accessor([[0, 0, 1], [0, 0, 2], [0, 0, 3]])}}
        },
    )
    b.doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    imported = read_gltf(b.glb(tmp_path / "inst.glb"))
    (part,) = imported.parts
    assert len(part.matrices) == 5 and node == 2
    origins = part.matrices[:, :3, 3]
    np.testing.assert_array_equal(origins, [[10, 0, 0], [0, 0, 0], [0, 0, -1], [0, 0, -2], [0, 0, -3]])
    scene = raylume.scene_from_dict(
        {"objects": [{"type": "gltf", "file": str(tmp_path / "inst.glb"), "transform": {"translate": [0, 5, 0]}}]}
    )
    # rays along +z (from raylume z = -10) and -z: each meets the copy the matrices put there
    origins = [[0.2, 5.2, -10], [1.5, 5.2, -10], [10.2, 5.2, -10], [5, 5.2, -10], [0.2, 5.2, 10]]
    directions = [[0, 0, 1]] * 4 + [[0, 0, -1]]
    t, obj, _ = raylume.intersect(scene, np.array(origins, float), np.array(directions, float))
    np.testing.assert_allclose(t, [7, 10, 10, np.inf, 10], rtol=1e-6)  # GPU copy at -3; scaled; moved; none
    assert list(obj) == [0, 0, 0, -1, 0]


def test_prim_and_instance_name_each_triangle_of_a_gltf_object(tmp_path):
    """DESIGN.md section 3: `prim` is the triangle's index inside its object, so the meshes of a
    glTF object number their triangles in turn (each had started at 0: two meshes' triangles
    read the same object, instance and prim)."""
    b = Builder()
    one = b.mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    two = b.mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])  # a square: prims 1, 2
    shared = b.mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    b.node(mesh=one, translation=[0, 0, 0])
    b.node(mesh=two, translation=[2, 0, 0])
    b.node(mesh=shared, translation=[4, 0, 0])
    b.node(mesh=shared, translation=[6, 0, 0])  # used twice: one stored mesh, two instances
    scene = raylume.scene_from_dict({"objects": [{"type": "gltf", "file": str(b.glb(tmp_path / "parts.glb"))}]})
    # glTF x is raylume's x, its z raylume's -z: rays from z = -10 along +z into each triangle
    xs = [0.2, 2.8, 2.2, 4.2, 6.2]  # mesh one; the square's lower-right and upper-left halves; the two copies
    origins = np.array([[x, 0.3 if k != 2 else 0.8, -10] for k, x in enumerate(xs)], float)
    t, obj, prim, inst = raylume.intersect(scene, origins, np.tile([0.0, 0.0, 1.0], (5, 1)), instances=True)
    assert np.isfinite(t).all() and list(obj) == [0] * 5
    assert list(prim) == [0, 1, 2, 3, 3] and list(inst) == [0, 0, 0, 0, 1]


def test_the_shipped_example_holds_what_the_readme_says():
    imported = read_gltf(Path(__file__).parents[1] / "examples" / "gltf" / "room.glb")
    assert [c.name for c in imported.cameras] == ["front"] and len(imported.lights) == 2
    assert {light["type"] for light in imported.lights} == {"point", "spot"}
    bars = [p for p in imported.parts if p.name.startswith("bar")]
    assert len(bars) == 1 and len(bars[0].matrices) == 3  # the F: one mesh, three nodes
    assert {m.type for m in imported.materials} == {"diffuse", "plastic", "conductor", "dielectric"}
    assert any(m.texture is not None for m in imported.materials) and any(
        max(m.emission) > 0 for m in imported.materials
    )


# ------------------------------------------------------------------ bad files


def small_file(tmp_path) -> Builder:
    b = Builder()
    b.node(mesh=b.quad(0, 1, 0, 1))
    return b


def test_extensions_required_are_errors_and_optional_ones_warnings(tmp_path):
    b = small_file(tmp_path)
    b.doc["extensionsUsed"] = ["KHR_draco_mesh_compression", "KHR_texture_transform"]
    b.doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    with pytest.raises(SceneError, match="requires the extension KHR_draco_mesh_compression"):
        gltf_scene(b.glb(tmp_path / "draco.glb"))
    b.doc.pop("extensionsRequired")
    with pytest.warns(SceneWarning, match="optional extensions KHR_draco_mesh_compression, KHR_texture_transform"):
        gltf_scene(b.glb(tmp_path / "optional.glb"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gltf_scene(small_file(tmp_path).glb(tmp_path / "plain.glb"))


def broken_files(tmp_path) -> dict:
    """name -> (file, words its error must contain)."""
    out = {}
    good = small_file(tmp_path).glb(tmp_path / "good.glb").read_bytes()
    (tmp_path / "truncated.glb").write_bytes(good[: len(good) - 20])
    out["truncated"] = ("truncated.glb", ["truncated"])
    b = small_file(tmp_path)
    b.doc["bufferViews"][0]["buffer"] = 3
    out["buffer"] = (b.glb(tmp_path / "buffer.glb").name, ["bufferViews[0].buffer", "buffers[3]"])
    b = small_file(tmp_path)
    b.doc["images"], b.doc["textures"] = [{"uri": "gone.png"}], [{"source": 0}]
    b.doc["meshes"][0]["primitives"][0]["material"] = b.material(
        pbrMetallicRoughness={"baseColorTexture": {"index": 0}}
    )
    out["texture"] = (b.gltf(tmp_path / "texture.gltf").name, ["images[0].uri", "gone.png", "does not exist"])
    b = small_file(tmp_path)  # an embedded image that is none: named, without Pillow's repr of its bytes
    b.doc["images"], b.doc["textures"] = [{"uri": "data:image/png;base64,bm90IGFuIGltYWdl"}], [{"source": 0}]
    b.doc["meshes"][0]["primitives"][0]["material"] = b.material(
        pbrMetallicRoughness={"baseColorTexture": {"index": 0}}
    )
    out["embedded"] = (b.gltf(tmp_path / "embedded.gltf").name, ["images[0] (data URI)", "cannot be decoded"])
    b = small_file(tmp_path)
    b.doc["nodes"][0]["matrix"] = [1, 0, 0, 0, 0, float("nan"), 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    out["matrix"] = (b.glb(tmp_path / "matrix.glb").name, ["nodes[0].matrix", "nan"])
    b = small_file(tmp_path)
    b.blob[4:8] = np.float32(np.nan).tobytes()
    out["accessor"] = (b.glb(tmp_path / "accessor.glb").name, ["accessors[0]", "POSITION", "NaN"])
    return out


def test_broken_files_are_refused_naming_the_file_and_the_fault(tmp_path):
    for name, (file, words) in broken_files(tmp_path).items():
        with pytest.raises(SceneError) as caught:
            load_scene(tmp_path / file)
        message = str(caught.value)
        assert file in message and all(w in message for w in words), (name, message)
        assert "object at 0x" not in message, message


@pytest.mark.parametrize(
    "key, value",
    [
        (("accessors", 0, "type"), ["VEC3"]),
        (("accessors", 0, "componentType"), {"a": 1}),
        (("meshes", 0, "primitives", 0, "material"), {"index": 0}),
        (("meshes", 0, "primitives", 0), "triangles"),
        (("nodes", 0, "mesh"), 1.5),
        (("extensionsUsed",), [True]),
        (("bufferViews", 0, "byteLength"), 10**9),
    ],
)
def test_values_of_the_wrong_type_are_errors_not_crashes(tmp_path, key, value):
    b = small_file(tmp_path)
    table = b.doc
    for part in key[:-1]:
        table = table[part]
    table[key[-1]] = value
    with pytest.raises(SceneError, match="wrong.glb"):
        gltf_scene(b.glb(tmp_path / "wrong.glb"))


def textured_file(tmp_path) -> Builder:
    b = small_file(tmp_path)
    b.doc["images"], b.doc["textures"] = [{"uri": "gone.png"}], [{"source": 0}]
    b.doc["meshes"][0]["primitives"][0]["material"] = b.material(
        pbrMetallicRoughness={"baseColorTexture": {"index": 0}}
    )
    return b


@pytest.mark.parametrize(
    "key, value, where",
    [
        (("nodes", 0, "mesh"), "0", 'nodes[0].mesh must be an index (a whole number >= 0), got "0"'),
        (("nodes", 0, "mesh"), 0.0, "nodes[0].mesh must be an index (a whole number >= 0), got 0.0"),
        (("nodes", 0, "mesh"), True, "nodes[0].mesh must be an index (a whole number >= 0), got true"),
        (("nodes", 0, "mesh"), -1, "nodes[0].mesh must be an index (a whole number >= 0), got -1"),
        (("nodes", 0, "camera"), "0", "nodes[0].camera must be an index"),
        (("nodes", 0, "children"), [1.0], "nodes[0].children[0] must be an index"),
        (("scenes", 0, "nodes", 0), "0", "scenes[0].nodes[0] must be an index"),
        (("scene",), "0", 'scene must be an index (a whole number >= 0), got "0"'),
        (("accessors", 0, "bufferView"), "0", "POSITION).bufferView must be an index"),
        (("bufferViews", 0, "buffer"), True, "bufferViews[0].buffer must be an index"),
        (("meshes", 0, "primitives", 0, "indices"), "0", "meshes[0].primitives[0].indices must be an index"),
        (("meshes", 0, "primitives", 0, "material"), "0", "meshes[0].primitives[0].material must be an index"),
        (("materials", 0, "pbrMetallicRoughness", "baseColorTexture", "index"), "0", "baseColorTexture.index must"),
        (("materials", 0, "pbrMetallicRoughness", "baseColorTexture"), {}, "baseColorTexture.index is missing"),
        (("textures", 0, "source"), -1, "textures[0].source must be an index (a whole number >= 0), got -1"),
    ],
)
def test_an_index_that_is_not_a_whole_number_says_so(tmp_path, key, value, where):
    b = textured_file(tmp_path)
    table = b.doc
    for part in key[:-1]:
        table = table[part]
    table[key[-1]] = value
    with pytest.raises(SceneError) as caught:
        gltf_scene(b.gltf(tmp_path / "index.gltf"))
    message = str(caught.value)
    assert "index.gltf: " in message and where in message and "refers to" not in message, message


def test_a_light_index_that_is_not_a_whole_number_says_so(tmp_path):
    b = small_file(tmp_path)
    b.light({"type": "point"})
    b.doc["nodes"][-1]["extensions"]["KHR_lights_punctual"]["light"] = "0"
    with pytest.raises(SceneError) as caught:
        gltf_scene(b.glb(tmp_path / "light.glb"))
    assert 'KHR_lights_punctual.light must be an index (a whole number >= 0), got "0"' in str(caught.value)


def test_the_command_line_exits_2_and_writes_nothing(tmp_path):
    file, words = broken_files(tmp_path)["truncated"]
    result = run_cli("render", file, "-o", "out.png", "--mode", "cast", "--width", "8", "--height", "8", cwd=tmp_path)
    assert_refused(result, file, *words)
    unknown = run_cli("render", "good.glb", "--camera", "x", "-o", "out.png", cwd=tmp_path)
    assert_refused(unknown, "--camera 'x'", "no perspective camera")
    assert not (tmp_path / "out.png").exists()
