"""The film: where camera samples land, weighted by the pixel filter.

The film keeps, per pixel, running sums (float64 (H, W, FILM_WIDTH): R, G, B and the sum of
filter weights) and divides only when it is read. A render adds its samples to those sums in
sample order, continuing from the values already there, so samples that arrive in several
passes (a progressive viewer, tiles of a cluster) give the same bits as one pass.

Pixel filters are applied by filter importance sampling: a sample's stratified position in the
unit square is warped through the filter's inverse CDF (a table, `filter_table`), so every
pixel gathers its own samples, spread over the filter's footprint, and weights them equally
(with the sign of the filter for Mitchell's negative lobes). No sample is shared between
pixels: deterministic and free of write races. Box is the plain jittered pixel of DESIGN.md.
"""

import math
import numbers

import numpy as np
from numba import njit

from ..vec import inline_function, kernel_function

FILM_RGB = 0  # 3 columns: sum of weighted colours
FILM_WEIGHT = 3  # sum of filter weights
FILM_WIDTH = 4
# Films of filters with negative lobes (Mitchell) also keep the unsigned sums: the sum of the
# colours whatever their weight's sign, and the sample count (see Film.rgb).
FILM_ABS_RGB = 4  # 3 columns
FILM_COUNT = 7
FILM_SIGNED_WIDTH = 8

# The pixel filter array, float64 (FILTER_WIDTH,): kind, |offset| beyond which the filter is
# negative (inf for none), then FILTER_TABLE_SIZE offsets in pixels: the filter's inverse CDF.
FILTER_KIND = 0
FILTER_NEGATIVE = 1
FILTER_TABLE = 2
FILTER_TABLE_SIZE = 257
FILTER_WIDTH = FILTER_TABLE + FILTER_TABLE_SIZE
FILTER_BOX = 0
FILTER_WARPED = 1  # any other filter: samples placed by the tabulated inverse CDF


@kernel_function
def filter_offset(table, first, u):
    """Offset in pixels (from the pixel centre) of the unit sample u under the filter whose
    inverse CDF is tabulated at table[first : first + FILTER_TABLE_SIZE]."""
    x = u * (FILTER_TABLE_SIZE - 1)
    k = min(int(x), FILTER_TABLE_SIZE - 2)
    t = x - k
    return table[first + k] * (1.0 - t) + table[first + k + 1] * t


@inline_function
def filter_sample(filt, i, j, ux, uy):
    """Image position (x, y) of the unit-square sample (ux, uy) of pixel (i, j), and its
    weight (+-1)."""
    if filt[FILTER_KIND] == FILTER_BOX:
        return i + ux, j + uy, 1.0
    dx = filter_offset(filt, FILTER_TABLE, ux)
    dy = filter_offset(filt, FILTER_TABLE, uy)
    weight = 1.0
    if abs(dx) > filt[FILTER_NEGATIVE]:
        weight = -weight
    if abs(dy) > filt[FILTER_NEGATIVE]:
        weight = -weight
    return i + 0.5 + dx, j + 0.5 + dy, weight


@inline_function
def pixel_sums(film, j, i):
    """The pixel's running sums: ((r, g, b, weight), (|r|, |g|, |b|, count)); the unsigned half
    is kept only by films of filters with negative lobes (zeros otherwise)."""
    signed = (film[j, i, FILM_RGB], film[j, i, FILM_RGB + 1], film[j, i, FILM_RGB + 2], film[j, i, FILM_WEIGHT])
    if film.shape[2] == FILM_WIDTH:
        return signed, (0.0, 0.0, 0.0, 0.0)
    return signed, (film[j, i, FILM_ABS_RGB], film[j, i, FILM_ABS_RGB + 1], film[j, i, FILM_ABS_RGB + 2],
                    film[j, i, FILM_COUNT])  # fmt: skip


@inline_function
def add_sample(total, col, w):
    """A pixel's running sums plus one sample of filter weight w = +-1."""
    signed, unsigned = total
    unsigned = (unsigned[0] + col[0], unsigned[1] + col[1], unsigned[2] + col[2], unsigned[3] + 1.0)
    if w > 0.0:
        return (signed[0] + col[0], signed[1] + col[1], signed[2] + col[2], signed[3] + w), unsigned
    # a negative lobe of the pixel filter
    return (signed[0] - col[0], signed[1] - col[1], signed[2] - col[2], signed[3] + w), unsigned


