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

Lookup
------
Radiance is the image read *bilinearly*, as Mitsuba 3's `envmap` reads it: texel (i, j) is the
value at its centre, u = (j + 0.5) / W, v = (i + 0.5) / H, and between centres the four nearest
texels are blended. Columns wrap around (the left and right edges meet behind the viewer, -z);
rows clamp (within half a texel of a pole the top or bottom row alone is blended along u). A low
resolution sky is then smooth in the background and in mirror-like reflections, not blocky.
Mitsuba puts its first and last rows on the poles (row i at theta = pi i / (H - 1)); raylume
keeps each texel's centre where the nearest-texel lookup it replaces had it. A 1 x 1 image
(a constant colour) returns its one texel, bit for bit, without looking at the direction.

Sampling
--------
Sampling picks a texel *cell* (the solid angle a texel covers, theta in [pi i / H, pi (i + 1) / H],
phi likewise in W columns) from a piecewise-constant 2D distribution: a marginal CDF over rows
and a conditional CDF over the columns of each row (pbrt-v4 style) give each cell's probability
and pdf, and a sample picks its cell in one step from Walker's alias table of the same
probabilities (alias_table). A cell is weighted by the
integral over it of the lookup's mean channel (cell_integrals): the cell's mean radiance times its
solid angle, (2 pi / W) (cos theta_i - cos theta_i+1). That is what the lookup contributes to
the light the cell sends, so the pdf is proportional to the cell's mean. Inside a cell the lookup
blends the texel with its neighbours (the left or right column, the row above or below, by the
quarter of the cell), so the mean is a weighted sum of the 3 x 3 texels around it: along u,
[1, 6, 1] / 8 of the left, own and right columns (wrapping around), the exact mean of the tents;
along theta the rows above, at and below weighed by their tents times sin theta (row_blend:
[1, 6, 1] / 8 near the equator, but the sine favours a cell's equatorward half, so the top row
takes up to 5/24 of the row below it and 1/24 of the one above, which the lookup clamps to the
top row itself; the bottom row likewise). Every one of the
nine weights is positive, so the pdf is nonzero wherever the lookup is: a single bright texel
lights its neighbours' cells too, and they are sampled. Weighing a cell by the brightest of those
nine texels (an upper bound of the lookup in it) has the same support, but samples a bright sun's
neighbours as if they were all sun: the mean gave 3 to 7 times lower variance integrating the
lookup over the sphere (1.5 to 2.6 times for irradiance) on the shipped sky and random images,
and 1.4 times lower on examples/materials.toml's floor at 16 spp. Inside the cell the direction
is uniform in solid angle (phi uniform, cos theta uniform), so the solid-angle pdf is constant
over each cell:

    pdf = P(row) P(column | row) / cell solid angle

(sample_environment returns it, environment_pdf finds the same cell and value for a direction:
MIS needs the two to agree). The radiance a sample carries is the bilinear lookup at it, so
radiance / pdf varies inside a cell only as the lookup does. A constant colour (1 x 1) is sampled
uniformly over the sphere, pdf 1 / (4 pi); an all-black image likewise.

Kernel functions take the `Environment` tuple E; with `E.present` False they return black and
pdf 0, so a scene without an environment can pass `no_environment()` through the same code.
The `[environment]` table and its image files become an Environment in compile/environment.py.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..geometry.wide_nodes import prefetch_row
from ..vec import acos, atan2, element, inline_function, kernel_function, turn

PI = math.pi
TWO_PI = 2.0 * math.pi
# Largest float64 below 1: random numbers are clamped to it so the alias slot stays in range.
ONE_MINUS_EPSILON = 1.0 - 2.0**-53


