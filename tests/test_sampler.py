"""The low-discrepancy sampler (kernels/film/sampler.py): shuffled, Owen-scrambled Sobol points,
checked against scipy's Sobol sequence, the (0, m, 2)-net property, uniformity across pixels,
independence between dimensions, and the variance of the estimates they give."""

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import qmc

from raylume.kernels.film.sampler import (
    DIM_BSDF,
    DIM_LENS,
    DIM_LIGHT,
    DIM_PIXEL,
    SAMPLE_BITS,
    ld_uniform2,
    light_sample,
    owen_scramble,
    pixel_sample,
    reverse_bits32,
    sample_index,
    sample_key,
    sobol2,
)

TWO32 = 2.0**32


def _key(seed, pixel, s):
    return np.uint64(sample_key(seed, pixel, s))  # back from Python as an int, which may not fit int64


def _points(seed, pixel, n, dim, event):
    return np.array([ld_uniform2(_key(seed, pixel, s), dim, event) for s in range(n)])


def test_sobol2_is_the_sobol_sequence_scipy_gives():
    """scipy's points are in Gray-code order: its point i is Sobol's point i ^ (i >> 1)."""
    want = qmc.Sobol(d=2, scramble=False).random_base2(10)
    got = np.array([sobol2(i ^ (i >> 1)) for i in range(1024)], dtype=np.float64) / TWO32
    np.testing.assert_array_equal(got, want)


def test_reverse_bits_and_the_sample_index():
    reverse = numba.njit(lambda x: reverse_bits32(x))  # an intrinsic: called from compiled code
    rng = np.random.default_rng(1)
    for x in rng.integers(0, 2**32, 200, dtype=np.uint64):
        assert int(reverse(x)) == int(f"{int(x):032b}"[::-1], 2)
    for s in (0, 1, 4095, 2**SAMPLE_BITS - 1):
        assert int(sample_index(_key(7, 123456, s))) == s
    from raylume.scene.model import MAX_SPP
    from raylume.viewer.renderer import PATH_MAX_SPP

    assert max(MAX_SPP, PATH_MAX_SPP) <= 2**SAMPLE_BITS


def test_samples_beyond_the_index_bits_are_new_samples():
    """A Film may take more samples a pixel than the key's 16 index bits hold: sample 2^16 + s is
    another sample than sample s (QA found passes beyond 65,536 repeating the first ones), and
    each block of 2^16 is still a stratified sequence."""
    for s in (0, 1, 37):
        first, again = _key(5, 77, s), _key(5, 77, 2**SAMPLE_BITS + s)
        assert int(sample_index(again)) == s and first != again
        assert ld_uniform2(first, DIM_BSDF, 1) != ld_uniform2(again, DIM_BSDF, 1)
        assert pixel_sample(first) != pixel_sample(again)
    block = np.array([ld_uniform2(_key(5, 77, 2**SAMPLE_BITS + s), DIM_BSDF, 1) for s in range(64)])
    assert _is_net(block, 6)


def _is_net(points, m):
    """Whether every elementary interval of volume 2^-m, 2^a x 2^(m-a) cells for every a,
    holds exactly one of the 2^m points."""
    for a in range(m + 1):
        cells = np.floor(points[:, 0] * 2**a).astype(np.int64) * 2 ** (m - a) + np.floor(
            points[:, 1] * 2 ** (m - a)
        ).astype(np.int64)
        if np.bincount(cells, minlength=2**m).max() != 1:
            return False
    return True


@pytest.mark.parametrize("dim, event", [(DIM_PIXEL, 0), (DIM_LENS, 0), (DIM_BSDF, 3), (DIM_LIGHT, 1)])
def test_each_power_of_two_prefix_of_a_pixels_samples_is_a_net(dim, event):
    """A pixel's first 2^m samples, for every m, form a (0, m, 2)-net in every dimension: the
    shuffle and the scrambles keep Sobol's stratification. The control, independent uniforms,
    fails it."""
    for pixel in (0, 1, 99991):
        points = _points(5, pixel, 256, dim, event)
        for m in range(9):
            assert _is_net(points[: 2**m], m), (pixel, m)
    rng = np.random.default_rng(0)
    assert not _is_net(rng.random((64, 2)), 6)


