"""Path tracing against analytic answers (pbrt-v4's integrator tests, white furnaces), its own
estimators against each other (light sampling, BSDF sampling, MIS), and its determinism.

Tolerances come from the estimator's standard error: pixels are independent samples (keys
per pixel), so the standard error of an image mean is the pixels' standard deviation over
sqrt(pixels); a check allows Z standard errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_cli import raylume as run_cli  # the command line in a subprocess

import raylume

Z = 4.5  # standard errors allowed: a false alarm about once in 150 000 checks
SIDE = 24


def _scene(objects, lights=(), environment=None, spp=16, max_depth=-1, **render):
    tables = {
        "render": {"width": SIDE, "height": SIDE, "spp": spp, "mode": "path", "max_depth": max_depth, **render},
        "camera": {"position": [0, 0, -4], "look_at": [0, 0, 0], "fov": 30},
        "objects": list(objects),
        "lights": list(lights),
    }
    if environment is not None:
        tables["environment"] = environment
    return raylume.scene_from_dict(tables)


def _mean_and_error(rgb: np.ndarray) -> tuple[float, float]:
    values = rgb.mean(axis=2).ravel()
    return float(values.mean()), float(values.std(ddof=1) / math.sqrt(values.size))


def _assert_mean(rgb, expected, what):
    mean, se = _mean_and_error(rgb)
    assert np.isfinite(rgb).all(), what
    assert abs(mean - expected) < Z * se + 1e-6, f"{what}: mean {mean:.5f} +- {se:.5f}, expected {expected}"


INSIDE = {"camera": {"position": [0, 0, 0], "look_at": [0, 0, 1], "fov": 60}}
UNIT_SPHERE = {"type": "sphere", "center": [0, 0, 0], "radius": 1}


def _inside(material, lights=()):
    scene = _scene([{**UNIT_SPHERE, "material": material}], lights, spp=16)
    return scene.replace(camera=INSIDE["camera"])


@pytest.mark.parametrize(
    "case",
    ["point light at the centre", "four point lights", "emissive sphere"],
)
def test_pbrt_analytic_scenes_inside_a_diffuse_sphere(case):
    """pbrt-v4 integrators_test.cpp: inside a unit sphere of reflectance 0.5 lit by a point light
    of intensity pi at the centre (or four of pi/4 around it), or glowing with emission 0.5,
    the radiance everywhere is 1: L = 0.5 + 0.5 L."""
    diffuse = {"type": "diffuse", "color": [0.5, 0.5, 0.5]}
    if case == "point light at the centre":
        scene = _inside(diffuse, [{"type": "point", "position": [0, 0, 0], "intensity": math.pi}])
    elif case == "four point lights":
        offsets = [[0.1, 0, 0], [-0.1, 0, 0], [0, 0.1, 0], [0, -0.1, 0]]
        scene = _inside(diffuse, [{"type": "point", "position": p, "intensity": math.pi / 4} for p in offsets])
        # off-centre lights light the sphere unevenly: only the whole sphere's mean is exactly 1,
        # so look at it from the centre with a wide camera and compare against the exact answer
        # for each pixel instead (below)
    else:
        scene = _inside({**diffuse, "emission": [0.5, 0.5, 0.5]})
    img = raylume.render(scene, aovs=False)
    if case != "four point lights":
        _assert_mean(img.rgb, 1.0, case)
        return
    # A point at distance r from a light of intensity I at angle cos: direct = rho / pi * I cos / r^2.
    # Interreflection inside a sphere is uniform (the sphere's form factor is constant), so the
    # indirect part is rho / (1 - rho) times the mean direct radiance: exactly 1 - mean direct.
    direct = _four_lights_direct(img)
    mean_direct = 0.5  # total power pi * 4 * pi/4... spread over 4 pi: E_mean = pi, rho/pi E = 0.5
    expected = direct + (1.0 - mean_direct)
    diff = img.rgb.mean(axis=2) - expected
    se = diff.std(ddof=1) / math.sqrt(diff.size)
    assert abs(diff.mean()) < Z * se + 1e-6, (diff.mean(), se)


def _four_lights_direct(img) -> np.ndarray:
    """The direct radiance per pixel of the four-lights scene (pixel centres, pinhole)."""
    from raylume.kernels.film.camera import camera_frame, camera_ray

    cam = camera_frame((0, 0, 0), (0, 0, 1), (0, 1, 0), 60, SIDE, SIDE)
    out = np.zeros((SIDE, SIDE))
    for j in range(SIDE):
        for i in range(SIDE):
            _, d = camera_ray(cam, i + 0.5, j + 0.5, SIDE, SIDE)
            p = np.asarray(d)  # the unit sphere around the eye
            for light in ([0.1, 0, 0], [-0.1, 0, 0], [0, 0.1, 0], [0, -0.1, 0]):
                to_l = np.asarray(light) - p
                r2 = to_l @ to_l
                cos = max(0.0, float(-p @ to_l) / math.sqrt(r2))
                out[j, i] += 0.5 / math.pi * (math.pi / 4) * cos / r2
    return out


FURNACE = {"color": [1, 1, 1]}
SPHERE = {"type": "sphere", "center": [0, 0, 0], "radius": 1}


@pytest.mark.parametrize(
    "material",
    [
        {"type": "diffuse", "color": [1, 1, 1]},
        {"type": "dielectric", "ior": 1.5},
        {"type": "conductor", "color": [1, 1, 1]},
        {"type": "plastic", "color": [1, 1, 1], "ior": 1.5},
        {"type": "dielectric", "ior": 50},
    ],
    ids=["diffuse", "smooth dielectric", "smooth conductor", "smooth plastic", "dielectric of index 50"],
)
def test_white_furnace_hides_energy_conserving_materials(material):
    """A sphere that reflects (and transmits) all light, under a uniform environment of radiance
    1, is invisible: every pixel is 1. Inside glass of index 50, a path's throughput is 1/2500
    of what leaves it: Russian roulette by that throughput, without the radiance factor undone,
    kept 1 path in 2500 a bounce there, and the sphere read 0.943 +- 0.001 (64 spp)."""
    scene = _scene([{**SPHERE, "material": material}], environment=FURNACE, spp=16)
    img = raylume.render(scene, aovs=False)
    _assert_mean(img.rgb, 1.0, material["type"])


@pytest.mark.parametrize(
    "material",
    [
        {"type": "conductor", "color": [1, 1, 1], "roughness": 0.5},
        {"type": "dielectric", "ior": 1.5, "roughness": 0.5},
        {"type": "plastic", "color": [1, 1, 1], "roughness": 0.3},
    ],
    ids=["rough conductor", "rough dielectric", "rough plastic"],
)
def test_white_furnace_rough_materials_lose_a_little_never_gain(material):
    """Single-scattering microfacet models lose the energy of light that would bounce between
    microfacets: under the furnace they are slightly darker than 1, never brighter."""
    scene = _scene([{**SPHERE, "material": material}], environment=FURNACE, spp=16)
    img = raylume.render(scene, aovs=False)
    mean, se = _mean_and_error(img.rgb)
    assert mean < 1.0 + Z * se and mean > 0.6, (mean, se)


def _glossy_room(strategy_scene_tweak=None):
    """A box lit by a quad light and an emissive triangle, with rough and diffuse surfaces."""
    objects = [
        {
            "type": "plane",
            "point": [0, -1, 0],
            "normal": [0, 1, 0],
            "material": {"type": "plastic", "color": [0.6, 0.5, 0.4], "roughness": 0.2},
        },
        {
            "type": "plane",
            "point": [0, 0, 2],
            "normal": [0, 0, -1],
            "material": {"type": "diffuse", "color": [0.7, 0.7, 0.7]},
        },
        {
            "type": "sphere",
            "center": [-0.5, -0.4, 0.5],
            "radius": 0.6,
            "material": {"type": "conductor", "color": [0.9, 0.8, 0.6], "roughness": 0.25},
        },
        {
            "type": "triangle",
            "vertices": [[0.6, -1, 1.5], [1.4, -1, 1.5], [1.0, 0.2, 1.6]],
            "material": {"type": "diffuse", "color": [0.2, 0.2, 0.2], "emission": [3, 2, 1]},
        },
    ]
    lights = [
        {"type": "quad", "position": [0, 1.5, 0.5], "u": [1, 0, 0], "v": [0, 0, 1], "intensity": 4},
        {"type": "point", "position": [1, 0.5, -1], "intensity": 1},
    ]
    return _scene(objects, lights, spp=32, max_depth=4)


@pytest.mark.parametrize("strategy", ["light", "bsdf"])
def test_light_bsdf_and_mis_estimators_agree(strategy, monkeypatch):
    """Next-event estimation alone, BSDF sampling alone and their MIS combination are three
    unbiased estimators of the same image: their means agree within standard errors."""
    scene = _glossy_room()
    mis = raylume.render(scene, aovs=False).rgb.mean(axis=2)
    monkeypatch.setenv("RAYLUME_PATH_STRATEGY", strategy)
    other = raylume.render(scene, aovs=False).rgb.mean(axis=2)
    diff = other - mis
    se = diff.std(ddof=1) / math.sqrt(diff.size)
    assert abs(diff.mean()) < Z * se, (strategy, diff.mean(), se)
    # and MIS is the better estimator of the three: less noise than BSDF sampling alone
    if strategy == "bsdf":
        assert mis.std() < other.std()


def test_path_images_depend_only_on_scene_seed_and_spp():
    scene = _glossy_room()
    one = raylume.render(scene, threads=1, aovs=False).rgb
    two = raylume.render(scene, threads=2, aovs=False).rgb
    assert np.array_equal(one, two)
    session = raylume.Session(scene)
    film = raylume.Film(SIDE, SIDE, "box", total_spp=32)
    session.add_samples(film, 12)
    session.add_samples(film, 20)
    assert np.array_equal(film.rgb(), one)
    other_seed = raylume.render(scene, seed=1, aovs=False).rgb
    assert not np.array_equal(one, other_seed)


def test_max_depth_counts_segments_as_mitsuba():
    """1: only emitters seen directly (the quad light and the glowing triangle); 2: direct
    light; more depth adds light, never takes it away (in expectation; here per image mean)."""
    scene = _glossy_room()
    means = [raylume.render(scene, max_depth=k, aovs=False).rgb.mean() for k in (1, 2, 3)]
    only_emitters = raylume.render(scene, max_depth=1, aovs=False).rgb
    # Only the glowing triangle shows (the quad light is in no pixel of this view): each pixel
    # is its emission (3, 2, 1) times the share of the pixel's 32 samples that hit it.
    share = only_emitters / np.array([3.0, 2.0, 1.0])
    np.testing.assert_allclose(share, share[..., :1].repeat(3, axis=2), atol=1e-6)
    np.testing.assert_allclose(share * 32, np.round(share * 32), atol=1e-4)
    assert share.max() == pytest.approx(1.0) and (share == 0).mean() > 0.5
    assert means[0] < means[1] < means[2]
    # 0: no segment, a black image (Mitsuba's; path mode gave max_depth 1's), in both integrators
    for integrator in ("path", "bdpt"):
        assert not raylume.render(scene, max_depth=0, integrator=integrator, aovs=False).rgb.any(), integrator


def test_stats_count_rejected_samples_and_images_are_finite():
    img = raylume.render(_glossy_room(), aovs=False)
    assert img.stats["rejected_samples"] == 0
    assert np.isfinite(img.rgb).all() and (img.rgb >= 0).all()


@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_a_scene_where_nothing_emits_is_black_without_rejected_samples(integrator):
    """A black environment is the one light: its pick probability was 0 / 0, and every path that
    left the scene a NaN sample, dropped (path mode: 4 of 16 samples a pixel on the sphere)."""
    scene = _scene([SPHERE], environment={"color": [0, 0, 0]}, spp=4, integrator=integrator)
    img = raylume.render(scene, aovs=False)
    assert img.stats["rejected_samples"] == 0
    assert (img.rgb == 0).all()


def test_spot_light_lights_only_its_cone():
    """A spot pointing straight down at a floor: lit inside the outer cone, dark outside."""
    floor = {
        "type": "plane",
        "point": [0, 0, 0],
        "normal": [0, 1, 0],
        "material": {"type": "diffuse", "color": [0.5, 0.5, 0.5]},
    }
    spot = {
        "type": "spot",
        "position": [0, 2, 0],
        "direction": [0, -1, 0],
        "angle": 20,
        "inner_angle": 10,
        "intensity": 10,
    }
    scene = _scene([floor], [spot], spp=1, max_depth=2).replace(
        camera={"position": [0, 6, -0.001], "look_at": [0, 0, 0], "fov": 60}
    )
    img = raylume.render(scene)
    depth = img.aovs["depth"]
    hit = np.isfinite(depth)
    # the floor point of each pixel, from the depth along the pinhole ray
    from raylume.kernels.film.camera import camera_frame, camera_ray

    cam = camera_frame((0, 6, -0.001), (0, 0, 0), (0, 1, 0), 60, SIDE, SIDE)
    radius = np.zeros((SIDE, SIDE))
    for j in range(SIDE):
        for i in range(SIDE):
            o, d = camera_ray(cam, i + 0.5, j + 0.5, SIDE, SIDE)
            p = np.asarray(o) + np.asarray(d) * depth[j, i]
            radius[j, i] = math.hypot(p[0], p[2])
    outer = 2 * math.tan(math.radians(20))
    inner = 2 * math.tan(math.radians(10))
    lum = img.rgb.mean(axis=2)
    assert (lum[hit & (radius > outer * 1.05)] == 0).all()
    # inside the inner cone: exactly E = I cos / r^2 times rho / pi (direct light, depth 2)
    inside = hit & (radius < inner * 0.9)
    cos = 2 / np.sqrt(4 + radius[inside] ** 2)
    expected = 0.5 / math.pi * 10 * cos / (4 + radius[inside] ** 2)
    np.testing.assert_allclose(lum[inside], expected, rtol=1e-4)


def test_seed_scene_renders_in_path_mode():
    """The seed's phong materials have an energy-conserving path-mode mapping: finite, lit."""
    img = raylume.render(raylume.builtin_scene("seed"), mode="path", width=48, height=48, spp=4, aovs=False)
    assert np.isfinite(img.rgb).all()
    assert img.rgb.mean() > 0.01


