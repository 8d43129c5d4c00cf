"""The real-time filter of moving frames (raylume.svgf): on images whose answer is known from
numpy: a noisy constant keeps its mean and loses its noise, a crease in the normals is not
blurred across, a still camera accumulates, a moving one reprojects its history onto the same
world points, and nothing it is given makes it output NaN or infinity."""

from __future__ import annotations

import numpy as np
import pytest

import raylume
from raylume.kernels.film.camera import camera_of
from raylume.scene.model import Camera
from raylume.svgf import Svgf

W, H = 64, 48
WALL_Z = 5.0


def wall(camera: Camera, width: int = W, height: int = H, normal=(0.0, 0.0, -1.0)):
    """Depth, normals and world points of the plane z = WALL_Z seen by `camera` (numpy)."""
    origins, directions = raylume.camera_rays(camera, width, height)
    t = (WALL_Z - origins[..., 2]) / directions[..., 2]
    points = origins + directions * t[..., None]
    normals = np.broadcast_to(np.asarray(normal, dtype=np.float32), (height, width, 3)).copy()
    return t.astype(np.float32), normals, points


def frame(svgf: Svgf, rgb, depth, normals, camera: Camera, albedo=0.5, emitted=None):
    h, w = depth.shape
    albedo = np.broadcast_to(np.asarray(albedo, dtype=np.float32), (h, w, 3))
    return svgf.filter(rgb, albedo, normals, depth, camera_of(camera, w, h), emitted)


HOME = Camera(position=[0, 0, 0], look_at=[0, 0, 1], up=[0, 1, 0], fov=50)


def test_a_noisy_constant_keeps_its_mean_and_loses_its_variance():
    rng = np.random.default_rng(1)
    depth, normals, _ = wall(HOME)
    noisy = (0.5 + 0.1 * rng.standard_normal((H, W, 3))).astype(np.float32)
    out = frame(Svgf(), noisy, depth, normals, HOME)
    assert out.shape == (H, W, 3) and out.dtype == np.float32
    standard_error = noisy.std() / np.sqrt(noisy.size)
    assert abs(out.mean() - noisy.mean()) < 3 * standard_error
    assert abs(out.mean() - 0.5) < 4 * standard_error
    assert out.var() < noisy.var() / 20


@pytest.mark.parametrize("crease", [True, False])
def test_a_crease_in_the_normals_is_not_blurred_across(crease):
    """Left half 0.3, right half 0.6, both noisy, on one plane. With the right half's normals
    turned by 90 degrees (a crease) the columns beside the step keep their own side's mean;
    with the same normals they are blurred towards the other side (the control)."""
    rng = np.random.default_rng(2)
    depth, normals, _ = wall(HOME)
    half = W // 2
    if crease:
        normals[:, half:] = (-1.0, 0.0, 0.0)
    clean = np.full((H, W, 3), 0.3, dtype=np.float32)
    clean[:, half:] = 0.6
    noisy = (clean + 0.2 * rng.standard_normal((H, W, 3))).astype(np.float32)
    out = frame(Svgf(), noisy, depth, normals, HOME, albedo=1.0)
    left, right = noisy[:, :half].mean(), noisy[:, half:].mean()  # each side's own mean (numpy)
    near_left, near_right = out[:, half - 2 : half].mean(), out[:, half : half + 2].mean()
    if crease:
        assert abs(near_left - left) < 0.02 and abs(near_right - right) < 0.02
        assert out[:, :half].std() < noisy[:, :half].std() / 3  # each side is still smoothed
    else:
        assert near_left - left > 0.03 and right - near_right > 0.03


def test_a_still_camera_accumulates():
    rng = np.random.default_rng(3)
    depth, normals, _ = wall(HOME)
    temporal, full = Svgf(iterations=0), Svgf()  # temporal accumulation alone: a moving average
    errors, filtered = [], []
    for _ in range(12):
        noisy = (0.5 + 0.1 * rng.standard_normal((H, W, 3))).astype(np.float32)
        errors.append(np.sqrt(((frame(temporal, noisy, depth, normals, HOME) - 0.5) ** 2).mean()))
        filtered.append(np.sqrt(((frame(full, noisy, depth, normals, HOME) - 0.5) ** 2).mean()))
    assert np.all(temporal.history_length == 12) and np.all(full.history_length == 12)
    # Frames 1-3 (short histories) show a spatial mean; the history itself is the moving
    # average, weights 1/n up to n = 5 (the mean of the frames so far), then 0.2 (variance
    # 0.64 var + 0.04 sigma^2 a frame, from sigma^2 / 5 after the fifth).
    assert errors[0] < 0.1 / 3
    assert errors[3] == pytest.approx(0.1 / np.sqrt(4), rel=0.1)
    assert errors[4] == pytest.approx(0.1 / np.sqrt(5), rel=0.1)
    variance = 0.2
    for _ in range(7):
        variance = 0.64 * variance + 0.04
    assert errors[-1] == pytest.approx(0.1 * np.sqrt(variance), rel=0.1)
    assert filtered[-1] < filtered[0] and filtered[-1] < errors[-1] / 2