def test_a_sample_is_uniform_over_pixels():
    """Sample s of many pixels: a chi-square test of a 16 x 16 histogram, for two samples, at a
    fixed seed (p above 1e-4)."""
    from scipy.stats import chisquare

    for s in (0, 37):
        pts = np.array([ld_uniform2(_key(3, p, s), DIM_BSDF, 2) for p in range(25600)])
        assert np.all((pts >= 0.0) & (pts < 1.0))
        cells = np.floor(pts[:, 0] * 16).astype(int) * 16 + np.floor(pts[:, 1] * 16).astype(int)
        assert chisquare(np.bincount(cells, minlength=256)).pvalue > 1e-4


def test_trace_modes_light_samples_are_stratified_over_the_pixels_samples():
    """A pixel's 16 camera samples' 4 shadow samples each on one light (trace mode's area
    lights): the 64 points together are a net, and so are each sample's 4; another light's
    points differ."""
    for pixel in (3, 4):
        pts = np.array([light_sample(_key(9, pixel, s), 2, 1, k, 4) for s in range(16) for k in range(4)])
        assert _is_net(pts, 6)
        for s in range(16):
            assert _is_net(pts[4 * s : 4 * s + 4], 2)
        other = np.array([light_sample(_key(9, pixel, s), 2, 0, k, 4) for s in range(16) for k in range(4)])
        assert not np.allclose(pts, other)


def test_dimensions_are_not_correlated():
    """Over a pixel's 64 samples, the first coordinates of two dimensions (or two events of one)
    have a correlation near 0: the mean over 400 pixels is within 4 standard errors of 0. The
    control, the two dimensions scrambled apart but not shuffled (the same Sobol index), is far
    from it: their first bits agree in every sample or in none."""
    pairs = [((DIM_BSDF, 1), (DIM_LIGHT, 1)), ((DIM_BSDF, 1), (DIM_BSDF, 2)), ((DIM_PIXEL, 0), (DIM_LENS, 0))]
    for a, b in pairs:
        corr = []
        for p in range(400):
            xa = _points(11, p, 64, *a)[:, 0]
            xb = _points(11, p, 64, *b)[:, 0]
            corr.append(np.corrcoef(xa, xb)[0, 1])
        corr = np.array(corr)
        assert abs(corr.mean()) < 4 * corr.std() / np.sqrt(len(corr)), (a, b)
    control = []
    for p in range(100):
        xa = np.array([owen_scramble(sobol2(s)[0], 2 * p + 1) for s in range(64)], np.float64)
        xb = np.array([owen_scramble(sobol2(s)[0], 2 * p + 2) for s in range(64)], np.float64)
        control.append(abs(np.corrcoef(xa, xb)[0, 1]))
    assert np.mean(control) > 0.5


def test_estimates_are_unbiased_and_far_less_noisy_than_independent_ones():
    """A pixel's 64-sample estimate of the integral of a smooth function over [0, 1)^2 (exact
    value 1/4 + sin(1)^2 ... computed by scipy's dblquad): over 2000 pixels its mean is within 4
    standard errors of the integral, and its variance is below a twentieth of independent
    uniforms' (scrambled nets converge as n^-3 for smooth integrands, against n^-1)."""
    from scipy.integrate import dblquad

    def f(x, y):
        return x * y + np.sin(3.0 * x + y) ** 2

    exact = dblquad(lambda y, x: f(x, y), 0, 1, 0, 1)[0]
    n = 64
    estimates = np.array([f(*_points(17, p, n, DIM_BSDF, 4).T).mean() for p in range(2000)])
    se = estimates.std() / np.sqrt(len(estimates))
    assert abs(estimates.mean() - exact) < 4 * se + 1e-12
    rng = np.random.default_rng(2)
    independent = f(*rng.random((2, 2000, n))).mean(axis=1)
    assert estimates.var() < independent.var() / 20


@settings(max_examples=300, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    pixel=st.integers(0, 2**40),
    s=st.integers(0, 4095),
    event=st.integers(0, 1000),
)
def test_low_discrepancy_numbers_stay_in_the_unit_interval(seed, pixel, s, event):
    key = _key(seed, pixel, s)
    for dim in (DIM_PIXEL, DIM_BSDF, DIM_LIGHT):
        x, y = ld_uniform2(key, dim, event)
        assert 0.0 <= x < 1.0 and 0.0 <= y < 1.0
    x, y = light_sample(key, event, event % 7, s % 16, 16)
    assert 0.0 <= x < 1.0 and 0.0 <= y < 1.0