@inline_function
def store_sums(film, j, i, total):
    signed, unsigned = total
    film[j, i, FILM_RGB] = signed[0]
    film[j, i, FILM_RGB + 1] = signed[1]
    film[j, i, FILM_RGB + 2] = signed[2]
    film[j, i, FILM_WEIGHT] = signed[3]
    if film.shape[2] > FILM_WIDTH:
        film[j, i, FILM_ABS_RGB] = unsigned[0]
        film[j, i, FILM_ABS_RGB + 1] = unsigned[1]
        film[j, i, FILM_ABS_RGB + 2] = unsigned[2]
        film[j, i, FILM_COUNT] = unsigned[3]


@inline_function
def next_sample(i, s, samples):
    """The sample after sample s of pixel i, a row's samples coming in pixel order (each pixel's
    samples first..first+count-1 of this pass, samples = (first, count, total)): (pixel, sample)."""
    first, count, _ = samples
    if s + 1 == first + count:
        return i + 1, first
    return i, s + 1


@inline_function
def add_in_pixel_order(film, j, x0, pixel, total, i, col, w):
    """Sample col (filter weight w) of pixel i into row j of the film, a row's samples coming in
    pixel order: the running sums `total` of the pixel being added to are kept until its samples
    end. Returns the (pixel, total) to go on with; store_sums(film, j, pixel - x0, total) after
    the row's last sample."""
    if i != pixel:
        store_sums(film, j, pixel - x0, total)
        pixel = i
        total = pixel_sums(film, j, i - x0)
    return pixel, add_sample(total, col, w)


@inline_function
def add_one_each(flat, at, samples, rows, n):
    """Samples 0..n-1 into n pixels in a row, one each, of a film without the unsigned half:
    add_in_pixel_order's sums for pixels of one sample, without its running sums and pixel
    checks. `flat` is film.reshape(film.size) and `at` the first pixel's index into it; the
    samples' colours and filter weights are slots 0..n-1 of the rows of `samples` at the offsets
    rows = (r, g, b, weight)."""
    r0, g0, b0, w0 = rows
    no_unsigned = (0.0, 0.0, 0.0, 0.0)
    for k in range(n):
        p = at + k * FILM_WIDTH
        signed = (flat[p + FILM_RGB], flat[p + FILM_RGB + 1], flat[p + FILM_RGB + 2], flat[p + FILM_WEIGHT])
        col = (samples[r0 + k], samples[g0 + k], samples[b0 + k])
        signed, _ = add_sample((signed, no_unsigned), col, samples[w0 + k])
        flat[p + FILM_RGB], flat[p + FILM_RGB + 1], flat[p + FILM_RGB + 2], flat[p + FILM_WEIGHT] = signed


