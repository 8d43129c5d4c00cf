"""Alpha maps (cut-out masks) against what a hole means: where the mask's coverage is below the
cutoff, every ray passes as if the surface were not there. So a pixel seen through a hole
equals a pixel of what lies behind seen directly, lit the same way (its shadow ray passes the
hole too); the solid part stays as it is; the AOVs name what lies behind. Small renders, pixels
read where the surfaces are uniform."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image as PILImage

import raylume
from raylume.errors import SceneError
from raylume.scene.checks import SceneWarning


def half_mask(tmp_path, mode="RGBA") -> str:
    """An 8 x 8 mask whose left half (u < 0.5) is a hole and right half solid: in its alpha
    channel (RGBA, with opaque colour everywhere), or as grey (L, no alpha)."""
    path = tmp_path / f"half_{mode}.png"
    if mode == "RGBA":
        pixels = np.full((8, 8, 4), 255, dtype=np.uint8)
        pixels[:, :4, 3] = 0
    else:
        pixels = np.full((8, 8), 255, dtype=np.uint8)
        pixels[:, :4] = 0
    PILImage.fromarray(pixels, mode=mode).save(path)
    return str(path)


def scene(mask: dict | None, mode: str, front=(0.8, 0.1, 0.1)) -> dict:
    """A 2 x 2 quad at z = 0 (its UVs' u along +x), `mask` its alpha map, in front of a 6 x 6 wall
    at z = 1, both diffuse, seen from z = -5 and lit from the camera's side by a directional
    light: the wall is lit wherever nothing solid stands between it and the light."""
    front_material = {"type": "diffuse", "color": list(front)}
    if mask is not None:
        front_material["alpha_map"] = mask
    render = {"mode": "path", "integrator": "bdpt"} if mode == "bdpt" else {"mode": mode}
    return {
        "render": {"width": 24, "height": 12, "spp": 1, "max_depth": 2, **render},
        "camera": {"position": [0, 0, -5], "look_at": [0, 0, 0], "fov": 40},
        "materials": {"front": front_material, "wall": {"type": "diffuse", "color": [0.1, 0.2, 0.8]}},
        "objects": [
            {
                "type": "mesh",
                "vertices": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
                "faces": [[0, 1, 2], [0, 2, 3]],
                "uvs": [[0, 0], [1, 0], [1, 1], [0, 1]],
                "material": "front",
            },
            {"type": "quad", "position": [0, 0, 1], "u": [6, 0, 0], "v": [0, 6, 0], "material": "wall"},
        ],
        "lights": [{"type": "directional", "direction": [0, 0, -1], "intensity": 1.0}],
    }


# pixels (row, column) of the 24 x 12 image: through the hole (x ~ -0.75 on the quad), on its solid
# half (x ~ +0.75), and the wall beside the quad (x ~ -2.4 at the wall)
HOLE, SOLID, WALL = (6, 9), (6, 14), (6, 5)


@pytest.mark.parametrize("mode", ["cast", "trace", "path"])
def test_a_hole_shows_what_lies_behind_lit_as_if_nothing_were_there(tmp_path, mode):
    mask = {"file": half_mask(tmp_path)}
    cut = raylume.render(raylume.scene_from_dict(scene(mask, mode)))
    whole = raylume.render(raylume.scene_from_dict(scene(None, mode)))
    rgb, aovs = cut.rgb.astype(np.float64), cut.aovs
    assert rgb[WALL].max() > 0.01  # the wall, lit
    np.testing.assert_allclose(rgb[HOLE], rgb[WALL], rtol=1e-6)  # the wall through the hole, lit too
    np.testing.assert_allclose(rgb[SOLID], whole.rgb[SOLID], rtol=1e-6)  # the solid half as without a mask
    assert not np.allclose(whole.rgb[HOLE], rgb[WALL])  # without the mask, the quad is there
    assert aovs["object"][HOLE] == 1 and aovs["object"][SOLID] == 0
    assert aovs["depth"][HOLE] > aovs["depth"][SOLID]
    np.testing.assert_allclose(aovs["albedo"][HOLE], [0.1, 0.2, 0.8], rtol=1e-6)


def test_bdpt_sees_and_lights_through_a_hole_as_path_mode_does(tmp_path):
    # bdpt's estimates are noisy: the wall through the hole against the wall beside the quad,
    # block means over rows of pixels, within 5 standard errors of their difference
    mask = {"file": half_mask(tmp_path)}
    image = raylume.render(raylume.scene_from_dict(scene(mask, "bdpt")), spp=16, seed=5).rgb.astype(np.float64)
    hole = image[3:9, 9:11].reshape(-1, 3)
    wall = image[3:9, 4:7].reshape(-1, 3)
    se = np.sqrt(hole.var(axis=0, ddof=1) / len(hole) + wall.var(axis=0, ddof=1) / len(wall))
    assert wall.mean(axis=0).max() > 0.01
    assert (np.abs(hole.mean(axis=0) - wall.mean(axis=0)) <= 5 * se + 1e-7).all(), (hole.mean(0), wall.mean(0), se)


def test_a_mask_without_alpha_is_read_by_its_grey(tmp_path):
    mask = {"file": half_mask(tmp_path, mode="L")}
    cut = raylume.render(raylume.scene_from_dict(scene(mask, "cast")))
    np.testing.assert_allclose(cut.rgb[HOLE], cut.rgb[WALL], rtol=1e-6)
    np.testing.assert_allclose(cut.rgb[SOLID], [0.8, 0.1, 0.1], rtol=1e-6)


def test_the_cutoff_decides_which_coverage_is_a_hole(tmp_path):
    # a mask of coverage 120 / 255 = 0.4706 everywhere: a hole under cutoffs above it, solid under those below
    path = tmp_path / "grey.png"
    PILImage.fromarray(np.full((4, 4), 120, dtype=np.uint8), mode="L").save(path)
    for cutoff, solid in ((0.5, False), (0.48, False), (0.46, True), (0.4, True)):
        image = raylume.render(raylume.scene_from_dict(scene({"file": str(path), "cutoff": cutoff}, "cast")))
        assert (image.aovs["object"][SOLID] == 0) == solid, cutoff


def test_an_srgb_encoded_mask_is_decoded_before_the_cutoff(tmp_path):
    # stored 120 / 255 = 0.4706 is 0.1878 decoded from sRGB: solid under a cutoff of 0.3 read as
    # stored, a hole decoded (pbrt-v4's and Mitsuba 3's reading of an 8-bit mask)
    path = tmp_path / "grey.png"
    PILImage.fromarray(np.full((4, 4), 120, dtype=np.uint8), mode="L").save(path)
    for encoding, solid in (("linear", True), ("srgb", False)):
        mask = {"file": str(path), "cutoff": 0.3, "encoding": encoding}
        image = raylume.render(raylume.scene_from_dict(scene(mask, "cast")))
        assert (image.aovs["object"][SOLID] == 0) == solid, encoding


def test_an_emitting_material_cannot_take_an_alpha_map(tmp_path):
    document = scene({"file": half_mask(tmp_path)}, "path")
    document["materials"]["front"]["emission"] = [1, 1, 1]
    with pytest.raises(SceneError, match="an emitting material cannot take an alpha_map"):
        raylume.scene_from_dict(document)


def test_raster_mode_says_it_draws_masked_surfaces_whole(tmp_path):
    with pytest.warns(SceneWarning, match="raster mode draws alpha-mapped surfaces whole"):
        raylume.render(raylume.scene_from_dict(scene({"file": half_mask(tmp_path)}, "raster")))


def ink_ball(mask: dict | None) -> dict:
    """A glass ball of index 1 (no bending) filled with ink (absorbing only), in front of a
    glowing wall of radiance 1: the centre pixels see exp(-2 x 1) of the wall through it."""
    ball = {"type": "dielectric", "ior": 1.0}
    if mask is not None:
        ball["alpha_map"] = mask
    return {
        "render": {"width": 8, "height": 8, "spp": 64, "max_depth": 8, "mode": "path"},
        "camera": {"position": [0, 0, -4], "look_at": [0, 0, 0], "fov": 12},
        "media": {"ink": {"type": "homogeneous", "sigma_a": 1.0, "sigma_s": 0.0}},
        "materials": {"ball": ball, "wall": {"type": "diffuse", "color": [1, 1, 1], "emission": [1, 1, 1]}},
        "objects": [
            {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "ball", "interior": "ink"},
            {"type": "quad", "position": [0, 0, 5], "u": [20, 0, 0], "v": [0, 20, 0], "material": "wall"},
        ],
    }


@pytest.mark.parametrize("cut", ["back", "front"])
@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_a_closed_object_with_holes_keeps_its_inside_filled(tmp_path, cut, integrator):
    # the sphere's u runs around it from its back (+z, u = 0 and 1) to its front (-z, u = 0.5):
    # a mask whose outer columns are holes cuts the back half away, its middle ones the front.
    # A ray entering or leaving through a hole still crosses the ink inside: the image is the
    # unmasked ball's, within the standard error of the difference of the two block means
    columns = np.full((1, 8), 255, dtype=np.uint8)
    if cut == "back":
        columns[0, [0, 1, 6, 7]] = 0
    else:
        columns[0, 2:6] = 0
    PILImage.fromarray(columns, mode="L").save(tmp_path / "mask.png")
    render = {"integrator": integrator, "seed": 3}
    masked = raylume.render(raylume.scene_from_dict(ink_ball({"file": str(tmp_path / "mask.png")})), **render)
    whole = raylume.render(raylume.scene_from_dict(ink_ball(None)), **render)
    a = masked.rgb[2:6, 2:6, 0].astype(np.float64).ravel()
    b = whole.rgb[2:6, 2:6, 0].astype(np.float64).ravel()
    se = math.sqrt(a.var(ddof=1) / a.size + b.var(ddof=1) / b.size)
    assert 0.1 < b.mean() < 0.2  # about exp(-2): the unmasked ball absorbs as it should
    assert abs(a.mean() - b.mean()) <= 5 * se + 1e-3, (a.mean(), b.mean(), se)


def test_shadow_rays_pass_as_many_holes_as_camera_rays(tmp_path):
    # 40 masked quads stacked in front of the wall: the wall seen through all their holes is lit
    # as beside them (trace mode's shadow rays once gave up after 32 surfaces)
    document = scene({"file": half_mask(tmp_path)}, "trace")
    quad = document["objects"][0]
    document["objects"] = [
        {**quad, "vertices": [[x, y, -0.02 * k] for x, y, _ in quad["vertices"]]} for k in range(40)
    ] + document["objects"][1:]
    image = raylume.render(raylume.scene_from_dict(document)).rgb
    np.testing.assert_allclose(image[HOLE], image[WALL], rtol=1e-6)
