"""The rendered Image, 8- and 16-bit encodings (the seed's clamp, or sRGB, after an optional
exposure and tone mapping) and atomic file writers: PNG (8 or 16 bits), JPEG, NPY, OpenEXR (with AOV layers) and
Radiance HDR."""

from __future__ import annotations

import io
import os
import struct
import tempfile
import zlib
from pathlib import Path

import numpy as np

from .errors import OutputError
from .scene.model import MAX_EXPOSURE
from .tonemap import TONEMAPS, tone_map

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".npy", ".exr", ".hdr")
# Outputs that hold encoded (display) values; the others store linear floats as rendered.
ENCODED_SUFFIXES = (".png", ".jpg", ".jpeg")
JPEG_QUALITY = 95

# EXR channels of each AOV when written as layers beside R, G, B. Ids are UINT channels that
# hold the int32 bits, so every id is exact and -1 (nothing hit) reads back as -1 through
# `.view(np.int32)` (it is 4294967295 as an unsigned number).
EXR_LAYERS = {
    "depth": ("Z",),
    "normal": ("X", "Y", "Z"),
    "albedo": ("R", "G", "B"),
    "noisy": ("R", "G", "B"),
    "spp": ("Y",),
    "object": ("id",),
    "prim": ("id",),
    "instance": ("id",),
}


def encode_levels(rgb: np.ndarray, encoding: str = "clamp", exposure: float = 0.0, tonemap: str = "none") -> np.ndarray:
    """Linear float RGB -> encoded values in 0..1 (float64), before quantisation. `exposure`
    (in stops) scales the linear values by 2**exposure first, then `tonemap` brings them into
    0..1 (tone_map; 'none' clamps); 'clamp' is the seed's encoding, no transfer curve, 'srgb'
    applies the sRGB curve."""
    if exposure:
        with np.errstate(over="ignore"):  # values past float32's range become inf, clipped below
            rgb = np.asarray(rgb, dtype=np.float32) * np.float32(2.0**exposure)
    if tonemap == "none":
        x = np.nan_to_num(rgb, nan=0.0, posinf=1.0, neginf=0.0).clip(0.0, 1.0)
    else:
        x = tone_map(np.nan_to_num(rgb, nan=0.0, posinf=np.finfo(np.float32).max, neginf=0.0), tonemap)
    if encoding == "srgb":
        x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    elif encoding != "clamp":
        raise ValueError(f"unknown encoding {encoding!r}; use 'clamp' or 'srgb'")
    return x


def check_display(encoding: str | None, exposure: float | None, tonemap: str | None) -> None:
    """Refuse (ValueError) an encoding, exposure or tonemap that encode_levels cannot apply
    (None: not given), before an image holds it or a file is written."""
    if encoding is not None and encoding not in ("clamp", "srgb"):
        raise ValueError(f"unknown encoding {encoding!r}; use 'clamp' or 'srgb'")
    if tonemap is not None and tonemap not in TONEMAPS:
        raise ValueError(f"unknown tonemap {tonemap!r}; use one of {', '.join(TONEMAPS)}")
    if exposure is not None and (
        isinstance(exposure, bool)
        or not isinstance(exposure, (int, float, np.integer, np.floating))
        or not -MAX_EXPOSURE <= exposure <= MAX_EXPOSURE  # (NaN fails too)
    ):
        raise ValueError(f"exposure must be a number of stops from -{MAX_EXPOSURE} to {MAX_EXPOSURE}, got {exposure!r}")


def encode_8bit(rgb: np.ndarray, encoding: str = "clamp", exposure: float = 0.0, tonemap: str = "none") -> np.ndarray:
    """Linear float RGB -> uint8: the encoded value times 255, rounded."""
    return np.round(encode_levels(rgb, encoding, exposure, tonemap) * 255.0).astype(np.uint8)


