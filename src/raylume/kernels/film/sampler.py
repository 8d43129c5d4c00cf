"""Random numbers that depend only on (seed, pixel, sample, dimension): counter-based hashes
and per-pixel low-discrepancy sequences, so images do not depend on threads, tiles, passes or on
how many rays were traced before.

Every camera sample has a 64-bit key, `sample_key(seed, pixel, sample)`: a hash of (seed, pixel)
and the sample's index in its pixel. A *dimension* is a named stream of numbers that the sample
uses for one purpose, at each `event` (the n-th surface or segment of its path) that needs it:

* PIXEL: the position inside the pixel,
* LENS: the point on the thin lens,
* LIGHT: points on lights (next-event estimation; in trace mode per light, every shadow sample),
* BSDF: directions sampled from materials (path tracing).

Those four are low-discrepancy (`ld_uniform2`): in each dimension and event, a pixel's samples
are the points of its own shuffled, Owen-scrambled Sobol sequence, so that any power of two of
them is stratified (a (0, m, 2)-net), while each point alone is uniform. The rest (which light,
which lobe, Russian roulette, media, bidirectional paths) take independent hashes of the key:
`key_uniform2(dimension_key(key, DIM, event))`. Nothing random is stored or passed around by
reference.
"""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ..vec import kernel_function, quarter_sincos, turn

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_GOLDEN32 = np.uint64(0x9E3779B1)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_TO_UNIT32 = 2.0**-32
_S32 = np.uint64(32)
_MASK32 = np.uint64(0xFFFFFFFF)
# A sample key's low 16 bits are the sample's index in its pixel (MAX_SPP is 4096), the high
# 48 its pixel's hash (all of a 4K image's 8.3 M pixels differ there with a probability of 0.9).
SAMPLE_BITS = 16
_SAMPLE_MASK = np.uint64((1 << SAMPLE_BITS) - 1)
_SAMPLE_SHIFT = np.uint64(SAMPLE_BITS)
_PIXEL_MASK = np.uint64(~((1 << SAMPLE_BITS) - 1) & 0xFFFFFFFFFFFFFFFF)
_U1, _U8, _U16, _U24 = np.uint64(1), np.uint64(8), np.uint64(16), np.uint64(24)
_OWEN1, _OWEN2, _OWEN3 = (np.uint64(c) for c in (0x3D20ADEA, 0x05526C56, 0x53A22864))
_BYTE = np.uint64(255)

# Dimensions: 32-bit salts, xor-ed into the pixel's part of a sample key (dimension_key, ld_seed).
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
    """The key of one camera sample: a hash of (seed, pixel) in its high 48 bits and the
    sample's index in the pixel in its low 16. Everything random about the sample derives from
    it: the independent streams hash the whole key (`dimension_key`), the low-discrepancy ones
    the pixel's part and the index apart (`ld_uniform2`). A film may take more than 2^16 samples
    a pixel (passes into a raylume.Film): the index's higher bits go into the hash, so each
    block of 2^16 samples is a sequence of its own rather than the first block again."""
    block = np.uint64(sample) >> _SAMPLE_SHIFT
    pixel_hash = mix64(np.uint64(seed) * _GOLDEN + np.uint64(pixel) + block * _M2)
    return (pixel_hash & _PIXEL_MASK) | (np.uint64(sample) & _SAMPLE_MASK)


@kernel_function(error_model="numpy", _nrt=False)
def sample_index(key):
    """The index of a camera sample in its pixel, from its key (sample_key)."""
    return np.uint64(key) & _SAMPLE_MASK


# Compiled on first use like the other samplers (a kernel_function takes a literal event 0 as
# any int64): explicit signatures here and on light_sample had compiled both at the import of
# this module, which every kernel imports, 0.24 s of every cold start's compile.
@kernel_function(error_model="numpy", _nrt=False)
def dimension_key(key, dim, event):
    """The key of dimension `dim` of a camera sample, for its `event`-th use along the path. The
    salt goes above the sample's index (dimensions are 32-bit salts), so that no two samples of a
    pixel, however their salts differ, share a key."""
    return mix64((np.uint64(key) ^ (np.uint64(dim) << _SAMPLE_SHIFT)) + np.uint64(event) * _GOLDEN)


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
def uniform_sphere(u1, u2):
    """A unit vector uniform over the sphere for (u1, u2) in [0, 1)^2 (pdf 1 / 4 pi)."""
    z = 1.0 - 2.0 * u1
    r = math.sqrt(max(0.0, 1.0 - z * z))
    c, s = turn(u2)
    return (r * c, r * s, z)


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


# --- Low-discrepancy dimensions: shuffled, Owen-scrambled Sobol points (Burley 2020) ---------
# 32-bit fractions are held in uint64 (Numba computes on uint32 in 64 bits), masked to 32 bits
# after every product.


@intrinsic
def reverse_bits32(typingctx, x):
    """The low 32 bits of x in reverse order (LLVM's bitreverse: a byte swap and three masked
    steps on x86, where five shift-and-mask steps in Python's form took twice the instructions)."""
    if not isinstance(x, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        value = builder.trunc(context.cast(builder, args[0], sig.args[0], types.uint64), i32)
        reverse = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i32, [i32]), "llvm.bitreverse.i32")
        return builder.zext(builder.call(reverse, [value]), i64)

    return types.uint64(x), codegen


