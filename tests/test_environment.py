"""The environment light (kernels/shading/environment.py): its direction convention, its bilinear
lookup (against a numpy model of it), its sampling (pdf normalisation, consistency, chi-square
tests, cell weights that are the lookup's integral over each cell, a pdf that covers the
bilinear footprint, importance-sampling estimates against exact integrals, path mode under an
image sky) and its image loaders (.hdr with and without run-length encoding, .exr), with the
errors bad input gives. Fixed seeds; tolerances from standard errors."""

from __future__ import annotations

import math
from pathlib import Path

import numba
import numpy as np
import pytest
from numba import njit
from scipy import stats

import raylume
from raylume.compile.environment import MAX_TEXELS, build_environment, load_environment_image, rgbe_decode
from raylume.errors import SceneError
from raylume.image import rgbe_encode, save_array
from raylume.kernels.shading.environment import (
    environment_pdf,
    environment_radiance,
    environment_radiance_pdf,
    no_environment,
    sample_environment,
    sampling_tables,
)
from raylume.scene.mesh import transform_matrix

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# ---------------------------------------------------------------------------------------------
# Batch helpers (one compilation each: every Environment has the same Numba type)


@njit(cache=False)
def _radiance_many(E, dirs):
    out = np.empty((dirs.shape[0], 3))
    for k in range(dirs.shape[0]):
        r = environment_radiance(E, (dirs[k, 0], dirs[k, 1], dirs[k, 2]))
        out[k, 0], out[k, 1], out[k, 2] = r
    return out


@njit(cache=False)
def _pdf_many(E, dirs):
    out = np.empty(dirs.shape[0])
    for k in range(dirs.shape[0]):
        out[k] = environment_pdf(E, (dirs[k, 0], dirs[k, 1], dirs[k, 2]))
    return out


@njit(cache=False)
def _sample_many(E, u):
    n = u.shape[0]
    dirs = np.empty((n, 3))
    rgb = np.empty((n, 3))
    pdf = np.empty(n)
    for k in range(n):
        d, c, p = sample_environment(E, u[k, 0], u[k, 1])
        dirs[k, 0], dirs[k, 1], dirs[k, 2] = d
        rgb[k, 0], rgb[k, 1], rgb[k, 2] = c
        pdf[k] = p
    return dirs, rgb, pdf


def formula_direction(u, v):
    """The documented convention: image coordinates -> environment-frame direction."""
    phi = 2 * np.pi * (np.asarray(u) - 0.5)
    theta = np.pi * np.asarray(v)
    return np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), np.cos(phi) * np.sin(theta)], axis=-1)


def bilinear_reference(img, u, v):
    """The documented lookup, in numpy: texel (i, j) is the value at ((j + 0.5) / W, (i + 0.5) / H),
    the four nearest texels weighted (1 - s)(1 - t), s(1 - t), (1 - s)t, st, columns wrapping
    around, rows clamped. (..., 3) for u, v of any shape."""
    h, w = img.shape[:2]
    a = img.astype(np.float64)
    x = np.asarray(u, dtype=np.float64) * w - 0.5
    y = np.asarray(v, dtype=np.float64) * h - 0.5
    j = np.floor(x).astype(int)
    i = np.floor(y).astype(int)
    s = (x - j)[..., None]
    t = (y - i)[..., None]
    j0, j1 = j % w, (j + 1) % w
    i0, i1 = np.clip(i, 0, h - 1), np.clip(i + 1, 0, h - 1)
    return (1 - s) * (1 - t) * a[i0, j0] + s * (1 - t) * a[i0, j1] + (1 - s) * t * a[i1, j0] + s * t * a[i1, j1]


def row_profile(img, theta):
    """The lookup averaged over phi at polar angle theta, (..., 3): along u the tents of a row's
    texels each integrate to 1 / W (columns wrap), so it is the rows' means blended along v."""
    h = img.shape[0]
    means = img.astype(np.float64).mean(axis=1)
    y = np.asarray(theta) / np.pi * h - 0.5
    i = np.floor(y).astype(int)
    t = (y - i)[..., None]
    return (1 - t) * means[np.clip(i, 0, h - 1)] + t * means[np.clip(i + 1, 0, h - 1)]


def exact_integral(img, weight, n=400_000):
    """The integral over the sphere of the bilinear lookup times weight(cos theta), (3,): exact
    in phi (row_profile), the midpoint rule in theta on n points (error ~1 / n^2)."""
    theta = (np.arange(n) + 0.5) * np.pi / n
    f = row_profile(img, theta) * (weight(np.cos(theta)) * np.sin(theta))[:, None]
    return 2 * np.pi * f.sum(axis=0) * np.pi / n


def cell_weights_reference(img):
    """(P, solid angles), (H, W) each: the probability of each texel cell, written out: the
    integral over the cell, in solid angle, of the lookup's mean channel, normalised. Each of the
    3 x 3 texels around the cell (columns wrapped, rows clamped) weighs in with its tents'
    integral over the cell: along phi 1/8, 6/8, 1/8 of the cell's 2 pi / W; along theta the
    closed forms of the integral of (the row's tent) sin(theta) dtheta over the cell's band
    (integrals of (theta_c - theta) sin theta and (theta - theta_c) sin theta, by parts)."""
    h, w = img.shape[:2]
    m = img.astype(np.float64).mean(axis=2)
    d = np.pi / h
    p = np.zeros((h, w))
    for i in range(h):
        t0, t1, tc = i * d, (i + 1) * d, (i + 0.5) * d
        up = 0.5 * np.cos(t0) + (np.sin(t0) - np.sin(tc)) / d
        down = -0.5 * np.cos(t1) + (np.sin(t1) - np.sin(tc)) / d
        rows = {-1: up, 0: np.cos(t0) - np.cos(t1) - up - down, 1: down}
        for j in range(w):
            for di, wr in rows.items():
                for dj, wc in ((-1, 1 / 8), (0, 6 / 8), (1, 1 / 8)):
                    p[i, j] += wr * wc * m[min(max(i + di, 0), h - 1), (j + dj) % w]
    z = np.cos(np.pi * np.arange(h + 1) / h)
    area = (z[:-1] - z[1:])[:, None] * np.full(w, 2 * np.pi / w)[None, :]
    return p / p.sum(), area


