"""The sampled angles' sine and cosine (vec.turn, vec.quarter_sincos) against libm's, through
Python's math module: the polynomials replace libm in every direction sampler."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from raylume.kernels.vec import quarter_sincos, turn

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
