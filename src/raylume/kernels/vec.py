"""3-vectors as tuples of floats inside Numba kernels: no allocation, inlined by LLVM."""

import math

from numba import njit

# fastmath without 'nnan'/'ninf': traversal relies on +-inf behaving as IEEE says.
FAST = {"nsz", "arcp", "contract", "afn"}

# Options for per-ray functions. They never allocate, so they run without Numba's reference
# counting: otherwise every call increments and decrements the count of each array it is
# passed, atomically, and that cost more than the traversal itself (210 vs 117 ns per ray on
# the bunny), and made two threads slower than one as they fought over the counters.
# forceinline is said on every one: a Numba function that leaves it unset inherits it from the
# function whose compilation triggered its own (as with fastmath), and a call kept on purpose
# (the transparent-shadow walk, area-light sampling) would then be inlined.
KERNEL = dict(fastmath=FAST, error_model="numpy", _nrt=False, forceinline=False)
# Per-ray functions that take arrays and run once or more per ray: inlined by LLVM
# (`alwaysinline`), because a call passes each array descriptor by value (the seed's trace lost a
# quarter of its speed to that). Not Numba's own inline="always", which inlined at the level of
# Numba IR and typed every inlined copy again: a cold render of the seed spent 40 of its 81 s of
# compilation inlining and 13 more typing; with LLVM's inlining it compiles in 38 s.
INLINE = dict(KERNEL, forceinline=True)


@njit(**KERNEL)
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(**KERNEL)
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(**KERNEL)
def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@njit(**KERNEL)
def hadamard(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@njit(**KERNEL)
def madd(a, b, s):
    """a + b * s"""
    return (a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s)


@njit(**KERNEL)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**KERNEL)
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(**KERNEL)
def length(a):
    return math.sqrt(dot(a, a))


@njit(**KERNEL)
def normalize(a):
    n = length(a)
    if n == 0.0:
        return (0.0, 0.0, 0.0)
    inv = 1.0 / n
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@njit(**KERNEL)
def max_abs(a):
    return max(abs(a[0]), abs(a[1]), abs(a[2]))


@njit(**KERNEL)
def row3(arr, i, k):
    """arr[i, k:k+3] as a float tuple (float64 even when arr is float32)."""
    return (float(arr[i, k]), float(arr[i, k + 1]), float(arr[i, k + 2]))