def pattern(points: np.ndarray) -> np.ndarray:
    """A smooth pattern fixed on the wall (world coordinates), as RGB."""
    value = 0.5 + 0.4 * np.sin(3.0 * points[..., 0]) * np.cos(2.0 * points[..., 1])
    return np.repeat(value[..., None], 3, axis=2).astype(np.float32)


def test_a_moving_camera_reprojects_its_history_onto_the_same_points():
    """A pattern fixed on the wall, seen by a camera that slides and turns: with temporal
    accumulation alone the output is the pattern itself (history and frame agree where the
    reprojection follows the wall's points). A history kept at the same pixels would smear it
    (the control: that moving average, in numpy)."""
    svgf = Svgf(iterations=0)
    naive = None
    for step in range(6):
        camera = Camera(position=[0.15 * step, 0.05 * step, 0], look_at=[0.1 * step, 0, 1], up=[0, 1, 0], fov=50)
        depth, normals, points = wall(camera)
        rgb = pattern(points)
        out = frame(svgf, rgb, depth, normals, camera, albedo=1.0)
        naive = rgb if naive is None else naive + max(0.2, 1 / (step + 1)) * (rgb - naive)
    kept = svgf.history_length == 6  # pixels on screen all along (short histories show a spatial mean)
    assert kept.mean() > 0.6
    assert np.abs(out - rgb)[kept].max() < 0.02
    assert np.abs(naive - rgb)[kept].max() > 0.2


def test_a_frame_of_another_size_reprojects_too():
    """Four frames at one size, then one at half the size: its history is the first frames'
    resampled (bilinear) at its pixels, and the pattern stays where it was."""
    svgf = Svgf(iterations=0)
    depth, normals, points = wall(HOME)
    for _ in range(4):
        frame(svgf, pattern(points), depth, normals, HOME, albedo=1.0)
    depth, normals, points = wall(HOME, W // 2, H // 2)
    out = frame(svgf, pattern(points), depth, normals, HOME, albedo=1.0)
    assert out.shape == (H // 2, W // 2, 3)
    assert np.all(svgf.history_length == 5)
    assert np.abs(out - pattern(points)).max() < 0.02


def test_a_moved_object_starts_a_new_history():
    """Where the depth jumps (another surface now), the history is rejected: the pixel shows
    the new frame, not a blend with the old surface's light."""
    svgf = Svgf(iterations=0)
    depth, normals, _ = wall(HOME)
    frame(svgf, np.full((H, W, 3), 0.2, np.float32), depth, normals, HOME, albedo=1.0)
    nearer = depth.copy()
    nearer[:, : W // 2] *= 0.5  # the left half now sees a plane twice as near
    out = frame(svgf, np.full((H, W, 3), 0.8, np.float32), nearer, normals, HOME, albedo=1.0)
    assert np.all(svgf.history_length[:, : W // 2] == 1) and np.all(svgf.history_length[:, W // 2 + 1 :] == 2)
    np.testing.assert_allclose(out[:, : W // 2], 0.8, rtol=1e-5)
    # the second frame: weight 1/2 (short histories show a spatial mean, over the same wall only)
    np.testing.assert_allclose(out[:, W // 2 + 1 :], 0.2 + 0.5 * (0.8 - 0.2), atol=1e-3)


def test_nothing_makes_it_output_nan_or_infinity():
    rng = np.random.default_rng(4)
    depth, normals, _ = wall(HOME)
    depth[:8] = np.inf  # the background: nothing hit
    albedo = rng.random((H, W, 3)).astype(np.float32)
    rgb = albedo * rng.random((H, W, 3)).astype(np.float32)  # light below 1, reflected
    rgb[:8] = (0.1, 0.2, 0.3)
    rgb[20, 20] = np.nan
    rgb[21, 21] = np.inf
    rgb[22, 22] = -1.0
    albedo[10:20, 10:20] = 0.0  # a black emitter
    rgb[10:20, 10:20] = 5.0
    normals[30, 30] = 0.0  # no normal
    svgf = Svgf()
    for _ in range(3):
        out = svgf.filter(rgb, albedo, normals, depth, camera_of(HOME, W, H))
        assert np.all(np.isfinite(out)) and out.min() >= 0.0
    np.testing.assert_array_equal(out[:8], rgb[:8])  # the background passes unfiltered
    np.testing.assert_allclose(out[12:18, 12:18], 5.0, rtol=1e-5)  # the emitter keeps its light ...
    around = np.ones((H, W), bool)
    around[:8] = around[10:20, 10:20] = False
    assert out[around].max() < 1.2  # ... and does not bleed into its surroundings


def test_the_emitted_part_is_added_back_unfiltered():
    rng = np.random.default_rng(5)
    depth, normals, _ = wall(HOME)
    emitted = (3.0 * rng.random((H, W, 3))).astype(np.float32)
    out = frame(Svgf(), emitted, depth, normals, HOME, albedo=0.7, emitted=emitted)  # no light but emission
    np.testing.assert_allclose(out, emitted, rtol=1e-6)


def test_bad_shapes_are_refused():
    depth, normals, _ = wall(HOME)
    with pytest.raises(ValueError, match="albedo"):
        Svgf().filter(np.zeros((H, W, 3)), np.zeros((H, W)), normals, depth, camera_of(HOME, W, H))