class Environment(NamedTuple):
    image: np.ndarray  # float32 (H, W, 3) linear radiance, intensity applied; (1, 1, 3) for a constant colour
    # Walker's alias table over the H x W cells with the probabilities of sampling_tables' cdfs
    # (alias_table; the kernels read no cdf): per slot k, float64 (threshold, alias cell, cell
    # k's pdf, the alias cell's pdf): a sample picks one cell in one step, its pdf with it;
    # column 2 is also environment_pdf's table
    alias: np.ndarray
    # float64 (H + 1,): cos(pi i / H), the rows' edges in cos theta (row_edges): the cells' solid
    # angles and the samples read them, so the kernels call no cos
    row_z: np.ndarray
    rotation: np.ndarray  # float64 (3, 3) world-from-environment; its transpose maps back
    present: bool  # False: no [environment] (rays that miss see the background)


# ---------------------------------------------------------------------------------------------
# Kernels


@kernel_function
def _image_uv(E, d):
    """Image coordinates (u, v) in [0, 1] of world direction d (any length)."""
    r = E.rotation
    # environment-frame direction: R^T d
    x = r[0, 0] * d[0] + r[1, 0] * d[1] + r[2, 0] * d[2]
    y = r[0, 1] * d[0] + r[1, 1] * d[1] + r[2, 1] * d[2]
    z = r[0, 2] * d[0] + r[1, 2] * d[1] + r[2, 2] * d[2]
    n = math.sqrt(x * x + y * y + z * z)
    cos_theta = min(1.0, max(-1.0, y / n)) if n > 0.0 else 1.0
    return atan2(x, z) / TWO_PI + 0.5, acos(cos_theta) / PI


@inline_function
def _lerp(a, b, t):
    # a + (b - a) t, not a (1 - t) + b t: equal texels blend to exactly themselves
    return a + (b - a) * t


@kernel_function
def _bilinear(image, u, v):
    """The image (H, W, 3) at (u, v), bilinearly: texel centres at ((j + 0.5) / W, (i + 0.5) / H),
    columns wrapping, rows clamped. Indices are clamped before use, so even a NaN (u, v) reads
    inside the image."""
    h = image.shape[0]
    w = image.shape[1]
    x = u * w - 0.5
    y = v * h - 0.5
    fx = math.floor(x)
    fy = math.floor(y)
    tx = min(max(x - fx, 0.0), 1.0)
    ty = min(max(y - fy, 0.0), 1.0)
    # u in [0, 1] puts the left column in -1..w-1; -1 is the last column (the seam)
    j0 = min(max(int(fx), -1), w - 1)
    if j0 < 0:
        j0 += w
    j1 = j0 + 1
    if j1 == w:
        j1 = 0
    i = int(fy)
    i0 = min(max(i, 0), h - 1)
    i1 = min(max(i + 1, 0), h - 1)
    # np.float64, not float(): Numba's float() keeps a float32 a float32, and the blend must not
    # round to float32 (halfway between two texels is their mean to float64 precision)
    r0 = _lerp(np.float64(image[i0, j0, 0]), np.float64(image[i0, j1, 0]), tx)
    g0 = _lerp(np.float64(image[i0, j0, 1]), np.float64(image[i0, j1, 1]), tx)
    b0 = _lerp(np.float64(image[i0, j0, 2]), np.float64(image[i0, j1, 2]), tx)
    r1 = _lerp(np.float64(image[i1, j0, 0]), np.float64(image[i1, j1, 0]), tx)
    g1 = _lerp(np.float64(image[i1, j0, 1]), np.float64(image[i1, j1, 1]), tx)
    b1 = _lerp(np.float64(image[i1, j0, 2]), np.float64(image[i1, j1, 2]), tx)
    return (_lerp(r0, r1, ty), _lerp(g0, g1, ty), _lerp(b0, b1, ty))


@kernel_function
def environment_radiance(E, d):
    """Radiance (r, g, b) arriving from world direction d: the image looked up bilinearly."""
    if not E.present:
        return (0.0, 0.0, 0.0)
    image = E.image
    if image.shape[0] == 1 and image.shape[1] == 1:  # a constant colour: no trigonometry
        return (float(image[0, 0, 0]), float(image[0, 0, 1]), float(image[0, 0, 2]))
    u, v = _image_uv(E, d)
    return _bilinear(image, u, v)


