"""Participating media (DESIGN.md section 7) against what is known without raylume: Beer-Lambert
transmittance, a white furnace, the Henyey-Greenstein distribution, the exact transmittance of a
trilinear grid (scipy's interpolation), determinism, and the errors bad input gets. The
comparison with Mitsuba 3's volpath is in test_media_vs_mitsuba.py."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from numba import njit
from scipy import ndimage, stats

import raylume
from raylume.compile import compile_scene
from raylume.kernels.scene import Media
from raylume.kernels.shading.media import hg_eval, hg_sample, transmittance
from raylume.kernels.shading.media.tracking import SCATTERED, free_flight
from raylume.scene.document import scene_from_dict

# --- helpers ------------------------------------------------------------------------------------


def scene(**tables) -> raylume.Scene:
    return raylume.Scene.model_validate(tables)


def seeds_mean(s: raylume.Scene, seeds: range, **kw) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel mean over renders with independent seeds, and its standard error."""
    images = np.stack([np.asarray(raylume.render(s.with_render(seed=seed), **kw).rgb, np.float64) for seed in seeds])
    return images.mean(0), images.std(0, ddof=1) / math.sqrt(len(seeds))


def media_view(s: raylume.Scene) -> Media:
    k = compile_scene(s).kernel
    return Media(
        k.medium_data,
        k.medium_density,
        k.medium_majorants,
        k.medium_interface,
        k.camera_medium,
        k.media_present,
        k.pass_through,
    )


CLOSED_BOX = "box.obj"


def write_box(folder, size=2.0) -> str:
    import trimesh

    trimesh.creation.box(extents=(size, size, size)).export(folder / CLOSED_BOX)
    return str(folder / CLOSED_BOX)


# --- Beer-Lambert ----------------------------------------------------------------------------------

SIGMA_A = (0.2, 0.5, 1.1)
EMISSION = (1.0, 2.0, 4.0)
WALL_Z = 2.0


def absorbing_scene(medium: dict) -> raylume.Scene:
    """The camera in an absorbing medium looking at an emitting wall WALL_Z ahead (a narrow view:
    every ray travels WALL_Z / cos(angle) to it)."""
    return scene(
        render={"width": 12, "height": 8, "spp": 16, "mode": "path", "max_depth": 1, "medium": "m"},
        camera={"position": [0, 0, 0], "look_at": [0, 0, 1], "fov": 10},
        media={"m": medium},
        objects=[
            {"type": "quad", "position": [0, 0, WALL_Z], "u": [10, 0, 0], "v": [0, 10, 0],
             "material": {"type": "diffuse", "color": [0, 0, 0], "emission": list(EMISSION)}},
        ],
    )  # fmt: skip


def expected_beer_lambert(s: raylume.Scene) -> np.ndarray:
    origins, directions = raylume.camera_rays(s)
    distance = WALL_Z / directions[..., 2]
    return np.asarray(EMISSION) * np.exp(-np.asarray(SIGMA_A) * distance[..., None])


@pytest.mark.parametrize(
    "medium",
    [
        {"type": "homogeneous", "sigma_a": list(SIGMA_A)},
        {"type": "grid", "density": "ones.npy", "bounds_min": [-5, -5, -1], "bounds_max": [5, 5, 5],
         "sigma_a": list(SIGMA_A)},
    ],
    ids=["homogeneous", "constant grid"],
)  # fmt: skip
def test_an_absorbing_medium_attenuates_an_emitter_by_beer_lambert(medium, tmp_path):
    np.save(tmp_path / "ones.npy", np.ones((3, 4, 5), np.float32))
    s = absorbing_scene(medium).with_base_dir(tmp_path)
    mean, se = seeds_mean(s, range(8))
    expected = expected_beer_lambert(s)
    # pixel centres' distances; samples spread over the pixel change them by < 1e-5 relative.
    # Every pixel's estimate has the same distribution to 1% (the view is 10 degrees wide), so
    # each channel's standard error is pooled over the pixels: one pixel's own, from 8 seeds of
    # a few transmitted samples, is a poor estimate (0 where every seed happened to count one).
    pooled = np.sqrt((se**2).mean(axis=(0, 1)))
    random = pooled > 0  # the grid's tracking is random; the homogeneous medium's transmittance exact
    z = (mean - expected)[..., random] / pooled[random]
    assert np.all(np.abs(z) < 5.5), np.abs(z).max()
    exact = ~random
    assert np.all(np.abs(mean - expected)[..., exact] < 1e-4 * expected[..., exact])
    # the whole image per channel, more precisely
    image_z = (mean.mean((0, 1)) - expected.mean((0, 1))) / (se.mean((0, 1)) / math.sqrt(mean[..., 0].size) + 1e-12)
    assert np.all(np.abs(image_z) < 4.5 * math.sqrt(mean[..., 0].size)), image_z


