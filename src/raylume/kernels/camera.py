"""Camera rays as DESIGN.md defines them: pixel (i, j) from the top-left, centres at +0.5."""

import math

import numpy as np
from numba import njit

from .vec import FAST, KERNEL, normalize


def camera_frame(position, look_at, up, fov_degrees, width, height) -> np.ndarray:
    """float64 (12,): origin, forward, right * w, up * h (left-handed: r = up x f)."""
    p = np.asarray(position, dtype=np.float64)
    f = np.asarray(look_at, dtype=np.float64) - p
    f /= np.linalg.norm(f)
    r = np.cross(np.asarray(up, dtype=np.float64), f)
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    h = math.tan(math.radians(fov_degrees) / 2.0)
    w = h * width / height
    return np.concatenate([p, f, r * w, u * h])


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