# --- the command line -----------------------------------------------------------------------


def test_cli_path_mode_denoises_and_keeps_the_noisy_image(tmp_path):
    """--mode path --denoise writes the denoised image, --aov noisy=PATH the image before it;
    denoising a noisy render brings it closer to a converged one."""
    scene = tmp_path / "room.toml"
    scene.write_text(
        """
[render]
width = 48
height = 48
[camera]
position = [0, 0, -4]
look_at = [0, 0, 0]
fov = 30
[[objects]]
type = "sphere"
center = [0, 0, 0]
radius = 1
material = { type = "diffuse", color = [0.8, 0.5, 0.3] }
[[objects]]
type = "plane"
point = [0, -1, 0]
normal = [0, 1, 0]
material = { type = "diffuse", color = [0.6, 0.6, 0.6] }
[[lights]]
type = "quad"
position = [0, 3, 0]
u = [1.5, 0, 0]
v = [0, 0, 1.5]
intensity = 6
"""
    )
    result = run_cli(
        "render", scene, "--mode", "path", "--spp", 4, "--denoise", "--aov", "noisy=noisy.npy", "-o", "out.exr",
        "--stats", "s.json", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    from raylume.compile.environment import load_environment_image

    denoised = load_environment_image(tmp_path / "out.exr")
    noisy = np.load(tmp_path / "noisy.npy")
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["mode"] == "path" and stats["rejected_samples"] == 0 and stats["denoise_seconds"] > 0
    reference = raylume.render(raylume.load_scene(scene), mode="path", spp=256, aovs=False).rgb
    error = lambda x: float(np.sqrt(np.mean((x - reference) ** 2)))  # noqa: E731
    assert error(denoised) < 0.7 * error(noisy), (error(denoised), error(noisy))


def test_cli_noisy_aov_needs_denoise_and_path_mode(tmp_path):
    result = run_cli("render", "--aov", "noisy=n.npy", "-o", "o.png", cwd=tmp_path)
    assert result.returncode == 2
    assert "--denoise" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "o.png").exists()


