"""Splats: samples that land on the film away from the pixel that made them (bidirectional path
tracing's light subpaths seen by the camera, t = 1), summed exactly.

A light subpath of pixel A's sample may reach any pixel B, so the sums of B are written by
whichever thread traced A. Floating-point sums in that order would depend on the threads, the
tiles and the machines. Splats are therefore summed as integers: each value becomes a fixed-point
pair (hi: units of 2^-16, lo: the rest in units of 2^-48, truncated), added to int64 sums with
atomic additions. Integer addition is exact and commutes, so the sums, and the image read from
them, are the same bits whatever order the splats arrive in (any threads, tiles, passes, or
machines whose sums are added). The truncation loses < 2^-48 a splat; |value| >= 2^46 is refused.

A splat spreads over the pixels in the pixel filter's radius with the filter's normalised
weight, as pbrt-v4's RGBFilm::AddSplat (each 1D profile divided by its integral): the camera's
samples, placed by filter importance sampling (film.py), converge to the same filtered image.
The filter array: radius, the number n of table entries, then the 1D profile (normalised) at n
evenly spaced offsets from -radius to radius."""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core.errors import TypingError
from numba.extending import intrinsic

from ..vec import inline_function, kernel_function
from .film import PIXEL_FILTERS
from .film import SPLAT_HI_SCALE as HI_SCALE
from .film import SPLAT_LO_SCALE as LO_SCALE

SPLAT_LIMIT = 2.0**46
SPLAT_RADIUS = 0
SPLAT_COUNT = 1
SPLAT_TABLE = 2
PROFILE_SIZE = 1025


@intrinsic
def atomic_add(typingctx, values, index, amount):
    """values[index] += amount, atomically (values: a C-contiguous int64 array, read flat)."""
    if not (isinstance(values, types.Array) and values.dtype == types.int64 and values.layout == "C"):
        raise TypingError("atomic_add: values must be a C-contiguous int64 array")

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        at = context.cast(builder, args[1], sig.args[1], types.int64)
        add = context.cast(builder, args[2], sig.args[2], types.int64)
        p = builder.gep(arr.data, [at], inbounds=True)
        builder.atomic_rmw("add", p, add, "monotonic")
        return ir.Constant(ir.IntType(64), 0)

    return types.int64(values, index, amount), codegen


@inline_function
def _profile(filt, x):
    """The normalised 1D filter profile at offset x (0 outside [-radius, radius))."""
    r = filt[SPLAT_RADIUS]
    if not (x >= -r and x < r):
        return 0.0
    n = int(filt[SPLAT_COUNT])
    u = (x + r) / (2.0 * r) * (n - 1)
    k = min(int(u), n - 2)
    t = u - k
    return filt[SPLAT_TABLE + k] * (1.0 - t) + filt[SPLAT_TABLE + k + 1] * t


@kernel_function
def splat(flat, window, filt, x, y, rgb):
    """Add rgb at image point (x, y) (pixels) to the splat sums (int64 (h, w, 3, 2) of the window
    (x0, y0, x1, y1), flat): to each pixel in the filter's radius, weighted. Returns False (nothing
    added) for a value that is not finite or too large."""
    if not splat_finite(rgb):
        return False
    x0, y0, x1, y1 = window
    r = filt[SPLAT_RADIUS]
    for py in range(max(int(math.floor(y - r)), y0), min(int(math.floor(y + r)) + 1, y1)):
        wy = _profile(filt, y - (py + 0.5))
        if wy == 0.0:
            continue
        for px in range(max(int(math.floor(x - r)), x0), min(int(math.floor(x + r)) + 1, x1)):
            wt = wy * _profile(filt, x - (px + 0.5))
            if wt == 0.0:
                continue
            splat_pixel(flat, window, px, py, rgb, wt)
    return True


@inline_function
def splat_finite(rgb):
    """Whether rgb can be splatted: finite and below SPLAT_LIMIT."""
    for c in range(3):
        if not (abs(rgb[c]) < SPLAT_LIMIT):
            return False
    return True


@inline_function
def splat_pixel(flat, window, px, py, rgb, wt):
    """Add rgb * wt to pixel (px, py) of the window's splat sums (exactly: fixed point)."""
    x0, y0, x1, _ = window
    at = ((py - y0) * (x1 - x0) + (px - x0)) * 6
    for c in range(3):
        v = rgb[c] * wt * HI_SCALE
        a = math.floor(v)
        b = math.floor((v - a) * LO_SCALE)
        atomic_add(flat, at + 2 * c, np.int64(a))
        atomic_add(flat, at + 2 * c + 1, np.int64(b))


def splat_filter(name: str) -> np.ndarray:
    """The filter array `splat` reads for pixel filter `name` (film.PIXEL_FILTERS)."""
    radius, profile = PIXEL_FILTERS[name]
    x = np.linspace(-radius, radius, PROFILE_SIZE)
    f = np.ones_like(x) if profile is None else profile(x)
    fine = np.linspace(-radius, radius, 200001)
    g = np.ones_like(fine) if profile is None else profile(fine)
    integral = float(np.sum((g[1:] + g[:-1]) * 0.5) * (fine[1] - fine[0]))
    out = np.empty(SPLAT_TABLE + PROFILE_SIZE)
    out[SPLAT_RADIUS] = radius
    out[SPLAT_COUNT] = PROFILE_SIZE
    out[SPLAT_TABLE:] = f / integral
    return out
