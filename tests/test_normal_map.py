"""Normal and bump maps against the frame their conventions define (pbrt-v4's NormalMap and
BumpMap, Mitsuba 3's normalmap and bumpmap, glTF's normalTexture): a normal map's texel
(r, g, b) is the normal 2 (r, g, b) / 255 - 1 in the frame of increasing u (x), increasing v
(y, up the image) and the shading normal (z); a bump map's texel a height along the normal,
whose displaced surface's normal is the shading normal. Each expected value below is that
frame or surface, written out for the surface's documented UVs, and the lighting's cosine law;
small renders, one pixel read where the surface is uniform."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage

import raylume
from raylume.errors import SceneError

REPO = Path(__file__).resolve().parents[1]
TILT = math.radians(30)


def texel_of(normal) -> np.ndarray:
    """The 8-bit texel that stores a tangent-space normal."""
    return np.round((np.asarray(normal, dtype=np.float64) + 1.0) / 2.0 * 255.0).astype(np.uint8)


def decoded(texel) -> np.ndarray:
    """What the spec reads from that texel: 2 t / 255 - 1, normalised."""
    n = 2.0 * np.asarray(texel, dtype=np.float64) / 255.0 - 1.0
    return n / np.linalg.norm(n)


def map_file(tmp_path, normal, name="tilt.png") -> tuple[str, np.ndarray]:
    """A 4 x 4 map of one normal (the lookup is exact whatever the UV); its decoded normal."""
    texel = texel_of(normal)
    path = tmp_path / name
    PILImage.fromarray(np.tile(texel, (4, 4, 1))).save(path)
    return str(path), decoded(texel)


TILTED_U = (math.sin(TILT), 0.0, math.cos(TILT))  # towards increasing u
TILTED_V = (0.0, math.sin(TILT), math.cos(TILT))  # towards increasing v


def floor_scene(material: dict, uvs, light_direction, mode="trace") -> dict:
    """A 2 x 2 floor at y = 0 (an inline mesh with the given UVs at its corners (-1, 1), (1, 1),
    (1, -1), (-1, -1) in x, z), seen from above, lit by one directional light. Mode "bdpt":
    path mode's bidirectional integrator (every strategy's contribution scales by the cosine at
    the floor, and both renders draw the same random numbers, so the ratio below is exact)."""
    render = {"mode": "path", "integrator": "bdpt"} if mode == "bdpt" else {"mode": mode}
    return {
        "render": {"width": 8, "height": 8, "spp": 1, "max_depth": 2, **render},
        "camera": {"position": [0, 3, 0.001], "look_at": [0, 0, 0], "fov": 20},
        "materials": {"floor": {"type": "diffuse", "color": [0.8, 0.8, 0.8], **material}},
        "objects": [
            {
                "type": "mesh",
                "vertices": [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]],
                "faces": [[0, 1, 2], [0, 2, 3]],
                "uvs": uvs,
                "material": "floor",
            }
        ],
        "lights": [{"type": "directional", "direction": list(light_direction), "intensity": 1.0}],
    }


# u along +x and v along -z; and the same mirrored (u along -x)
UVS = [[0, 0], [1, 0], [1, 1], [0, 1]]
MIRRORED_UVS = [[1, 0], [0, 0], [0, 1], [1, 1]]


def centre(image) -> tuple[np.ndarray, np.ndarray]:
    """The centre pixel's colour and normal AOV."""
    return image.rgb[4, 4].astype(np.float64), image.aovs["normal"][4, 4].astype(np.float64)


@pytest.mark.parametrize(
    ("tangent_normal", "uvs", "frame"),
    [
        # (T, B, N) on the floor: T along increasing u, B along increasing v, N = +y
        (TILTED_U, UVS, ((1, 0, 0), (0, 0, -1), (0, 1, 0))),
        (TILTED_U, MIRRORED_UVS, ((-1, 0, 0), (0, 0, -1), (0, 1, 0))),
        (TILTED_V, UVS, ((1, 0, 0), (0, 0, -1), (0, 1, 0))),
    ],
    ids=["x-along-u", "x-along-mirrored-u", "y-along-v"],
)
@pytest.mark.parametrize("mode", ["trace", "raster", "path", "bdpt"])
def test_a_tilted_map_turns_the_shading_normal_in_the_uv_frame(tmp_path, tangent_normal, uvs, frame, mode):
    path, n_t = map_file(tmp_path, tangent_normal)
    t, b, n = (np.array(a, dtype=np.float64) for a in frame)
    expected = n_t[0] * t + n_t[1] * b + n_t[2] * n
    light = np.array([1.0, 1.0, 0.3])  # off every axis, so each component counts
    light_unit = light / np.linalg.norm(light)
    flat = raylume.render(raylume.scene_from_dict(floor_scene({}, uvs, light, mode)))
    mapped = raylume.render(raylume.scene_from_dict(floor_scene({"normal_map": {"file": path}}, uvs, light, mode)))
    rgb_flat, normal_flat = centre(flat)
    rgb, normal = centre(mapped)
    np.testing.assert_allclose(normal_flat, n, atol=1e-6)
    np.testing.assert_allclose(normal, expected, atol=1e-6)
    # the lighting's cosine law (each mode's own scale cancels in the ratio)
    np.testing.assert_allclose(rgb / rgb_flat, expected @ light_unit / (n @ light_unit), rtol=1e-5)