class Film:
    """Sums of samples for (a window of) a width x height image that will receive `total_spp`
    samples per pixel, in one pass or several (the sampler stratifies over the total: one
    sample per pixel is the pixel centre); `rgb()` reads the image at any time.

    `window` = (x0, x1, y0, y1): the film holds columns x0..x1-1 and rows y0..y1-1 only (a
    crop; pbrt's --pixelbounds); its pixels equal that part of the whole image's film.

    `first_sample`: the film holds samples first_sample..first_sample + total_spp - 1 of each
    pixel's low-discrepancy sequences (default 0). Films of one seed whose ranges follow each
    other are together the samples of one sequence, stratified together, as one film of their
    total would be (the live view's films, each with the samples after the one before); the
    texture filter's ray cone is that of first_sample + total_spp samples a pixel."""

    def __init__(
        self,
        width: int,
        height: int,
        pixel_filter: str = "box",
        total_spp: int = 1,
        window: tuple[int, int, int, int] | None = None,
        first_sample: int = 0,
    ):
        for name, value in (("width", width), ("height", height), ("total_spp", total_spp)):
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
                raise ValueError(f"{name} must be a whole number, at least 1 (got {value!r})")
        if isinstance(first_sample, bool) or not isinstance(first_sample, numbers.Integral) or first_sample < 0:
            raise ValueError(f"first_sample must be a whole number, at least 0 (got {first_sample!r})")
        if pixel_filter not in PIXEL_FILTERS:
            raise ValueError(f"pixel_filter must be one of {', '.join(PIXEL_FILTERS)} (got {pixel_filter!r})")
        x0, x1, y0, y1 = window if window is not None else (0, width, 0, height)
        if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
            raise ValueError(f"window {window} must lie inside the {width} x {height} image and be non-empty")
        self.width = width
        self.height = height
        self.window = (x0, x1, y0, y1)
        self.total_spp = total_spp
        self.first_sample = int(first_sample)
        self.filter = filter_array(pixel_filter)
        self.filter_name = pixel_filter
        signed = np.isfinite(self.filter[FILTER_NEGATIVE])
        shape = (y1 - y0, x1 - x0, FILM_SIGNED_WIDTH if signed else FILM_WIDTH)
        self.sums = np.empty(shape, dtype=np.float64)
        # Written here rather than left to lazily zeroed pages, so the first pass's kernels do
        # not stall on page faults (a third of a cast frame's time at 600 x 600).
        self.sums.fill(0.0)
        self.spp = 0  # samples per pixel added so far
        self.rejected = 0  # samples dropped as NaN, infinite or negative (path mode)
        # bidirectional path tracing's splats (splat.py): exact int64 sums, (h, w, 3, 2) flat
        self.splats: np.ndarray | None = None
        self.strategies: dict[str, int] = {}  # bdpt: samples that contributed per strategy "s,t"
        self.glint: np.ndarray | None = None  # bdpt: the glint strategy's cdf, made by its first pass

    def enable_splats(self) -> np.ndarray:
        """The splat sums of the film's window (made zero on first use)."""
        if self.splats is None:
            x0, x1, y0, y1 = self.window
            self.splats = np.zeros((y1 - y0) * (x1 - x0) * 6, dtype=np.int64)
        return self.splats

    @property
    def pixel_centres(self) -> bool:
        """Whether the film's one sample a pixel is the pixel's centre (a film of one sample,
        the first of its sequence) rather than a point of the filter's area."""
        return self.total_spp == 1 and self.first_sample == 0

    @property
    def kernel_window(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1), as the lane kernels take it."""
        x0, x1, y0, y1 = self.window
        return x0, y0, x1, y1

    def compile_rgb(self, always: bool = False) -> None:
        """Compile (or load from the disk cache) the kernel rgb() runs, on no pixels, where rgb()
        will take it: a render does it while it compiles its kernels, so that its compile time
        counts it. `always`: whatever the film's size (the live view, whose many small frames
        gain from the kernel)."""
        if always or self._rgb_by_kernel():
            _film_rgb(self.sums[:0], np.empty((0,) + self.sums.shape[1:2] + (3,), dtype=np.float32))

    def _rgb_by_kernel(self) -> bool:
        """Whether rgb() runs the kernel: once it is compiled in this process, for signed sums,
        or for films of RGB_KERNEL_PIXELS or more; the others take numpy (the same image to the
        bit, film_rgb_numpy)."""
        h, w, columns = self.sums.shape
        return bool(_film_rgb.signatures) or columns > FILM_WIDTH or h * w >= RGB_KERNEL_PIXELS

    def rgb(self) -> np.ndarray:
        """float32 (H, W, 3): each pixel's filter-weighted mean. Weights are +-1, so a pixel's
        sum of weights is its sample count when the filter is positive (box, gaussian).

        With negative lobes (Mitchell) the signed sums can cancel: at a few samples a pixel may
        have as many negative samples as positive ones, and the weighted mean divides by
        nearly nothing. Where more than a quarter of a pixel's samples are negative (weight
        sum below half the count), it takes the plain mean of its samples instead, so a
        constant image stays constant; negative results of the lobes are clipped to 0."""
        return sums_image(self.sums, self.splats, self.spp, self._rgb_by_kernel())

    @staticmethod
    def max_bytes_per_pixel() -> int:
        return 8 * FILM_SIGNED_WIDTH


# bidirectional path tracing's splat sums (splat.py): hi in units of 2^-16, lo in 2^-48
SPLAT_HI_SCALE = 65536.0  # 2^16
SPLAT_LO_SCALE = 4294967296.0  # 2^32


def splat_image(sums: np.ndarray, spp: int) -> np.ndarray:
    """float64 (h, w, 3): splat sums (h, w, 3, 2) as radiance, divided by the samples per pixel taken."""
    hi = sums[..., 0].astype(np.float64)
    lo = sums[..., 1].astype(np.float64)
    return (hi / SPLAT_HI_SCALE + lo / (SPLAT_HI_SCALE * SPLAT_LO_SCALE)) / max(spp, 1)


def sums_image(sums: np.ndarray, splats: np.ndarray | None, spp: int, by_kernel: bool = True) -> np.ndarray:
    """float32 (H, W, 3): Film.rgb's image of film sums (H, W, columns) and, for bdpt, splat
    sums (flat int64) of `spp` samples a pixel: films of one image pooled by adding their sums,
    splats and spp are read as one film of all their samples. `by_kernel`: _film_rgb, else
    numpy (the same bits)."""
    if by_kernel:
        out = np.empty(sums.shape[:2] + (3,), dtype=np.float32)
        _film_rgb(sums, out)
    else:
        out = film_rgb_numpy(sums)
    if splats is not None:
        h, w = sums.shape[:2]
        both = out.astype(np.float64) + splat_image(splats.reshape(h, w, 3, 2), spp)
        out = np.maximum(both, 0.0).astype(np.float32)
    return out


# Film.rgb in numpy for films of unsigned sums below RGB_KERNEL_PIXELS while _film_rgb is not
# compiled in the process: as fast as the kernel there (600 x 600: 9.6 ms each), and compiling
# the kernel takes ~0.35 s, a twentieth of the seed's first picture. Signed sums (filters with
# negative lobes) take the kernel: their cancelled pixels cost numpy 2.7x its time.
RGB_KERNEL_PIXELS = 1 << 20


_F32_MAX = float(np.finfo(np.float32).max)  # a pixel past it is read as it (film_rgb_numpy, _film_rgb)


def film_rgb_numpy(sums: np.ndarray) -> np.ndarray:
    """float32 (H, W, 3): _film_rgb's image of the running sums, in numpy (IEEE arithmetic, the
    same operations: the same image to the bit; tests/test_quality.py)."""
    w = sums[..., FILM_WEIGHT]
    inv = np.where(w < 0.5, 1.0, w)
    np.divide(1.0, inv, out=inv)
    x = sums[..., FILM_RGB : FILM_RGB + 3] * inv[..., None]
    if sums.shape[2] > FILM_WIDTH:  # signed sums: where they cancel, the plain mean
        count = sums[..., FILM_COUNT]
        cancelled = (w < 0.5 * count) & (count > 0.0)
        mean = sums[..., FILM_ABS_RGB : FILM_ABS_RGB + 3] / np.maximum(count, 1.0)[..., None]
        x = np.where(cancelled[..., None], mean, x)
    # NaN kept (the image checks refuse it), -0.0 made 0.0: np.maximum(x, 0.0) does both; past
    # float32's range, its largest value (as Image holds it), not inf and numpy's overflow warning
    np.maximum(x, 0.0, out=x)
    np.minimum(x, _F32_MAX, out=x)
    return x.astype(np.float32)


# IEEE arithmetic (no fast-math), so the image is what film_rgb_numpy gives, to the bit: numpy
# took 48 ms a megapixel, almost half the trace kernel's time for a 1024 x 1024 frame of the
# bunny.
@njit(cache=True, error_model="numpy", no_cfunc_wrapper=True)
def _film_rgb(sums, out):
    """Film.rgb's image of the running sums into out (float32 (H, W, 3))."""
    signed = sums.shape[2] > FILM_WIDTH
    for j in range(sums.shape[0]):
        for i in range(sums.shape[1]):
            w = sums[j, i, FILM_WEIGHT]
            inv = 1.0 / (1.0 if w < 0.5 else w)
            cancelled = False
            if signed:
                count = sums[j, i, FILM_COUNT]
                cancelled = w < 0.5 * count and count > 0.0
            for c in range(3):
                if cancelled:
                    x = sums[j, i, FILM_ABS_RGB + c] / max(count, 1.0)
                else:
                    x = sums[j, i, FILM_RGB + c] * inv
                # as np.maximum(x, 0.0): NaN kept (the image checks refuse it), -0.0 made 0.0;
                # as np.minimum(x, _F32_MAX)
                out[j, i, c] = min(x, _F32_MAX) if x > 0.0 else (0.0 if x == x else x)


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
    """(kind, negative-from, inverse CDF table) of a pixel filter.

    The separable filter's 1D profile f is sampled in proportion to |f|: table[k] is the offset
    x with CDF(x) = k / (FILTER_TABLE_SIZE - 1), so warping a stratified u gives stratified
    offsets distributed like the filter, and each sample weighs sign(f(x)) (normalised by the
    pixel's sum of weights)."""
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


def filter_array(name: str) -> np.ndarray:
    """The float64 (FILTER_WIDTH,) array the kernels read for pixel filter `name`."""
    kind, negative, table = filter_table(name)
    out = np.empty(FILTER_WIDTH, dtype=np.float64)
    out[FILTER_KIND] = kind
    out[FILTER_NEGATIVE] = negative
    out[FILTER_TABLE:] = table
    return out
