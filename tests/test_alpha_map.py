"""Alpha maps (cut-out masks) against what a hole means: where the mask's coverage is below the
cutoff, every ray passes as if the surface were not there. So a pixel seen through a hole
equals a pixel of what lies behind seen directly, lit the same way (its shadow ray passes the
hole too); the solid part stays as it is; the AOVs name what lies behind. Small renders, pixels
read where the surfaces are uniform."""

from __future__ import annotations

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