@kernel_function(error_model="numpy", _nrt=False)
def laine_karras(v, seed):
    """A hash of the 32-bit v in which each bit is flipped by a function of the bits below it
    (pbrt-v4's FastOwenScrambler, after Laine and Karras): in bit-reversed order, a nested
    uniform (Owen) scramble."""
    seed = np.uint64(seed) & _MASK32
    v ^= (v * _OWEN1) & _MASK32
    v = (v + seed) & _MASK32
    v = (v * ((seed >> _U16) | _U1)) & _MASK32
    v ^= (v * _OWEN2) & _MASK32
    v ^= (v * _OWEN3) & _MASK32
    return v


@kernel_function(error_model="numpy", _nrt=False)
def owen_scramble(x, seed):
    """A nested uniform (Owen) scramble of the 32-bit fraction x: each bit flipped by a hash of
    the bits above it."""
    return reverse_bits32(laine_karras(reverse_bits32(x), seed))


def _pascal_table():
    """Sobol's second dimension, bit-reversed, a byte of the index at a time: table[b, byte] is
    the xor of the reversed direction numbers of the byte's set bits (bits 8b..8b+7 of the
    index). Reversed, because its scramble (owen_scramble) reverses it first."""
    v = np.empty(32, np.uint32)
    v[0] = 1 << 31
    for k in range(1, 32):
        v[k] = v[k - 1] ^ (v[k - 1] >> 1)
    table = np.zeros((4, 256), np.uint64)
    for b in range(4):
        for byte in range(256):
            for j in range(8):
                if byte >> j & 1:
                    table[b, byte] ^= int(f"{int(v[8 * b + j]):032b}"[::-1], 2)
    return table


_PASCAL = _pascal_table()


@kernel_function(error_model="numpy", _nrt=False)
def sobol2_reversed(index):
    """The first two dimensions of the Sobol sequence at `index`, as 32-bit fractions with their
    bits reversed (the first digit in bit 0): the van der Corput sequence (the index itself) and
    Pascal's matrix mod 2 (together the (0, 2)-sequence in base 2)."""
    i = np.uint64(index) & _MASK32
    y = (
        _PASCAL[0, i & _BYTE]
        ^ _PASCAL[1, (i >> _U8) & _BYTE]
        ^ _PASCAL[2, (i >> _U16) & _BYTE]
        ^ _PASCAL[3, (i >> _U24) & _BYTE]
    )
    return i, y


@kernel_function(error_model="numpy", _nrt=False)
def sobol2(index):
    """The first two dimensions of the Sobol sequence at `index`, as 32-bit fractions."""
    x, y = sobol2_reversed(index)
    return reverse_bits32(x), reverse_bits32(y)


@kernel_function(error_model="numpy", _nrt=False)
def ld_seed(key, dim, event):
    """A hash of the sample's pixel (not of the sample), dimension `dim` and its `event`-th use:
    the scrambles every sample of the pixel shares in that dimension."""
    return mix64(((np.uint64(key) & _PIXEL_MASK) ^ dim) + np.uint64(event) * _GOLDEN)


@kernel_function(error_model="numpy", _nrt=False)
def ld_point(h, index):
    """Point `index` of the shuffled, Owen-scrambled Sobol (0, 2)-sequence chosen by the hash h
    (Burley 2020, "Practical Hash-based Owen Scrambling"), in [0, 1)^2. The index is scrambled
    first, by h's low half: that takes the first 2^m indices, for every m, to an aligned block
    of 2^m, whose points are a (0, m, 2)-net as the first 2^m are, in an order of h's own; the
    points' digits are scrambled next, so each point alone is uniform."""
    x, y = sobol2_reversed(owen_scramble(index, h & _MASK32))
    # owen_scramble of the reversed fractions (it reverses its argument first)
    x = reverse_bits32(laine_karras(x, h >> _S32))
    y = reverse_bits32(laine_karras(y, ((h ^ (h >> _S32)) * _GOLDEN32) & _MASK32))
    return float(x) * _TO_UNIT32, float(y) * _TO_UNIT32


@kernel_function(error_model="numpy", _nrt=False)
def ld_uniform2(key, dim, event):
    """Two uniforms in [0, 1) for the camera sample of `key`, dimension `dim`, its `event`-th
    use: point sample_index(key) of the pixel's own sequence for (dim, event), so the first 2^m
    samples of a pixel are stratified in every dimension, for every m; a different shuffle for
    every dimension and event keeps the dimensions from correlating (Owen scrambling alone, on
    one index, would give them the same strata)."""
    return ld_point(ld_seed(key, dim, event), sample_index(key))


@kernel_function(error_model="numpy", _nrt=False)
def pixel_sample(key):
    """Position in [0, 1)^2 inside the pixel of the camera sample of `key` (dimension PIXEL)."""
    return ld_uniform2(key, DIM_PIXEL, 0)


@kernel_function(error_model="numpy", _nrt=False)
def lens_sample(key):
    """Point in [0, 1)^2 on the lens for the camera sample of `key` (dimension LENS)."""
    return ld_uniform2(key, DIM_LENS, 0)


@kernel_function(error_model="numpy", _nrt=False)
def light_sample(key, event, light, s, count):
    """Point s of `count` in [0, 1)^2 on light `light` at the `event`-th surface the camera
    sample shades (dimension LIGHT; trace mode's area lights): point sample_index(key) * count +
    s of the pixel's sequence for that light and event, so that the pixel's spp x count points
    on the light are stratified together."""
    h = ld_seed(key, DIM_LIGHT ^ (np.uint64(light) * _M2), event)
    return ld_point(h, sample_index(key) * np.uint64(count) + np.uint64(s))
