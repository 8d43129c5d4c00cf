"""Denoising with the light the camera sees directly kept apart (raylume.seen_light), checked
against an emitter's exact pixel coverage and against hand-made masks."""

import math

import numpy as np
import pytest

import raylume
import raylume.seen_light as sl
from raylume.denoise import is_available

needs_oidn = pytest.mark.skipif(not is_available(), reason="pyoidn (raylume[denoise]) is not installed")

W = 64
LE = np.array([6.0, 4.0, 2.0])
# A quad facing the camera at z = 2. With fov 2 atan(1/2) the image spans [-1, 1] in x and y
# there, so pixel (i, j) is the square [-1 + 2i/W, -1 + 2(i+1)/W] x [1 - 2(j+1)/W, 1 - 2j/W]
# (DESIGN.md's camera: pixel (0, 0) at the top left, +x to the right).
X0, X1, Y0, Y1 = -0.33, 0.21, -0.27, 0.3


def _quad_scene():
    return raylume.scene_from_dict(
        {
            "render": {"width": W, "height": W, "mode": "path"},
            "camera": {"fov": math.degrees(2 * math.atan(0.5))},
            "materials": {"light": {"type": "diffuse", "color": [0, 0, 0], "emission": LE.tolist()}},
            "objects": [
                {
                    "type": "quad",
                    "position": [(X0 + X1) / 2, (Y0 + Y1) / 2, 2],
                    "u": [X1 - X0, 0, 0],
                    "v": [0, Y1 - Y0, 0],
                    "material": "light",
                }
            ],
        }
    )


def _coverage() -> np.ndarray:
    """(W, W): the fraction of each pixel the quad covers."""
    edges = -1 + 2 * np.arange(W + 1) / W
    across = np.clip(np.minimum(edges[1:], X1) - np.maximum(edges[:-1], X0), 0, None) * W / 2
    down = np.clip(np.minimum(-edges[:-1], Y1) - np.maximum(-edges[1:], Y0), 0, None) * W / 2
    return down[:, None] * across[None, :]


@needs_oidn
def test_emitter_interior_is_exact_and_its_edges_get_more_samples(monkeypatch):
    monkeypatch.setattr(sl, "EDGE_BUDGET", 1e9)  # the edge tiles always get EDGE_FACTOR x the samples
    spp = 4
    img = raylume.Session(_quad_scene()).render(spp=spp, denoise=True, seed=7)
    coverage = _coverage()
    assert img.stats["denoise_edge_spp"] == sl.EDGE_FACTOR * spp
    partial = (coverage > 0) & (coverage < 1)
    assert img.stats["denoise_edge_pixels"] >= partial.sum()
    rgb = np.asarray(img.rgb, np.float64)
    # Nothing else in the scene reflects or emits: inside the quad the image is its radiance
    # and outside nothing, up to what OIDN makes of an image of zeros (about 1e-6).
    inside = rgb[coverage == 1]
    np.testing.assert_allclose(inside, np.broadcast_to(LE, inside.shape), rtol=1e-5)
    assert np.abs(rgb[coverage == 0]).max() < 1e-5 * LE.max()
    # On the edges, the mean of n x n jittered strata misses a straight edge by at most 1/n per
    # edge crossing the pixel (two at a corner): n = 8 with the edge's 64 samples, 2 with 4.
    found = rgb[partial] / LE
    assert np.abs(found - coverage[partial, None]).max() <= 2 / 8 + 1e-9
    noisy = np.asarray(img.aovs["noisy"], np.float64)[partial] / LE
    rms = lambda e: float(np.sqrt(np.mean((e - coverage[partial, None]) ** 2)))  # noqa: E731
    assert rms(found) < 0.5 * rms(noisy), (rms(found), rms(noisy))


def test_first_segment_is_part_of_the_render():
    """The max_depth 1 pass traces the render's own camera rays: the emitter seen directly is
    never more than what the path-traced pixel holds (the split's remainder is >= 0)."""
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 24, "height": 24, "mode": "path", "spp": 3},
            "camera": {"position": [0, 0, -3], "fov": 40},
            "materials": {
                "lamp": {"type": "diffuse", "color": [0, 0, 0], "emission": [5, 5, 5]},
                "wall": {"type": "diffuse", "color": [0.7, 0.7, 0.7]},
            },
            "objects": [
                {"type": "sphere", "center": [0.4, 0.1, 0], "radius": 0.5, "material": "lamp"},
                {"type": "plane", "point": [0, 0, 1], "normal": [0, 0, -1], "material": "wall"},
            ],
        }
    )
    session = raylume.Session(scene)
    full = session.render(seed=5, aovs=False).rgb
    settings = scene.render.model_copy(update={"seed": 5})
    seen = sl.first_segment(session.compiled, scene.camera, settings, (0, 24, 0, 24), lanes=1).rgb
    assert seen.max() == pytest.approx(5.0) and 0 < (seen > 0).mean() < 1
    assert np.all(full - seen >= -1e-5 * np.maximum(full, 1.0))


def test_edge_mask_marks_both_sides_of_a_step_and_not_a_gentle_slope():
    img = np.zeros((6, 8, 3))
    img[:, 4:] = 1.0
    mask = sl.edge_mask(img)
    assert mask[:, 3:5].all() and not mask[:, :3].any() and not mask[:, 5:].any()
    slope = np.broadcast_to(1.0 + 0.001 * np.arange(8)[None, :, None], (6, 8, 3))
    assert not sl.edge_mask(slope).any()


def test_edge_windows_merge_runs_of_tiles_and_stay_inside_the_image():
    mask = np.zeros((10, 13), bool)
    mask[1, 1] = mask[2, 5] = True  # tiles (0, 0) and (0, 1): one run
    mask[9, 12] = True  # the last, partial tile
    assert sl.edge_windows(mask, tile=4) == [(0, 8, 0, 4), (12, 13, 8, 10)]


def test_edge_spp_respects_the_budget():
    assert sl.edge_spp(16, 10_000, 0) == 0
    assert sl.edge_spp(16, 65_536, 1_000) == sl.EDGE_FACTOR * 16
    # many edge pixels: the budget allows fewer than the render's own samples, so none are added
    assert sl.edge_spp(16, 10_000, 10_000) == 0
    assert sl.edge_spp(4096, 65_536, 10) == 0  # MAX_SPP caps it
