"""What the viewer sends: a Frame (8-bit pixels encoded as the scene says, and what they show)
and the WebSocket message that carries it."""

from __future__ import annotations

import json
import struct
import time
from dataclasses import dataclass, field

import numpy as np

from ..image import jpeg_bytes, png_bytes

# JPEG for frames while the camera moves: a 640 x 480 frame encodes in ~3 ms and is ~10x smaller
# than PNG. Resting frames are PNG, lossless.
MOVING_JPEG_QUALITY = 85
# zlib level 1: a 640 x 480 PNG in ~10 ms instead of ~30 ms at the default level, ~20 % larger.
PNG_LEVEL = 1


@dataclass
class Frame:
    """One image the viewer shows: `rgb8` (h, w, 3) is the scene's 8-bit encoding of the
    rendered pixels (exactly what `raylume render` writes to a PNG); `data` is it encoded as
    `format` (jpeg while moving, png at rest). `width`/`height` are the frame's own pixels; a
    reduced-resolution frame is drawn scaled up to the view's size."""

    number: int
    rgb8: np.ndarray
    format: str
    spp: int
    mode: str
    camera_version: int
    converged: bool
    denoised: bool = False  # path mode's image through SVGF (moving) or OIDN (at rest)
    time: float = field(default_factory=time.monotonic)
    data: bytes = b""
    _png: bytes | None = None

    def __post_init__(self) -> None:
        if not self.data:
            self.data = (
                png_bytes(self.rgb8, PNG_LEVEL) if self.format == "png" else jpeg_bytes(self.rgb8, MOVING_JPEG_QUALITY)
            )
        if self.format == "png":
            self._png = self.data

    @property
    def width(self) -> int:
        return self.rgb8.shape[1]

    @property
    def height(self) -> int:
        return self.rgb8.shape[0]

    def png(self) -> bytes:
        """The frame losslessly (encoded on first use for a JPEG frame)."""
        if self._png is None:
            self._png = png_bytes(self.rgb8, PNG_LEVEL)
        return self._png

    def header(self) -> dict:
        return {
            "frame": self.number,
            "format": self.format,
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "mode": self.mode,
            "camera_version": self.camera_version,
            "converged": self.converged,
            "denoised": self.denoised,
        }

    def message(self, extra: dict | None = None) -> bytes:
        """The binary WebSocket message: a big-endian uint32 n, n bytes of JSON header, then
        the encoded image."""
        head = json.dumps({**self.header(), **(extra or {})}).encode()
        return struct.pack(">I", len(head)) + head + self.data
