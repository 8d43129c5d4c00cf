"""Deterministic per-sample random numbers: a counter-based hash, so images do not depend
on thread scheduling or on how the frame is split into tiles.

Every camera sample has a 64-bit key, `sample_key(seed, pixel, sample)`; whatever that sample
needs later (its lens position, the points it picks on area lights at each bounce) is hashed
from the key and a small counter, so no random state is stored or passed around by reference.

Pixel filters are applied by filter importance sampling: a sample's stratified position in the
unit square is warped through the filter's inverse CDF (tabulated by `filter_table`), so every
pixel gathers its own samples, spread over the filter's footprint, and weights them equally
(with the sign of the filter for Mitchell's negative lobes). No sample is shared between pixels:
deterministic and free of write races; box is the plain jittered pixel of DESIGN.md.
"""

import math

import numpy as np
from numba import njit

from .layout import FILTER_TABLE_SIZE

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2**-53
_LENS = np.uint64(0x5EED1E45)  # salts: lens samples, shading events
_EVENT = np.uint64(0xE7E47)
_MASK32 = np.uint64(0xFFFFFFFF)
# Largest unit float below 1, so that scaled samples stay inside their stratum.
ONE_MINUS_EPS = 1.0 - 2.0**-53


@njit(error_model="numpy", _nrt=False)
def mix64(x):
    """splitmix64 finaliser."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@njit(error_model="numpy", _nrt=False)
def sample_key(seed, pixel, sample):
    """The key of one camera sample; everything random about that sample derives from it."""
    key = mix64(np.uint64(seed) * _GOLDEN + np.uint64(pixel))
    return mix64(key + np.uint64(sample) * _GOLDEN)


@njit(error_model="numpy", _nrt=False)
def key_uniform2(key):
    """Two independent uniforms in [0, 1) from a key."""
    a = float(key >> _S11) * _TO_UNIT
    b = float(mix64(key + _GOLDEN) >> _S11) * _TO_UNIT
    return a, b


@njit(error_model="numpy", _nrt=False)
def uniform2(seed, pixel, sample):
    """Two independent uniforms in [0, 1) for (seed, pixel, sample)."""
    return key_uniform2(sample_key(seed, pixel, sample))


@njit(error_model="numpy", _nrt=False)
def sub_key(key, index):
    """An independent key for the index-th use of `key` (a bounce, a light, a sample)."""
    return mix64(key ^ (np.uint64(index) * _M2 + _GOLDEN))


@njit(error_model="numpy", _nrt=False)
def event_key(key, event):
    """The key of a shading event along a camera sample's path (event: rays traced so far)."""
    return mix64(key + (np.uint64(event) + _EVENT) * _GOLDEN)