def cell_means_numeric(img, n=64, solid_angle=True):
    """(H, W): the mean channel of bilinear_reference averaged over each texel cell on an n x n
    midpoint grid inside it, weighed by sin(theta) (solid angle) or not (uniform in u and v).
    With n even the grid's rows and columns never straddle the lookup's kinks (the cell's
    centre lines), so along u and, without the sine, along v the midpoint rule is exact."""
    h, w = img.shape[:2]
    f = (np.arange(n) + 0.5) / n
    v = ((np.arange(h)[:, None] + f[None, :]) / h).reshape(-1)  # (H n,)
    u = ((np.arange(w)[:, None] + f[None, :]) / w).reshape(-1)  # (W n,)
    vv, uu = np.meshgrid(v, u, indexing="ij")
    lookup = bilinear_reference(img, uu, vv).mean(axis=-1)
    weight = np.sin(np.pi * v) if solid_angle else np.ones_like(v)
    lookup = lookup * weight[:, None]
    sums = lookup.reshape(h, n, w, n).sum(axis=(1, 3))
    return sums / (weight.reshape(h, n).sum(axis=1)[:, None] * n)


def cells_of(dirs, h, w):
    """Environment-frame directions -> (row, column) of the texel cell each lies in."""
    theta = np.arccos(np.clip(dirs[:, 1], -1, 1))
    u = np.mod(np.arctan2(dirs[:, 0], dirs[:, 2]) / (2 * np.pi) + 0.5, 1.0)
    return np.minimum((theta / np.pi * h).astype(int), h - 1), np.minimum((u * w).astype(int), w - 1)


def sphere_grid(n_theta: int, n_phi: int):
    """Midpoints of an equal-area grid (uniform in cos theta and phi): (directions, weight of
    each, the cell's solid angle, all equal)."""
    z = 1 - (np.arange(n_theta) + 0.5) * 2 / n_theta
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    s = np.sqrt(1 - z * z)
    d = np.stack(
        [
            s[:, None] * np.sin(phi)[None, :],
            np.broadcast_to(z[:, None], (n_theta, n_phi)),
            s[:, None] * np.cos(phi)[None, :],
        ],
        axis=-1,
    )
    return np.ascontiguousarray(d.reshape(-1, 3)), 4 * np.pi / (n_theta * n_phi)


