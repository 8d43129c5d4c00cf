"""The environment: the radiance that rays which hit nothing see, and a light that a path tracer
samples (the scene's `[environment]` table).

Conventions
-----------
An equirectangular image (H, W) covers the sphere: image coordinates u (0 at the left edge, 1 at
the right) and v (0 at the top, 1 at the bottom) look along

    phi = 2 pi (u - 0.5),  theta = pi v
    direction = (sin(phi) sin(theta), cos(theta), cos(phi) sin(theta))

in the environment's frame, which `rotation` (world-from-environment, the rotation part of
`scene.mesh.transform_matrix(rotate=...)`) turns into the world. So the centre column looks
along +z, the top row along +y, and a texel right of the centre column lies towards +x: a camera
looking along +z in raylume's left-handed world sees the image the right way round, not
mirrored. A constant colour is a 1 x 1 image.

Lookup and sampling
-------------------
Radiance is the *nearest texel* (piecewise constant): no filtering, so the pdf below, also
piecewise constant over texels, is exactly proportional to what is looked up, and a texel of
zero radiance is the only place the pdf may be zero.

Sampling picks a texel from a piecewise-constant 2D distribution (pbrt-v4 style: a marginal CDF
over rows, a conditional CDF over the columns of each row), with each texel weighted by its
mean channel times its solid angle (2 pi / W) (cos theta_i - cos theta_i+1): the exact area of
the texel on the sphere, which is sin(theta) dtheta dphi integrated over it. Inside the texel
the direction is uniform in solid angle (phi uniform, cos theta uniform), so the solid-angle pdf
is constant over each texel:

    pdf = P(row) P(column | row) / texel solid angle

and radiance / pdf is the same for every direction of a texel. A constant colour (1 x 1) is
therefore sampled uniformly over the sphere, pdf 1 / (4 pi); an all-black image likewise.

Kernel functions take the `Environment` tuple E; with `E.present` False they return black and
pdf 0, so a scene without an environment can pass `no_environment()` through the same code.
The `[environment]` table and its image files become an Environment in compile/environment.py.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..vec import inline_function, kernel_function

PI = math.pi
TWO_PI = 2.0 * math.pi
# Largest float64 below 1: random numbers are clamped to it so the CDF search stays in range.
ONE_MINUS_EPSILON = 1.0 - 2.0**-53


class Environment(NamedTuple):
    image: np.ndarray  # float32 (H, W, 3) linear radiance, intensity applied; (1, 1, 3) for a constant colour
    marginal_cdf: np.ndarray  # float64 (H + 1,): P(row < i); 0 first, exactly 1 last
    conditional_cdf: np.ndarray  # float64 (H, W + 1): P(column < j | row i); 0 first, exactly 1 last
    rotation: np.ndarray  # float64 (3, 3) world-from-environment; its transpose maps back
    present: bool  # False: no [environment] (rays that miss see the background)


# ---------------------------------------------------------------------------------------------
# Kernels


@kernel_function
def _texel_of(E, d):
    """(row, column) of the texel that world direction d falls in."""
    r = E.rotation
    # environment-frame direction: R^T d
    x = r[0, 0] * d[0] + r[1, 0] * d[1] + r[2, 0] * d[2]
    y = r[0, 1] * d[0] + r[1, 1] * d[1] + r[2, 1] * d[2]
    z = r[0, 2] * d[0] + r[1, 2] * d[1] + r[2, 2] * d[2]
    h = E.image.shape[0]
    w = E.image.shape[1]
    n = math.sqrt(x * x + y * y + z * z)
    cos_theta = min(1.0, max(-1.0, y / n)) if n > 0.0 else 1.0
    v = math.acos(cos_theta) / PI
    u = math.atan2(x, z) / TWO_PI + 0.5
    i = min(max(int(v * h), 0), h - 1)
    j = min(max(int(u * w), 0), w - 1)
    return i, j


@kernel_function
def environment_radiance(E, d):
    """Radiance (r, g, b) arriving from world direction d (unit): the nearest texel."""
    if not E.present:
        return (0.0, 0.0, 0.0)
    i, j = _texel_of(E, d)
    return (float(E.image[i, j, 0]), float(E.image[i, j, 1]), float(E.image[i, j, 2]))


@inline_function
def _texel_solid_angle(i, h, w):
    return (math.cos(PI * i / h) - math.cos(PI * (i + 1) / h)) * (TWO_PI / w)


@kernel_function
def environment_pdf(E, d):
    """The solid-angle pdf with which sample_environment returns world direction d."""
    if not E.present:
        return 0.0
    i, j = _texel_of(E, d)
    h = E.image.shape[0]
    w = E.image.shape[1]
    p_row = E.marginal_cdf[i + 1] - E.marginal_cdf[i]
    p_col = E.conditional_cdf[i, j + 1] - E.conditional_cdf[i, j]
    area = _texel_solid_angle(i, h, w)
    if area <= 0.0:
        return 0.0
    return p_row * p_col / area


@inline_function
def _search_marginal(cdf, n, u):
    """The i in 0..n-1 with cdf[i] <= u < cdf[i + 1] (cdf[0] = 0 <= u < 1 = cdf[n]): never
    an empty interval."""
    lo = 0
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@inline_function
def _search_conditional(cdf, row, n, u):
    lo = 0
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if cdf[row, mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@kernel_function
def sample_environment(E, u1, u2):
    """A world direction for the random numbers u1 (row) and u2 (column) in [0, 1): (direction,
    its radiance (r, g, b), its solid-angle pdf). The pdf is 0 for a failed sample (no
    environment). The numbers' remainders inside the chosen texel place the direction in it,
    so stratified u1, u2 stay stratified."""
    if not E.present:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    h = E.image.shape[0]
    w = E.image.shape[1]
    u1 = min(max(u1, 0.0), ONE_MINUS_EPSILON)
    u2 = min(max(u2, 0.0), ONE_MINUS_EPSILON)
    i = _search_marginal(E.marginal_cdf, h, u1)
    c0 = E.marginal_cdf[i]
    p_row = E.marginal_cdf[i + 1] - c0
    j = _search_conditional(E.conditional_cdf, i, w, u2)
    d0 = E.conditional_cdf[i, j]
    p_col = E.conditional_cdf[i, j + 1] - d0
    if p_row <= 0.0 or p_col <= 0.0:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    dv = min((u1 - c0) / p_row, 1.0)
    du = min((u2 - d0) / p_col, 1.0)
    z0 = math.cos(PI * i / h)
    z1 = math.cos(PI * (i + 1) / h)
    area = (z0 - z1) * (TWO_PI / w)
    if area <= 0.0:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    cos_theta = z0 - (z0 - z1) * dv
    sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
    phi = TWO_PI * ((j + du) / w - 0.5)
    x = math.sin(phi) * sin_theta
    z = math.cos(phi) * sin_theta
    r = E.rotation
    d = (
        r[0, 0] * x + r[0, 1] * cos_theta + r[0, 2] * z,
        r[1, 0] * x + r[1, 1] * cos_theta + r[1, 2] * z,
        r[2, 0] * x + r[2, 1] * cos_theta + r[2, 2] * z,
    )
    rgb = (float(E.image[i, j, 0]), float(E.image[i, j, 1]), float(E.image[i, j, 2]))
    return d, rgb, p_row * p_col / area


# ---------------------------------------------------------------------------------------------
# Python side: building the tables, reading the images


def no_environment() -> Environment:
    """No [environment]: present False, tiny arrays of the same types as a real one (so the
    kernels compile once for both)."""
    return Environment(
        image=np.zeros((1, 1, 3), dtype=np.float32),
        marginal_cdf=np.array([0.0, 1.0]),
        conditional_cdf=np.array([[0.0, 1.0]]),
        rotation=np.eye(3),
        present=False,
    )


def sampling_tables(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(marginal_cdf (H + 1,), conditional_cdf (H, W + 1)) for a float (H, W, 3) image: texels
    weighted by their mean channel times their solid angle; an all-black image (or row) is
    sampled by solid angle alone (uniformly)."""
    h, w = image.shape[:2]
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    band = np.maximum(edges[:-1] - edges[1:], 0.0)  # a row's solid angle / (2 pi)
    weights = image.astype(np.float64).mean(axis=2) * band[:, None]
    if not weights.sum() > 0.0:
        weights = np.broadcast_to(band[:, None], (h, w)).copy()
    rows = weights.sum(axis=1)
    conditional = np.zeros((h, w + 1))
    conditional[:, 1:] = np.cumsum(weights, axis=1)
    empty = rows <= 0.0
    conditional[empty, 1:] = np.arange(1, w + 1) / w  # never chosen; keeps the table well formed
    conditional[~empty] /= rows[~empty, None]
    conditional = np.minimum(conditional, 1.0)
    conditional[:, -1] = 1.0
    marginal = np.zeros(h + 1)
    marginal[1:] = np.cumsum(rows) / rows.sum()
    marginal = np.minimum(marginal, 1.0)
    marginal[-1] = 1.0
    return marginal, conditional
