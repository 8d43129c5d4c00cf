"""pbrt-v4's equal-area octahedral environment maps resampled to raylume's equirectangular ones.

pbrt-v4 stores an image infinite light as a square image in Clarberg's equal-area octahedral
mapping (pbrt-v4 src/pbrt/util/math.cpp, EqualAreaSquareToSphere / EqualAreaSphereToSquare):
the direction (x, y, z) of the light's frame lands at (u, v) in [0, 1]^2, u along the image's
columns, v down its rows. Each texel of the equirectangular image (kernels/shading/environment.py:
phi = 2 pi (u - 0.5), theta = pi v, direction (sin phi sin theta, cos theta, cos phi sin theta))
takes the octahedral image's bilinear value in its direction, in the same frame.
"""

from __future__ import annotations

import numpy as np


def sphere_to_square(d: np.ndarray) -> np.ndarray:
    """(..., 2) equal-area square coordinates in [0, 1] of unit directions (..., 3)."""
    x, y, z = np.abs(d[..., 0]), np.abs(d[..., 1]), np.abs(d[..., 2])
    r = np.sqrt(np.maximum(1.0 - z, 0.0))
    a, b = np.maximum(x, y), np.minimum(x, y)
    b = np.where(a == 0, 0.0, b / np.where(a == 0, 1.0, a))
    phi = np.arctan(b) * 2 / np.pi
    phi = np.where(x < y, 1 - phi, phi)
    v = phi * r
    u = r - v
    south = d[..., 2] < 0
    u, v = np.where(south, 1 - v, u), np.where(south, 1 - u, v)
    u = np.copysign(u, d[..., 0])
    v = np.copysign(v, d[..., 1])
    return np.stack([0.5 * (u + 1), 0.5 * (v + 1)], axis=-1)


def equal_area_to_equirectangular(image: np.ndarray) -> np.ndarray:
    """(N, 2N, 3) equirectangular image of an (N, N, 3) equal-area octahedral one."""
    n = image.shape[0]
    height, width = n, 2 * n
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    theta, phi = np.meshgrid(np.pi * v, 2 * np.pi * (u - 0.5), indexing="ij")
    d = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), np.cos(phi) * np.sin(theta)], -1)
    st = sphere_to_square(d)
    return _bilinear(image, st[..., 0] * n - 0.5, st[..., 1] * n - 0.5).astype(np.float32)


def _bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The image at continuous texel coordinates (texel centres at integers), edges clamped."""
    n_y, n_x = image.shape[:2]
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    xs0, xs1 = np.clip(x0, 0, n_x - 1), np.clip(x0 + 1, 0, n_x - 1)
    ys0, ys1 = np.clip(y0, 0, n_y - 1), np.clip(y0 + 1, 0, n_y - 1)
    top = image[ys0, xs0] * (1 - fx) + image[ys0, xs1] * fx
    bottom = image[ys1, xs0] * (1 - fx) + image[ys1, xs1] * fx
    return top * (1 - fy) + bottom * fy