def make_image(seed=1, h=16, w=32) -> np.ndarray:
    """A non-uniform colour image: a gradient, noise, a bright spot and a black band."""
    rng = np.random.default_rng(seed)
    img = 0.2 + rng.random((h, w, 3)) * np.linspace(0.1, 1.0, w)[None, :, None]
    img[h // 4, (3 * w) // 4] = (40.0, 30.0, 10.0)
    img[h - 2] = 0.0
    return img.astype(np.float32)


def env_from(img, tmp_path, rotate=(0, 0, 0), name="env.exr", **kw):
    save_array(tmp_path / name, img)
    return build_environment(file=name, base_dir=tmp_path, rotate=rotate, **kw)


# ---------------------------------------------------------------------------------------------
# Conventions


@pytest.mark.parametrize("texel", [(0, 7), (2, 11), (4, 3), (8, 14), (5, 7)])
def test_single_texel_is_seen_in_the_documented_direction(tmp_path, texel):
    h, w = 9, 15  # odd sizes: the centre column and the middle row are texels
    img = np.zeros((h, w, 3), np.float32)
    i, j = texel
    img[i, j] = (5.0, 6.0, 7.0)
    E = env_from(img, tmp_path)
    centre = formula_direction((j + 0.5) / w, (i + 0.5) / h)
    np.testing.assert_allclose(environment_radiance(E, tuple(centre)), (5.0, 6.0, 7.0), rtol=1e-12)
    # every other texel centre is black (up to the rounding of a direction's angles)
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    seen = _radiance_many(E, np.ascontiguousarray(formula_direction(u, v).reshape(-1, 3))).reshape(h, w, 3)
    np.testing.assert_allclose(seen, img, rtol=1e-12, atol=1e-12)


def test_centre_column_looks_along_z_top_row_along_y_and_right_is_x(tmp_path):
    h, w = 9, 15
    img = np.zeros((h, w, 3), np.float32)
    img[h // 2, w // 2] = (1, 0, 0)  # the centre of the image
    img[0, :] = (0, 1, 0)  # the top row
    img[h - 1, :] = (0, 0, 1)  # the bottom row
    img[h // 2, (3 * w) // 4] = (1, 1, 0)  # right of the centre (column 11): +x
    img[h // 2, w // 4] = (0, 1, 1)  # left of the centre (column 3): -x
    E = env_from(img, tmp_path)

    def close(d, want):
        np.testing.assert_allclose(environment_radiance(E, d), want, rtol=1e-12, atol=1e-12)

    close((0.0, 0.0, 1.0), (1, 0, 0))  # the centre texel's centre
    close((0.0, 1.0, 0.0), (0, 1, 0))
    close((0.1, 0.99, -0.05), (0, 1, 0))  # within half a texel of the pole: the top row alone
    close((0.0, -1.0, 0.0), (0, 0, 1))
    # +x is u = 3/4: x = 0.75 * 15 - 0.5 = 10.75, a quarter of column 10 and three of column 11
    close((1.0, 0.0, 0.0), (0.75, 0.75, 0))
    # -x is u = 1/4: x = 3.25, three quarters of column 3 and one of column 4
    close((-1.0, 0.0, 0.0), (0, 0.75, 0.75))


def test_rotate_turns_the_image_as_object_transforms_do(tmp_path):
    h, w = 9, 15
    img = np.zeros((h, w, 3), np.float32)
    img[h // 2, w // 2] = (1, 0, 0)  # +z in the environment's frame
    img[2, 11] = (0, 2, 0)
    E = env_from(img, tmp_path, rotate=(0, 90, 0))
    # transform_matrix: rotating 90 degrees about y maps +z to +x
    np.testing.assert_allclose(environment_radiance(E, (1.0, 0.0, 0.0)), (1, 0, 0), rtol=1e-12)
    np.testing.assert_allclose(environment_radiance(E, (0.0, 0.0, 1.0)), (0, 0, 0), atol=1e-12)
    for rotate in [(0, 90, 0), (30, -50, 70)]:
        E = env_from(img, tmp_path, rotate=rotate)
        m = transform_matrix(rotate=rotate)[:3, :3]
        np.testing.assert_allclose(E.rotation, m)
        d = m @ formula_direction(11.5 / w, 2.5 / h)
        np.testing.assert_allclose(environment_radiance(E, tuple(d)), (0, 2, 0), rtol=1e-12, atol=1e-12)


def test_constant_colour_is_sampled_uniformly():
    E = build_environment(color=(0.5, 1.0, 2.0), intensity=3.0)
    assert E.image.shape == (1, 1, 3)
    rng = np.random.default_rng(2)
    dirs, rgb, pdf = _sample_many(E, rng.random((20000, 2)))
    np.testing.assert_allclose(pdf, 1 / (4 * np.pi), rtol=1e-12)
    np.testing.assert_array_equal(rgb, np.broadcast_to([1.5, 3.0, 6.0], rgb.shape))
    # the lookup is the colour itself in every direction, bit for bit (no blending)
    np.testing.assert_array_equal(_radiance_many(E, dirs), rgb)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1, atol=1e-12)
    # uniform over the sphere: each coordinate's mean is 0 and its mean square 1/3
    se = np.sqrt(1 / 3 / len(dirs))
    assert np.all(np.abs(dirs.mean(axis=0)) < 4 * se)
    assert np.all(np.abs((dirs**2).mean(axis=0) - 1 / 3) < 4 * np.sqrt(4 / 45 / len(dirs)))
    assert environment_pdf(E, (0.0, 0.0, 1.0)) == pytest.approx(1 / (4 * np.pi))


def test_no_environment_is_black_has_pdf_zero_and_the_same_numba_type():
    none = no_environment()
    assert not none.present
    assert environment_radiance(none, (0.0, 0.0, 1.0)) == (0.0, 0.0, 0.0)
    assert environment_pdf(none, (0.0, 0.0, 1.0)) == 0.0
    assert sample_environment(none, 0.5, 0.5)[2] == 0.0
    assert numba.typeof(none) == numba.typeof(build_environment(color=(1, 1, 1)))
    assert numba.typeof(none) == numba.typeof(build_environment(file="sky.hdr", base_dir=EXAMPLES))


@njit(cache=False)
def _radiance_pdf_many(E, dirs):
    rgb = np.empty((dirs.shape[0], 3))
    pdf = np.empty(dirs.shape[0])
    for k in range(dirs.shape[0]):
        r, pdf[k] = environment_radiance_pdf(E, (dirs[k, 0], dirs[k, 1], dirs[k, 2]))
        rgb[k, 0], rgb[k, 1], rgb[k, 2] = r
    return rgb, pdf


@pytest.mark.parametrize("kind", ["image", "rotated", "colour", "none"])
def test_radiance_and_pdf_together_are_each_alone(tmp_path, kind):
    """environment_radiance_pdf (what a path leaving the scene looks up, one atan2 and acos for
    both) gives environment_radiance's and environment_pdf's numbers, to the bit: at random
    directions, the poles and the seam."""
    if kind == "colour":
        E = build_environment(color=(0.5, 1.0, 2.0))
    elif kind == "none":
        E = no_environment()
    else:
        E = env_from(make_image(5), tmp_path, rotate=(20, 35, -10) if kind == "rotated" else (0, 0, 0))
    rng = np.random.default_rng(8)
    dirs = rng.normal(size=(4000, 3))
    dirs[:4] = [[0, 1, 0], [0, -1, 0], [0, 0, -1], [1e-9, 0.3, -1]]  # poles, the seam, beside it
    rgb, pdf = _radiance_pdf_many(E, dirs)
    np.testing.assert_array_equal(rgb, _radiance_many(E, dirs))
    np.testing.assert_array_equal(pdf, _pdf_many(E, dirs))
    assert (pdf > 0).all() if kind != "none" else (pdf == 0).all()


# ---------------------------------------------------------------------------------------------
# Bilinear lookup


def test_lookup_is_the_texel_at_its_centre_and_the_mean_halfway(tmp_path):
    h, w = 5, 8
    img = np.random.default_rng(12).uniform(0.0, 4.0, (h, w, 3)).astype(np.float32)
    E = env_from(img, tmp_path)
    a = img.astype(np.float64)

    def seen(u, v):
        d = np.ascontiguousarray(formula_direction(u, v).reshape(-1, 3))
        return _radiance_many(E, d).reshape(np.shape(u) + (3,))

    def close(got, want):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)

    j, i = np.meshgrid(np.arange(w), np.arange(h))
    close(seen((j + 0.5) / w, (i + 0.5) / h), a)  # texel centres: the texels
    # halfway between horizontal neighbours (the last column's right neighbour is the first)
    close(seen((j + 1.0) / w, (i + 0.5) / h), (a + np.roll(a, -1, axis=1)) / 2)
    # halfway between vertical neighbours, and between four texels
    close(seen((j[:-1] + 0.5) / w, (i[:-1] + 1.0) / h), (a[:-1] + a[1:]) / 2)
    right = np.roll(a, -1, axis=1)
    close(seen((j[:-1] + 1.0) / w, (i[:-1] + 1.0) / h), (a[:-1] + right[:-1] + a[1:] + right[1:]) / 4)
    # the seam at u = 0 (and 1): the mean of the last and the first columns
    close(seen(np.zeros(h), (np.arange(h) + 0.5) / h), (a[:, -1] + a[:, 0]) / 2)
    close(seen(np.full(h, 0.25 / w), (np.arange(h) + 0.5) / h), 0.25 * a[:, -1] + 0.75 * a[:, 0])
    close(seen(np.full(h, 1 - 0.25 / w), (np.arange(h) + 0.5) / h), 0.75 * a[:, -1] + 0.25 * a[:, 0])
    # within half a texel of a pole, the top (bottom) row alone, blended along u
    close(seen((np.arange(w) + 0.75) / w, np.full(w, 0.2 / h)), 0.75 * a[0] + 0.25 * np.roll(a[0], -1, axis=0))
    close(seen((np.arange(w) + 0.5) / w, np.full(w, 1 - 0.3 / h)), a[-1])


@pytest.mark.parametrize("rotate", [(0, 0, 0), (25, -40, 110)])
def test_lookup_matches_a_numpy_model_everywhere(tmp_path, rotate):
    """Random directions against bilinear_reference (the image coordinates found in numpy)."""
    img = make_image(seed=13, h=7, w=12)
    E = env_from(img, tmp_path, rotate=rotate)
    rng = np.random.default_rng(14)
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    local = d @ transform_matrix(rotate=rotate)[:3, :3]  # R^T d, row by row
    u = np.mod(np.arctan2(local[:, 0], local[:, 2]) / (2 * np.pi) + 0.5, 1.0)
    v = np.arccos(np.clip(local[:, 1], -1, 1)) / np.pi
    want = bilinear_reference(img, u, v)
    np.testing.assert_allclose(_radiance_many(E, np.ascontiguousarray(d)), want, rtol=1e-9, atol=1e-9)


def test_lookup_is_continuous_across_texel_edges_and_the_seam(tmp_path):
    """Nearest-texel lookup jumps by a texel's difference at every edge; bilinear by no more
    than the step times the largest slope between neighbours."""
    img = make_image(seed=15, h=6, w=10)
    E = env_from(img, tmp_path)
    h, w = img.shape[:2]
    eps = 1e-7
    i = np.repeat(np.arange(h), w + 1)
    edges = np.tile(np.arange(w + 1) / w, h)  # every vertical texel edge, the seam twice
    v = (i + 0.37) / h
    left = _radiance_many(E, np.ascontiguousarray(formula_direction(np.mod(edges - eps, 1), v)))
    right = _radiance_many(E, np.ascontiguousarray(formula_direction(np.mod(edges + eps, 1), v)))
    slope = float(np.abs(np.diff(img, axis=1, append=img[:, :1])).max()) * w
    assert np.abs(left - right).max() < 4 * eps * slope


# ---------------------------------------------------------------------------------------------
# Sampling


@pytest.mark.parametrize("rotate", [(0, 0, 0), (25, -40, 110)])
def test_pdf_integrates_to_one(tmp_path, rotate):
    E = env_from(make_image(), tmp_path, rotate=rotate)
    dirs, cell = sphere_grid(1024, 2048)
    total = _pdf_many(E, dirs).sum() * cell
    # midpoint rule over a grid not aligned with the texels: error ~ 1 / (cells per texel edge)
    assert total == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("rotate", [(0, 0, 0), (25, -40, 110)])
def test_samples_carry_their_pdf_and_radiance(tmp_path, rotate):
    E = env_from(make_image(), tmp_path, rotate=rotate)
    rng = np.random.default_rng(3)
    dirs, rgb, pdf = _sample_many(E, rng.random((50000, 2)))
    assert np.all(pdf > 0)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1, atol=1e-12)
    np.testing.assert_allclose(pdf, _pdf_many(E, dirs), rtol=1e-9)
    # the radiance a sample carries is the lookup along it (found from its image coordinates,
    # the lookup's from the world direction: the two differ by rounding)
    np.testing.assert_allclose(rgb, _radiance_many(E, dirs), rtol=1e-9, atol=1e-12)
    # the black band's cells (second row from the bottom) are sampled, for the lookup blends
    # the rows beside it into them, but no sample lands where the lookup is black
    assert np.all(rgb.max(axis=1) > 0)


def test_sampled_directions_follow_the_pdf_chi_square(tmp_path):
    rotate = (10, 35, -20)
    E = env_from(make_image(seed=4), tmp_path, rotate=rotate)
    n = 200_000
    rng = np.random.default_rng(5)
    dirs, _, _ = _sample_many(E, rng.random((n, 2)))
    # bins: 24 x 48 in world (cos theta, phi), equal solid angle
    nt, nphi = 24, 48
    ti = np.minimum(((1 - dirs[:, 1]) / 2 * nt).astype(int), nt - 1)
    pj = np.minimum((np.mod(np.arctan2(dirs[:, 0], dirs[:, 2]), 2 * np.pi) / (2 * np.pi) * nphi).astype(int), nphi - 1)
    observed = np.bincount(ti * nphi + pj, minlength=nt * nphi).astype(float)
    # expected: the pdf integrated over each bin on a 32 x 32 sub-grid
    sub = 32
    fine, cell = sphere_grid(nt * sub, nphi * sub)
    p = _pdf_many(E, fine).reshape(nt, sub, nphi, sub).sum(axis=(1, 3)).reshape(-1) * cell
    expected = p / p.sum() * n
    small = expected < 20  # pooled into one bin
    assert small.sum() < 0.2 * len(small)
    obs, exp = observed[~small], expected[~small]
    if expected[small].sum() >= 20:
        obs, exp = np.append(obs, observed[small].sum()), np.append(exp, expected[small].sum())
    else:
        assert observed[small].sum() <= 40
    exp = exp * obs.sum() / exp.sum()
    result = stats.chisquare(obs, exp)
    assert result.pvalue > 1e-3, result


@pytest.mark.parametrize("shape", [(6, 10), (3, 5), (2, 3), (1, 4)])
def test_cell_weights_are_the_lookups_integral_over_each_cell(tmp_path, shape):
    """Every cell of a small random image (the seam's columns and the pole rows included),
    numerically: uniform in u and v, the lookup's mean over a cell is the [1, 6, 1] / 8 blur of
    the texels along both axes, rows clamped (an edge row's 7/8 and 1/8); in solid angle (what
    the pdf is per) the sine weighs rows near the poles otherwise, and the sampling tables'
    cells follow the solid-angle integral, as cell_weights_reference writes it out."""
    h, w = shape
    rng = np.random.default_rng(21)
    img = rng.uniform(0.0, 3.0, (h, w, 3)) * (rng.random((h, w, 1)) < 0.7)
    img[0, 0] = (8.0, 4.0, 2.0)  # at the pole and the seam
    img = img.astype(np.float32)
    m = img.astype(np.float64).mean(axis=2)
    cols = (np.roll(m, 1, axis=1) + 6 * m + np.roll(m, -1, axis=1)) / 8
    padded = np.pad(cols, ((1, 1), (0, 0)), mode="edge")
    blur = (padded[:-2] + 6 * padded[1:-1] + padded[2:]) / 8
    np.testing.assert_allclose(cell_means_numeric(img, solid_angle=False), blur, rtol=1e-12)

    E = env_from(img, tmp_path)
    marginal, conditional = sampling_tables(E.image)
    prob = np.diff(marginal)[:, None] * np.diff(conditional, axis=1)
    z = np.cos(np.pi * np.arange(h + 1) / h)
    area = (z[:-1] - z[1:])[:, None] * np.full(w, 2 * np.pi / w)[None, :]
    integral = cell_means_numeric(img, n=128) * area  # midpoint rule in theta: error ~1e-6
    np.testing.assert_allclose(prob, integral / integral.sum(), rtol=2e-5, atol=1e-12)
    np.testing.assert_allclose(prob, cell_weights_reference(img)[0], rtol=1e-9, atol=1e-15)
    if h >= 3:
        # the blur times the solid angle would put too little on the pole rows' neighbours
        approx = blur * area / (blur * area).sum()
        assert np.abs(approx / (integral / integral.sum()) - 1)[[0, -1]].max() > 0.01


def test_sampled_cells_follow_a_numpy_model_chi_square(tmp_path):
    """A sparse random image, its cells' probabilities written out (cell_weights_reference):
    each cell split in four equal solid angles (cos theta and phi halved), the counts of
    directions sampled in each against the model, and the kernels' pdf equal to the model's."""
    h, w = 6, 10
    rng = np.random.default_rng(16)
    img = (rng.uniform(0.0, 3.0, (h, w, 3)) * (rng.random((h, w, 1)) < 0.25)).astype(np.float32)
    img[0, 0] = (2.0, 1.0, 0.5)  # at the pole and the seam
    img[2:5, 3:8] = 0.0  # a black region wider than a footprint: cells with nothing to sample
    E = env_from(img, tmp_path)
    prob, area = cell_weights_reference(img)
    assert (prob == 0).any() and (prob > 0).sum() > 20
    n = 400_000  # a lit texel's dark neighbours get only its tent's tail
    dirs, _, pdf = _sample_many(E, np.random.default_rng(17).random((n, 2)))
    i, j = cells_of(dirs, h, w)
    np.testing.assert_allclose(pdf, (prob / area)[i, j], rtol=1e-9)
    z = np.cos(np.pi * np.arange(h + 1) / h)
    lower = dirs[:, 1] < (z[i] + z[i + 1]) / 2
    u = np.mod(np.arctan2(dirs[:, 0], dirs[:, 2]) / (2 * np.pi) + 0.5, 1.0)
    right = np.mod(np.floor(u * 2 * w), 2).astype(int)
    observed = np.bincount(((i * w + j) * 2 + lower) * 2 + right, minlength=4 * h * w).astype(float)
    expected = np.repeat(prob.ravel(), 4) * n / 4
    assert observed[expected == 0].sum() == 0  # no sample where the model has none
    keep = expected > 0
    assert expected[keep].min() > 20
    result = stats.chisquare(observed[keep], expected[keep])
    assert result.pvalue > 1e-3, result
    # environment_pdf of random directions (not only sampled ones) is the model's too
    d = rng.normal(size=(4000, 3))
    d = np.ascontiguousarray(d / np.linalg.norm(d, axis=1, keepdims=True))
    i, j = cells_of(d, h, w)
    np.testing.assert_allclose(_pdf_many(E, d), (prob / area)[i, j], rtol=1e-9)


@pytest.mark.parametrize("texel", [(2, 3), (0, 0), (5, 7)], ids=["inside", "pole-and-seam", "bottom-right"])
def test_pdf_is_positive_wherever_the_lookup_is(tmp_path, texel):
    """One bright texel: the lookup reaches half way into each neighbouring cell (wrapping at the
    seam, clamped at a pole), and the pdf is positive exactly in those cells; a nearest-texel
    distribution would miss the neighbours (biased light sampling). Then light sampling alone
    integrates the lookup over the sphere exactly (within standard errors)."""
    h, w = 6, 8
    img = np.zeros((h, w, 3), np.float32)
    img[texel] = (3.0, 2.0, 1.0)
    E = env_from(img, tmp_path)
    dirs, _ = sphere_grid(480, 640)
    lit = _radiance_many(E, dirs).max(axis=1) > 0
    pdf = _pdf_many(E, dirs)
    assert lit.sum() > 1000
    assert np.all(pdf[lit] > 0)
    i, j = cells_of(dirs, h, w)
    a, b = texel
    around = {(min(max(a + di, 0), h - 1), (b + dj) % w) for di in (-1, 0, 1) for dj in (-1, 0, 1)}
    assert set(zip(i[pdf > 0].tolist(), j[pdf > 0].tolist())) == around
    assert set(zip(i[lit].tolist(), j[lit].tolist())) == around
    # the integral of the lookup over the sphere, by light sampling alone
    n = 100_000
    sampled, rgb, p = _sample_many(E, np.random.default_rng(18).random((n, 2)))
    assert np.all(p > 0)
    f = rgb / p[:, None]
    mean, se = f.mean(axis=0), f.std(axis=0, ddof=1) / np.sqrt(n)
    exact = exact_integral(img, np.ones_like)
    assert np.all(np.abs(mean - exact) < 4.5 * se), (mean, exact, se)


@pytest.mark.parametrize("rotate", [(0, 0, 0), (0, 37, 0)])
def test_importance_sampled_irradiance_matches_the_exact_integral(tmp_path, rotate):
    """E(+y) = integral of L(w) max(0, w.y) dw over the bilinear lookup: exact in phi, numeric in
    theta (exact_integral), against the mean of L cos / pdf over sampled directions (a
    rotation about y keeps +y)."""
    img = make_image(seed=6)
    E = env_from(img, tmp_path, rotate=rotate)
    exact = exact_integral(img, lambda c: np.maximum(c, 0.0))
    rng = np.random.default_rng(7)
    n = 100_000
    dirs, rgb, pdf = _sample_many(E, rng.random((n, 2)))
    f = rgb * np.maximum(dirs[:, 1], 0)[:, None] / pdf[:, None]
    mean = f.mean(axis=0)
    se = f.std(axis=0, ddof=1) / np.sqrt(n)
    assert np.all(se > 0)
    assert np.all(np.abs(mean - exact) < 4 * se), (mean, exact, se)


def test_importance_sampling_has_lower_variance_than_uniform_on_a_sunny_sky():
    """The shipped sky: the sun carries most of the light, and sampling finds it."""
    E = build_environment(file="sky.hdr", base_dir=EXAMPLES)
    rng = np.random.default_rng(8)
    n = 20000
    dirs, rgb, pdf = _sample_many(E, rng.random((n, 2)))
    f_is = rgb.mean(axis=1) / pdf
    v = rng.normal(size=(n, 3))
    v = np.ascontiguousarray(v / np.linalg.norm(v, axis=1, keepdims=True))
    f_uniform = _radiance_many(E, v).mean(axis=1) * 4 * np.pi
    assert f_is.std() < 0.1 * f_uniform.std()
    assert abs(f_is.mean() - f_uniform.mean()) < 4 * f_uniform.std() / np.sqrt(n)


# ---------------------------------------------------------------------------------------------
# Path mode


@pytest.mark.parametrize("strategy", ["mis", "light", "bsdf"])
def test_diffuse_plane_under_an_image_sky_in_path_mode(tmp_path, monkeypatch, strategy):
    """A white diffuse plane (albedo 0.8) facing +y under an image environment, seen from above:
    every pixel is 0.8 / pi times the irradiance E(+y) of the bilinear lookup (exact_integral;
    light leaving the plane upwards never returns). Next-event estimation alone, BSDF sampling
    alone and MIS each find it: light sampling would miss radiance where its pdf were zero, and
    MIS weights that did not sum to one (the two pdfs disagreeing) would bias it."""
    img = make_image(seed=19, h=8, w=16)  # a bright texel above the horizon, a black row below
    save_array(tmp_path / "sky.exr", img)
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 24, "height": 24, "spp": 16, "mode": "path", "max_depth": -1},
            "camera": {"position": [0, 3, -3], "look_at": [0, 0, 0], "fov": 30},
            "objects": [
                {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0],
                 "material": {"type": "diffuse", "color": [0.8, 0.8, 0.8]}},
            ],
            "environment": {"file": str(tmp_path / "sky.exr"), "rotate": [0, 30, 0]},
        }
    )  # fmt: skip
    monkeypatch.setenv("RAYLUME_PATH_STRATEGY", strategy)
    image = raylume.render(scene, aovs=False, seed=20)
    rgb = image.rgb.reshape(-1, 3).astype(np.float64)
    assert np.isfinite(rgb).all()
    expected = 0.8 / np.pi * exact_integral(img, lambda c: np.maximum(c, 0.0))
    mean, se = rgb.mean(axis=0), rgb.std(axis=0, ddof=1) / np.sqrt(len(rgb))
    assert np.all(se > 0)
    assert np.all(np.abs(mean - expected) < 4.5 * se), (strategy, mean, expected, se)