def test_a_medium_whose_null_coefficient_rounds_below_zero_loses_no_samples():
    """sigma_a + sigma_s of the densest channel is the majorant, and mu - sigma_a - sigma_s rounds
    to -1e-17 there for these coefficients: without clamping the null coefficient at 0, spectral
    tracking turned a sixth of the samples' throughputs negative, and they were rejected (the
    green channel 27% dark). Every sample counts, and the wall is Beer-Lambert's with sigma_t."""
    sigma_a, sigma_s = (0.5, 0.3, 0.1), (0.0001, 0.0001, 0.0001)
    s = absorbing_scene({"type": "homogeneous", "sigma_a": list(sigma_a), "sigma_s": list(sigma_s)})
    assert raylume.render(s).stats["rejected_samples"] == 0
    mean, se = seeds_mean(s, range(8))
    origins, directions = raylume.camera_rays(s)
    distance = WALL_Z / directions[..., 2]
    expected = np.asarray(EMISSION) * np.exp(-np.add(sigma_a, sigma_s) * distance[..., None])
    # (spectral tracking's estimate is unbiased; the rays that scatter, at most 1 - exp(-0.0001
    # * 2.1) of them, end there at max_depth 1, as the expectation's sigma_t says)
    n = mean[..., 0].size
    image_z = (mean.mean((0, 1)) - expected.mean((0, 1))) / (np.sqrt((se**2).sum((0, 1))) / n + 1e-12)
    assert np.all(np.abs(image_z) < 4.5), image_z


# --- the white furnace ---------------------------------------------------------------------------


def furnace(medium: dict, tmp_path, boundary: str = "sphere") -> raylume.Scene:
    shape = (
        {"type": "sphere", "center": [0, 0, 0], "radius": 1.0}
        if boundary == "sphere"
        else {"type": "mesh", "file": write_box(tmp_path)}
    )
    return scene(
        render={"width": 10, "height": 10, "spp": 16, "mode": "path"},
        camera={"position": [0, 0, -3], "look_at": [0, 0, 0], "fov": 45},
        environment={"color": [1, 1, 1]},
        media={"m": medium},
        objects=[{**shape, "material": {"type": "null"}, "interior": "m"}],
    ).with_base_dir(tmp_path)


@pytest.mark.parametrize(
    "medium, boundary",
    [
        ({"type": "homogeneous", "sigma_s": 2.0, "g": 0.0}, "sphere"),
        ({"type": "homogeneous", "sigma_s": [0.5, 2.0, 6.0], "g": 0.7}, "sphere"),
        ({"type": "grid", "density": "noise.npy", "bounds_min": [-1, -1, -1], "bounds_max": [1, 1, 1],
          "sigma_s": [1.0, 3.0, 8.0], "g": -0.4}, "box"),
    ],
    ids=["grey isotropic", "chromatic forward", "chromatic grid backward"],
)  # fmt: skip
def test_a_white_furnace_medium_disappears(medium, boundary, tmp_path):
    """Albedo 1 under a uniform environment of radiance 1: every path returns 1, whatever the
    medium scatters (a check of tracking, next-event estimation through the boundary, MIS and
    roulette together)."""
    rng = np.random.default_rng(7)
    np.save(tmp_path / "noise.npy", ndimage.gaussian_filter(rng.random((9, 10, 11)), 1.5).astype(np.float32) * 2)
    mean, se = seeds_mean(furnace(medium, tmp_path, boundary), range(6))
    for c in range(3):
        values = mean[..., c].ravel()
        se_mean = values.std(ddof=1) / math.sqrt(values.size)  # pixels are independent
        assert abs(values.mean() - 1.0) < 4.5 * max(se_mean, 1e-6), (c, values.mean(), se_mean)


