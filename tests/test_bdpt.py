"""Bidirectional path tracing (integrator = "bdpt") against independent answers: path mode's
images (its own estimator, tested against Mitsuba and pbrt's analytic scenes), the Mitsuba
Cornell box reference, pbrt's analytic scenes, white furnaces, path mode's images of paths of
each length (each strategy alone), a pinhole's geometry for the splats; and its determinism.

Tolerances come from standard errors: of an image mean, the pixels' standard deviation over
sqrt(pixels) (each pixel's samples are independent of the others'; a light subpath splats into
one pixel, so the splats of different pixels are independent but for the multinomial choice of
where they land), or the spread of per-seed means; a check allows Z of them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_path import FURNACE, SPHERE, Z, _assert_mean, _glossy_room, _inside, _scene

import raylume

BDPT = {"mode": "path", "integrator": "bdpt"}
REPO = Path(__file__).resolve().parents[1]


def _diff_within(a: np.ndarray, b: np.ndarray, what: str, z: float = Z) -> None:
    """Two independent unbiased images of the same thing: their per-pixel difference has mean
    0 within z standard errors."""
    assert np.isfinite(a).all() and np.isfinite(b).all(), what
    diff = (a.astype(np.float64) - b.astype(np.float64)).mean(axis=2)
    se = diff.std(ddof=1) / math.sqrt(diff.size)
    assert abs(diff.mean()) < z * se + 1e-7, f"{what}: difference {diff.mean():.5f} +- {se:.5f}"


def test_camera_importance_inverts_the_camera_rays():
    """The image point of a camera ray's direction is the one it was made for; lens or not."""
    from raylume.kernels.film.camera import camera_frame, camera_importance, camera_ray, thin_lens_ray

    w, h = 40, 30
    cam = camera_frame((1, 2, -3), (0, 0.5, 1), (0, 1, 0), 50, w, h, aperture=0.2, focus_distance=3.0)
    for x, y, lu, lv in [(0.5, 0.5, 0.3, 0.7), (39.9, 12.25, 0.9, 0.1), (20.0, 29.5, 0.5, 0.5)]:
        o, d = camera_ray(cam, x, y, w, h)
        lo, ld = thin_lens_ray(cam, o, d, lu, lv)
        we, pdf, x2, y2 = camera_importance(cam, w, h, lo, ld)
        assert (x2, y2) == pytest.approx((x, y), abs=1e-9)
        cos = float(np.dot(ld, cam[3:6]))
        area = 4 * cam[14] * cam[15]
        assert pdf == pytest.approx(1 / (area * cos**3))
        assert we == pytest.approx(1 / (area * math.pi * 0.1**2 * cos**4))
    assert camera_importance(cam, w, h, lo, (-ld[0], -ld[1], -ld[2]))[0] == 0.0  # behind the camera


def test_splats_land_in_the_pixels_the_pinhole_sees():
    """Light subpaths seen by the camera alone (t = 1, s = 2, unweighted): a point light at the
    pinhole lights a quad whose corners project onto pixel corners (columns 8..15, rows 20..23 of
    a 32 x 32 image, 90 degrees). Splats land in exactly those pixels, every one of them, and
    each pixel converges to path mode's direct light there."""
    quad = {"type": "quad", "position": [-0.5, -0.75, 2], "u": [1, 0, 0], "v": [0, 0.5, 0],
            "material": {"type": "diffuse", "color": [0.8, 0.8, 0.8]}}  # fmt: skip
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 32, "height": 32, "spp": 64, "mode": "path", "max_depth": 2},
            "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1], "fov": 90},
            "objects": [quad],
            "lights": [{"type": "point", "position": [0, 0, 0], "intensity": 5}],
        }
    )
    import os

    os.environ["RAYLUME_BDPT_STRATEGY"] = "2,1,nomis"
    try:
        splats = raylume.render(scene, integrator="bdpt", aovs=False).rgb
    finally:
        del os.environ["RAYLUME_BDPT_STRATEGY"]
    lit = splats.max(axis=2) > 0
    expected = np.zeros((32, 32), bool)
    expected[20:24, 8:16] = True
    assert np.array_equal(lit, expected)
    path = raylume.render(scene, spp=256, aovs=False).rgb
    assert np.array_equal(path.max(axis=2) > 0, expected)
    _diff_within(splats[expected][None], path[expected][None], "splats against path mode's direct light")