def test_strength_scales_the_maps_x_and_y(tmp_path):
    path, _ = map_file(tmp_path, TILTED_U)
    raw = 2.0 * texel_of(TILTED_U).astype(np.float64) / 255.0 - 1.0
    light = (1.0, 1.0, 0.3)
    for strength in (0.0, 0.5, 2.0):
        material = {"normal_map": {"file": path, "strength": strength}}
        _, normal = centre(raylume.render(raylume.scene_from_dict(floor_scene(material, UVS, light))))
        n_t = raw * [strength, strength, 1.0]
        n_t /= np.linalg.norm(n_t)
        np.testing.assert_allclose(normal, [n_t[0], n_t[2], -n_t[1]], atol=1e-6)


def test_scale_repeats_the_map(tmp_path):
    # left half of the map tilted towards +u, right half towards -u: at scale 2 the floor's
    # centre (u = 0.5) reads the map at u = 1, the left half again
    left, right = texel_of(TILTED_U), texel_of((-TILTED_U[0], 0.0, TILTED_U[2]))
    image = np.concatenate([np.tile(left, (8, 4, 1)), np.tile(right, (8, 4, 1))], axis=1)
    path = tmp_path / "halves.png"
    PILImage.fromarray(image).save(path)
    light = (1.0, 1.0, 0.3)
    scene = floor_scene({"normal_map": {"file": str(path), "scale": 2}}, UVS, light)
    scene["camera"]["look_at"] = [0.25, 0, 0]  # the centre pixel at u = 0.625: u * 2 = 1.25, left
    scene["camera"]["position"] = [0.25, 3, 0.001]
    _, normal = centre(raylume.render(raylume.scene_from_dict(scene)))
    assert normal[0] > 0.4, normal  # tilted towards +x (+u)


def sphere_scene(material: dict, light_direction) -> dict:
    return {
        "render": {"width": 9, "height": 9, "mode": "trace"},
        "camera": {"position": [0, 0, -4], "look_at": [0, 0, 0], "fov": 20},
        "materials": {"ball": {"type": "diffuse", "color": [0.8, 0.8, 0.8], **material}},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "ball"}],
        "lights": [{"type": "directional", "direction": list(light_direction), "intensity": 1.0}],
    }


def test_a_spheres_map_follows_its_documented_uvs(tmp_path):
    # the sphere's u = 0.5 + atan2(n.x, -n.z) / 2 pi grows towards +x where it faces -z, and
    # v = 0.5 + asin(n.y) / pi towards +y: at the point facing the camera, T = +x, B = +y
    light = np.array([1.0, 0.5, -1.0])
    light_unit = light / np.linalg.norm(light)
    n = np.array([0.0, 0.0, -1.0])
    for tangent_normal, axis in ((TILTED_U, np.array([1.0, 0, 0])), (TILTED_V, np.array([0, 1.0, 0]))):
        path, n_t = map_file(tmp_path, tangent_normal, name=f"{axis[0]}.png")
        expected = n_t[0] * np.array([1.0, 0, 0]) + n_t[1] * np.array([0, 1.0, 0]) + n_t[2] * n
        flat = raylume.render(raylume.scene_from_dict(sphere_scene({}, light)))
        mapped = raylume.render(raylume.scene_from_dict(sphere_scene({"normal_map": {"file": path}}, light)))
        rgb_flat, normal_flat = centre(flat)
        rgb, normal = centre(mapped)
        np.testing.assert_allclose(normal_flat, n, atol=1e-6)
        np.testing.assert_allclose(normal, expected, atol=1e-5)
        # trace mode shades the sphere from the turned normal
        np.testing.assert_allclose(rgb / rgb_flat, expected @ light_unit / (n @ light_unit), rtol=1e-4)


def test_a_normal_map_without_uvs_is_an_error_naming_the_object(tmp_path):
    path, _ = map_file(tmp_path, TILTED_U)
    scene = floor_scene({"normal_map": {"file": path}}, UVS, (1, 1, 0))
    del scene["objects"][0]["uvs"]
    no_uvs = r"objects\[0\]\.uvs: the mesh has no texture coordinates .* map \(normal, bump, alpha\) needs"
    with pytest.raises(SceneError, match=no_uvs):
        raylume.render(raylume.scene_from_dict(scene))


def test_a_missing_normal_map_names_its_key(tmp_path):
    scene = floor_scene({"normal_map": {"file": str(tmp_path / "nowhere.png")}}, UVS, (1, 1, 0))
    missing = r"materials\.floor\.normal_map\.file: texture file .*nowhere\.png does not exist"
    with pytest.raises(SceneError, match=missing):
        raylume.render(raylume.scene_from_dict(scene))


