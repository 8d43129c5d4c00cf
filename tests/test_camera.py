"""Camera rays at the corners and centre, against DESIGN.md's formula and the seed's viewport."""

from __future__ import annotations

import math

import numpy as np
import pytest

import raylume
from raylume.kernels.film.camera import camera_frame, camera_ray


def _ray(pos, look, up, fov, W, H, i, j):
    cam = camera_frame(pos, look, up, fov, W, H)
    o, d = camera_ray(cam, i + 0.5, j + 0.5, W, H)
    return np.array(o), np.array(d)


def test_default_camera_centre_looks_along_plus_z():
    o, d = _ray((0, 0, 0), (0, 0, 1), (0, 1, 0), 53.13, 3, 3, 1, 1)
    np.testing.assert_allclose(o, 0)
    np.testing.assert_allclose(d, (0, 0, 1), atol=1e-15)


def test_seed_viewport_corners():
    """The seed: viewport 1 x 1 at distance 1; pixel (0, 0) is the top-left, +x to the right."""
    W = H = 600
    h = math.tan(math.radians(53.13) / 2)
    for (i, j), (sx, sy) in {
        (0, 0): (-1, 1),
        (W - 1, 0): (1, 1),
        (0, H - 1): (-1, -1),
        (W - 1, H - 1): (1, -1),
    }.items():
        _, d = _ray((0, 0, 0), (0, 0, 1), (0, 1, 0), 53.13, W, H, i, j)
        v = d / d[2]  # back onto the viewport plane z = 1
        expected = (sx * (1 - 1 / W) * h, sy * (1 - 1 / H) * h)
        np.testing.assert_allclose(v[:2], expected, atol=1e-12)
        assert abs(v[0]) < 0.5 and abs(v[1]) < 0.5  # the seed's Vw = Vh = 1


def test_aspect_ratio_widens_horizontal_field():
    W, H = 200, 100
    _, d = _ray((0, 0, 0), (0, 0, 1), (0, 1, 0), 90, W, H, W - 1, H // 2)
    # vertical half-extent tan(45) = 1, so the horizontal half-extent is 2
    assert d[0] / d[2] == pytest.approx(2 * (1 - 1 / W), rel=1e-12)


def test_left_handed_frame_for_arbitrary_camera():
    pos, look, up = np.array([1.0, 2.0, 3.0]), np.array([4.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0])
    f = (look - pos) / np.linalg.norm(look - pos)
    r = np.cross(up, f)
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    W, H, fov = 64, 48, 60.0
    h = math.tan(math.radians(fov) / 2)
    w = h * W / H
    for i, j in [(0, 0), (63, 0), (0, 47), (63, 47), (31, 20)]:
        a = (i + 0.5) / W * 2 - 1
        b = 1 - (j + 0.5) / H * 2
        expected = f + r * a * w + u * b * h
        expected /= np.linalg.norm(expected)
        o, d = _ray(pos, look, up, fov, W, H, i, j)
        np.testing.assert_allclose(o, pos)
        np.testing.assert_allclose(d, expected, atol=1e-12)
    # looking down -z with y up, +x appears on the left (DESIGN.md)
    _, d_left = _ray((0, 0, 0), (0, 0, -1), (0, 1, 0), 60, 64, 64, 0, 32)
    assert d_left[0] > 0


# --- raylume.camera_rays: the same rays for the caller's own queries ---------------------------


def test_camera_rays_are_designs_rays_shaped_as_the_image():
    """Every pixel's ray by DESIGN.md's formula, written out in plain Python for each pixel."""
    import raylume

    pos, look, up, fov, W, H = (1.0, 2.0, 3.0), (4.0, 0.0, -1.0), (0.0, 1.0, 0.2), 60.0, 7, 5
    origins, directions = raylume.camera_rays(raylume.Camera(position=pos, look_at=look, up=up, fov=fov), W, H)
    assert origins.shape == directions.shape == (H, W, 3)
    assert origins.dtype == directions.dtype == np.float64

    def unit(v):
        n = math.sqrt(sum(c * c for c in v))
        return [c / n for c in v]

    f = unit([b - a for a, b in zip(pos, look)])
    r = unit([up[1] * f[2] - up[2] * f[1], up[2] * f[0] - up[0] * f[2], up[0] * f[1] - up[1] * f[0]])
    u = [f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2], f[0] * r[1] - f[1] * r[0]]
    h = math.tan(math.radians(fov) / 2)
    w = h * W / H
    for j in range(H):
        for i in range(W):
            a = (i + 0.5) / W * 2 - 1
            b = 1 - (j + 0.5) / H * 2
            expected = unit([f[k] + r[k] * a * w + u[k] * b * h for k in range(3)])
            np.testing.assert_allclose(directions[j, i], expected, rtol=0, atol=1e-15)
            assert tuple(origins[j, i]) == pos


def test_camera_rays_take_a_scenes_camera_and_size_and_refuse_what_is_not_an_image():
    import raylume

    scene = raylume.scene_from_dict({"render": {"width": 12, "height": 9}, "camera": {"position": [0, 1, -4]}})
    origins, directions = raylume.camera_rays(scene)
    assert directions.shape == (9, 12, 3)
    np.testing.assert_array_equal(directions, raylume.camera_rays(scene.camera, 12, 9)[1])
    assert raylume.camera_rays(scene, 4, 3)[1].shape == (3, 4, 3)  # the arguments win
    with pytest.raises(TypeError, match="width and height"):
        raylume.camera_rays(scene.camera)
    with pytest.raises(TypeError, match="Camera or raylume.Scene"):
        raylume.camera_rays({"position": [0, 0, 0]}, 4, 4)
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match="width"):
            raylume.camera_rays(scene, bad, 4)


def test_a_look_at_any_distance_away_frames_the_same_view():
    """Only the direction to look_at counts. One 1e-300 away was refused as 'up parallel to the
    viewing direction': the frame test's squares underflowed to 0."""
    scene = {"objects": [{"type": "sphere", "center": [0.5, 0, 3], "radius": 1}]}
    near = raylume.scene_from_dict({**scene, "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1e-300]}})
    far = raylume.scene_from_dict({**scene, "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1]}})
    a, b = (raylume.render(s, width=8, height=6, mode="cast").aovs["object"] for s in (near, far))
    np.testing.assert_array_equal(a, b)
    assert (a == 0).any() and (a == -1).any()