def test_a_furnace_medium_that_absorbs_is_darker(tmp_path):
    mean, _ = seeds_mean(furnace({"type": "homogeneous", "sigma_s": 2.0, "sigma_a": 0.5}, tmp_path), range(2))
    assert mean[4:6, 4:6].mean() < 0.8  # through the middle: lost to absorption
    assert mean.max() <= 1.0 + 0.25


# --- the phase function and tracking on their own ---------------------------------------------------


@pytest.mark.parametrize("g", [-0.8, 0.0, 0.3, 0.9])
def test_henyey_greenstein_sampling_follows_its_pdf(g):
    """cos(theta) of HG samples against the pdf's integral over 40 bins (chi-square), and the
    pdf integrates to 1 over the sphere."""
    n = 200_000
    u = np.random.default_rng(1).random((n, 2))
    cos = sample_cosines(g, u)
    edges = np.linspace(-1.0, 1.0, 41)
    counts, _ = np.histogram(cos, edges)
    fine = np.linspace(-1.0, 1.0, 400_001)
    density = 2 * math.pi * np.array([hg_eval(g, c) for c in fine[::1000]])  # coarse check of the call
    pdf = 2 * math.pi * (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * fine) ** 1.5)
    assert np.allclose(density, pdf[::1000])
    cdf = np.concatenate([[0.0], np.cumsum((pdf[1:] + pdf[:-1]) / 2 * np.diff(fine))])
    assert abs(cdf[-1] - 1.0) < 1e-6
    expected = n * np.diff(np.interp(edges, fine, cdf))
    keep = expected > 5
    chi2 = (((counts - expected) ** 2) / expected)[keep].sum()
    assert stats.chi2.sf(chi2, keep.sum() - 1) > 1e-4, chi2


@njit(cache=False)
def _cosines(g, u):
    out = np.empty(len(u))
    d = (0.0, 0.6, 0.8)
    for i in range(len(u)):
        w, _ = hg_sample(g, d, u[i, 0], u[i, 1])
        out[i] = w[0] * d[0] + w[1] * d[1] + w[2] * d[2]
    return out


def sample_cosines(g, u):
    return _cosines(g, u)


@njit(cache=False)
def _transmittances(Md, o, d, tmax, n):
    out = np.empty((n, 3))
    for i in range(n):
        tr = transmittance(Md, 0, o, d, tmax, np.uint64(i) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(1))
        out[i, 0], out[i, 1], out[i, 2] = tr
    return out