@kernel_function
def environment_pdf(E, d):
    """The solid-angle pdf with which sample_environment returns world direction d."""
    if not E.present:
        return 0.0
    u, v = _image_uv(E, d)
    return _pdf_at(E, u, v)


@kernel_function
def environment_radiance_pdf(E, d):
    """(environment_radiance(E, d), environment_pdf(E, d)) from one lookup of d's image
    coordinates: what a path that leaves the scene needs (its radiance and, for MIS, the pdf of
    sampling it), one atan2, acos and square root instead of two."""
    if not E.present:
        return (0.0, 0.0, 0.0), 0.0
    u, v = _image_uv(E, d)
    image = E.image
    if image.shape[0] == 1 and image.shape[1] == 1:  # a constant colour: as environment_radiance
        rgb = (float(image[0, 0, 0]), float(image[0, 0, 1]), float(image[0, 0, 2]))
    else:
        rgb = _bilinear(image, u, v)
    return rgb, _pdf_at(E, u, v)


@inline_function
def _pdf_at(E, u, v):
    """environment_pdf at image coordinates (u, v)."""
    h = E.image.shape[0]
    w = E.image.shape[1]
    i = min(max(int(v * h), 0), h - 1)
    j = min(max(int(u * w), 0), w - 1)
    return E.alias[i * w + j, 2]  # the cell's pdf (alias_table)


@inline_function
def prefetch_environment(E, u1):
    """Start loading the alias slot sample_environment(E, u1, ...) will read."""
    n = E.alias.shape[0]
    prefetch_row(E.alias, min(int(u1 * n), n - 1))


@inline_function
def environment_cell(E, u1, u2):
    """sample_environment's choice for the random numbers u1 (the cell) and u2 (the column inside
    it) in [0, 1): (the cell's pdf, the direction's polar cosine in the environment's frame, its
    image u). The pdf is 0 for a failed sample (no environment). The cell comes from the alias
    table in one step: the two searches of the cdfs it replaced mispredicted a branch at about
    every other of their ~15 steps (~10% of path mode's samples in examples/materials.toml's
    profile); now what is left is one load, often a cache miss (materials.toml 640 x 320, 16
    spp, 1 thread, CPU time: 0.93x at the minimum of 5 alternating runs, 0.98x at the median).
    u1's remainder places the direction in the cell's rows, u2 in its columns."""
    if not E.present:
        return 0.0, 1.0, 0.0
    w = E.image.shape[1]
    u1 = min(max(u1, 0.0), ONE_MINUS_EPSILON)
    u2 = min(max(u2, 0.0), ONE_MINUS_EPSILON)
    n = E.alias.shape[0]
    x = u1 * n
    k = min(int(x), n - 1)
    frac = x - k
    threshold = E.alias[k, 0]
    # the slot's own cell below the threshold, its alias above, picked by index (a branch on
    # frac < threshold was mispredicted about as often as not)
    above = int(frac >= threshold)
    cell = element((k, int(E.alias[k, 1])), above)
    pdf = element((E.alias[k, 2], E.alias[k, 3]), above)  # the cell's, from the same slot
    dv = (frac - element((0.0, threshold), above)) / element((threshold, 1.0 - threshold), above)
    if not pdf > 0.0:
        return 0.0, 1.0, 0.0
    i = cell // w
    j = cell - i * w
    dv = min(max(dv, 0.0), 1.0)
    z0 = E.row_z[i]
    z1 = E.row_z[i + 1]
    cos_theta = min(1.0, max(-1.0, z0 - (z0 - z1) * dv))
    return pdf, cos_theta, (j + u2) / w


@inline_function
def environment_rotation(E):
    """The environment's rotation matrix as a tuple, row by row (environment_direction's `r`)."""
    r = E.rotation
    return (r[0, 0], r[0, 1], r[0, 2], r[1, 0], r[1, 1], r[1, 2], r[2, 0], r[2, 1], r[2, 2])


