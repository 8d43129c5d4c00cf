"""3-vectors as tuples of floats inside Numba kernels: no allocation, inlined by LLVM."""

import math

from numba import njit

# fastmath without 'nnan'/'ninf': traversal relies on +-inf behaving as IEEE says.
FAST = {"nsz", "arcp", "contract", "afn"}


@njit(fastmath=FAST)
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(fastmath=FAST)
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(fastmath=FAST)
def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(fastmath=FAST)
def hadamard(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@njit(fastmath=FAST)
def madd(a, b, s):
    """a + b * s"""
    return (a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s)


@njit(fastmath=FAST)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(fastmath=FAST)
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(fastmath=FAST)
def length(a):
    return math.sqrt(dot(a, a))


@njit(fastmath=FAST)
def normalize(a):
    n = length(a)
    if n == 0.0:
        return (0.0, 0.0, 0.0)
    inv = 1.0 / n
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@njit(fastmath=FAST)
def max_abs(a):
    return max(abs(a[0]), abs(a[1]), abs(a[2]))


@njit(fastmath=FAST)
def row3(arr, i, k):
    """arr[i, k:k+3] as a float tuple (float64 even when arr is float32)."""
    return (float(arr[i, k]), float(arr[i, k + 1]), float(arr[i, k + 2]))