# ---------------------------------------------------------------------------------------------
# Loading


@pytest.mark.parametrize("shape", [(13, 37), (5, 6), (2, 300)])
def test_hdr_written_by_raylume_reads_back(tmp_path, shape):
    rng = np.random.default_rng(9)
    img = (rng.random(shape + (3,)) * np.exp(rng.normal(0, 4, shape + (1,)))).astype(np.float32)
    img[0, 0] = 0.0
    save_array(tmp_path / "a.hdr", img)
    back = load_environment_image(tmp_path / "a.hdr")
    assert back.dtype == np.float32 and back.shape == img.shape
    np.testing.assert_array_equal(back, rgbe_decode(rgbe_encode(img)))
    # RGBE precision: within 1/128 of each texel's largest channel
    assert np.all(np.abs(back - img) <= img.max(axis=2, keepdims=True) / 128 + 1e-30)


def test_exr_written_by_raylume_reads_back_exactly(tmp_path):
    rng = np.random.default_rng(10)
    img = (rng.random((11, 23, 3)) * 100).astype(np.float32)
    save_array(tmp_path / "a.exr", img)
    np.testing.assert_array_equal(load_environment_image(tmp_path / "a.exr"), img)


def _rle_channel(values: bytes) -> bytes:
    """New-style RLE of one channel: runs (count + 128, byte) of 3 or more equal bytes,
    literals (count, bytes...) otherwise."""
    out = bytearray()
    k = 0
    literal = bytearray()
    while k < len(values):
        run = 1
        while k + run < len(values) and values[k + run] == values[k] and run < 127:
            run += 1
        if run >= 3:
            if literal:
                out += bytes([len(literal)]) + literal
                literal = bytearray()
            out += bytes([128 + run, values[k]])
            k += run
        else:
            literal.append(values[k])
            k += 1
            if len(literal) == 128:
                out += bytes([128]) + literal
                literal = bytearray()
    if literal:
        out += bytes([len(literal)]) + literal
    return bytes(out)


