"""Tests for the pure-Python reference ray tracer (tests/reference/seed_python.py).

The reference is the oracle for the Numba renderer, so it is checked here
against values derived by hand (closed-form geometry and the lecture's
lighting formulas written out for specific configurations), never against
itself.
"""

from __future__ import annotations

import ast
import copy
import math
from pathlib import Path

import numpy as np
import pytest

try:  # tests/ as a package (rootdir on sys.path)
    from tests.reference.seed_python import SEED_SCENE, camera_ray_direction, render_reference
except ImportError:  # pytest "prepend" mode with tests/ not a package
    from reference.seed_python import SEED_SCENE, camera_ray_direction, render_reference

H_53 = math.tan(math.radians(53.13) / 2.0)  # ~0.5: the lecture's 1x1 viewport at d=1


def _scene(objects, lights, materials=None, background=(0.0, 0.0, 0.0), max_depth=3, camera=None):
    return {
        "render": {"background": list(background), "max_depth": max_depth},
        "camera": camera or {"position": [0, 0, 0], "look_at": [0, 0, 1], "up": [0, 1, 0], "fov": 53.13},
        "materials": materials or {},
        "lights": lights,
        "objects": objects,
    }


def _unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


# ---------------------------------------------------------------- independence


def test_reference_does_not_import_raylume():
    src = (Path(__file__).parent / "reference" / "seed_python.py").read_text()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Import):
            assert all(not a.name.startswith("raylume") for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert not (node.module or "").startswith("raylume")


# ---------------------------------------------------------------- camera


def test_camera_centre_and_corner_directions_default_camera():
    scene = _scene([], [])
    W, H = 5, 3
    # Centre pixel of an odd-sized image looks straight down +z.
    assert camera_ray_direction(scene, W, H, 2, 1) == pytest.approx((0.0, 0.0, 1.0), abs=1e-15)
    # Top-left pixel: a = 0.5/W*2-1, b = 1-0.5/H*2, w = h*W/H; right = +x, up = +y.
    h = H_53
    w = h * W / H
    a = 0.5 / W * 2 - 1
    b = 1 - 0.5 / H * 2
    expect = _unit((a * w, b * h, 1.0))
    assert camera_ray_direction(scene, W, H, 0, 0) == pytest.approx(expect, abs=1e-12)
    assert expect[0] < 0 and expect[1] > 0  # top-left really is left and up
    # Bottom-right pixel is the mirror image.
    br = camera_ray_direction(scene, W, H, W - 1, H - 1)
    assert br == pytest.approx((-expect[0], -expect[1], expect[2]), abs=1e-12)


def test_camera_lecture_viewport_at_distance_one():
    # fov 53.13 => tan(fov/2) = 0.5: a 600x600 image spans the 1x1 viewport at d=1,
    # so pixel (0,0)'s ray goes through (-0.5 + 0.5/600, 0.5 - 0.5/600, 1).
    scene = _scene([], [])
    d = camera_ray_direction(scene, 600, 600, 0, 0)
    vx, vy = d[0] / d[2], d[1] / d[2]
    assert vx == pytest.approx(-0.5 + 0.5 / 600, abs=1e-5)
    assert vy == pytest.approx(0.5 - 0.5 / 600, abs=1e-5)


def test_camera_rotated_basis():
    # Looking along +x with up +y: r = cross(up, f) = (0,0,-1), u = cross(f, r) = (0,1,0).
    scene = _scene([], [], camera={"position": [1, 2, 3], "look_at": [5, 2, 3], "up": [0, 1, 0], "fov": 90.0})
    assert camera_ray_direction(scene, 3, 3, 1, 1) == pytest.approx((1.0, 0.0, 0.0), abs=1e-15)
    # Rightmost centre-row pixel: a = 2/3, w = tan(45deg) = 1 => f + r*2/3.
    assert camera_ray_direction(scene, 3, 3, 2, 1) == pytest.approx(_unit((1.0, 0.0, -2.0 / 3.0)), abs=1e-12)
    # Top centre pixel: b = 2/3 => f + u*2/3.
    assert camera_ray_direction(scene, 3, 3, 1, 0) == pytest.approx(_unit((1.0, 2.0 / 3.0, 0.0)), abs=1e-12)


def test_image_orientation_row0_top_col0_left():
    # A small sphere placed on the top-left pixel's ray lights up only that pixel
    # (cast mode), and only in image[0, 0].
    W, H = 7, 5
    scene = _scene([], [], background=(0.1, 0.2, 0.3))
    d = camera_ray_direction(scene, W, H, 0, 0)
    scene["objects"] = [
        {"type": "sphere", "center": [10 * c for c in d], "radius": 0.05, "material": {"color": [1.0, 0.5, 0.25]}}
    ]
    img = render_reference(scene, W, H, mode="cast")
    assert img.shape == (H, W, 3) and img.dtype == np.float64
    assert tuple(img[0, 0]) == (1.0, 0.5, 0.25)
    rest = img.reshape(-1, 3)[1:]
    assert np.all(rest == np.array([0.1, 0.2, 0.3]))


# ---------------------------------------------------------------- basic lighting

MATTE = {"color": [0.8, 0.5, 0.25]}


def test_matte_sphere_centre_pixel_directional_along_view_axis():
    # Sphere straight ahead; the light comes from the camera side (L = (0,0,-1)).
    # Centre pixel: P = (0,0,4), N = (0,0,-1), cos = 1 => colour*(ambient + I).
    scene = _scene(
        [{"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": MATTE}],
        [{"type": "ambient", "intensity": 0.1}, {"type": "directional", "direction": [0, 0, -1], "intensity": 0.7}],
    )
    img = render_reference(scene, 11, 11)
    assert img[5, 5] == pytest.approx(np.array(MATTE["color"]) * 0.8, abs=1e-12)


def test_matte_sphere_oblique_light_cosine():
    # L = (0, 3, -4): |L| = 5, N.L = 4 at the centre hit point => cos = 0.8.
    # Per-channel intensities multiply per channel.
    scene = _scene(
        [{"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": MATTE}],
        [
            {"type": "ambient", "intensity": [0.1, 0.2, 0.3]},
            {"type": "directional", "direction": [0, 3, -4], "intensity": [0.5, 0.25, 1.0]},
        ],
    )
    img = render_reference(scene, 11, 11)
    expect = np.array(MATTE["color"]) * (np.array([0.1, 0.2, 0.3]) + np.array([0.5, 0.25, 1.0]) * 0.8)
    assert img[5, 5] == pytest.approx(expect, abs=1e-12)


def test_light_behind_surface_gives_ambient_only():
    # L = (0,0,1) points away from the visible hemisphere: N.L < 0 => no diffuse, and
    # R.V = N.L < 0 at the centre => no specular either.  (Shadow: the sphere itself
    # blocks it anyway.)
    scene = _scene(
        [{"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": {"color": [1, 1, 1], "specular": 10}}],
        [{"type": "ambient", "intensity": 0.25}, {"type": "directional", "direction": [0, 0, 1], "intensity": 0.7}],
    )
    img = render_reference(scene, 11, 11)
    assert img[5, 5] == pytest.approx([0.25, 0.25, 0.25], abs=1e-12)


def test_specular_highlight_hand_computed():
    # Centre hit: N = V = (0,0,-1); L = (0,1,-1): N.L = 1, |L| = sqrt2 => diffuse I/sqrt2.
    # R = 2N(N.L) - L = (0,-1,-1), R.V = 1, |R| = sqrt2 => specular I*(1/sqrt2)^10 = I/32.
    I = 0.6
    color = np.array([0.9, 0.6, 0.3])
    scene = _scene(
        [{"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": {"color": list(color), "specular": 10}}],
        [{"type": "ambient", "intensity": 0.2}, {"type": "directional", "direction": [0, 1, -1], "intensity": I}],
    )
    img = render_reference(scene, 11, 11)
    assert img[5, 5] == pytest.approx(color * (0.2 + I / math.sqrt(2) + I / 32), abs=1e-12)
    # Same scene matte (no "specular" key, or -1): no highlight.
    for spec in (None, -1):
        s2 = copy.deepcopy(scene)
        if spec is None:
            del s2["objects"][0]["material"]["specular"]
        else:
            s2["objects"][0]["material"]["specular"] = spec
        img2 = render_reference(s2, 11, 11)
        assert img2[5, 5] == pytest.approx(color * (0.2 + I / math.sqrt(2)), abs=1e-12)


def test_miss_is_background_exactly():
    bg = (0.1, 0.2, 0.3)
    scene = _scene(
        [{"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": MATTE}],
        [{"type": "ambient", "intensity": 1.0}],
        background=bg,
    )
    for mode in ("trace", "cast"):
        img = render_reference(scene, 11, 11, mode=mode)
        for j, i in [(0, 0), (0, 10), (10, 0), (10, 10), (5, 0), (0, 5)]:
            assert tuple(img[j, i]) == bg
        assert tuple(img[5, 5]) == (tuple(MATTE["color"]) if mode == "cast" else tuple(np.array(MATTE["color"]) * 1.0))


def test_sphere_behind_camera_is_invisible():
    scene = _scene(
        [{"type": "sphere", "center": [0, 0, -5], "radius": 1, "material": MATTE}],
        [{"type": "ambient", "intensity": 1.0}],
        background=(0.5, 0.5, 0.5),
    )
    img = render_reference(scene, 5, 5)
    assert np.all(img == 0.5)


# ---------------------------------------------------------------- shadows


def _ground_scene(extra_objects, lights):
    # Camera looks exactly at P = (0,-1,5), the top point of a huge ground sphere,
    # so the centre pixel of an odd image hits P with N = (0,1,0).
    return _scene(
        [{"type": "sphere", "center": [0, -1001, 5], "radius": 1000, "material": {"color": [1, 1, 1]}}] + extra_objects,
        lights,
        camera={"position": [0, 0, 0], "look_at": [0, -1, 5], "up": [0, 1, 0], "fov": 53.13},
    )


LIGHTS_GROUND = [
    {"type": "ambient", "intensity": 0.2},
    {"type": "point", "position": [0, 3, 5], "intensity": 0.6},  # straight above P: cos = 1
    {"type": "directional", "direction": [1, 1, 0], "intensity": 0.3},  # cos = 1/sqrt2
]


def test_ground_unshadowed_and_unclamped():
    img = render_reference(_ground_scene([], LIGHTS_GROUND), 9, 9)
    expect = 0.2 + 0.6 + 0.3 / math.sqrt(2)
    assert expect > 1.0
    assert img[4, 4] == pytest.approx([expect] * 3, abs=1e-9)  # not clamped to 1


def test_point_light_occluded_by_sphere():
    occluder = {"type": "sphere", "center": [0, 1, 5], "radius": 0.5, "material": {"color": [1, 0, 0]}}
    img = render_reference(_ground_scene([occluder], LIGHTS_GROUND), 9, 9)
    # The point light is blocked; ambient and the directional light (which misses the
    # occluder) still count.
    assert img[4, 4] == pytest.approx([0.2 + 0.3 / math.sqrt(2)] * 3, abs=1e-9)


def test_occluder_beyond_point_light_casts_no_shadow():
    # Point-light shadow rays stop at the light (t_max = 1 with unnormalised L).
    beyond = {"type": "sphere", "center": [0, 6, 5], "radius": 0.5, "material": {"color": [1, 0, 0]}}
    img = render_reference(_ground_scene([beyond], LIGHTS_GROUND[:2]), 9, 9)
    assert img[4, 4] == pytest.approx([0.8] * 3, abs=1e-9)


def test_directional_light_occluded_anywhere_along_ray():
    # Directional shadow rays are infinite: an occluder far away along L still blocks.
    far = {"type": "sphere", "center": [50, 49, 5], "radius": 1, "material": {"color": [1, 0, 0]}}
    lights = [LIGHTS_GROUND[0], LIGHTS_GROUND[2]]
    img = render_reference(_ground_scene([far], lights), 9, 9)
    assert img[4, 4] == pytest.approx([0.2] * 3, abs=1e-9)


# ---------------------------------------------------------------- reflections


def _mirror_scene(r, back_sphere=True, max_depth=3, background=(0.0, 0.0, 0.0), back_reflective=0.0):
    objs = [
        {"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": {"color": [1.0, 0.0, 0.0], "reflective": r}}
    ]
    if back_sphere:  # behind the camera: invisible to primary rays, seen in the mirror
        objs.append(
            {
                "type": "sphere",
                "center": [0, 0, -5],
                "radius": 1,
                "material": {"color": [0.0, 0.4, 1.0], "reflective": back_reflective},
            }
        )
    return _scene(objs, [{"type": "ambient", "intensity": 0.5}], background=background, max_depth=max_depth)


@pytest.mark.parametrize("r", [1.0, 0.25])
def test_reflection_mix(r):
    # Centre ray hits the mirror at (0,0,4) with N = (0,0,-1); the reflected ray goes
    # straight back along -z, through the camera position, and hits the back sphere
    # at (0,0,-4), where only ambient light counts.
    img = render_reference(_mirror_scene(r), 11, 11)
    local = np.array([1.0, 0.0, 0.0]) * 0.5
    seen = np.array([0.0, 0.4, 1.0]) * 0.5
    assert img[5, 5] == pytest.approx(local * (1 - r) + seen * r, abs=1e-12)


def test_reflection_of_background_and_depth_zero():
    bg = np.array([0.3, 0.6, 0.9])
    img = render_reference(_mirror_scene(0.4, back_sphere=False, background=tuple(bg)), 11, 11)
    assert img[5, 5] == pytest.approx(np.array([0.5, 0, 0]) * 0.6 + bg * 0.4, abs=1e-12)
    # max_depth = 0: no reflection at all, only the local colour.
    img0 = render_reference(_mirror_scene(0.4, max_depth=0), 11, 11)
    assert img0[5, 5] == pytest.approx([0.5, 0.0, 0.0], abs=1e-12)


@pytest.mark.parametrize("depth", [1, 2, 3])
def test_reflection_recursion_depth_between_two_mirrors(depth):
    # Two facing mirrors A (front) and B (behind the camera), both reflective r,
    # ambient a.  T(X, 0) = a*cX; T(X, d) = (1-r)*a*cX + r*T(other, d-1).
    r, a = 0.5, 0.5
    cA, cB = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.4, 1.0])

    def T(first, d):
        c, other = (cA, "B") if first == "A" else (cB, "A")
        if d == 0:
            return a * c
        return (1 - r) * a * c + r * T(other, d - 1)

    img = render_reference(_mirror_scene(r, max_depth=depth, back_reflective=r), 11, 11)
    assert img[5, 5] == pytest.approx(T("A", depth), abs=1e-12)