def test_ratio_tracking_matches_the_exact_transmittance_of_a_grid(tmp_path):
    """The mean of many ratio-tracking estimates along a ray through a grid against
    exp(-integral of sigma_t), the integral by scipy's trilinear interpolation on a fine step."""
    rng = np.random.default_rng(3)
    density = ndimage.gaussian_filter(rng.random((6, 7, 8)), 1.0) * 0.8
    density[:, :, :2] = 0.0  # empty space: majorant cells of 0 are stepped over
    np.save(tmp_path / "d.npy", density.astype(np.float32))
    lo, hi = np.array([-1.0, -2.0, 0.0]), np.array([3.0, 1.0, 2.0])
    sigma = np.array([0.5, 1.0, 2.0])
    s = scene(
        media={"m": {"type": "grid", "density": "d.npy", "bounds_min": lo.tolist(), "bounds_max": hi.tolist(),
                     "sigma_a": (sigma * 0.3).tolist(), "sigma_s": (sigma * 0.7).tolist()}},
        objects=[{"type": "sphere", "center": [0, 0, 0], "radius": 1}],
    ).with_base_dir(tmp_path)  # fmt: skip
    Md = media_view(s)
    o = np.array([-2.0, 0.5, 0.3])
    d = np.array([1.0, -0.6, 0.4])
    d /= np.linalg.norm(d)
    tmax = 6.0
    estimates = _transmittances(Md, tuple(o), tuple(d), tmax, 40_000)
    ts = np.linspace(0, tmax, 120_001)
    p = o + ts[:, None] * d
    inside = np.all((p >= lo) & (p <= hi), axis=1)
    coords = ((p - lo) / (hi - lo) * np.array(density.shape[::-1]) - 0.5)[:, ::-1].T  # (z, y, x)
    dens = np.where(inside, ndimage.map_coordinates(density, coords, order=1, mode="nearest"), 0.0)
    optical = np.trapezoid(dens, ts) * sigma
    exact = np.exp(-optical)
    se = estimates.std(0, ddof=1) / math.sqrt(len(estimates))
    assert np.all(np.abs(estimates.mean(0) - exact) < 4.5 * se + 1e-4), (estimates.mean(0), exact, se)
    assert 0.02 < exact.min() and exact.max() < 0.9  # the ray does pass through the medium


def test_free_flights_scatter_where_a_homogeneous_medium_says():
    """Grey medium: distances to the first scattering are exponential with rate sigma_t (the
    fraction absorbed sigma_a / sigma_t)."""
    s = scene(media={"m": {"type": "homogeneous", "sigma_a": 0.5, "sigma_s": 1.5}},
              objects=[{"type": "sphere", "center": [0, 0, 0], "radius": 1}])  # fmt: skip
    Md = media_view(s)
    status, t = _flights(Md, 20_000)
    scattered = status == SCATTERED
    assert abs(scattered.mean() - 0.75) < 4.5 * math.sqrt(0.75 * 0.25 / len(status))
    assert stats.kstest(t[scattered], stats.expon(scale=1 / 2.0).cdf).pvalue > 1e-4


@njit(cache=False)
def _flights(Md, n):
    status = np.empty(n, np.int64)
    ts = np.empty(n)
    for i in range(n):
        st, t, _ = free_flight(
            Md, 0, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1e9, np.uint64(i) * np.uint64(7919) + np.uint64(3), (1.0, 1.0, 1.0)
        )
        status[i] = st
        ts[i] = t
    return status, ts


# --- rendering as users do it ---------------------------------------------------------------------

