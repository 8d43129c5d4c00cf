"""Denoising of path-traced images with Intel Open Image Denoise (the optional `pyoidn` package).

`denoise` runs OIDN's "RT" filter, a neural network trained on Monte Carlo renders, on a linear
RGB image. Two optional auxiliary images ("guides") tell it what the noise hides:

- `albedo`: the surface colour at the first hit, in [0, 1]. It lets the filter keep texture and
  colour edges: the noisy colour is largely albedo times lighting, so detail that is in the
  albedo is detail, not noise.
- `normal`: the shading normal at the first hit (world or view space, components in [-1, 1]).
  It keeps geometric edges and creases where the albedo is the same on both sides. OIDN takes
  normals only together with albedo.

Guides are best noise-free (first-hit AOVs are, up to antialiasing); OIDN prefilters them anyway.
Every input is sanitized before OIDN sees it: NaN and infinities become 0, colour is clamped to
>= 0 (and to [0, 1] with `hdr=False`), albedo to [0, 1], normals to [-1, 1].

The filter runs on OIDN's default CPU device, which uses every core; the device and filter are
created on the first call (about 0.1 s) and reused by later ones. A 600 x 600 image takes about
2 s on two cores, a 128 x 128 one about 0.13 s.
"""

from __future__ import annotations

import numpy as np

from raylume.errors import RaylumeError

__all__ = ["denoise", "is_available", "require_denoiser"]

_INSTALL = "pip install 'raylume[denoise]'"


def _pyoidn():
    """The pyoidn module with its native library loaded, or a RaylumeError saying what to install."""
    try:
        import pyoidn
    except ImportError:
        raise RaylumeError(
            f"Denoising needs the optional package pyoidn (Intel Open Image Denoise): install it with {_INSTALL}."
        ) from None
    try:
        # pyoidn loads its shared library on the first call into it
        supported = bool(pyoidn.Device.is_cpu_available())
    except Exception as exc:
        raise RaylumeError(
            f"Denoising could not load Intel Open Image Denoise's library from pyoidn "
            f"({type(exc).__name__}: {exc}): reinstall it with pip install --force-reinstall "
            f"'raylume[denoise]'."
        ) from None
    if not supported:
        raise RaylumeError("Intel Open Image Denoise does not support this CPU, so the image cannot be denoised.")
    return pyoidn


def require_denoiser() -> None:
    """Raise the RaylumeError `denoise` would raise when it cannot run (check before a render)."""
    _pyoidn()


def is_available() -> bool:
    """True when `denoise` can run: pyoidn is installed and its library loads on this CPU."""
    try:
        _pyoidn()
    except RaylumeError:
        return False
    return True


def _image(name: str, value, shape: tuple[int, ...] | None, low: float, high: float) -> np.ndarray:
    """A contiguous float32 copy of an (H, W, 3) image, non-finite values set to 0, clamped to [low, high]."""
    array = np.asarray(value)
    if array.ndim != 3 or array.shape[2] != 3 or 0 in array.shape:
        raise ValueError(f"denoise: {name} must have shape (H, W, 3), got {array.shape}")
    if shape is not None and array.shape != shape:
        raise ValueError(f"denoise: {name} has shape {array.shape}, but the image has shape {shape}")
    if not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
        raise ValueError(f"denoise: {name} must hold real numbers, got dtype {array.dtype}")
    out = np.array(array, dtype=np.float32, order="C", copy=True)
    out[~np.isfinite(out)] = 0.0
    np.clip(out, low, high, out=out)
    return out


def denoise(rgb, albedo=None, normal=None, *, hdr: bool = True) -> np.ndarray:
    """Denoise a linear RGB image (H, W, 3) with OIDN's RT filter; returns a new finite float32 array >= 0.

    `albedo` and `normal` are optional (H, W, 3) guides of the same size (see the module docstring);
    `normal` needs `albedo`. `hdr=False` says the colour is low dynamic range, in [0, 1].
    Raises ValueError for a bad shape and RaylumeError when pyoidn or its library is missing.
    """
    color = _image("rgb", rgb, None, 0.0, np.inf if hdr else 1.0)
    if normal is not None and albedo is None:
        raise ValueError("denoise: normal needs albedo too (OIDN takes normals only together with albedo)")
    guides = {}
    if albedo is not None:
        guides["albedo"] = _image("albedo", albedo, color.shape, 0.0, 1.0)
    if normal is not None:
        guides["normal"] = _image("normal", normal, color.shape, -1.0, 1.0)
    pyoidn = _pyoidn()
    try:
        out = pyoidn.denoise(color, guides.get("albedo"), guides.get("normal"), hdr=bool(hdr), quality="high")
    except RuntimeError as exc:
        raise RaylumeError(f"Intel Open Image Denoise failed: {exc}") from exc
    out = np.asarray(out, dtype=np.float32)
    out[~np.isfinite(out)] = 0.0
    return np.maximum(out, 0.0, out=out)
