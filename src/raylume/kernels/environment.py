"""The environment: the radiance that rays which hit nothing see, and a light that a path tracer
samples (the scene's `[environment]` table).

Conventions
-----------
An equirectangular image (H, W) covers the sphere: image coordinates u (0 at the left edge, 1 at
the right) and v (0 at the top, 1 at the bottom) look along

    phi = 2 pi (u - 0.5),  theta = pi v
    direction = (sin(phi) sin(theta), cos(theta), cos(phi) sin(theta))

in the environment's frame, which `rotation` (world-from-environment, the rotation part of
`scene.mesh.transform_matrix(rotate=...)`) turns into the world. So the centre column looks
along +z, the top row along +y, and a texel right of the centre column lies towards +x: a camera
looking along +z in raylume's left-handed world sees the image the right way round, not
mirrored. A constant colour is a 1 x 1 image.

Lookup and sampling
-------------------
Radiance is the *nearest texel* (piecewise constant): no filtering, so the pdf below, also
piecewise constant over texels, is exactly proportional to what is looked up, and a texel of
zero radiance is the only place the pdf may be zero.

Sampling picks a texel from a piecewise-constant 2D distribution (pbrt-v4 style: a marginal CDF
over rows, a conditional CDF over the columns of each row), with each texel weighted by its
mean channel times its solid angle (2 pi / W) (cos theta_i - cos theta_i+1): the exact area of
the texel on the sphere, which is sin(theta) dtheta dphi integrated over it. Inside the texel
the direction is uniform in solid angle (phi uniform, cos theta uniform), so the solid-angle pdf
is constant over each texel:

    pdf = P(row) P(column | row) / texel solid angle

and radiance / pdf is the same for every direction of a texel. A constant colour (1 x 1) is
therefore sampled uniformly over the sphere, pdf 1 / (4 pi); an all-black image likewise.

Kernel functions take the `Environment` tuple E; with `E.present` False they return black and
pdf 0, so a scene without an environment can pass `no_environment()` through the same code.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import SceneError
from .vec import inline_function, kernel_function

PI = math.pi
TWO_PI = 2.0 * math.pi
# Largest float64 below 1: random numbers are clamped to it so the CDF search stays in range.
ONE_MINUS_EPSILON = 1.0 - 2.0**-53

# A guard against decompression bombs (the texture table's limit): 64 Mi texels, 768 MiB.
MAX_TEXELS = 1 << 26

SUFFIXES = (".hdr", ".exr")


class Environment(NamedTuple):
    image: np.ndarray  # float32 (H, W, 3) linear radiance, intensity applied; (1, 1, 3) for a constant colour
    marginal_cdf: np.ndarray  # float64 (H + 1,): P(row < i); 0 first, exactly 1 last
    conditional_cdf: np.ndarray  # float64 (H, W + 1): P(column < j | row i); 0 first, exactly 1 last
    rotation: np.ndarray  # float64 (3, 3) world-from-environment; its transpose maps back
    present: bool  # False: no [environment] (rays that miss see the background)


# ---------------------------------------------------------------------------------------------
# Kernels


@kernel_function
def _texel_of(E, d):
    """(row, column) of the texel that world direction d falls in."""
    r = E.rotation
    # environment-frame direction: R^T d
    x = r[0, 0] * d[0] + r[1, 0] * d[1] + r[2, 0] * d[2]
    y = r[0, 1] * d[0] + r[1, 1] * d[1] + r[2, 1] * d[2]
    z = r[0, 2] * d[0] + r[1, 2] * d[1] + r[2, 2] * d[2]
    h = E.image.shape[0]
    w = E.image.shape[1]
    n = math.sqrt(x * x + y * y + z * z)
    cos_theta = min(1.0, max(-1.0, y / n)) if n > 0.0 else 1.0
    v = math.acos(cos_theta) / PI
    u = math.atan2(x, z) / TWO_PI + 0.5
    i = min(max(int(v * h), 0), h - 1)
    j = min(max(int(u * w), 0), w - 1)
    return i, j


@kernel_function
def environment_radiance(E, d):
    """Radiance (r, g, b) arriving from world direction d (unit): the nearest texel."""
    if not E.present:
        return (0.0, 0.0, 0.0)
    i, j = _texel_of(E, d)
    return (float(E.image[i, j, 0]), float(E.image[i, j, 1]), float(E.image[i, j, 2]))


@inline_function
def _texel_solid_angle(i, h, w):
    return (math.cos(PI * i / h) - math.cos(PI * (i + 1) / h)) * (TWO_PI / w)


@kernel_function
def environment_pdf(E, d):
    """The solid-angle pdf with which sample_environment returns world direction d."""
    if not E.present:
        return 0.0
    i, j = _texel_of(E, d)
    h = E.image.shape[0]
    w = E.image.shape[1]
    p_row = E.marginal_cdf[i + 1] - E.marginal_cdf[i]
    p_col = E.conditional_cdf[i, j + 1] - E.conditional_cdf[i, j]
    area = _texel_solid_angle(i, h, w)
    if area <= 0.0:
        return 0.0
    return p_row * p_col / area


@inline_function
def _search_marginal(cdf, n, u):
    """The i in 0..n-1 with cdf[i] <= u < cdf[i + 1] (cdf[0] = 0 <= u < 1 = cdf[n]): never
    an empty interval."""
    lo = 0
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@inline_function
def _search_conditional(cdf, row, n, u):
    lo = 0
    hi = n
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if cdf[row, mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@kernel_function
def sample_environment(E, u1, u2):
    """A world direction for the random numbers u1 (row) and u2 (column) in [0, 1): (direction,
    its radiance (r, g, b), its solid-angle pdf). The pdf is 0 for a failed sample (no
    environment). The numbers' remainders inside the chosen texel place the direction in it,
    so stratified u1, u2 stay stratified."""
    if not E.present:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    h = E.image.shape[0]
    w = E.image.shape[1]
    u1 = min(max(u1, 0.0), ONE_MINUS_EPSILON)
    u2 = min(max(u2, 0.0), ONE_MINUS_EPSILON)
    i = _search_marginal(E.marginal_cdf, h, u1)
    c0 = E.marginal_cdf[i]
    p_row = E.marginal_cdf[i + 1] - c0
    j = _search_conditional(E.conditional_cdf, i, w, u2)
    d0 = E.conditional_cdf[i, j]
    p_col = E.conditional_cdf[i, j + 1] - d0
    if p_row <= 0.0 or p_col <= 0.0:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    dv = min((u1 - c0) / p_row, 1.0)
    du = min((u2 - d0) / p_col, 1.0)
    z0 = math.cos(PI * i / h)
    z1 = math.cos(PI * (i + 1) / h)
    area = (z0 - z1) * (TWO_PI / w)
    if area <= 0.0:
        return (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0
    cos_theta = z0 - (z0 - z1) * dv
    sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
    phi = TWO_PI * ((j + du) / w - 0.5)
    x = math.sin(phi) * sin_theta
    z = math.cos(phi) * sin_theta
    r = E.rotation
    d = (
        r[0, 0] * x + r[0, 1] * cos_theta + r[0, 2] * z,
        r[1, 0] * x + r[1, 1] * cos_theta + r[1, 2] * z,
        r[2, 0] * x + r[2, 1] * cos_theta + r[2, 2] * z,
    )
    rgb = (float(E.image[i, j, 0]), float(E.image[i, j, 1]), float(E.image[i, j, 2]))
    return d, rgb, p_row * p_col / area


# ---------------------------------------------------------------------------------------------
# Python side: building the tables, reading the images


def no_environment() -> Environment:
    """No [environment]: present False, tiny arrays of the same types as a real one (so the
    kernels compile once for both)."""
    return Environment(
        image=np.zeros((1, 1, 3), dtype=np.float32),
        marginal_cdf=np.array([0.0, 1.0]),
        conditional_cdf=np.array([[0.0, 1.0]]),
        rotation=np.eye(3),
        present=False,
    )


def sampling_tables(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(marginal_cdf (H + 1,), conditional_cdf (H, W + 1)) for a float (H, W, 3) image: texels
    weighted by their mean channel times their solid angle; an all-black image (or row) is
    sampled by solid angle alone (uniformly)."""
    h, w = image.shape[:2]
    edges = np.cos(np.pi * np.arange(h + 1) / h)
    band = np.maximum(edges[:-1] - edges[1:], 0.0)  # a row's solid angle / (2 pi)
    weights = image.astype(np.float64).mean(axis=2) * band[:, None]
    if not weights.sum() > 0.0:
        weights = np.broadcast_to(band[:, None], (h, w)).copy()
    rows = weights.sum(axis=1)
    conditional = np.zeros((h, w + 1))
    conditional[:, 1:] = np.cumsum(weights, axis=1)
    empty = rows <= 0.0
    conditional[empty, 1:] = np.arange(1, w + 1) / w  # never chosen; keeps the table well formed
    conditional[~empty] /= rows[~empty, None]
    conditional = np.minimum(conditional, 1.0)
    conditional[:, -1] = 1.0
    marginal = np.zeros(h + 1)
    marginal[1:] = np.cumsum(rows) / rows.sum()
    marginal = np.minimum(marginal, 1.0)
    marginal[-1] = 1.0
    return marginal, conditional


