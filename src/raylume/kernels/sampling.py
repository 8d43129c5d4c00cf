"""Deterministic per-sample random numbers: a counter-based hash, so images do not depend
on thread scheduling or on how the frame is split into tiles."""

import numpy as np
from numba import njit

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2**-53


@njit(error_model="numpy", _nrt=False)
def mix64(x):
    """splitmix64 finaliser."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@njit(error_model="numpy", _nrt=False)
def uniform2(seed, pixel, sample):
    """Two independent uniforms in [0, 1) for (seed, pixel, sample)."""
    key = mix64(np.uint64(seed) * _GOLDEN + np.uint64(pixel))
    key = mix64(key + np.uint64(sample) * _GOLDEN)
    a = float(key >> _S11) * _TO_UNIT
    b = float(mix64(key + _GOLDEN) >> _S11) * _TO_UNIT
    return a, b


@njit(error_model="numpy", _nrt=False)
def stratified_offset(seed, pixel, sample, spp):
    """Sample position inside the pixel, in [0, 1)^2: jittered in a near-square grid of strata.
    One sample per pixel is the pixel centre, as DESIGN.md's camera says."""
    if spp == 1:
        return 0.5, 0.5
    cols = int(np.sqrt(spp))
    rows = (spp + cols - 1) // cols
    cx = sample % cols
    cy = sample // cols
    jx, jy = uniform2(seed, pixel, sample)
    return (cx + jx) / cols, (cy + jy) / rows
