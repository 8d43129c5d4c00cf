"""Bidirectional path tracing (integrator = "bdpt") through participating media and null
boundaries, against path mode's images (its own estimator, tested against Mitsuba 3's volpath
in test_media_vs_mitsuba.py and against Beer-Lambert and white furnaces in test_media.py): per
8 x 8 block and channel, over independent seeds (test_bdpt._assert_blocks_agree); a white
furnace (every path returns 1); and its determinism with media."""

from __future__ import annotations

import numpy as np
import pytest
from test_bdpt import BDPT, _assert_blocks_agree, _block_means
from test_media import furnace, seeds_mean
from test_path import _assert_mean

import raylume

SEEDS = 12  # independent renders per integrator
# A floor that ends (a quad, not a plane) where a scene has an environment: the lights at infinity
# then reach all of it from their disk
FLOOR = {"type": "quad", "position": [0, 0, 0], "u": [30, 0, 0], "v": [0, 0, 30],
         "material": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}}  # fmt: skip

FOG = {  # a homogeneous fog around everything, the camera and a sphere light in it (an area light:
    # a point light's 1 / d^2 near the medium vertices around it has no finite variance)
    "render": {"width": 32, "height": 24, "mode": "path", "max_depth": 5, "medium": "fog"},
    "camera": {"position": [0, 1, -4], "look_at": [0, 0.8, 0], "fov": 50},
    "media": {"fog": {"type": "homogeneous", "sigma_s": [0.5, 0.4, 0.3], "sigma_a": 0.05, "g": 0.3}},
    "lights": [{"type": "sphere", "position": [-0.3, 1.8, 0.3], "radius": 0.2, "intensity": 8}],
    "objects": [
        {"type": "plane", "material": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}},
        {"type": "sphere", "center": [0.7, 0.5, 0.6], "radius": 0.5,
         "material": {"type": "plastic", "color": [0.7, 0.3, 0.2], "roughness": 0.3}},
    ],
}  # fmt: skip

INTERIORS = {  # closed shapes filled with scattering media: a null boundary and a glass one
    "render": {"width": 32, "height": 24, "mode": "path", "max_depth": 6},
    "camera": {"position": [0, 1, -3.2], "look_at": [0, 0.45, 0], "fov": 45},
    "environment": {"color": [0.3, 0.3, 0.35]},
    "media": {"milk": {"type": "homogeneous", "sigma_s": 3.0, "sigma_a": [0.1, 0.2, 0.4], "g": 0.2},
              "jade": {"type": "homogeneous", "sigma_s": [2.0, 3.0, 2.0], "sigma_a": 0.2, "g": -0.3}},
    "lights": [{"type": "point", "position": [0.5, 2.5, -1.0], "intensity": 10}],
    "objects": [
        FLOOR,
        {"type": "sphere", "center": [-0.55, 0.45, 0], "radius": 0.45, "material": {"type": "null"},
         "interior": "milk"},
        {"type": "sphere", "center": [0.55, 0.45, 0], "radius": 0.45,
         "material": {"type": "dielectric", "ior": 1.4}, "interior": "jade"},
    ],
}  # fmt: skip


BEHIND_THE_LIGHT = {  # a big sphere light in fog: the fog behind it, lit, is hidden from the camera
    # (light subpaths scattered there must not reach the camera through the light: 11% too bright)
    "render": {"width": 32, "height": 24, "mode": "path", "max_depth": 2, "medium": "fog"},
    "camera": {"position": [0, 0, -3], "look_at": [0, 0, 0], "fov": 40},
    "media": {"fog": {"type": "homogeneous", "sigma_s": 0.5, "g": 0.0}},
    "lights": [{"type": "sphere", "position": [0, 0, 0], "radius": 0.5, "intensity": 1}],
    "objects": [{"type": "quad", "position": [0, 0, 30], "u": [1, 0, 0], "v": [0, 1, 0],
                 "material": {"type": "diffuse", "color": [0, 0, 0]}}],
}  # fmt: skip


THROUGH_THE_FOG = {  # an infinite floor through a sphere of fog, the point the floor is given by
    # inside it: light subpaths took the fog as the medium around the floor everywhere (the floor
    # 7x too bright), as the medium "around" an open surface is found from that one point
    "render": {"width": 32, "height": 24, "mode": "path", "max_depth": -1},
    "camera": {"position": [0, 1.2, -3], "look_at": [0, 0.4, 0], "fov": 50},
    "media": {"milk": {"type": "homogeneous", "sigma_s": 5.0, "sigma_a": 0.2}},
    "lights": [{"type": "point", "position": [1, 2, -1], "intensity": 3}],
    "objects": [
        {"type": "plane", "point": [0, 0, 0], "material": {"type": "diffuse", "color": [0.7, 0.7, 0.7]}},
        {"type": "sphere", "center": [0, 0.4, 0], "radius": 0.5, "material": {"type": "null"}, "interior": "milk"},
    ],
}  # fmt: skip