def build_environment(
    color=None,
    file=None,
    intensity=1.0,
    rotate=(0.0, 0.0, 0.0),
    base_dir=".",
    source: str = "<scene>",
    where: str = "environment",
) -> Environment:
    """The kernels' Environment for `[environment]`: a constant `color` (linear [r, g, b]) or an
    equirectangular `file` (.hdr or .exr, relative to `base_dir`), scaled by `intensity` and
    turned by `rotate` (degrees about x, then y, then z, as object transforms). Bad input
    raises SceneError naming `source` and the key (`{where}.file`, ...)."""
    from ..scene.mesh import transform_matrix

    def fail(key: str, why: str):
        raise SceneError(f"{source}: {where}.{key}: {why}") from None

    if (color is None) == (file is None):
        raise SceneError(f"{source}: {where}: give exactly one of 'color' (a constant radiance) or 'file' (an image)")
    scale = _finite_number(intensity)
    if scale is None or scale < 0.0:
        fail("intensity", f"must be a finite number >= 0, got {intensity!r}")
    try:
        rotation = np.ascontiguousarray(transform_matrix(rotate=rotate)[:3, :3], dtype=np.float64)
    except (ValueError, TypeError):
        fail("rotate", f"must be [x, y, z] in degrees (finite numbers), got {rotate!r}")

    if color is not None:
        try:
            rgb = np.asarray(color, dtype=np.float64)
        except (ValueError, TypeError):
            rgb = None
        if rgb is None or rgb.shape != (3,) or not np.all(np.isfinite(rgb)) or np.any(rgb < 0):
            fail("color", f"must be [r, g, b] with finite components >= 0, got {color!r}")
        image = rgb.reshape(1, 1, 3)
    else:
        path = Path(file)
        if not path.is_absolute():
            path = Path(base_dir) / path
        image = load_environment_image(path, source, f"{where}.file")

    scaled = image.astype(np.float64) * scale
    if not np.all(scaled <= np.finfo(np.float32).max):
        fail("intensity", f"{intensity!r} times the image's brightest texel overflows float32")
    image = np.ascontiguousarray(scaled, dtype=np.float32)
    marginal, conditional = sampling_tables(image)
    return Environment(image, marginal, conditional, rotation, True)