# ------------------------------------------------------------------ bump maps


def ramp_file(tmp_path, along_v: bool) -> tuple[str, float]:
    """A 32 x 32 height map rising by 8 levels a texel, along the image's columns (u) or up its
    rows (v); the height's change per unit of u or v, as stored (8 / 255 a texel of 1 / 32)."""
    ramp = np.arange(32, dtype=np.uint8) * 8
    grey = np.tile(ramp[::-1, None], (1, 32)) if along_v else np.tile(ramp[None, :], (32, 1))
    path = tmp_path / ("ramp_v.png" if along_v else "ramp_u.png")
    PILImage.fromarray(grey, mode="L").save(path)
    return str(path), 8 / 255 * 32


@pytest.mark.parametrize(
    ("along_v", "uvs", "rising"),
    [
        # the floor spans 2 units for each unit of u and v: u along +x, v along -z (mirrored: u along -x)
        (False, UVS, (2, 0, 0)),
        (False, MIRRORED_UVS, (-2, 0, 0)),
        (True, UVS, (0, 0, -2)),
    ],
    ids=["rising-along-u", "rising-along-mirrored-u", "rising-along-v"],
)
@pytest.mark.parametrize("mode", ["trace", "path"])
def test_a_bump_maps_slope_tilts_the_normal_away_from_the_rise(tmp_path, along_v, uvs, rising, mode):
    path, slope = ramp_file(tmp_path, along_v)
    height = 0.5
    # the displaced floor rises by height x slope for each unit of u (or v), over |rising| units
    # of floor: its normal is (-rise, run, 0) rotated into the rising direction
    run = np.array(rising, dtype=np.float64)
    rise = height * slope
    expected = np.array([0.0, 1.0, 0.0]) * np.linalg.norm(run) - run / np.linalg.norm(run) * rise
    expected /= np.linalg.norm(expected)
    light = np.array([1.0, 1.0, 0.3])
    light_unit = light / np.linalg.norm(light)
    bumped = floor_scene({"bump_map": {"file": path, "height": height}}, uvs, light, mode)
    rgb_flat, _ = centre(raylume.render(raylume.scene_from_dict(floor_scene({}, uvs, light, mode))))
    rgb, normal = centre(raylume.render(raylume.scene_from_dict(bumped)))
    np.testing.assert_allclose(normal, expected, atol=1e-5)
    np.testing.assert_allclose(rgb / rgb_flat, expected @ light_unit / light_unit[1], rtol=1e-4)


def test_a_material_takes_a_normal_map_or_a_bump_map_not_both(tmp_path):
    path, _ = map_file(tmp_path, TILTED_U)
    maps = {"normal_map": {"file": path}, "bump_map": {"file": path}}
    with pytest.raises(SceneError, match="a normal_map or a bump_map, not both"):
        raylume.render(raylume.scene_from_dict(floor_scene(maps, UVS, (1, 1, 0))))


def test_a_scene_saved_elsewhere_still_finds_its_maps(tmp_path):
    scene = raylume.load(REPO / "examples" / "surface_maps.toml")
    (tmp_path / "elsewhere").mkdir()
    saved = raylume.save_scene(scene, tmp_path / "elsewhere" / "copy.toml")
    text = saved.read_text()
    for name in ("tiles_normal.png", "dimples_height.png", "lattice_alpha.png"):
        assert f"examples/textures/{name}" in text  # relative to the new folder, back to the files
    size = {"width": 32, "height": 18, "spp": 1}
    np.testing.assert_array_equal(raylume.render(raylume.load(saved), **size).rgb, raylume.render(scene, **size).rgb)


def test_a_bump_maps_srgb_encoding_decodes_the_heights_first(tmp_path):
    # the ramp's texels 120 and 128 around u = 0.5 (32 texels: texel centres at (x + 0.5) / 32),
    # decoded from sRGB: the slope between the centre and one texel on is that of the decoded ramp
    path, _ = ramp_file(tmp_path, along_v=False)

    def decoded(level):
        c = level / 255
        return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4

    slope = (decoded(136) - decoded(120)) / 2 * 32  # per unit of u, bilinear between texel centres
    height = 4.0
    material = {"bump_map": {"file": path, "height": height, "encoding": "srgb"}}
    scene = floor_scene(material, UVS, (1, 1, 0.3))
    scene["render"].update(width=9, height=9)  # the centre pixel's ray hits the floor at u = 0.5 (the ramp curves)
    normal = raylume.render(raylume.scene_from_dict(scene)).aovs["normal"][4, 4]
    expected = np.array([-height * slope, 2.0, 0.0])  # the floor spans 2 units of x for one of u
    np.testing.assert_allclose(normal, expected / np.linalg.norm(expected), atol=1e-5)