@inline_function
def environment_direction(r, cos_theta, cos_phi, sin_phi):
    """The world direction at polar cosine cos_theta and azimuth phi (its cosine and sine: turn(u
    - 0.5) of the image's u) in the environment's frame rotated by r (environment_rotation)."""
    sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
    x = sin_phi * sin_theta
    z = cos_phi * sin_theta
    return (
        r[0] * x + r[1] * cos_theta + r[2] * z,
        r[3] * x + r[4] * cos_theta + r[5] * z,
        r[6] * x + r[7] * cos_theta + r[8] * z,
    )


@inline_function
def environment_at(E, u, cos_theta):
    """The radiance sample_environment returns for image u and polar cosine cos_theta."""
    if E.image.shape[0] == 1 and E.image.shape[1] == 1:  # a constant colour, as environment_radiance
        return (float(E.image[0, 0, 0]), float(E.image[0, 0, 1]), float(E.image[0, 0, 2]))
    return _bilinear(E.image, u, acos(cos_theta) / PI)


@kernel_function
def sample_environment(E, u1, u2):
    """A world direction for the random numbers u1, u2 in [0, 1) (environment_cell): (direction,
    its radiance (r, g, b), its solid-angle pdf). The pdf is 0 for a failed sample."""
    pdf, cos_theta, u = environment_cell(E, u1, u2)
    if not pdf > 0.0:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    cos_phi, sin_phi = turn(u - 0.5)  # phi = 2 pi (u - 0.5)
    d = environment_direction(environment_rotation(E), cos_theta, cos_phi, sin_phi)
    return d, environment_at(E, u, cos_theta), pdf


# ---------------------------------------------------------------------------------------------
# Python side: building the tables


def no_environment() -> Environment:
    """No [environment]: present False, tiny arrays of the same types as a real one (so the
    kernels compile once for both)."""
    return Environment(
        image=np.zeros((1, 1, 3), dtype=np.float32),
        alias=np.array([[1.0, 0.0, 0.0, 0.0]]),
        row_z=row_edges(1),
        rotation=np.eye(3),
        present=False,
    )


# Gauss-Legendre nodes and weights on [0, 1/2]: the lookup's row tents times sin theta over half
# a texel row are smooth, and 8 nodes integrate them to float64 precision even at H = 1.
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_HALF_NODES = (_GL_NODES + 1.0) / 4.0
_HALF_WEIGHTS = _GL_WEIGHTS / 4.0