def test_run_length_encoded_hdr_reads_right(tmp_path):
    h, w = 4, 150  # more than 127 equal bytes in a row: several runs per channel
    rgbe = np.zeros((h, w, 4), np.uint8)
    rgbe[..., 3] = 130  # one exponent everywhere: long runs
    rgbe[0, :, 0] = 200
    rgbe[1, :, 1] = np.arange(w) % 256  # literals
    rgbe[2, 10:20] = (128, 64, 32, 129)
    rgbe[3] = (255, 255, 255, 140)
    body = bytearray()
    for y in range(h):
        body += bytes([2, 2, w >> 8, w & 0xFF])
        for c in range(4):
            body += _rle_channel(rgbe[y, :, c].tobytes())
    header = f"#?RADIANCE\nGAMMA=1\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode()
    assert len(body) < h * w * 4 / 2  # runs really were used
    (tmp_path / "rle.hdr").write_bytes(header + body)
    got = load_environment_image(tmp_path / "rle.hdr")
    np.testing.assert_array_equal(got, rgbe_decode(rgbe))
    # a value check independent of rgbe_decode: (m + 0.5) / 256 * 2^(e - 128)
    assert got[2, 15, 0] == pytest.approx((128.5 / 256) * 2, rel=1e-7)
    assert got[0, 0, 1] == pytest.approx((0.5 / 256) * 4, rel=1e-7)


