"""What the kernels of one pass over the image share, bundled so that entry points stay short:
the pass's parameters (ImagePass), the lanes' control (integrators/frame.py's LaneControl) and
the primary-hit AOV outputs (Aovs)."""

from typing import NamedTuple

import numpy as np


class ImagePass(NamedTuple):
    """One pass over a window of the image: the camera array (camera.py) and pixel filter
    (film.py), the image's size, the window (x0, y0, x1, y1: columns x0..x1-1, rows y0..y1-1),
    the samples (first, count, total: this pass adds samples first..first+count-1 of total), the
    seed, the depth limit (trace and path modes) and the background colour."""

    camera: np.ndarray
    pixel_filter: np.ndarray
    width: int
    height: int
    window: tuple[int, int, int, int]
    samples: tuple[int, int, int]
    seed: int
    max_depth: int
    background: tuple[float, float, float]


class Aovs(NamedTuple):
    """The primary-hit AOV arrays of a window (DESIGN.md section 3), filled row by row."""

    depth: np.ndarray  # float32 (H, W)
    normal: np.ndarray  # float32 (H, W, 3)
    object: np.ndarray  # int32 (H, W)
    prim: np.ndarray  # int32 (H, W)
    albedo: np.ndarray  # float32 (H, W, 3)
    instance: np.ndarray  # int32 (H, W)
