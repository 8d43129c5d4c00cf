"""Camera rays as DESIGN.md defines them: pixel (i, j) from the top-left, centres at +0.5;
optionally through a thin lens for depth of field."""

import math

import numpy as np
from numba import njit

from .layout import (
    CAM_FILTER,
    CAM_FILTER_NEGATIVE,
    CAM_FILTER_TABLE,
    CAM_FOCUS_DISTANCE,
    CAM_HALF_HEIGHT,
    CAM_HALF_WIDTH,
    CAM_LENS_RADIUS,
    CAM_WIDTH,
)
from .sampling import concentric_disk, filter_table
from .vec import KERNEL, madd, normalize, sub


def camera_frame(position, look_at, up, fov_degrees, width, height, aperture=0.0, focus_distance=1.0,
                 pixel_filter="box") -> np.ndarray:
    """float64 (CAM_WIDTH,): origin, forward, right * w, up * h (left-handed: r = up x f), then
    the lens (radius aperture / 2, focus distance), w, h and the pixel filter's table."""
    p = np.asarray(position, dtype=np.float64)
    f = np.asarray(look_at, dtype=np.float64) - p
    f /= np.abs(f).max()  # scale first: tiny differences must not underflow
    f /= np.linalg.norm(f)
    r = np.cross(np.asarray(up, dtype=np.float64), f)
    r /= np.abs(r).max()
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    h = math.tan(math.radians(fov_degrees) / 2.0)
    w = h * width / height
    cam = np.zeros(CAM_WIDTH, dtype=np.float64)
    cam[:12] = np.concatenate([p, f, r * w, u * h])
    cam[CAM_LENS_RADIUS] = 0.5 * aperture
    cam[CAM_FOCUS_DISTANCE] = focus_distance
    cam[CAM_HALF_WIDTH] = w
    cam[CAM_HALF_HEIGHT] = h
    kind, negative, table = filter_table(pixel_filter)
    cam[CAM_FILTER] = kind
    cam[CAM_FILTER_NEGATIVE] = negative
    cam[CAM_FILTER_TABLE:] = table
    return cam


@njit(**KERNEL)
def camera_ray(cam, x, y, width, height):
    """Unit direction through the image point (x, y) in pixels; (i + 0.5, j + 0.5) is a centre."""
    a = x / width * 2.0 - 1.0
    b = 1.0 - y / height * 2.0
    d = (
        cam[3] + cam[6] * a + cam[9] * b,
        cam[4] + cam[7] * a + cam[10] * b,
        cam[5] + cam[8] * a + cam[11] * b,
    )
    return (cam[0], cam[1], cam[2]), normalize(d)


@njit(**KERNEL)
def thin_lens_ray(cam, o, d, u1, u2):
    """The pinhole ray (o, d) through a thin lens: from the lens point of (u1, u2) (concentric
    disk of radius aperture / 2, in the camera's right/up plane) towards the point where the
    pinhole ray meets the focus plane (forward . (x - o) = focus_distance). Points on that
    plane therefore image to the same spot whatever the aperture."""
    lx, ly = concentric_disk(u1, u2)
    radius = cam[CAM_LENS_RADIUS]
    sx = lx * radius / cam[CAM_HALF_WIDTH]
    sy = ly * radius / cam[CAM_HALF_HEIGHT]
    lens = (
        o[0] + cam[6] * sx + cam[9] * sy,
        o[1] + cam[7] * sx + cam[10] * sy,
        o[2] + cam[8] * sx + cam[11] * sy,
    )
    t = cam[CAM_FOCUS_DISTANCE] / (d[0] * cam[3] + d[1] * cam[4] + d[2] * cam[5])
    focus = madd(o, d, t)
    return lens, normalize(sub(focus, lens))