def row_blend(h: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(above, own, below), (H,) each: over row i's band (theta in [pi i / H, pi (i + 1) / H]),
    the integral of sin(theta) dtheta times the weight the bilinear lookup gives row i - 1, row i
    and row i + 1 (a tent falling from 1/2 at the cell's top edge to 0 at its centre, the
    complement, one rising from 0 at the centre to 1/2 at its bottom edge). The three sum to the
    band's cos theta_i - cos theta_i+1. Near a pole the sine weighs a cell's equatorward half
    more: the top row's (above, own, below) tend to (1/24, 18/24, 5/24) of its band as H grows,
    not (1/8, 6/8, 1/8). Every entry is > 0 (the nodes are inside the band)."""
    s = _HALF_NODES  # position inside a half row, in texel heights
    i = np.arange(h, dtype=np.float64)[:, None]

    def sin_at(t):  # sin(pi t / H) for t in texel heights from the top, exact near both poles
        return np.sin(np.pi * np.minimum(t, h - t) / h)

    upper = sin_at(i + s)  # the cell's upper half: rows i - 1 and i blended
    lower = sin_at(i + 0.5 + s)  # its lower half: rows i and i + 1
    dtheta = np.pi / h
    above = (upper * (0.5 - s)) @ _HALF_WEIGHTS * dtheta
    own = (upper * (0.5 + s) + lower * (1.0 - s)) @ _HALF_WEIGHTS * dtheta
    below = (lower * s) @ _HALF_WEIGHTS * dtheta
    return above, own, below


def cell_integrals(values: np.ndarray) -> np.ndarray:
    """(H, W) -> (H, W): the integral over each texel cell, in solid angle, of the values' bilinear
    lookup. Separable: along u the lookup's mean over a cell is [1, 6, 1] / 8 of the texel and its
    left and right neighbours (columns wrapping around), and phi is uniform in solid angle; along
    theta the rows above, at and below are weighed by row_blend (rows clamped at the poles, as the
    lookup clamps them). Nonzero wherever the lookup is nonzero in the cell (every weight is > 0)."""
    h, w = values.shape
    v = np.asarray(values, dtype=np.float64)
    cols = (np.roll(v, 1, axis=1) + 6.0 * v + np.roll(v, -1, axis=1)) / 8.0
    padded = np.pad(cols, ((1, 1), (0, 0)), mode="edge")
    above, own, below = row_blend(h)
    rows = above[:, None] * padded[:-2] + own[:, None] * padded[1:-1] + below[:, None] * padded[2:]
    return rows * (TWO_PI / w)


def row_edges(h: int) -> np.ndarray:
    """float64 (H + 1,): cos(pi i / H) for i = 0 .. H, the edges of the image's rows in cos theta
    (1 and -1 exactly at the poles). Computed once here, not per sample in the kernels: the
    cells' solid angles in the sampling tables and in the pdf are then the same numbers, on
    every machine of a cluster whatever its libm (the scene ships the table)."""
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    edges[0], edges[-1] = 1.0, -1.0
    return edges


def sampling_tables(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(marginal_cdf (H + 1,), conditional_cdf (H, W + 1)) for a float (H, W, 3) image: texel
    cells weighted by the integral of the lookup's mean channel over them (cell_integrals); an
    all-black image (or row) is sampled by solid angle alone (uniformly)."""
    h, w = image.shape[:2]
    edges = row_edges(h)
    band = np.maximum(edges[:-1] - edges[1:], 0.0)  # a row's solid angle / (2 pi)
    weights = cell_integrals(image.astype(np.float64).mean(axis=2))
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


def alias_table(marginal: np.ndarray, conditional: np.ndarray) -> np.ndarray:
    """Walker's alias table (Vose's construction) of the cells' probabilities P(row i) P(column j
    | row i), row-major: float64 (H W, 4), per slot k its threshold, its alias cell, cell k's
    solid-angle pdf and the alias cell's. A sample u in [0, 1) picks slot k = floor(u H W); the
    cell is k if the remainder is below k's threshold, else k's alias: each cell is picked with
    exactly its probability (up to rounding), cells of probability 0 never. The pdfs come with
    the slot (no second lookup of the cdfs, a cache miss, for a sample), and column 2 is every
    cell's pdf for environment_pdf, so that a sample and a lookup of its direction agree to the
    bit (MIS)."""
    h, w = len(marginal) - 1, conditional.shape[1] - 1
    p_cells = np.diff(marginal)[:, None] * np.diff(conditional, axis=1)
    z = row_edges(h)
    area = ((z[:-1] - z[1:]) * (TWO_PI / w))[:, None]
    pdf = np.divide(p_cells, area, out=np.zeros_like(p_cells), where=area > 0.0).ravel()
    p = p_cells.ravel()
    slots = _vose(p / p.sum())
    return np.column_stack([slots, pdf, pdf[slots[:, 1].astype(np.int64)]])


@njit(cache=True)
def _vose(p):
    n = p.shape[0]
    table = np.zeros((n, 2))
    scaled = p * n
    small = np.empty(n, np.int64)
    large = np.empty(n, np.int64)
    ns = nl = 0
    for k in range(n):
        table[k, 1] = k
        if scaled[k] < 1.0:
            small[ns] = k
            ns += 1
        else:
            large[nl] = k
            nl += 1
    while ns > 0 and nl > 0:
        ns -= 1
        s = small[ns]
        g = large[nl - 1]
        table[s, 0] = scaled[s]
        table[s, 1] = g
        scaled[g] = (scaled[g] + scaled[s]) - 1.0
        if scaled[g] < 1.0:
            nl -= 1
            small[ns] = g
            ns += 1
    for q in range(nl):  # what is left holds 1 up to rounding: always itself
        table[large[q], 0] = 1.0
    for q in range(ns):
        table[small[q], 0] = 1.0
    return table