@njit(error_model="numpy", _nrt=False)
def stratum(s, n, jx, jy):
    """Sample s of n in [0, 1)^2: jitter (jx, jy) inside cell s of a near-square grid of
    cols x rows = floor(sqrt n) x floor(n / cols) strata; the few samples beyond the grid
    (n not a product) take the jitter itself as a uniform point, which keeps the estimate
    unbiased (an incomplete grid would leave a corner of the domain unsampled)."""
    cols = int(math.sqrt(n))
    rows = n // cols
    if s >= cols * rows:
        return jx, jy
    x = (s % cols + jx) / cols
    y = (s // cols + jy) / rows
    return min(x, ONE_MINUS_EPS), min(y, ONE_MINUS_EPS)


@njit(error_model="numpy", _nrt=False)
def stratified_offset(seed, pixel, sample, spp):
    """Sample position inside the pixel, in [0, 1)^2: jittered in a near-square grid of strata.
    One sample per pixel is the pixel centre, as DESIGN.md's camera says."""
    if spp == 1:
        return 0.5, 0.5
    jx, jy = uniform2(seed, pixel, sample)
    return stratum(sample, spp, jx, jy)


@njit(error_model="numpy", _nrt=False)
def stratified_key(key, s, n):
    """Sample s of n stratified points in [0, 1)^2, jittered by a hash of key."""
    jx, jy = key_uniform2(sub_key(key, s))
    return stratum(s, n, jx, jy)


@njit(error_model="numpy", _nrt=False)
def permute(i, n, p):
    """Element i of a pseudo-random permutation of 0..n-1 chosen by p (Kensler 2013,
    "Correlated Multi-Jittered Sampling"): lets the lens use the pixel's strata in a
    shuffled order, so lens and pixel positions are both stratified but not correlated."""
    w = np.uint64(n - 1)
    w |= w >> np.uint64(1)
    w |= w >> np.uint64(2)
    w |= w >> np.uint64(4)
    w |= w >> np.uint64(8)
    w |= w >> np.uint64(16)
    p = np.uint64(p) & _MASK32
    x = np.uint64(i)
    while True:
        x ^= p
        x = (x * np.uint64(0xE170893D)) & _MASK32
        x ^= p >> np.uint64(16)
        x ^= (x & w) >> np.uint64(4)
        x ^= p >> np.uint64(8)
        x = (x * np.uint64(0x0929EB3F)) & _MASK32
        x ^= p >> np.uint64(23)
        x ^= (x & w) >> np.uint64(1)
        x = (x * (np.uint64(1) | (p >> np.uint64(27)))) & _MASK32
        x = (x * np.uint64(0x6935FA69)) & _MASK32
        x ^= (x & w) >> np.uint64(11)
        x = (x * np.uint64(0x74DCB303)) & _MASK32
        x ^= (x & w) >> np.uint64(2)
        x = (x * np.uint64(0x9E501CC3)) & _MASK32
        x ^= (x & w) >> np.uint64(2)
        x = (x * np.uint64(0xC860A3DF)) & _MASK32
        x &= w
        x ^= x >> np.uint64(5)
        if x < np.uint64(n):
            break
    return np.int64((x + p) % np.uint64(n))


@njit(error_model="numpy", _nrt=False)
def lens_sample(key, sample, spp):
    """Stratified point in [0, 1)^2 for the lens of camera sample `sample` of `spp`."""
    lens_key = key ^ _LENS
    if spp == 1:
        return key_uniform2(mix64(lens_key))
    s = permute(sample, spp, int(mix64(lens_key) >> np.uint64(40)))
    jx, jy = key_uniform2(mix64(lens_key + _GOLDEN))
    return stratum(s, spp, jx, jy)


@njit(error_model="numpy", _nrt=False)
def concentric_disk(u1, u2):
    """Map [0, 1)^2 onto the unit disk, area-preserving and keeping strata compact
    (Shirley and Chiu 1997)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        r = a
        phi = (math.pi / 4.0) * (b / a)
    else:
        r = b
        phi = math.pi / 2.0 - (math.pi / 4.0) * (a / b)
    return r * math.cos(phi), r * math.sin(phi)


@njit(error_model="numpy", _nrt=False)
def filter_offset(cam, first, u):
    """Offset in pixels (from the pixel centre) of the unit sample u under the filter whose
    inverse CDF is tabulated at cam[first : first + FILTER_TABLE_SIZE]."""
    x = u * (FILTER_TABLE_SIZE - 1)
    k = min(int(x), FILTER_TABLE_SIZE - 2)
    t = x - k
    return cam[first + k] * (1.0 - t) + cam[first + k + 1] * t


# --- pixel filters (Python side: tables the kernels read) ------------------------------------

def _gaussian(x, radius=1.5, sigma=0.5):
    g = np.exp(-x * x / (2 * sigma * sigma)) - math.exp(-radius * radius / (2 * sigma * sigma))
    return np.maximum(g, 0.0)


def _mitchell(x, radius=2.0, b=1.0 / 3.0, c=1.0 / 3.0):
    x = np.abs(2.0 * x / radius)  # Mitchell-Netravali on [-2, 2], stretched to the radius
    near = (12 - 9 * b - 6 * c) * x**3 + (-18 + 12 * b + 6 * c) * x**2 + (6 - 2 * b)
    far = (-b - 6 * c) * x**3 + (6 * b + 30 * c) * x**2 + (-12 * b - 48 * c) * x + (8 * b + 24 * c)
    return np.where(x < 1, near, np.where(x < 2, far, 0.0)) / 6.0


# name -> (radius in pixels, separable 1D profile on [-radius, radius]); pbrt-v4's defaults.
PIXEL_FILTERS = {
    "box": (0.5, None),
    "gaussian": (1.5, _gaussian),
    "mitchell": (2.0, _mitchell),
}


def filter_table(name: str) -> tuple[int, float, np.ndarray]:
    """(kind, negative-from, inverse CDF table) of a pixel filter, for the camera array.

    The separable filter's 1D profile f is sampled in proportion to |f|: table[k] is the offset
    x with CDF(x) = k / (FILTER_TABLE_SIZE - 1), so warping a stratified u gives stratified
    offsets distributed like the filter, and each sample weighs sign(f(x)) (normalised by the
    pixel's sum of weights)."""
    from .layout import FILTER_BOX, FILTER_WARPED

    radius, profile = PIXEL_FILTERS[name]
    if profile is None:
        return FILTER_BOX, math.inf, np.linspace(-0.5, 0.5, FILTER_TABLE_SIZE)
    x = np.linspace(-radius, radius, 20001)
    signed = profile(x)
    negative = float(np.abs(x[signed < 0]).min()) if (signed < 0).any() else math.inf
    f = np.abs(signed)
    cdf = np.concatenate([[0.0], np.cumsum((f[1:] + f[:-1]) * 0.5)])
    cdf /= cdf[-1]
    u = np.linspace(0.0, 1.0, FILTER_TABLE_SIZE)
    table = np.interp(u, cdf, x)
    table[0], table[-1] = -radius, radius
    return FILTER_WARPED, negative, table
