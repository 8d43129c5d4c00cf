"""Denoising path mode without the light the camera sees directly.

A path-traced pixel is the sum of two parts: what its camera rays find emitted at their first
hit (an area light, an emissive surface, the environment, the background: the paths' first
segment), and everything that arrives after bouncing. Only the second part is noisy in the
way Intel Open Image Denoise is trained to remove. The first has no noise inside an emitter;
what it has is the emitter's edge, a coverage fraction estimated from the pixel's few samples.
Given to OIDN, a bright emitter bleeds into its neighbours, OIDN shifts its interior, and its
edge keeps the aliasing of a few samples (measured on the Cornell box at 256 x 256 and 16 spp:
the light's edge alone had six times the squared error of the whole raw 256-spp image;
benchmarks/bench_path.py, part 3).

So `denoise_path_image` splits the image:

1. The same camera samples rendered with max_depth 1 give exactly the first-segment part: the
   sampler keys camera rays by (seed, pixel, sample), so these are the render's own rays.
2. OIDN gets the rest (the image less that part), and the first-segment part is added back.
3. Pixels on the edges of what is seen directly get a path-traced value of many more samples
   per pixel instead, not denoised. There the rest has detail below the pixel that no guide
   shows: the Cornell box's light hangs 0.1 mm below the ceiling and lights a strip of it
   thinner than a pixel, which OIDN took for noise. These pixels are few (the light's outline),
   so their samples cost a fraction of the render.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .compile import CompiledScene
from .render_window import render_window
from .scene.model import MAX_SPP, Camera, RenderSettings

TILE = 4  # side of the tiles that get more samples (a pixel's edge mask is its 3 x 3 neighbourhood)
EDGE_FACTOR = 16  # the edge pixels get this many times the render's samples per pixel ...
# ... but at most this many path samples per path sample of the whole window (half the
# render's cost again at most), and never above MAX_SPP.
EDGE_BUDGET = 0.5
# A pixel is on an edge when its 3 x 3 neighbourhood differs by more than this fraction of the
# neighbourhood's brightest value (smooth environments and gradients stay below it).
EDGE_CONTRAST = 0.02


@dataclass
class SplitStats:
    edge_pixels: int = 0  # pixels given a path-traced value of edge_spp samples
    edge_spp: int = 0  # (0: none given)
    rays: int = 0  # rays the split traced
    seconds: float = 0.0


def first_segment(
    compiled: CompiledScene,
    camera: Camera,
    settings: RenderSettings,
    window: tuple[int, int, int, int],
    lanes: int,
):
    """The light seen directly (path mode with max_depth 1) in `window` = (x0, x1, y0, y1), at
    the render's own camera samples. Returns the WindowResult."""
    # path tracing whatever the render's integrator: at one segment bdpt's only strategy is the
    # camera ray meeting a light (s = 0, t = 2, weight 1), path tracing's own estimate
    seen = settings.model_copy(update={"max_depth": 1, "denoise": False, "integrator": "path"})
    return render_window(compiled, camera, seen, window, aovs=False, lanes=lanes)


def edge_mask(rgb: np.ndarray, contrast: float = EDGE_CONTRAST) -> np.ndarray:
    """bool (H, W): pixels whose 3 x 3 neighbourhood (edges repeated) varies by more than
    `contrast` times its brightest channel value."""
    value = rgb.max(axis=2).astype(np.float64)
    padded = np.pad(value, 1, mode="edge")
    H, W = value.shape
    shifts = [padded[1 + dy : 1 + dy + H, 1 + dx : 1 + dx + W] for dy in (-1, 0, 1) for dx in (-1, 0, 1)]
    high = np.max(shifts, axis=0)
    low = np.min(shifts, axis=0)
    return (high - low) > np.maximum(contrast * high, 1e-12)


def edge_windows(mask: np.ndarray, tile: int = TILE) -> list[tuple[int, int, int, int]]:
    """Windows (x0, x1, y0, y1), relative to the mask, covering the tiles that hold a marked
    pixel: each tile row's runs of such tiles merged into one window."""
    H, W = mask.shape
    rows, cols = -(-H // tile), -(-W // tile)
    padded = np.zeros((rows * tile, cols * tile), dtype=bool)
    padded[:H, :W] = mask
    marked = padded.reshape(rows, tile, cols, tile).any(axis=(1, 3))
    windows = []
    for r in range(rows):
        c = 0
        while c < cols:
            if not marked[r, c]:
                c += 1
                continue
            start = c
            while c < cols and marked[r, c]:
                c += 1
            windows.append((start * tile, min(c * tile, W), r * tile, min((r + 1) * tile, H)))
    return windows


def edge_spp(spp: int, window_pixels: int, edge_pixels: int) -> int:
    """Path samples per pixel for the edge tiles (see EDGE_FACTOR, EDGE_BUDGET); 0 when that
    would not add to the render's own `spp`."""
    if edge_pixels == 0:
        return 0
    budget = int(EDGE_BUDGET * spp * window_pixels / edge_pixels)
    more = min(EDGE_FACTOR * spp, budget, MAX_SPP)
    return more if more > spp else 0


def split_settings(table: RenderSettings, adaptive: dict | None) -> RenderSettings:
    """The settings denoise_path_image renders the light seen directly and the edges at: an
    adaptive image's samples are its rounds', so at its mean spp (`adaptive`: its statistics),
    that they cost what they cost beside a plain render; else the render's own."""
    if not adaptive:
        return table
    return table.model_copy(update={"spp": max(2, round(adaptive["mean_spp"]))})


def denoise_path_image(
    compiled: CompiledScene,
    camera: Camera,
    settings: RenderSettings,
    window: tuple[int, int, int, int],
    lanes: int,
    noisy: np.ndarray,
    albedo: np.ndarray,
    normal: np.ndarray,
) -> tuple[np.ndarray, SplitStats]:
    """The denoised image of a path-mode render of `window` = (x0, x1, y0, y1): OIDN on `noisy`
    less the light seen directly, that light added back, and the edges of what is seen
    directly path-traced with more samples (module docstring)."""
    from .denoise import denoise as oidn  # pyoidn is optional: loaded when denoising

    started = time.perf_counter()
    stats = SplitStats()
    seen = first_segment(compiled, camera, settings, window, lanes)
    stats.rays += seen.rays
    rest = np.maximum(noisy - seen.rgb, 0.0)
    out = oidn(rest, albedo, normal) + seen.rgb
    x0, x1, y0, y1 = window
    mask = edge_mask(seen.rgb)
    tiles = edge_windows(mask)
    tile_pixels = sum((a1 - a0) * (b1 - b0) for a0, a1, b0, b1 in tiles)
    stats.edge_spp = edge_spp(settings.spp, (x1 - x0) * (y1 - y0), tile_pixels)
    if stats.edge_spp:
        # the edge tiles by path tracing (the same image in expectation): a bdpt window would trace
        # the whole image's light subpaths for its splats, tile after tile
        more = settings.model_copy(update={"spp": stats.edge_spp, "denoise": False, "integrator": "path"})
        for a0, a1, b0, b1 in tiles:
            part = render_window(compiled, camera, more, (x0 + a0, x0 + a1, y0 + b0, y0 + b1), aovs=False, lanes=lanes)
            edges = mask[b0:b1, a0:a1]
            out[b0:b1, a0:a1][edges] = part.rgb[edges]
            stats.rays += part.rays
        stats.edge_pixels = int(mask.sum())
    stats.seconds = time.perf_counter() - started
    return out.astype(np.float32), stats