def _finite_number(value) -> float | None:
    if isinstance(value, bool):
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def load_environment_image(path: str | Path, source: str = "<scene>", where: str = "environment.file") -> np.ndarray:
    """A .hdr (Radiance RGBE) or .exr (OpenEXR: R, G, B channels, or Y) file as float32
    (H, W, 3) linear radiance; refuses, as SceneError, missing files, folders, other suffixes,
    unreadable or truncated files, images over MAX_TEXELS and NaN, infinite or negative texels."""
    path = Path(path)

    def fail(why: str):
        raise SceneError(f"{source}: {where}: {why}") from None

    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        fail(f"{path}: unsupported image format {path.suffix or '(none)'!r}; use a .hdr or .exr file")
    if not path.exists():
        fail(f"the file {path} does not exist")
    if path.is_dir():
        fail(f"{path} is a folder, not an image file")
    try:
        image = _read_hdr(path) if suffix == ".hdr" else _read_exr(path)
    except _BadImage as exc:
        fail(f"cannot read {path}: {exc}")
    except OSError as exc:
        fail(f"cannot read {path}: {exc.strerror or exc}")
    bad = ~np.isfinite(image)
    if bad.any():
        fail(f"{path} holds {int(bad.any(axis=2).sum())} texels that are NaN or infinite; radiance must be finite")
    negative = image < 0
    if negative.any():
        fail(f"{path} holds {int(negative.any(axis=2).sum())} texels with negative values; radiance must be >= 0")
    return image