def test_bdpt_agrees_with_path_mode_on_a_glossy_room():
    """Quad light, emissive triangle, point light; plastic, rough conductor, diffuse planes."""
    scene = _glossy_room()
    path = raylume.render(scene, spp=64, aovs=False).rgb
    bdpt = raylume.render(scene, **BDPT, aovs=False)
    _diff_within(bdpt.rgb, path, "glossy room")
    assert bdpt.stats["rejected_samples"] == 0
    strategies = bdpt.stats["bdpt_strategies"]
    for key in ("0,2", "1,2", "2,1", "2,2", "1,3", "3,1"):
        assert strategies.get(key, 0) > 0, (key, strategies)


def _every_light(folder):
    """tools/render_check.py's scene of every light, emitter and material kind."""
    import importlib.util

    import trimesh

    spec = importlib.util.spec_from_file_location("render_check", REPO / "tools" / "render_check.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    mesh = folder / "every_light.ply"
    trimesh.creation.icosphere(subdivisions=1, radius=0.12).export(mesh)
    instanced = {"type": "mesh", "file": str(mesh), "material": {"type": "diffuse", "emission": [3, 1, 3]},
                 "instances": [{"translate": [x, 2.8, 2.0]} for x in (-2.0, -1.0, 1.0)]}  # fmt: skip
    tables = module.EVERY_LIGHT
    return raylume.Scene.model_validate({**tables, "objects": [*tables["objects"], instanced]})


def test_bdpt_agrees_with_path_mode_with_every_light_and_material(tmp_path):
    """Spot, point, directional, quad and sphere lights, ambient lights, an environment, emissive
    spheres, disks, quads, triangles and an instanced mesh; every material kind; a ground plane
    (beyond the bounding sphere from which the lights at infinity shine)."""
    scene = _every_light(tmp_path)
    path = raylume.render(scene, mode="path", spp=64, seed=1, aovs=False).rgb
    bdpt = raylume.render(scene, **BDPT, spp=8, seed=2, aovs=False).rgb
    _diff_within(bdpt, path, "every light")
    # the same per quarter of the image (the plane, the spheres, the lights)
    for rows in (slice(0, 16), slice(16, 32)):
        for cols in (slice(0, 24), slice(24, 48)):
            _diff_within(bdpt[rows, cols], path[rows, cols], f"every light, part {rows}, {cols}")


@pytest.mark.parametrize("case", ["point light at the centre", "emissive sphere"])
def test_pbrt_analytic_scenes_inside_a_diffuse_sphere(case):
    """pbrt-v4 integrators_test.cpp: inside a unit sphere of reflectance 0.5 lit by a point light
    of intensity pi at its centre, or glowing with emission 0.5, the radiance everywhere is 1."""
    diffuse = {"type": "diffuse", "color": [0.5, 0.5, 0.5]}
    if case == "point light at the centre":
        scene = _inside(diffuse, [{"type": "point", "position": [0, 0, 0], "intensity": math.pi}])
    else:
        scene = _inside({**diffuse, "emission": [0.5, 0.5, 0.5]})
    img = raylume.render(scene, **BDPT, aovs=False)
    _assert_mean(img.rgb, 1.0, case)


@pytest.mark.parametrize(
    "material",
    [
        {"type": "diffuse", "color": [1, 1, 1]},
        {"type": "dielectric", "ior": 1.5},
        {"type": "conductor", "color": [1, 1, 1]},
    ],
    ids=["diffuse", "smooth dielectric", "smooth conductor"],
)
def test_white_furnace_hides_energy_conserving_materials(material):
    """Under a uniform environment of radiance 1 (light subpaths from the bounding sphere's
    disk), a sphere that reflects and transmits all light is invisible, delta BSDFs included."""
    scene = _scene([{**SPHERE, "material": material}], environment=FURNACE, spp=8, max_depth=12)
    img = raylume.render(scene, **BDPT, aovs=False)
    _assert_mean(img.rgb, 1.0, material["type"])


def test_images_depend_only_on_scene_seed_spp_and_integrator():
    """Bit-identical across 1 and 2 threads, passes, and crops (a crop is the full render's
    window: its splats come from every pixel's light subpath)."""
    scene = _glossy_room()
    one = raylume.render(scene, **BDPT, spp=4, threads=1, aovs=False).rgb
    two = raylume.render(scene, **BDPT, spp=4, threads=2, aovs=False).rgb
    assert np.array_equal(one, two)
    crop = raylume.render(scene, **BDPT, spp=4, threads=2, crop=(5, 17, 3, 20), aovs=False).rgb
    assert np.array_equal(crop, one[3:20, 5:17])
    session = raylume.Session(scene)
    film = raylume.Film(one.shape[1], one.shape[0], "box", total_spp=4)
    session.add_samples(film, 1, integrator="bdpt")
    session.add_samples(film, 3, integrator="bdpt")
    assert np.array_equal(film.rgb(), one)
    assert not np.array_equal(raylume.render(scene, **BDPT, spp=4, seed=1, aovs=False).rgb, one)