def encode_16bit(rgb: np.ndarray, encoding: str = "clamp", exposure: float = 0.0, tonemap: str = "none") -> np.ndarray:
    """Linear float RGB -> uint16 by the same curve as encode_8bit, times 65535."""
    return np.round(encode_levels(rgb, encoding, exposure, tonemap) * 65535.0).astype(np.uint16)


def check_output_path(path: str | Path, allowed=IMAGE_SUFFIXES, also: str = "") -> Path:
    """Reject an output path before rendering: a folder, an unknown extension (`also`: what
    else the caller takes, for its message), a folder that is missing, not a folder or not
    writable."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(
            f"{path}: is a folder; the output must be a file name ending in {_one_of(allowed)}, "
            f"e.g. {path / ('render' + allowed[0])}"
        )
    if path.suffix.lower() not in allowed:
        raise OutputError(f"{path}: unknown output format {path.suffix or '(none)'!r}; use {_one_of(allowed)}{also}")
    check_writable_folder(path)
    return path


def _one_of(allowed) -> str:
    return allowed[0] if len(allowed) == 1 else f"one of {', '.join(allowed)}"


def check_writable_folder(path: Path) -> None:
    """The folder that will hold `path` exists, is a folder and takes new files. Asked before
    rendering, so a render is never lost to an output that cannot be written. os.access alone
    misses read-only mounts and ACLs (and root passes it everywhere), so a file is created too."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.exists():
        raise OutputError(f"{path}: the folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputError(f"{path}: {folder} is not a folder")
    reason = None
    if not os.access(folder, os.W_OK | os.X_OK):
        reason = "Permission denied"
    else:
        try:
            fd, probe = tempfile.mkstemp(prefix=".raylume-", suffix=".probe", dir=folder)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            reason = _reason(exc)
    if reason:
        raise OutputError(f"{path}: cannot write into the folder {folder} ({reason}); choose another output path")


def _reason(exc: OSError) -> str:
    """An OSError in words: its strerror ("No space left on device"), never the temp file name."""
    return exc.strerror or str(exc) or "unknown error"


def write_failed(path: Path, exc: OSError) -> OutputError:
    """The error for an output that failed while being written (a full disk), naming the output."""
    return OutputError(f"{path}: cannot write the file ({_reason(exc)})")


def write_atomic(path: str | Path, write) -> None:
    """Write through a temporary file in the target folder, then rename it into place, so an
    existing file is only ever replaced by a complete new one. An OSError (disk full, the
    folder vanished) becomes an OutputError in words naming `path`."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    try:
        # (the name cut short: a file name of up to 255 bytes must still leave room for its temporary's)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name[:100]}.", suffix=".part", dir=folder)
    except OSError as exc:
        if not folder.exists():  # said as check_writable_folder says it
            raise OutputError(f"{path}: the folder {folder} does not exist") from None
        raise write_failed(path, exc) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.chmod(tmp, _mode_for(path))  # mkstemp makes 0600 files; outputs get the usual mode
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError):
            raise write_failed(path, exc) from None
        raise


def _mode_for(path: Path) -> int:
    """The replaced file's mode, or what a plain open() would give under the current umask."""
    try:
        return path.stat().st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


class _Writes:
    """A file seen only through its write(): np.save then writes chunks with Python's write,
    whose error on a full disk says so (errno ENOSPC). Given the file itself, numpy writes with
    C's fwrite, and a short write reports only "36864 requested and 992 written"."""

    def __init__(self, fh):
        self.write = fh.write


def _save_npy(fh, array: np.ndarray) -> None:
    np.save(_Writes(fh), array)


def png_bytes(rgb8: np.ndarray, compress_level: int = -1) -> bytes:
    """8-bit RGB as a PNG file's bytes; compress_level is zlib's (-1: its default, level 6)."""
    from PIL import Image as PILImage

    buf = io.BytesIO()
    PILImage.fromarray(rgb8, mode="RGB").save(buf, format="PNG", compress_level=compress_level)
    return buf.getvalue()


def jpeg_bytes(rgb8: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """8-bit RGB as a JPEG file's bytes."""
    from PIL import Image as PILImage

    buf = io.BytesIO()
    PILImage.fromarray(rgb8, mode="RGB").save(buf, format="JPEG", quality=quality)
    return buf.getvalue()


def _png16_bytes(rgb16: np.ndarray) -> bytes:
    """A 16-bit RGB PNG (colour type 2, bit depth 16), written here because Pillow cannot.
    Every row uses the Up filter (the byte difference to the row above), which lets zlib
    compress smooth renders well."""
    h, w = rgb16.shape[:2]
    rows = np.ascontiguousarray(rgb16, dtype=">u2").view(np.uint8).reshape(h, w * 6)
    up = rows.copy()
    up[1:] -= rows[:-1]  # uint8 arithmetic wraps modulo 256, as the filter is defined
    scanlines = np.concatenate([np.full((h, 1), 2, np.uint8), up], axis=1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", w, h, 16, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(scanlines.tobytes(), 6))
        + chunk(b"IEND", b"")
    )


def exr_channels(rgb: np.ndarray, layers: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """EXR channel name -> 2D array: R, G, B, then each AOV as `name.X`... (see EXR_LAYERS)."""
    channels = {c: np.ascontiguousarray(rgb[..., k], dtype=np.float32) for k, c in enumerate("RGB")}
    for name, array in (layers or {}).items():
        array = np.asarray(array)
        suffixes = EXR_LAYERS.get(name) or _layer_suffixes(array)
        if suffixes == ("id",):
            channels[f"{name}.id"] = np.ascontiguousarray(array, dtype=np.int32).view(np.uint32)
        elif len(suffixes) == 1:
            channels[f"{name}.{suffixes[0]}"] = np.ascontiguousarray(array, dtype=np.float32)
        else:
            for k, suffix in enumerate(suffixes):
                channels[f"{name}.{suffix}"] = np.ascontiguousarray(array[..., k], dtype=np.float32)
    return channels


def _layer_suffixes(array: np.ndarray) -> tuple[str, ...]:
    """Channel names for an AOV that EXR_LAYERS does not list, from its shape and type."""
    if array.ndim == 2:
        return ("id",) if np.issubdtype(array.dtype, np.integer) else ("Y",)
    components = array.shape[-1]
    return {2: ("U", "V"), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}.get(components) or tuple(
        str(k) for k in range(components)
    )


def _write_exr(fh, rgb: np.ndarray, layers: dict[str, np.ndarray] | None = None) -> None:
    try:
        import OpenEXR
    except ImportError:
        raise OutputError("writing .exr needs the OpenEXR package: pip install OpenEXR") from None
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = exr_channels(rgb, layers)
    with tempfile.TemporaryDirectory() as tmpdir:
        # OpenEXR writes to a path; copy the bytes into the atomic temp file.
        tmp = Path(tmpdir) / "image.exr"
        with OpenEXR.File(header, channels) as f:
            f.write(str(tmp))
        fh.write(tmp.read_bytes())


# Largest value RGBE stores (exponent byte 255); larger values, and +inf, are clipped to it.
_RGBE_MAX = float(np.ldexp(255.0 / 256.0, 127))


def rgbe_encode(rgb: np.ndarray) -> np.ndarray:
    """Linear float RGB (H, W, 3) -> uint8 (H, W, 4) Radiance RGBE: a shared exponent e and
    mantissas m with value = (m + 0.5) / 256 * 2**(e - 128) (Ward, Graphics Gems II).
    Negative and NaN values become 0; values below 1e-32 are stored as zero."""
    x = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=_RGBE_MAX, neginf=0.0)
    x = x.clip(0.0, _RGBE_MAX)
    top = x.max(axis=2)
    mantissa, exponent = np.frexp(top)  # top = mantissa * 2**exponent, mantissa in [0.5, 1)
    nonzero = top >= 1e-32
    scale = np.where(nonzero, mantissa * 256.0 / np.where(nonzero, top, 1.0), 0.0)
    out = np.zeros(x.shape[:2] + (4,), dtype=np.uint8)
    out[..., :3] = np.floor(x * scale[..., None]).clip(0, 255).astype(np.uint8)
    out[..., 3] = np.where(nonzero, exponent + 128, 0).astype(np.uint8)
    return out


def _hdr_bytes(rgb: np.ndarray) -> bytes:
    """A Radiance .hdr file. Scanlines 8..32767 pixels wide use the new run-length format,
    written as literal chunks only (every reader takes it; no ambiguity with flat pixels that
    happen to start with 2, 2); other widths are stored flat, as the format requires."""
    rgbe = rgbe_encode(rgb)
    h, w = rgbe.shape[:2]
    header = f"#?RADIANCE\n# raylume\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n".encode("ascii")
    if not 8 <= w <= 0x7FFF:
        return header + rgbe.tobytes()
    planes = rgbe.transpose(0, 2, 1)  # (H, 4, W): each channel of a scanline in turn
    full, rest = divmod(w, 128)
    parts = []
    if full:
        chunks = np.empty((h, 4, full, 129), dtype=np.uint8)
        chunks[..., 0] = 128
        chunks[..., 1:] = planes[..., : full * 128].reshape(h, 4, full, 128)
        parts.append(chunks.reshape(h, 4, -1))
    if rest:
        tail = np.empty((h, 4, rest + 1), dtype=np.uint8)
        tail[..., 0] = rest
        tail[..., 1:] = planes[..., full * 128 :]
        parts.append(tail)
    body = np.concatenate(parts, axis=2).reshape(h, -1)
    marker = np.tile(np.array([2, 2, w >> 8, w & 0xFF], dtype=np.uint8), (h, 1))
    return header + np.concatenate([marker, body], axis=1).tobytes()


def check_bit_depth(path: str | Path, bit_depth: int) -> None:
    """16 bits per channel only exist for PNG here; 8 is every encoded format's depth."""
    if bit_depth == 8:
        return
    if bit_depth != 16:
        raise OutputError(f"--bit-depth {bit_depth}: use 8 or 16")
    if Path(path).suffix.lower() != ".png":
        raise OutputError(
            f"{path}: --bit-depth 16 is for .png outputs only (JPEG and videos are 8-bit; .exr, .hdr and "
            ".npy store floats); write a .png, or drop --bit-depth"
        )


def save_array(
    path: str | Path,
    rgb: np.ndarray,
    encoding: str = "clamp",
    exposure: float = 0.0,
    bit_depth: int = 8,
    layers: dict[str, np.ndarray] | None = None,
    tonemap: str = "none",
) -> Path:
    """Write rgb by the path's extension: .png (8 or 16 bits) and .jpg/.jpeg (8 bits, quality
    95), exposure, tonemap and encoding applied; .npy, .exr and .hdr (linear floats as rendered).
    `layers` (AOV name -> array) go into an .exr beside R, G, B."""
    path = check_output_path(path)
    check_bit_depth(path, bit_depth)
    suffix = path.suffix.lower()
    if layers and suffix != ".exr":
        raise OutputError(f"{path}: AOV layers need an .exr output")
    if suffix == ".png" and bit_depth == 16:
        data = _png16_bytes(encode_16bit(rgb, encoding, exposure, tonemap))
    elif suffix == ".png":
        data = png_bytes(encode_8bit(rgb, encoding, exposure, tonemap))
    elif suffix in (".jpg", ".jpeg"):
        data = jpeg_bytes(encode_8bit(rgb, encoding, exposure, tonemap))
    elif suffix == ".hdr":
        data = _hdr_bytes(rgb)
    elif suffix == ".npy":
        write_atomic(path, lambda fh: _save_npy(fh, np.asarray(rgb, dtype=np.float32)))
        return path
    else:
        write_atomic(path, lambda fh: _write_exr(fh, rgb, layers))
        return path
    write_atomic(path, lambda fh: fh.write(data))
    return path


def save_npy(path: str | Path, array: np.ndarray) -> Path:
    path = check_output_path(path, allowed=(".npy",))
    write_atomic(path, lambda fh: _save_npy(fh, array))
    return path


class Image:
    """A rendered image: linear float32 RGB (H, W, 3), AOV arrays and render statistics.

    Shows itself in Jupyter (``_repr_png_``) and converts to numpy (``np.asarray(image)``)."""

    def __init__(
        self,
        rgb: np.ndarray,
        aovs: dict | None = None,
        stats: dict | None = None,
        encoding: str = "clamp",
        exposure: float = 0.0,
        tonemap: str = "none",
    ):
        # A pixel past float32's range (a light of 1e38, or a tiny distance to a bright point) is
        # the largest float32, not inf: no output image holds NaN or inf (NaN samples are dropped
        # before they reach the film). One pass over the image; a copy only where it is needed.
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"an Image holds RGB of shape (H, W, 3), got shape {rgb.shape}")
        check_display(encoding, exposure, tonemap)
        if rgb.dtype.kind == "f" and not np.isfinite(rgb).all():
            rgb = np.nan_to_num(rgb, nan=0.0, posinf=np.finfo(rgb.dtype).max, neginf=-np.finfo(rgb.dtype).max)
        self.rgb = rgb
        self.aovs = aovs or {}
        self.stats = stats or {}
        self.encoding = encoding
        self.exposure = exposure  # stops, applied to 8-bit encodings only
        self.tonemap = tonemap  # likewise

    @property
    def width(self) -> int:
        return self.rgb.shape[1]

    @property
    def height(self) -> int:
        return self.rgb.shape[0]

    def to_uint8(
        self, encoding: str | None = None, exposure: float | None = None, tonemap: str | None = None
    ) -> np.ndarray:
        """The image as 8-bit display values (H, W, 3): exposure, tone mapping and encoding, each the
        image's own unless given."""
        check_display(encoding, exposure, tonemap)
        exposure = self.exposure if exposure is None else exposure
        return encode_8bit(self.rgb, encoding or self.encoding, exposure, tonemap or self.tonemap)

    def save(
        self,
        path: str | os.PathLike,
        encoding: str | None = None,
        exposure: float | None = None,
        *,
        bit_depth: int = 8,
        layers: list[str] | tuple[str, ...] = (),
        tonemap: str | None = None,
    ) -> Path:
        """Write .png (8 or 16 bits) or .jpg/.jpeg (8 bits): exposure, tone mapping, then encoding
        (each the image's own unless given); .npy (float32 linear), .exr (float linear; `layers`
        names AOVs to add as layers, see EXR_LAYERS) or .hdr (Radiance RGBE, linear), atomically."""
        layers = [layers] if isinstance(layers, str) else list(layers)  # one name is a list of one
        check_display(encoding, exposure, tonemap)
        missing = [name for name in layers if name not in self.aovs]
        if missing:
            raise OutputError(f"{path}: the image has no {', '.join(missing)} AOV to write as a layer")
        return save_array(
            path,
            self.rgb,
            encoding or self.encoding,
            self.exposure if exposure is None else exposure,
            bit_depth=bit_depth,
            layers={name: self.aovs[name] for name in layers},
            tonemap=tonemap or self.tonemap,
        )

    def _repr_png_(self) -> bytes:
        return png_bytes(self.to_uint8())

    def __array__(self, dtype=None, copy=None):
        # numpy 2's protocol: copy=True always copies (np.copy, np.array), copy=False refuses a
        # copy it would need, None copies only to convert
        return np.array(self.rgb, dtype=dtype, copy=copy)

    def __repr__(self) -> str:
        mode = self.stats.get("mode", "?")
        return f"<raylume.Image {self.width}x{self.height} mode={mode} aovs={sorted(self.aovs)}>"