class _BadImage(Exception):
    """A malformed image file (the message says how)."""


def _check_size(width: int, height: int) -> None:
    if width < 1 or height < 1:
        raise _BadImage(f"the image is {width} x {height} pixels")
    if width * height > MAX_TEXELS:
        raise _BadImage(f"the image is {width} x {height}, more than {MAX_TEXELS} texels")


def _read_exr(path: Path) -> np.ndarray:
    import OpenEXR

    try:
        header = OpenEXR.File(str(path), separate_channels=True, header_only=True).header()
        lo, hi = header["dataWindow"]
        _check_size(int(hi[0]) - int(lo[0]) + 1, int(hi[1]) - int(lo[1]) + 1)
        channels = OpenEXR.File(str(path), separate_channels=True).channels()
    except _BadImage:
        raise
    except Exception as exc:  # OpenEXR reports every problem as RuntimeError/ValueError/...
        raise _BadImage(f"not a readable OpenEXR file ({_first_line(exc)})") from None
    names = [n for n in ("R", "G", "B") if n in channels]
    if len(names) == 3:
        planes = [channels[n].pixels for n in names]
    elif "Y" in channels:
        planes = [channels["Y"].pixels] * 3
    else:
        raise _BadImage(f"no R, G, B (or Y) channels; it has {', '.join(sorted(channels)) or 'none'}")
    shapes = {p.shape for p in planes}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2:
        raise _BadImage("its R, G, B channels are subsampled or differ in size")
    return np.ascontiguousarray(np.stack([p.astype(np.float32) for p in planes], axis=-1))


def _first_line(exc: Exception) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def rgbe_decode(rgbe: np.ndarray) -> np.ndarray:
    """uint8 (..., 4) RGBE -> float32 (..., 3): (m + 0.5) / 256 * 2**(e - 128), 0 where e = 0
    (the inverse of raylume.image.rgbe_encode, as Radiance decodes)."""
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0 / 256.0, e - 128), 0.0)
    return ((rgbe[..., :3].astype(np.float64) + 0.5) * scale[..., None]).astype(np.float32)


_HDR_MAX_HEADER = 1 << 16


def _read_hdr(path: Path) -> np.ndarray:
    data = path.read_bytes()
    pos, width, height, flip_y, flip_x = _hdr_header(data)
    _check_size(width, height)
    rgbe = np.empty((height, width, 4), dtype=np.uint8)
    for y in range(height):
        pos = _hdr_scanline(data, pos, width, rgbe[y], y)
    if flip_y:
        rgbe = rgbe[::-1]
    if flip_x:
        rgbe = rgbe[:, ::-1]
    return np.ascontiguousarray(rgbe_decode(rgbe))