# ---------------------------------------------------------------- the lecture's scene


def _geometric_closest(D, spheres):
    """Closest sphere along unit D from the origin, by the geometric (not quadratic) method."""
    best, best_t = None, math.inf
    for s in spheres:
        C, rad = s["center"], s["radius"]
        tca = sum(c * d for c, d in zip(C, D))
        d2 = sum(c * c for c in C) - tca * tca
        if d2 > rad * rad or tca <= 0:
            continue
        t = tca - math.sqrt(rad * rad - d2)
        if t < best_t:
            best, best_t = s, t
    return best


def test_seed_scene_cast_40x40_matches_geometric_classification():
    img = render_reference(SEED_SCENE, 40, 40, mode="cast")
    assert img.shape == (40, 40, 3)
    mats = SEED_SCENE["materials"]
    counts = {}
    for j in range(40):
        for i in range(40):
            # The camera formula written out for the default camera.
            a = (i + 0.5) / 40 * 2 - 1
            b = 1 - (j + 0.5) / 40 * 2
            D = _unit((a * H_53, b * H_53, 1.0))
            s = _geometric_closest(D, SEED_SCENE["objects"])
            expect = (0.0, 0.0, 0.0) if s is None else tuple(mats[s["material"]]["color"])
            assert tuple(img[j, i]) == expect, (i, j)
            counts[s and s["material"]] = counts.get(s and s["material"], 0) + 1
    assert set(counts) == {None, "red", "blue", "green", "yellow"}


