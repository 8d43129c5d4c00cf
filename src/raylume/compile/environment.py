"""The scene's `[environment]` made the kernels' Environment (kernels/shading/environment.py): a
constant colour or an equirectangular .hdr / .exr image read here, scaled, turned, and its
sampling tables built. Bad input is a SceneError naming the key."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..kernels.shading.environment import Environment, alias_table, row_edges, sampling_tables
from ..scene.mesh import transform_matrix
from .equal_area import equal_area_to_equirectangular

# A guard against decompression bombs (the texture table's limit): 64 Mi texels, 768 MiB.
MAX_TEXELS = 1 << 26

SUFFIXES = (".hdr", ".exr")


def build_environment(
    color=None,
    file=None,
    intensity=1.0,
    rotate=(0.0, 0.0, 0.0),
    base_dir=".",
    source: str = "<scene>",
    where: str = "environment",
    matrix=None,
    mapping: str = "equirectangular",
) -> Environment:
    """The kernels' Environment for `[environment]`: a constant `color` (linear [r, g, b]) or an
    equirectangular `file` (.hdr or .exr, relative to `base_dir`), scaled by `intensity` and
    turned by `rotate` (degrees about x, then y, then z, as object transforms). Bad input
    raises SceneError naming `source` and the key (`{where}.file`, ...). `matrix` (3 x 3,
    orthogonal) replaces `rotate`; `mapping = "equal-area"` reads the file as pbrt-v4's square
    equal-area octahedral map (equal_area.py) and resamples it to equirectangular."""

    def fail(key: str, why: str):
        raise SceneError(f"{source}: {where}.{key}: {why}") from None

    if (color is None) == (file is None):
        raise SceneError(f"{source}: {where}: give exactly one of 'color' (a constant radiance) or 'file' (an image)")
    scale = _finite_number(intensity)
    if scale is None or scale < 0.0:
        fail("intensity", f"must be a finite number >= 0, got {intensity!r}")
    try:
        turn = transform_matrix(rotate=rotate)[:3, :3] if matrix is None else np.array(matrix, dtype=np.float64)
        rotation = np.ascontiguousarray(turn, dtype=np.float64)
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
        if mapping == "equal-area":
            if image.shape[0] != image.shape[1]:
                fail("file", f"an equal-area (octahedral) map must be square, got {image.shape[1]} x {image.shape[0]}")
            image = equal_area_to_equirectangular(image)

    scaled = image.astype(np.float64) * scale
    if not np.all(scaled <= np.finfo(np.float32).max):
        fail("intensity", f"{intensity!r} times the image's brightest texel overflows float32")
    image = np.ascontiguousarray(scaled, dtype=np.float32)
    alias = alias_table(*sampling_tables(image))
    return Environment(image, alias, row_edges(image.shape[0]), rotation, True)


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
