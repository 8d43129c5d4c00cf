"""The viewer's gestures (raylume.viewer.camera_control) against hand-computed cameras."""

from __future__ import annotations

import math

import pytest

from raylume.viewer import camera_control as cc


def close(a, b, tol=1e-12):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def test_camera_frame_is_designs_left_handed_frame():
    f, r, u = cc.camera_frame((0, 0, 0), (0, 0, 1), (0, 1, 0))
    assert close(f, (0, 0, 1)) and close(r, (1, 0, 0)) and close(u, (0, 1, 0))


def test_orbit_right_by_half_the_height_turns_the_camera_a_quarter_to_its_left():
    # height 100: 50 px is pi/2. Camera at the origin looking at (0, 0, 3): it goes round the
    # target to (-3, 0, 3), still facing it, so the scene turns right with the cursor.
    p = cc.orbit((0, 0, 0), (0, 0, 3), (0, 1, 0), dx=50, dy=0, height=100)
    assert close(p, (-3, 0, 3), 1e-12)


def test_orbit_down_raises_the_camera():
    # 25 px of 100 is pi/4 up over the target, at the same distance 3.
    p = cc.orbit((0, 0, 0), (0, 0, 3), (0, 1, 0), dx=0, dy=25, height=100)
    s = 3 / math.sqrt(2)
    assert close(p, (0, s, 3 - s), 1e-12)


def test_orbit_stops_short_of_the_pole():
    p = cc.orbit((0, 0, 0), (0, 0, 3), (0, 1, 0), dx=0, dy=1000, height=100)
    v = (p[0], p[1], p[2] - 3)
    polar = math.acos(v[1] / math.dist(p, (0, 0, 3)))
    assert polar == pytest.approx(cc.POLE_MARGIN, abs=1e-12)
    assert math.dist(p, (0, 0, 3)) == pytest.approx(3)


def test_orbit_is_undone_by_the_opposite_drag():
    start = (1.0, 2.0, -4.0)
    p = cc.orbit(start, (0.5, 0, 3), (0, 1, 0), dx=37, dy=-12, height=240)
    q = cc.orbit(p, (0.5, 0, 3), (0, 1, 0), dx=0, dy=12, height=240)
    q = cc.orbit(q, (0.5, 0, 3), (0, 1, 0), dx=-37, dy=0, height=240)
    assert close(q, start, 1e-9)


def test_pan_moves_camera_and_target_by_the_footprint_of_a_pixel():
    # fov 90 at distance 2: the image is 4 units high, 1 unit per pixel at height 4.
    p, l = cc.pan((0, 0, 0), (0, 0, 2), (0, 1, 0), 90.0, dx=1, dy=2, height=4)
    # drag right: the camera goes left (-x); drag down: it goes up (+y)
    assert close(p, (-1, 2, 0), 1e-12) and close(l, (-1, 2, 2), 1e-12)


def test_dolly_scales_the_distance_to_look_at():
    p = cc.dolly((0, 0, 0), (0, 0, 4), delta=100)  # one wheel notch away from the user: 10 % farther
    assert close(p, (0, 0, 4 - 4.4), 1e-12)
    p = cc.dolly((0, 0, 0), (0, 0, 4), delta=-100)
    assert close(p, (0, 0, 4 - 4 / 1.1), 1e-12)
    p = cc.dolly((0, 0, 0), (0, 0, 4), delta=-1e6)  # never through the target
    assert math.dist(p, (0, 0, 4)) == pytest.approx(cc.MIN_DISTANCE)