def _grid_scene(folder) -> raylume.Scene:
    """A grid medium ([render] medium: density only inside its box) of a soft blob of noise,
    under a uniform environment (whose light subpaths start on a disk beyond the grid's box) and
    a point light."""
    rng = np.random.default_rng(7)
    z, y, x = np.mgrid[-1:1:8j, -1:1:8j, -1:1:8j]
    density = np.exp(-2.0 * (x * x + y * y + z * z)) * rng.uniform(0.5, 1.0, x.shape)
    np.save(folder / "blob.npy", density.astype(np.float32))
    return raylume.scene_from_dict(
        {
            "render": {"width": 32, "height": 24, "mode": "path", "max_depth": 5, "medium": "smoke"},
            "camera": {"position": [0, 1, -3.5], "look_at": [0, 0.8, 0], "fov": 50},
            "environment": {"color": [0.4, 0.45, 0.5]},
            "media": {"smoke": {"type": "grid", "density": "blob.npy", "bounds_min": [-1, 0, -1],
                                "bounds_max": [1, 2, 1], "sigma_s": 5.0, "sigma_a": 0.5, "g": 0.4}},
            "lights": [{"type": "point", "position": [1.5, 2.5, -1.0], "intensity": 12}],
            "objects": [FLOOR],
        }
    ).with_base_dir(folder)  # fmt: skip


def _seed_images(session: raylume.Session, integrator: str, spp: int, first_seed: int) -> np.ndarray:
    images = [session.render(integrator=integrator, spp=spp, seed=first_seed + k, aovs=False).rgb for k in range(SEEDS)]
    return np.stack(images).astype(np.float64)


@pytest.mark.parametrize(
    "case",
    [
        "fog with a light in it",
        "interiors behind null and glass",
        "grid medium",
        "fog behind a light",
        "floor through fog",
    ],
)
def test_bdpt_agrees_with_path_mode_through_media(case, tmp_path):
    """Scattering, absorption, chromatic media, multiple scattering up to max_depth, light
    subpaths that start in a medium (a sphere light in fog, a point light, the environment's
    disk beyond a grid), connections through media and null boundaries, glass around a medium
    (only paths through its delta surfaces reach inside), a light's body hiding the fog behind
    it; bdpt at 8 samples per pixel
    against path mode at 32, SEEDS seeds each."""
    scene = {
        "fog with a light in it": lambda: raylume.scene_from_dict(FOG),
        "interiors behind null and glass": lambda: raylume.scene_from_dict(INTERIORS),
        "grid medium": lambda: _grid_scene(tmp_path),
        "fog behind a light": lambda: raylume.scene_from_dict(BEHIND_THE_LIGHT),
        "floor through fog": lambda: raylume.scene_from_dict(THROUGH_THE_FOG),
    }[case]()
    session = raylume.Session(scene)
    bdpt = _seed_images(session, "bdpt", 8, 100)
    path = _seed_images(session, "path", 32, 200)
    assert bdpt.mean() > 0.0
    _assert_blocks_agree(_block_means(bdpt), _block_means(path), f"{case}, 8 x 8 blocks")
    # and the whole image, where a bias small against one block's noise shows sooner
    _assert_blocks_agree(bdpt.mean(axis=(1, 2), keepdims=True), path.mean(axis=(1, 2), keepdims=True), case)


@pytest.mark.parametrize(
    "medium",
    [{"type": "homogeneous", "sigma_s": 2.0, "g": 0.0}, {"type": "homogeneous", "sigma_s": [0.5, 2.0, 6.0], "g": 0.7}],
    ids=["grey isotropic", "chromatic forward"],
)
def test_a_white_furnace_medium_disappears(medium, tmp_path):
    """test_media's white furnace by bdpt: a medium of albedo 1 in a null sphere under a uniform
    environment of radiance 1 returns 1 everywhere, per channel (light subpaths from the
    environment's disk scatter inside, connections cross the boundary)."""
    mean, _ = seeds_mean(furnace(medium, tmp_path), range(6), integrator="bdpt")
    for c in range(3):
        _assert_mean(mean[..., c : c + 1], 1.0, f"channel {c}")


@pytest.mark.parametrize("case", ["interiors", "grid"])
def test_media_renders_are_bit_identical_across_threads_and_crops(case, tmp_path):
    """Free flights, phase samples and ratio tracking along connections (the grid) take numbers
    keyed by the camera sample: the image is the same bits on 1 and 2 threads and in a crop."""
    scene = raylume.scene_from_dict(INTERIORS) if case == "interiors" else _grid_scene(tmp_path)
    one = raylume.render(scene, **BDPT, spp=2, threads=1, aovs=False)
    two = raylume.render(scene, **BDPT, spp=2, threads=2, aovs=False)
    assert np.array_equal(one.rgb, two.rgb)
    assert np.isfinite(one.rgb).all() and one.rgb.max() > 0 and one.stats["rejected_samples"] == 0
    crop = raylume.render(scene, **BDPT, spp=2, threads=2, crop=(5, 17, 3, 20), aovs=False).rgb
    assert np.array_equal(crop, one.rgb[3:20, 5:17])
