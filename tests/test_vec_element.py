"""vec.element: a tuple's element at a run-time index, read from a stack copy (no branch)."""

import numpy as np
from numba import njit

from raylume.kernels.vec import element


@njit
def _elements(values, n):
    out = np.empty(n)
    for k in range(n):
        out[k] = element(values, k)
    return out


@njit
def _int_elements(values, n):
    out = np.empty(n, np.int64)
    for k in range(n):
        out[k] = element(values, k)
    return out


def test_element_is_the_tuple_item_at_a_runtime_index():
    values = (1.5, -0.0, np.inf, -2.25)
    got = _elements(values, 4)
    assert np.array_equal(got, np.array(values))
    assert np.signbit(got[1])  # the value's bits, -0.0 kept
    assert np.array_equal(_int_elements((7, -3, 11), 3), [7, -3, 11])
