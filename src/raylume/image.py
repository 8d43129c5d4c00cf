"""The rendered Image, 8-bit encodings (the seed's clamp, or sRGB) and atomic file writers."""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import OutputError

IMAGE_SUFFIXES = (".png", ".npy", ".exr")


def encode_8bit(rgb: np.ndarray, encoding: str = "clamp") -> np.ndarray:
    """Linear float RGB -> uint8. 'clamp' is the seed's: clamp to 0..1 and scale by 255."""
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


def save_array(path: str | Path, rgb: np.ndarray, encoding: str = "clamp") -> Path:
    path = check_output_path(path)
    suffix = path.suffix.lower()
    if suffix == ".png":
        data = _png_bytes(encode_8bit(rgb, encoding))
        write_atomic(path, lambda fh: fh.write(data))
    elif suffix == ".npy":
        write_atomic(path, lambda fh: np.save(fh, np.asarray(rgb, dtype=np.float32)))
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

    def __init__(self, rgb: np.ndarray, aovs: dict | None = None, stats: dict | None = None, encoding: str = "clamp"):
        self.rgb = rgb
        self.aovs = aovs or {}
        self.stats = stats or {}
        self.encoding = encoding

    @property
    def width(self) -> int:
        return self.rgb.shape[1]

    @property
    def height(self) -> int:
        return self.rgb.shape[0]

    def to_uint8(self, encoding: str | None = None) -> np.ndarray:
        return encode_8bit(self.rgb, encoding or self.encoding)

    def save(self, path: str | Path, encoding: str | None = None) -> Path:
        """Write .png (8-bit, encoded), .npy (float32 linear) or .exr (float linear), atomically."""
        return save_array(path, self.rgb, encoding or self.encoding)

    def _repr_png_(self) -> bytes:
        return _png_bytes(self.to_uint8())

    def __array__(self, dtype=None, copy=None):
        return self.rgb if dtype is None else self.rgb.astype(dtype)

    def __repr__(self) -> str:
        mode = self.stats.get("mode", "?")
        return f"<raylume.Image {self.width}x{self.height} mode={mode} aovs={sorted(self.aovs)}>"