def _stacked_lights(lower: str) -> raylume.Scene:
    """A floor under a small bright quad light, with a larger dim one between them: `lower`
    is "light" (the dim light), "blocker" (a black quad in its place, no light) or "alone" (the
    dim light without the bright one)."""
    high = {"type": "quad", "position": [0, 3, 0], "u": [0.5, 0, 0], "v": [0, 0, 0.5], "intensity": [60, 60, 60]}
    low = {"position": [0, 1.5, 0], "u": [1.5, 0, 0], "v": [0, 0, 1.5]}
    lights = [] if lower == "alone" else [high]
    objects = [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0],
                "material": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}}]  # fmt: skip
    if lower == "blocker":
        objects.append({"type": "quad", **low, "material": {"type": "diffuse", "color": [0, 0, 0]}})
    else:
        lights.append({"type": "quad", **low, "intensity": [1, 1, 1]})
    return raylume.scene_from_dict({
        "render": {"width": 24, "height": 16, "spp": 32, "mode": "path", "max_depth": 3},
        "camera": {"position": [0, 2.2, -4], "look_at": [0, 0.5, 0], "fov": 55},
        "objects": objects,
        "lights": lights,
    })  # fmt: skip


@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_an_area_light_shadows_the_light_behind_it(integrator):
    """Light is additive: the floor under two stacked quad lights is what it is under the
    bright one with a black quad in the dim one's place, plus the dim one alone. Quad and sphere
    lights are not in the BVH; shadow rays towards the bright light had passed through the dim
    one, and the floor under it came out lit by both."""
    kw = {"integrator": integrator, "aovs": False}
    both = raylume.render(_stacked_lights("light"), seed=1, **kw).rgb
    blocked = raylume.render(_stacked_lights("blocker"), seed=2, **kw).rgb
    alone = raylume.render(_stacked_lights("alone"), seed=3, **kw).rgb
    diff = (both.astype(np.float64) - blocked - alone).mean(axis=2)
    se = diff.std(ddof=1) / math.sqrt(diff.size)
    assert abs(diff.mean()) < Z * se + 1e-7, f"{integrator}: {diff.mean():.5f} +- {se:.5f}"