def test_seed_scene_trace_40x40_sky_and_bounds():
    img = render_reference(SEED_SCENE, 40, 40)
    cast = render_reference(SEED_SCENE, 40, 40, mode="cast")
    sky = np.all(cast == 0.0, axis=2)
    assert sky[0].all()  # top row is all sky
    # Sky pixels stay exactly black; nothing is negative.
    assert np.all(img[sky] == 0.0)
    assert img.min() >= 0.0
    # Lit surfaces: a pixel on the red sphere's lit face is brighter than ambient alone
    # (0.8 * 0.2 after the 0.2 reflective mix), and unlit objects never go below zero.
    assert cast[33, 19].tolist() == [1.0, 0.0, 0.0]
    assert img[33, 19, 0] > 0.8 * 0.2


def test_seed_scene_pixel_through_red_sphere_centre():
    # 39x39: column 19 is the centre column and row 32 satisfies
    # b = 1 - 65/39 = -2/3, so b*h = -1/3 (h ~ 0.5): the ray through (0,-1,3),
    # the red sphere's centre.  Derivation by hand for D = (0,-1,3)/sqrt10:
    #   P = C - D (radius 1), N = V = -D = (0,1,-3)/sqrt10.
    #   point light at (2,1,0): L = (2,1,0) - P; nothing lies on that segment;
    #     diffuse 0.6*N.L/|L|, specular 0.6*(R.V/|R|)^500, R = 2N(N.L) - L.
    #   directional (1,4,4): N.L = (4-12)/sqrt10 < 0 => no diffuse; R.V = N.L < 0 => no specular.
    #   reflection: R = 2N(N.V) - V = N, pointing up and back past the camera: hits nothing -> black.
    #   colour = (1-0.2) * red * (0.2 + diffuse + specular) + 0.2 * 0.
    D = _unit((0.0, -1.0, 3.0))
    N = tuple(-c for c in D)
    P = (0.0 - D[0], -1.0 - D[1], 3.0 - D[2])
    L = (2.0 - P[0], 1.0 - P[1], 0.0 - P[2])
    nl = sum(n * l for n, l in zip(N, L))
    lL = math.sqrt(sum(l * l for l in L))
    R = tuple(2 * n * nl - l for n, l in zip(N, L))
    rv = sum(r * v for r, v in zip(R, N))
    spec = (rv / math.sqrt(sum(r * r for r in R))) ** 500 if rv > 0 else 0.0
    intensity = 0.2 + 0.6 * nl / lL + 0.6 * spec
    assert nl > 0
    img = render_reference(SEED_SCENE, 39, 39)
    # Tolerance covers tan(53.13/2 deg) = 0.4999989 instead of exactly 0.5.
    assert img[32, 19] == pytest.approx([0.8 * intensity, 0.0, 0.0], abs=1e-4)


def test_seed_scene_is_the_lecture_scene():
    objs = {o["material"]: (tuple(o["center"]), o["radius"]) for o in SEED_SCENE["objects"]}
    assert objs == {
        "red": ((0, -1, 3), 1),
        "blue": ((2, 0, 4), 1),
        "green": ((-2, 0, 4), 1),
        "yellow": ((0, -5001, 0), 5000),
    }
    m = SEED_SCENE["materials"]
    assert [(m[k]["specular"], m[k]["reflective"]) for k in ("red", "blue", "green", "yellow")] == [
        (500, 0.2),
        (500, 0.3),
        (10, 0.4),
        (1000, 0.5),
    ]
    assert SEED_SCENE["render"]["max_depth"] == 3
    assert SEED_SCENE["camera"]["fov"] == 53.13


def test_bad_inputs_raise():
    with pytest.raises(ValueError):
        render_reference(SEED_SCENE, 4, 4, mode="raster")
    bad = copy.deepcopy(SEED_SCENE)
    bad["objects"].append({"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": "red"})
    with pytest.raises(NotImplementedError):
        render_reference(bad, 4, 4)
