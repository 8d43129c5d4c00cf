"""The rendered Image, 8-bit encodings (the seed's clamp, or sRGB, after an optional exposure)
and atomic file writers: PNG, NPY, OpenEXR and Radiance HDR."""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import OutputError

IMAGE_SUFFIXES = (".png", ".npy", ".exr", ".hdr")


def encode_8bit(rgb: np.ndarray, encoding: str = "clamp", exposure: float = 0.0) -> np.ndarray:
    """Linear float RGB -> uint8. 'clamp' is the seed's: clamp to 0..1 and scale by 255.
    `exposure` (in stops) scales the linear values by 2**exposure first."""
    if exposure:
        rgb = np.asarray(rgb, dtype=np.float32) * np.float32(2.0**exposure)
    x = np.nan_to_num(rgb, nan=0.0, posinf=1.0, neginf=0.0).clip(0.0, 1.0)
    if encoding == "srgb":
        x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    elif encoding != "clamp":
        raise ValueError(f"unknown encoding {encoding!r}; use 'clamp' or 'srgb'")
    return np.round(x * 255.0).astype(np.uint8)


def check_output_path(path: str | Path, allowed=IMAGE_SUFFIXES) -> Path:
    """Reject an output path before rendering: unknown extension, missing folder, a folder."""
    path = Path(path)
    if path.suffix.lower() not in allowed:
        raise OutputError(f"{path}: unknown output format {path.suffix or '(none)'!r}; use one of {', '.join(allowed)}")
    if path.is_dir():
        raise OutputError(f"{path}: is a folder; give a file name such as {path / 'render.png'}")
    if not path.parent.exists() and str(path.parent) not in ("", "."):
        raise OutputError(f"{path}: the folder {path.parent} does not exist")
    return path


def write_atomic(path: str | Path, write) -> None:
    """Write through a temporary file in the target folder, then rename it into place, so an
    existing file is only ever replaced by a complete new one."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.chmod(tmp, _mode_for(path))  # mkstemp makes 0600 files; outputs get the usual mode
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _mode_for(path: Path) -> int:
    """The replaced file's mode, or what a plain open() would give under the current umask."""
    try:
        return path.stat().st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _png_bytes(rgb8: np.ndarray) -> bytes:
    from PIL import Image as PILImage

    buf = io.BytesIO()
    PILImage.fromarray(rgb8, mode="RGB").save(buf, format="PNG")
    return buf.getvalue()


def _write_exr(fh, rgb: np.ndarray) -> None:
    try:
        import OpenEXR
    except ImportError:
        raise OutputError("writing .exr needs the OpenEXR package: pip install 'raylume[exr]'") from None
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {"RGB": np.ascontiguousarray(rgb, dtype=np.float32)}
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


def save_array(path: str | Path, rgb: np.ndarray, encoding: str = "clamp", exposure: float = 0.0) -> Path:
    """Write rgb by the path's extension: .png (8-bit, exposure and encoding applied), .npy,
    .exr and .hdr (linear floats as rendered)."""
    path = check_output_path(path)
    suffix = path.suffix.lower()
    if suffix == ".png":
        data = _png_bytes(encode_8bit(rgb, encoding, exposure))
        write_atomic(path, lambda fh: fh.write(data))
    elif suffix == ".npy":
        write_atomic(path, lambda fh: np.save(fh, np.asarray(rgb, dtype=np.float32)))
    elif suffix == ".hdr":
        data = _hdr_bytes(rgb)
        write_atomic(path, lambda fh: fh.write(data))
    else:
        write_atomic(path, lambda fh: _write_exr(fh, rgb))
    return path


def save_npy(path: str | Path, array: np.ndarray) -> Path:
    path = check_output_path(path, allowed=(".npy",))
    write_atomic(path, lambda fh: np.save(fh, array))
    return path


class Image:
    """A rendered image: linear float32 RGB (H, W, 3), AOV arrays and render statistics.

    Shows itself in Jupyter (``_repr_png_``) and converts to numpy (``np.asarray(image)``)."""

    def __init__(self, rgb: np.ndarray, aovs: dict | None = None, stats: dict | None = None, encoding: str = "clamp",
                 exposure: float = 0.0):
        self.rgb = rgb
        self.aovs = aovs or {}
        self.stats = stats or {}
        self.encoding = encoding
        self.exposure = exposure  # stops, applied to 8-bit encodings only

    @property
    def width(self) -> int:
        return self.rgb.shape[1]

    @property
    def height(self) -> int:
        return self.rgb.shape[0]

    def to_uint8(self, encoding: str | None = None, exposure: float | None = None) -> np.ndarray:
        return encode_8bit(self.rgb, encoding or self.encoding, self.exposure if exposure is None else exposure)

    def save(self, path: str | Path, encoding: str | None = None, exposure: float | None = None) -> Path:
        """Write .png (8-bit: exposure, then encoding), .npy (float32 linear), .exr (float
        linear) or .hdr (Radiance RGBE, linear), atomically."""
        return save_array(path, self.rgb, encoding or self.encoding, self.exposure if exposure is None else exposure)

    def _repr_png_(self) -> bytes:
        return _png_bytes(self.to_uint8())

    def __array__(self, dtype=None, copy=None):
        return self.rgb if dtype is None else self.rgb.astype(dtype)

    def __repr__(self) -> str:
        mode = self.stats.get("mode", "?")
        return f"<raylume.Image {self.width}x{self.height} mode={mode} aovs={sorted(self.aovs)}>"
