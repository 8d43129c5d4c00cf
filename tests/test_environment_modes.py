"""The [environment] as every mode shows it: rays (and raster pixels) that miss see it, and it
replaces the background; emission shows in every mode."""

from __future__ import annotations

import numpy as np
import pytest

import raylume
from raylume.compile.environment import build_environment
from raylume.kernels.film.camera import camera_frame, camera_ray
from raylume.kernels.shading.environment import environment_radiance

W, H = 24, 16
CAMERA = {"position": [0, 0, -3], "look_at": [0, 0.5, 0], "fov": 70}


def _scene(mode, environment):
    return raylume.scene_from_dict(
        {
            "render": {"width": W, "height": H, "mode": mode, "background": [1, 0, 1]},
            "camera": CAMERA,
            "objects": [
                {"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "material": {"emission": [0.25, 0.5, 1]}}
            ],
            "lights": [{"type": "ambient", "intensity": 0.0}],
            "environment": environment,
        }
    )


@pytest.mark.parametrize("mode", ["cast", "trace", "raster", "path"])
def test_missed_pixels_show_the_environment_image(mode, tmp_path):
    """An image environment: each pixel that hits nothing is the environment's radiance along
    its centre's ray (1 spp: the pixel centre), not the (magenta) background."""
    from raylume.image import Image

    rng = np.random.default_rng(0)
    sky = rng.uniform(0.1, 2.0, size=(8, 16, 3)).astype(np.float32)
    Image(sky, {}, {}, "clamp").save(tmp_path / "sky.exr")
    env = {"file": str(tmp_path / "sky.exr"), "rotate": [0, 30, 0]}
    img = raylume.render(_scene(mode, env), spp=1, max_depth=1 if mode == "path" else None)
    E = build_environment(file=str(tmp_path / "sky.exr"), rotate=(0, 30, 0))
    cam = camera_frame(CAMERA["position"], CAMERA["look_at"], (0, 1, 0), CAMERA["fov"], W, H)
    missed = img.aovs["object"] == -1
    assert missed.sum() > W * H / 2
    for j, i in zip(*np.nonzero(missed)):
        _, d = camera_ray(cam, i + 0.5, j + 0.5, W, H)
        np.testing.assert_allclose(img.rgb[j, i], environment_radiance(E, d), rtol=1e-5)


@pytest.mark.parametrize("mode", ["trace", "raster", "path"])
def test_emission_shows_in_every_lit_mode(mode):
    """The glowing sphere, unlit (ambient 0, a black environment), shows its emission."""
    img = raylume.render(_scene(mode, {"color": [0, 0, 0]}), spp=1)
    hit = img.aovs["object"] == 0
    np.testing.assert_allclose(img.rgb[hit], np.broadcast_to([0.25, 0.5, 1], img.rgb[hit].shape), rtol=1e-5)