FOG = {
    "render": {"width": 24, "height": 16, "spp": 4, "mode": "path", "medium": "fog"},
    "camera": {"position": [0, 1, -4], "look_at": [0, 0.5, 0], "fov": 50},
    "media": {"fog": {"type": "homogeneous", "sigma_s": 0.3, "sigma_a": 0.05, "g": 0.4},
              "milk": {"type": "homogeneous", "sigma_s": [6, 7, 8], "sigma_a": [0.02, 0.05, 0.2]}},
    "lights": [{"type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0], "intensity": 20, "angle": 25}],
    "objects": [
        {"type": "plane", "material": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}},
        {"type": "sphere", "center": [0, 0.6, 0], "radius": 0.5, "material": {"type": "dielectric", "ior": 1.4},
         "interior": "milk"},
    ],
}  # fmt: skip


def test_media_renders_are_bit_identical_across_threads_and_crops():
    s = scene(**FOG)
    a = raylume.render(s, threads=1)
    b = raylume.render(s, threads=2)
    assert np.array_equal(a.rgb, b.rgb)
    assert np.isfinite(a.rgb).all() and a.rgb.min() >= 0 and a.rgb.max() > 0
    crop = raylume.render(s, crop=(5, 17, 3, 11))
    assert np.array_equal(crop.rgb, a.rgb[3:11, 5:17])


def test_fog_is_lit_by_the_spot_light_inside_its_cone():
    """In-scattered light: with the fog, the air in the spot's cone is brighter than beside it."""
    s = scene(**{**FOG, "objects": FOG["objects"][:1]}).replace(render={"spp": 16, "width": 32, "height": 24})
    lit = raylume.render(s).rgb
    clear = raylume.render(s.replace(render={"medium": None})).rgb
    sky_rows = slice(0, 6)  # above the floor's horizon: only fog there
    assert clear[sky_rows].max() == 0.0
    cone, side = lit[sky_rows, 13:19], lit[sky_rows, :4]
    # medians: at 16 samples, one firefly of light scattered twice into the air beside the cone
    # can outweigh the whole cone's mean (2.3 in one pixel; 1024 samples give 0.064 against 0.009)
    assert np.median(cone) > 3 * np.median(side)
    assert side.mean() > 0  # light scattered more than once reaches it


@pytest.mark.parametrize("mode", ["trace", "cast", "raster"])
def test_other_modes_show_the_boundaries_and_say_media_need_path_mode(mode):
    s = scene(**FOG).replace(render={"mode": mode, "max_depth": 2}, lights=[{"type": "ambient", "intensity": 1}])
    with pytest.warns(raylume.SceneWarning, match="path mode"):
        image = raylume.render(s)
    assert np.isfinite(image.rgb).all()


# --- bad input --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "change, key",
    [
        ({"render": {"medium": "smoke"}}, "render.medium"),
        ({"objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "interior": "smoke"}]},
         "objects[0].interior"),
        ({"objects": [{"type": "quad", "u": [1, 0, 0], "v": [0, 1, 0], "interior": "fog"}]}, "interior"),
        ({"objects": [{"type": "plane", "interior": "fog"}]}, "interior"),
        ({"objects": [{"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 1, 0], "radius": 1, "capped": False,
                       "interior": "fog"}]}, "interior"),
        ({"media": {"fog": {"type": "homogeneous", "g": 1.0}}}, "media.fog.g"),
        ({"media": {"fog": {"type": "homogeneous", "sigma_s": [1, -1, 1]}}}, "media.fog.sigma_s"),
        ({"media": {"fog": {"type": "smoke"}}}, "media.fog"),
        ({"media": {"fog": {"type": "grid", "density": "d.npy", "bounds_min": [0, 0, 0], "bounds_max": [1, 0, 1]}}},
         "media.fog"),
    ],
)  # fmt: skip
def test_bad_media_are_one_error_naming_the_key(change, key):
    base = {"media": {"fog": {"type": "homogeneous", "sigma_s": 1}}, "render": {"mode": "path"}}
    document = {**base, **change}
    with pytest.raises(raylume.SceneError) as err:
        scene_from_dict(document)
    assert key in str(err.value), str(err.value)


@pytest.mark.parametrize(
    "array, why",
    [
        (None, "no such file"),
        (np.ones((4, 4)), "3-D"),
        (np.full((2, 2, 2), -1.0), "negative"),
        (np.full((2, 2, 2), np.nan), "not finite"),
    ],
)
def test_bad_density_grids_are_one_error_exit_2_and_no_output(array, why, tmp_path):
    if array is not None:
        np.save(tmp_path / "d.npy", array)
    (tmp_path / "s.toml").write_text(
        '[render]\nmode = "path"\nwidth = 8\nheight = 8\nmedium = "smoke"\n'
        '[media.smoke]\ntype = "grid"\ndensity = "d.npy"\nbounds_min = [0, 0, 0]\nbounds_max = [1, 1, 1]\n'
        '[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = 1\n'
    )
    out = tmp_path / "out.png"
    result = subprocess.run(
        [sys.executable, "-m", "raylume.cli", "render", str(tmp_path / "s.toml"), "-o", str(out)],
        capture_output=True, text=True,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert "media.smoke.density" in result.stderr and why in result.stderr
    assert "Traceback" not in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_an_interior_on_an_open_mesh_is_an_error(tmp_path):
    import trimesh

    open_box = trimesh.creation.box()
    open_box.faces = open_box.faces[:-2]
    open_box.export(tmp_path / "open.obj")
    s = scene(
        render={"mode": "path"},
        media={"m": {"type": "homogeneous", "sigma_s": 1}},
        objects=[{"type": "mesh", "file": "open.obj", "interior": "m"}],
    ).with_base_dir(tmp_path)
    with pytest.raises(raylume.SceneError, match=r"objects\[0\]\.interior: the mesh is not closed"):
        compile_scene(s)


def test_which_medium_surrounds_each_object(tmp_path):
    """A milk sphere inside a glass sphere inside fog: the milk's outside is the glass's clear
    inside, the glass's outside the fog; a diffuse ball in the fog is filled with it."""
    s = scene(
        render={"mode": "path", "medium": "fog"},
        media={"fog": {"type": "homogeneous", "sigma_s": 0.1}, "milk": {"type": "homogeneous", "sigma_s": 5}},
        objects=[
            {"type": "sphere", "center": [0, 0, 0], "radius": 2, "material": {"type": "dielectric"}},
            {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "null"}, "interior": "milk"},
            {"type": "sphere", "center": [5, 0, 0], "radius": 1, "material": {"type": "diffuse"}},
            {"type": "mesh", "file": write_box(tmp_path, 0.5), "material": {"type": "null"}, "interior": "milk"},
        ],
    ).with_base_dir(tmp_path)
    fog, milk, clear = 0, 1, -1
    interface = compile_scene(s).kernel.medium_interface
    assert interface.tolist() == [[clear, fog], [milk, clear], [fog, fog], [milk, milk]]


@pytest.mark.parametrize(
    ("position", "warned"),
    [([0, 0, 0.2], "objects[1] (medium: 'milk')"), ([0, 0, 1.5], "objects[0] (medium: none)"), ([0, 0, -3], None)],
)
def test_a_camera_inside_a_filled_object_is_warned_about(position, warned, tmp_path):
    """A camera sits in the outer medium (DESIGN 7), whatever it is inside: path mode's camera rays
    see none of a medium around it, while bdpt's light subpaths find it from the geometry. Inside
    the milk, and inside the glass (clear) in fog, it is said; outside everything, nothing is."""
    import warnings

    s = scene(
        render={"mode": "path", "medium": "fog"},
        camera={"position": position, "look_at": [0, 0, 5]},
        media={"fog": {"type": "homogeneous", "sigma_s": 0.1}, "milk": {"type": "homogeneous", "sigma_s": 5}},
        objects=[
            {"type": "sphere", "center": [0, 0, 0], "radius": 2, "material": {"type": "dielectric"}},
            {"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "null"}, "interior": "milk"},
        ],
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        compile_scene(s)
    said = [str(w.message) for w in caught if issubclass(w.category, raylume.SceneWarning)]
    if warned is None:
        assert said == []
    else:
        assert len(said) == 1 and warned in said[0] and "[render] medium: 'fog'" in said[0], said


def test_an_animation_whose_camera_flies_into_a_filled_object_is_warned_about():
    """An animation renders from its frames' cameras, not [camera]'s: one that flies into the
    milk at its last frame is named, with the frame (this went unsaid: only [camera] was checked)."""
    import warnings

    s = scene(
        render={"mode": "path"},
        camera={"position": [0, 0, -3], "look_at": [0, 0, 5]},
        media={"milk": {"type": "homogeneous", "sigma_s": 5}},
        objects=[{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": {"type": "null"},
                  "interior": "milk"}],
        animation={"frames": 6, "interpolation": "linear",
                   "camera": [{"frame": 0, "position": [0, 0, -3]}, {"frame": 5, "position": [0, 0, 0]}]},
    )  # fmt: skip
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        compile_scene(s)
    said = [str(w.message) for w in caught if issubclass(w.category, raylume.SceneWarning)]
    assert len(said) == 1 and "the camera at (0, 0, -0.6) (frame 4 of the animation) is inside objects[0]" in said[0]
