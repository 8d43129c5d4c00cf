"""The seed's lighting terms, shadows and reflection on hand-computed cases (1-pixel renders)."""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numba
import numpy as np
import pytest

import raylume
from raylume.kernels.shading.materials.seed_response import highlight


def centre_pixel(objects, lights, materials=None, max_depth=3, background=(0, 0, 0), mode="trace"):
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 1, "height": 1, "max_depth": max_depth, "background": list(background), "mode": mode},
            "materials": materials or {},
            "lights": lights,
            "objects": objects,
        }
    )
    return raylume.render(scene).rgb[0, 0].astype(np.float64)


SPHERE = {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"}  # hit at (0, 0, 2), N = -z


def test_ambient_only():
    rgb = centre_pixel([SPHERE], [{"type": "ambient", "intensity": 0.3}], {"m": {"color": [1, 0.5, 0.25]}})
    np.testing.assert_allclose(rgb, [0.3, 0.15, 0.075], rtol=1e-6)


def test_diffuse_cosine_law_and_rgb_intensity():
    # point light at (0, 1, 1): L = (0, 1, -1)/sqrt2, N.L = 1/sqrt2
    lights = [{"type": "point", "position": [0, 1, 1], "intensity": [0.8, 0.4, 0.2]}]
    rgb = centre_pixel([SPHERE], lights, {"m": {"color": [1, 1, 1]}})
    np.testing.assert_allclose(rgb, np.array([0.8, 0.4, 0.2]) / math.sqrt(2), rtol=1e-6)


def test_phong_specular_term():
    # R = 2N(N.L) - L = (0, -1, -1)/sqrt2, V = (0, 0, -1): R.V = 1/sqrt2, (1/sqrt2)^10 = 1/32
    lights = [{"type": "ambient", "intensity": 0.2}, {"type": "point", "position": [0, 1, 1], "intensity": 0.5}]
    rgb = centre_pixel([SPHERE], lights, {"m": {"color": [1, 1, 1], "specular": 10}})
    expected = 0.2 + 0.5 / math.sqrt(2) + 0.5 / 32
    np.testing.assert_allclose(rgb, [expected] * 3, rtol=1e-6)


def test_directional_light_towards_camera_side():
    lights = [{"type": "directional", "direction": [0, 0, -5], "intensity": 0.7}]
    rgb = centre_pixel([SPHERE], lights, {"m": {"color": [0, 1, 0]}})
    np.testing.assert_allclose(rgb, [0, 0.7, 0], atol=1e-7)


def test_light_behind_surface_gives_nothing():
    lights = [{"type": "directional", "direction": [0, 0, 1], "intensity": 0.7}]
    rgb = centre_pixel([SPHERE], lights, {"m": {"color": [1, 1, 1]}})
    np.testing.assert_allclose(rgb, 0, atol=1e-12)


def test_shadow_blocks_point_light_but_not_beyond_it():
    lights = [{"type": "ambient", "intensity": 0.1}, {"type": "point", "position": [0, 2, 0], "intensity": 0.6}]
    blocker = {"type": "sphere", "center": [0, 1, 1], "radius": 0.2, "material": "m"}  # on the segment to the light
    beyond = {"type": "sphere", "center": [0, 4, -2], "radius": 0.5, "material": "m"}  # past the light
    mats = {"m": {"color": [1, 1, 1]}}
    lit = centre_pixel([SPHERE], lights, mats)
    shadowed = centre_pixel([SPHERE, blocker], lights, mats)
    beyond_rgb = centre_pixel([SPHERE, beyond], lights, mats)
    np.testing.assert_allclose(shadowed, 0.1, rtol=1e-6)
    np.testing.assert_allclose(beyond_rgb, lit, rtol=1e-9)
    assert lit[0] > 0.1 + 0.3


def test_mirror_reflection_mix():
    """A plane mirror facing the camera reflects a red sphere placed behind the camera:
    colour = local * (1 - r) + reflected * r, and reflected = red * ambient."""
    r = 0.25
    mirror = {"type": "plane", "point": [0, 0, 4], "normal": [0, 0, -1], "material": "mirror"}
    behind = {"type": "sphere", "center": [0, 0, -3], "radius": 1, "material": "red"}
    mats = {"mirror": {"color": [0, 0, 1], "reflective": r}, "red": {"color": [1, 0, 0]}}
    lights = [{"type": "ambient", "intensity": 0.5}]
    rgb = centre_pixel([mirror, behind], lights, mats)
    np.testing.assert_allclose(rgb, [r * 0.5, 0, (1 - r) * 0.5], rtol=1e-6)
    # with max_depth 0 the mirror shows only its local colour
    rgb0 = centre_pixel([mirror, behind], lights, mats, max_depth=0)
    np.testing.assert_allclose(rgb0, [0, 0, 0.5], rtol=1e-6)


def test_reflected_ray_that_misses_sees_background():
    mirror = {"type": "plane", "point": [0, 0, 4], "normal": [0, 0, -1], "material": "mirror"}
    mats = {"mirror": {"color": [0, 0, 0], "reflective": 1.0}}
    rgb = centre_pixel([mirror], [], mats, background=[0.2, 0.4, 0.6])
    np.testing.assert_allclose(rgb, [0.2, 0.4, 0.6], rtol=1e-6)


def test_cast_mode_is_unlit_material_colour():
    rgb = centre_pixel(
        [SPHERE], [{"type": "ambient", "intensity": 0.1}], {"m": {"color": [0.3, 0.6, 0.9]}}, mode="cast"
    )
    np.testing.assert_allclose(rgb, [0.3, 0.6, 0.9], rtol=1e-6)


@numba.njit
def _highlight(c, s):
    return highlight(c, s)


@pytest.mark.parametrize("specular", [1, 2, 3, 10, 500, 1000, 4097, 65536, 0.5, 2.5, 99.9, 65537, 1e6])
def test_highlight_power_is_pow_within_its_rounding(specular):
    """cos^s by repeated squaring for whole exponents: each product rounds once (relative error
    at most u = 2**-53), and squaring k times grows a relative error e to 2**k e + u, so c**n is
    within (n + 2 log2 n + 1) u of the exact power; other exponents go to pow itself."""
    rng = np.random.default_rng(int(specular * 10))
    cos = 1.0 - rng.uniform(0, min(50.0 / specular, 1.0), 200)  # phong asks above 0 and 1 - 50 / s
    got = np.array([_highlight(c, float(specular)) for c in cos])
    if float(specular).is_integer() and specular <= 65536:
        with localcontext() as ctx:
            ctx.prec = 80  # Decimal(c) is c exactly; its integer power, to 80 digits
            exact = np.array([float(Decimal(c) ** int(specular)) for c in cos])
        bound = (specular + 2 * math.log2(specular) + 1) * 2.0**-53
        assert np.all(np.abs(got - exact) <= bound * exact)
    else:
        np.testing.assert_array_equal(got, [math.pow(c, specular) for c in cos])


@pytest.mark.parametrize("mode", ["trace", "raster"])
@pytest.mark.parametrize("offset", [1e4, 1e7])
def test_lighting_does_not_depend_on_where_the_scene_sits(mode, offset):
    """A sphere (float64: its hits exact anywhere) lit by a point light, and the same scene moved
    `offset` along x: the same image within float rounding. The lights' directions had been taken
    from the point offset off the surface, by 1e-7 of its largest coordinate (a unit at 1e7):
    the images differed by 0.157 at 1e7 (1.5e-4 at 1e4) of the 0.8 they can reach."""

    def scene(x):
        return raylume.scene_from_dict({
            "render": {"width": 24, "height": 24},
            "camera": {"position": [x, 0, -1], "look_at": [x, 0, 4], "fov": 40},
            "lights": [{"type": "point", "position": [x + 2, 3, 0], "intensity": 1.0}],
            "objects": [{"type": "sphere", "center": [x, 0, 4], "radius": 1,
                         "material": {"color": [0.8, 0.8, 0.8], "specular": 50}}],
        })  # fmt: skip

    here, there = (raylume.render(scene(x), mode=mode).rgb for x in (0.0, offset))
    assert here.max() > 0.5
    np.testing.assert_allclose(there, here, atol=1e-6)
