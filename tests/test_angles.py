"""The sampled angles' sine and cosine (vec.turn, vec.quarter_sincos) and the environment's
inverse functions (vec.atan2, vec.acos) against libm's, through Python's math module: the
polynomials replace libm in every direction sampler and environment lookup."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from raylume.kernels.vec import acos, atan2, quarter_sincos, turn

ULP = 2.0**-52  # of numbers in [1, 2); half that in [0.5, 1)


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-math.pi / 4, max_value=math.pi / 4))
def test_quarter_sincos_is_libm_to_an_ulp(a):
    c, s = quarter_sincos(a)
    assert abs(c - math.cos(a)) <= 2 * np.spacing(math.cos(a))
    assert abs(s - math.sin(a)) <= 2 * np.spacing(abs(math.sin(a)))


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=0.0, max_value=1.0, exclude_max=True))
def test_turn_is_the_point_at_that_fraction_of_a_turn(u):
    c, s = turn(u)
    # libm's answer at the rounded angle 2 pi u, whose rounding alone can move it by ~4 ulps of 1
    assert abs(c - math.cos(2.0 * math.pi * u)) <= 4 * ULP
    assert abs(s - math.sin(2.0 * math.pi * u)) <= 4 * ULP
    assert abs(c * c + s * s - 1.0) <= 4 * ULP


def test_turn_at_the_quarter_turns_is_exact():
    points = [turn(u) for u in (0.0, 0.25, 0.5, 0.75)]
    assert np.array_equal(np.array(points), np.array([(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]))


def within_ulps(value, expected, ulps):
    return abs(value - expected) <= ulps * np.spacing(abs(expected))


finite = st.floats(min_value=-1e300, max_value=1e300, allow_nan=False)


@settings(max_examples=500, deadline=None)
@given(finite, finite)
def test_atan2_is_libm_to_a_few_ulps(y, x):
    assert within_ulps(atan2(y, x), math.atan2(y, x), 3)


@settings(max_examples=500, deadline=None)
@given(st.floats(min_value=-1.0, max_value=1.0))
def test_acos_is_libm_to_a_few_ulps(x):
    assert within_ulps(acos(x), math.acos(x), 3)


def test_atan2_and_acos_on_dense_grids():
    """Every branch of the reductions (atan's at 7/16, 11/16, 19/16, 39/16; acos's at +-1/2),
    on both sides of each edge and the directions of a sphere."""
    rng = np.random.default_rng(7)
    for x, y in rng.normal(size=(20000, 2)):
        assert within_ulps(atan2(y, x), math.atan2(y, x), 3)
    for r in (0.4375, 0.6875, 1.1875, 2.4375, 1.0, 1.5, 0.5):
        for t in (np.nextafter(r, 0), r, np.nextafter(r, 3)):
            assert within_ulps(atan2(t, 1.0), math.atan2(t, 1.0), 3)
    for x in np.concatenate([np.linspace(-1, 1, 20001), [-0.5, 0.5, np.nextafter(0.5, 1), np.nextafter(-0.5, -1)]]):
        assert within_ulps(acos(x), math.acos(x), 3)


def test_atan2_and_acos_at_the_special_points():
    assert acos(1.0) == 0.0 and acos(-1.0) == math.pi and acos(0.0) == math.pi / 2
    assert math.isnan(acos(1.0 + 2**-52)) and math.isnan(acos(-1.5))
    for y, x in [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (1.0, 1.0), (-1.0, -1.0), (0.0, 0.0),
                 (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (5e-324, 1.0), (1.0, 5e-324)]:  # fmt: skip
        expected = math.atan2(y, x)
        got = atan2(y, x)
        assert got == expected and math.copysign(1.0, got) == math.copysign(1.0, expected), (y, x, got)


def test_turn_either_side_of_each_quarter_turn():
    # turn picks the quadrant's (cos, sin) by index from the nearest quarter turn: both sides of
    # every boundary between quarters, and of the eighths where the nearest one changes
    for k in range(8):
        for step in range(-3, 4):
            u = float(np.clip(k / 8 + step * 2.0**-53, 0.0, np.nextafter(1.0, 0.0)))
            c, s = turn(u)
            assert abs(c - math.cos(2.0 * math.pi * u)) <= 4 * ULP
            assert abs(s - math.sin(2.0 * math.pi * u)) <= 4 * ULP