def _hdr_header(data: bytes) -> tuple[int, int, int, bool, bool]:
    """(offset of the pixels, width, height, rows stored bottom-up, columns stored right-left)."""
    if not data.startswith(b"#?"):
        raise _BadImage("not a Radiance .hdr file (it does not start with '#?')")
    end = data.find(b"\n\n", 0, _HDR_MAX_HEADER)
    if end < 0:
        raise _BadImage("its header does not end (no blank line)")
    for line in data[:end].split(b"\n")[1:]:
        if line.startswith(b"FORMAT="):
            fmt = line[7:].strip()
            if fmt != b"32-bit_rle_rgbe":
                raise _BadImage(f"FORMAT={fmt.decode('latin-1')} is not supported (only 32-bit_rle_rgbe)")
    line_end = data.find(b"\n", end + 2)
    if line_end < 0:
        raise _BadImage("it has no resolution line (truncated)")
    parts = data[end + 2 : line_end].split()
    if len(parts) != 4 or parts[0] not in (b"-Y", b"+Y") or parts[2] not in (b"+X", b"-X"):
        raise _BadImage(
            f"unsupported resolution line {data[end + 2 : line_end][:40]!r} (expected '-Y height +X width')"
        )
    try:
        height, width = int(parts[1]), int(parts[3])
    except ValueError:
        raise _BadImage("its resolution line does not hold two whole numbers") from None
    return line_end + 1, width, height, parts[0] == b"+Y", parts[2] == b"-X"


def _hdr_scanline(data: bytes, pos: int, width: int, out: np.ndarray, y: int) -> int:
    """Decode one scanline into out (W, 4) uint8 and return the offset after it."""
    n = len(data)
    if pos + 4 > n:
        raise _BadImage(f"truncated at scanline {y}")
    if 8 <= width <= 0x7FFF and data[pos] == 2 and data[pos + 1] == 2 and data[pos + 2] < 128:
        if (data[pos + 2] << 8) | data[pos + 3] != width:
            raise _BadImage(f"scanline {y} says it is {(data[pos + 2] << 8) | data[pos + 3]} pixels wide, not {width}")
        pos += 4
        row = bytearray(4 * width)
        for c in range(4):
            k = c * width
            stop = k + width
            while k < stop:
                if pos >= n:
                    raise _BadImage(f"truncated at scanline {y}")
                count = data[pos]
                if count > 128:  # a run of one byte
                    count -= 128
                    if k + count > stop or pos + 1 >= n:
                        raise _BadImage(f"bad run-length data at scanline {y}")
                    row[k : k + count] = bytes((data[pos + 1],)) * count
                    pos += 2
                else:  # literal bytes
                    if count == 0 or k + count > stop or pos + 1 + count > n:
                        raise _BadImage(f"bad run-length data at scanline {y}")
                    row[k : k + count] = data[pos + 1 : pos + 1 + count]
                    pos += 1 + count
                k += count
        out[:] = np.frombuffer(bytes(row), dtype=np.uint8).reshape(4, width).T
        return pos
    # Flat pixels, possibly with old-style runs: (1, 1, 1, n) repeats the previous pixel.
    flat = np.frombuffer(data, dtype=np.uint8, count=min(4 * width, (n - pos) // 4 * 4), offset=pos).reshape(-1, 4)
    runs = (flat[:, 0] == 1) & (flat[:, 1] == 1) & (flat[:, 2] == 1)
    if len(flat) == width and not runs.any():
        out[:] = flat
        return pos + 4 * width
    x = 0
    shift = 0
    while x < width:
        if pos + 4 > n:
            raise _BadImage(f"truncated at scanline {y}")
        px = data[pos : pos + 4]
        pos += 4
        if px[0] == 1 and px[1] == 1 and px[2] == 1:
            count = px[3] << shift
            if x == 0 or x + count > width:
                raise _BadImage(f"bad run-length data at scanline {y}")
            out[x : x + count] = out[x - 1]
            x += count
            shift += 8
        else:
            out[x] = np.frombuffer(px, dtype=np.uint8)
            x += 1
            shift = 0
    return pos