@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_next_event_estimation_reaches_an_emitter_beside_a_surface(integrator, monkeypatch):
    """A lamp (an emissive quad, emitting both ways) hangs half a unit over a floor, far from the
    origin (x = 400: the rays' offset from surfaces, 1e-7 of the coordinates, is then 4e-5). Its
    underside lights the floor around it at grazing angles. A shadow ray towards a point on the
    lamp leaves the floor offset towards the lamp; aimed from the unoffset point and stopped
    1e-5 of the distance short, it met the lamp's own plane before its end and counted the lamp
    as its own blocker, so next-event estimation alone left that light out. Light sampling alone
    and BSDF sampling alone are unbiased estimators of the same floor: they agree within
    standard errors (bdpt: against path mode's BSDF sampling). The floor is the pixels that see
    none of the lamp: the lamp's partly covered pixels had been counted as floor light, and had
    carried the check that the light is there to find."""
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 32, "height": 24, "spp": 1024, "mode": "path", "max_depth": 2},
            "camera": {"position": [400, 40, -30], "look_at": [400, 0, 0], "fov": 50},
            "materials": {
                "white": {"type": "diffuse", "color": [0.8, 0.8, 0.8]},
                "lamp": {"type": "diffuse", "color": [0, 0, 0], "emission": [10, 10, 10]},
            },
            "objects": [
                {"type": "quad", "position": [0, 0, 0], "u": [1000, 0, 0], "v": [0, 0, 1000], "material": "white"},
                {"type": "quad", "position": [400, 0.5, 0], "u": [20, 0, 0], "v": [0, 0, 20], "material": "lamp"},
            ],
        }
    )
    monkeypatch.setenv("RAYLUME_PATH_STRATEGY", "bsdf")
    reference = raylume.render(scene, aovs=False).rgb.mean(axis=2)
    if integrator == "path":
        monkeypatch.setenv("RAYLUME_PATH_STRATEGY", "light")
        estimate = raylume.render(scene, aovs=False, seed=7).rgb.mean(axis=2)
    else:
        monkeypatch.delenv("RAYLUME_PATH_STRATEGY")
        estimate = raylume.render(scene, aovs=False, seed=7, integrator="bdpt").rgb.mean(axis=2)
    monkeypatch.delenv("RAYLUME_PATH_STRATEGY", raising=False)
    # the floor: the pixels that see none of the lamp (its emission met directly, at max_depth 1)
    floor = raylume.render(scene, aovs=False, max_depth=1).rgb.max(axis=2) == 0
    assert floor.mean() > 0.8
    diff = (estimate - reference)[floor]
    se = diff.std(ddof=1) / math.sqrt(diff.size)
    # the underside's light is there to find: an estimate without it would miss by twice the limit
    assert reference[floor].mean() > 2 * Z * se, (reference[floor].mean(), se)
    assert abs(diff.mean()) < Z * se, (integrator, diff.mean(), se, reference[floor].mean())
