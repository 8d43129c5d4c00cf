"""Random numbers that depend only on (seed, pixel, sample, dimension): a counter-based hash,
so images do not depend on threads, tiles, passes or on how many rays were traced before.

Every camera sample has a 64-bit key, `sample_key(seed, pixel, sample)`. A *dimension* is a
named stream of numbers that sample uses for one purpose:

* PIXEL: the position inside the pixel (the key itself; stratified over the pixel's samples),
* LENS: the point on the thin lens (stratified over the samples in a shuffled order),
* LIGHT: points on area lights, one stream per shading event along the sample's path (the
  n-th surface it shades), then per light and per shadow sample (stratified),
* BSDF: reserved for directions sampled from materials (path tracing).

`dimension_key(key, DIM, event)` gives a stream's key; nothing random is stored or passed
around by reference.
"""

import math

import numpy as np

from ..vec import kernel_function, quarter_sincos, turn

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_TO_UNIT32 = 2.0**-32
_S32 = np.uint64(32)
_MASK32 = np.uint64(0xFFFFFFFF)
# Largest unit float below 1, so that scaled samples stay inside their stratum.
ONE_MINUS_EPS = 1.0 - 2.0**-53

# Dimensions: salts xor-ed into the sample key.
DIM_PIXEL = np.uint64(0)
DIM_LENS = np.uint64(0x5EED1E45)
DIM_LIGHT = np.uint64(0x11647E47)
DIM_BSDF = np.uint64(0xB5DFB5DF)


@kernel_function(error_model="numpy", _nrt=False)
def mix64(x):
    """splitmix64 finaliser."""
    x = (x ^ (x >> _S30)) * _M1
    x = (x ^ (x >> _S27)) * _M2
    return x ^ (x >> _S31)


@kernel_function(error_model="numpy", _nrt=False)
def sample_key(seed, pixel, sample):
    """The key of one camera sample; everything random about that sample derives from it."""
    key = mix64(np.uint64(seed) * _GOLDEN + np.uint64(pixel))
    return mix64(key + np.uint64(sample) * _GOLDEN)


# Compiled on first use like the other samplers (a kernel_function takes a literal event 0 as
# any int64): explicit signatures here and on light_sample had compiled both at the import of
# this module, which every kernel imports, 0.24 s of every cold start's compile.
@kernel_function(error_model="numpy", _nrt=False)
def dimension_key(key, dim, event):
    """The key of dimension `dim` of a camera sample, for its `event`-th use along the path."""
    return mix64((np.uint64(key) ^ dim) + np.uint64(event) * _GOLDEN)  # the types the signature gave


@kernel_function(error_model="numpy", _nrt=False)
def key_uniform2(key):
    """Two independent uniforms in [0, 1) from a key (a splitmix64 output): its high and low 32
    bits, 2^-32 apart as Mitsuba's float32 samples are 2^-24. One hash for two numbers: a second
    mix64 for 53 bits of each was ~1.4% of path mode's instructions (a chain of three hashes
    before each light sample's numbers: ~0.97x the Cornell box's time)."""
    return float(key >> _S32) * _TO_UNIT32, float(key & _MASK32) * _TO_UNIT32


@kernel_function(error_model="numpy", _nrt=False)
def sub_key(key, index):
    """An independent key for the index-th use of `key` (a light, a sample)."""
    return mix64(key ^ (np.uint64(index) * _M2 + _GOLDEN))


@kernel_function(error_model="numpy", _nrt=False)
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


@kernel_function(error_model="numpy", _nrt=False)
def stratified_key(key, s, n):
    """Sample s of n stratified points in [0, 1)^2, jittered by a hash of key."""
    jx, jy = key_uniform2(sub_key(key, s))
    return stratum(s, n, jx, jy)


@kernel_function(error_model="numpy", _nrt=False)
def pixel_sample(key, s, spp):
    """Position in [0, 1)^2 inside the pixel of sample s of spp (dimension PIXEL)."""
    jx, jy = key_uniform2(key ^ DIM_PIXEL)
    return stratum(s, spp, jx, jy)


@kernel_function(error_model="numpy", _nrt=False)
def lens_sample(key, sample, spp):
    """Stratified point in [0, 1)^2 for the lens of camera sample `sample` of `spp`
    (dimension LENS): the pixel's strata in a shuffled order, so lens and pixel positions are
    both stratified but not correlated."""
    lens_key = key ^ DIM_LENS
    if spp == 1:
        return key_uniform2(mix64(lens_key))
    s = permute(sample, spp, int(mix64(lens_key) >> np.uint64(40)))
    jx, jy = key_uniform2(mix64(lens_key + _GOLDEN))
    return stratum(s, spp, jx, jy)


@kernel_function(error_model="numpy", _nrt=False)
def light_sample(key, event, light, s, count):
    """Stratified point s of `count` in [0, 1)^2 on light `light`, at the `event`-th surface the
    camera sample shades (dimension LIGHT)."""
    return stratified_key(sub_key(dimension_key(key, DIM_LIGHT, event), light), s, count)


@kernel_function(error_model="numpy", _nrt=False)
def uniform_sphere(u1, u2):
    """A unit vector uniform over the sphere for (u1, u2) in [0, 1)^2 (pdf 1 / 4 pi)."""
    z = 1.0 - 2.0 * u1
    r = math.sqrt(max(0.0, 1.0 - z * z))
    c, s = turn(u2)
    return (r * c, r * s, z)


@kernel_function(error_model="numpy", _nrt=False)
def permute(i, n, p):
    """Element i of a pseudo-random permutation of 0..n-1 chosen by p (Kensler 2013,
    "Correlated Multi-Jittered Sampling")."""
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


@kernel_function(error_model="numpy", _nrt=False)
def concentric_disk(u1, u2):
    """Map [0, 1)^2 onto the unit disk, area-preserving and keeping strata compact
    (Shirley and Chiu 1997)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if abs(a) > abs(b):
        c, s = quarter_sincos((math.pi / 4.0) * (b / a))
        return a * c, a * s
    c, s = quarter_sincos((math.pi / 4.0) * (a / b))  # the angle pi/2 minus this one
    return b * s, b * c