def test_flat_and_old_style_run_length_hdr_read_right(tmp_path):
    # width 5: too narrow for the new format; (1, 1, 1, n) repeats the previous pixel n times
    pixels = [(100, 50, 25, 129), (1, 1, 1, 3), (10, 20, 200, 127)]
    body = b"".join(bytes(p) for p in pixels)
    (tmp_path / "old.hdr").write_bytes(b"#?RGBE\n\n+Y 2 +X 5\n" + body + bytes((7, 8, 9, 128)) * 5)
    got = load_environment_image(tmp_path / "old.hdr")
    want = np.array([[pixels[0]] * 4 + [pixels[2]], [(7, 8, 9, 128)] * 5], np.uint8)[::-1]  # +Y: bottom-up
    np.testing.assert_array_equal(got, rgbe_decode(want))


def test_the_shipped_sky():
    E = build_environment(file="sky.hdr", base_dir=EXAMPLES)
    h, w = E.image.shape[:2]
    assert (h, w) == (128, 256)
    # above the horizon: blue sky; below: darker ground; the sun is far brighter than either
    upper, lower = E.image[: h // 2].reshape(-1, 3), E.image[h // 2 :].reshape(-1, 3)
    sun = upper.mean(axis=1) > 5
    assert 0 < sun.sum() < 100
    sky = upper[~sun].mean(axis=0)
    assert sky[2] > sky[0] and lower.mean() < 0.5 * sky.mean()
    assert upper.max() > 500 * upper[~sun].max()


# ---------------------------------------------------------------------------------------------
# Errors


def _check_error(exc, path_text: str, key: str = "environment.file"):
    message = str(exc.value)
    assert message.startswith(f"scene.toml: {key}:"), message
    assert path_text in message, message
    assert "\n" not in message and "Traceback" not in message


def _good_hdr(tmp_path):
    save_array(tmp_path / "good.hdr", make_image())
    return (tmp_path / "good.hdr").read_bytes()


def _bad_files(tmp_path):
    good = _good_hdr(tmp_path)
    save_array(tmp_path / "good.exr", make_image(h=64, w=64))
    exr = (tmp_path / "good.exr").read_bytes()
    nan = make_image()
    nan[3, 4, 1] = np.nan
    save_array(tmp_path / "nan.exr", nan)
    inf = make_image()
    inf[0, 0, 0] = np.inf
    save_array(tmp_path / "inf.exr", inf)
    neg = make_image()
    neg[5, 5, 2] = -1.0
    save_array(tmp_path / "negative.exr", neg)
    (tmp_path / "folder.hdr").mkdir()
    (tmp_path / "truncated.hdr").write_bytes(good[: len(good) * 2 // 3])
    (tmp_path / "header_only.hdr").write_bytes(good[:40])
    (tmp_path / "garbage.hdr").write_bytes(b"hello, world")
    (tmp_path / "garbage.exr").write_bytes(b"hello, world" * 10)
    (tmp_path / "truncated.exr").write_bytes(exr[: len(exr) * 4 // 5])
    (tmp_path / "bomb.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n" + b"\0" * 100)
    (tmp_path / "sky.png").write_bytes(b"\x89PNG")


@pytest.mark.parametrize(
    "name, words",
    [
        ("missing.hdr", "does not exist"),
        ("folder.hdr", "folder"),
        ("sky.png", "unsupported"),
        ("truncated.hdr", "truncated"),
        ("header_only.hdr", "cannot read"),
        ("garbage.hdr", "not a Radiance"),
        ("garbage.exr", "not a readable OpenEXR"),
        ("truncated.exr", "not a readable OpenEXR"),
        ("bomb.hdr", f"more than {MAX_TEXELS} texels"),
        ("nan.exr", "NaN or infinite"),
        ("inf.exr", "NaN or infinite"),
        ("negative.exr", "negative"),
    ],
)
def test_bad_files_raise_scene_errors_naming_file_and_key(tmp_path, name, words):
    _bad_files(tmp_path)
    with pytest.raises(SceneError) as exc:
        build_environment(file=name, base_dir=tmp_path, source="scene.toml")
    _check_error(exc, str(tmp_path / name))
    assert words in str(exc.value)


@pytest.mark.parametrize(
    "kwargs, key",
    [
        ({"intensity": float("nan")}, "environment.intensity"),
        ({"intensity": float("inf")}, "environment.intensity"),
        ({"intensity": -1.0}, "environment.intensity"),
        ({"intensity": 1e38}, "environment.intensity"),
        ({"rotate": (0, float("nan"), 0)}, "environment.rotate"),
        ({"color": (1, -1, 0)}, "environment.color"),
        ({"color": (1, 2)}, "environment.color"),
        ({"color": (1, 1, 1), "file": "good.hdr"}, "environment"),
    ],
)
def test_bad_values_raise_scene_errors_naming_the_key(tmp_path, kwargs, key):
    _good_hdr(tmp_path)
    args = {"file": "good.hdr"} if "color" not in kwargs else {}
    args.update(kwargs)
    with pytest.raises(SceneError) as exc:
        build_environment(**args, base_dir=tmp_path, source="scene.toml")
    _check_error(exc, "", key)


def test_errors_name_the_key_path_given(tmp_path):
    with pytest.raises(SceneError) as exc:
        build_environment(file="nope.exr", base_dir=tmp_path, source="a.toml", where="scenes[1].environment")
    assert str(exc.value).startswith("a.toml: scenes[1].environment.file: ")
    assert "nope.exr" in str(exc.value)


def test_rgbe_decode_inverts_rgbe_encode_within_its_precision():
    rng = np.random.default_rng(11)
    x = rng.random((50, 3)) * 10.0 ** rng.integers(-10, 10, (50, 1))
    back = rgbe_decode(rgbe_encode(x[None]))[0]
    assert np.all(np.abs(back - x) <= x.max(axis=1, keepdims=True) / 128)
    assert math.isclose(float(rgbe_decode(np.array([128, 0, 0, 129], np.uint8))[0]), 128.5 / 256 * 2)


def test_the_alias_table_picks_each_cell_with_its_probability():
    """Walker's alias table (one step a sample) gives each cell exactly the probability of the
    cdf tables: summing what every slot sends to its own cell and to its alias recovers
    P(row) P(column | row), and a cell of probability 0 gets nothing."""
    from raylume.kernels.shading.environment import alias_table, sampling_tables

    rng = np.random.default_rng(7)
    img = rng.uniform(0.0, 1.0, size=(9, 13, 3)) ** 4
    img[3] = 0.0  # a black row: the lookup still blends its neighbours into it, but not in row 0
    img[:2] = 0.0  # the two top rows black: cell row 0 gets no lookup at all
    marginal, conditional = sampling_tables(img.astype(np.float32))
    want = (np.diff(marginal)[:, None] * np.diff(conditional, axis=1)).ravel()
    table = alias_table(marginal, conditional)
    n = len(want)
    got = np.zeros(n)
    np.add.at(got, np.arange(n), table[:, 0] / n)
    np.add.at(got, table[:, 1].astype(int), (1.0 - table[:, 0]) / n)
    np.testing.assert_allclose(got, want / want.sum(), rtol=1e-10, atol=1e-15)
    assert (want[:13] == 0).all() and (got[:13] == 0).all()
    assert ((table[:, 0] >= 0) & (table[:, 0] <= 1)).all()
    # each slot carries its cell's solid-angle pdf and its alias cell's: P(cell) / the cell's
    # solid angle, 2 pi / W times the band between the row's polar edges
    theta = np.linspace(0.0, np.pi, 9 + 1)
    solid_angle = np.repeat((np.cos(theta[:-1]) - np.cos(theta[1:])) * 2 * np.pi / 13, 13)
    np.testing.assert_allclose(table[:, 2], want / want.sum() / solid_angle, rtol=1e-12)
    np.testing.assert_array_equal(table[:, 3], table[table[:, 1].astype(int), 2])
