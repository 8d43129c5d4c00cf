"""Generate the example textures (deterministic; numpy and Pillow only).

    python examples/textures/make_textures.py

* ``spots.png``  256 x 256: black patches on white, for Spot the cow's UVs (its own texture
  is not redistributed here).
* ``planks.jpg`` 256 x 256: wooden floor planks (JPEG, to show that JPEG loads too).
* ``globe.png``  256 x 128: a latitude/longitude grid with coloured bands, for sphere UVs.
* ``tiles_normal.png``   256 x 256: a normal map of 4 x 4 bevelled tiles in mortar, slightly
  uneven (tangent space: x along u, y up the image; examples/surface_maps.toml).
* ``dimples_height.png`` 256 x 256: a height (bump) map of hammered metal, round dimples.
* ``lattice_alpha.png``  64 x 64: a cut-out mask, one round hole in a solid cell (grey: black
  is the hole), tiled into a lattice screen (examples/surface_maps.toml).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent


def smooth_noise(shape, cells, rng, wrap=True) -> np.ndarray:
    """Value noise: random values on a coarse grid, bicubically upsampled (tileable)."""
    h, w = shape
    grid = rng.random((cells[0], cells[1]))
    y = np.arange(h) * cells[0] / h
    x = np.arange(w) * cells[1] / w
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    ty, tx = y - y0, x - x0
    ty, tx = ty * ty * (3 - 2 * ty), tx * tx * (3 - 2 * tx)
    y1, x1 = (y0 + 1) % cells[0], (x0 + 1) % cells[1]
    a = grid[y0][:, x0] * (1 - tx) + grid[y0][:, x1] * tx
    b = grid[y1][:, x0] * (1 - tx) + grid[y1][:, x1] * tx
    return a * (1 - ty[:, None]) + b * ty[:, None]


def spots(rng) -> np.ndarray:
    n = smooth_noise((256, 256), (6, 6), rng) * 0.7 + smooth_noise((256, 256), (16, 16), rng) * 0.3
    patch = n > 0.58
    white = np.array([236, 232, 222], dtype=np.float64)
    black = np.array([28, 24, 22], dtype=np.float64)
    img = np.where(patch[..., None], black, white)
    return img.round().astype(np.uint8)


def planks(rng) -> np.ndarray:
    h, w = 256, 256
    rows = 4
    y = np.arange(h)[:, None]
    x = np.arange(w)[None, :]
    plank = y * rows // h
    shift = rng.integers(0, w, size=rows)[plank]
    xs = (x + shift) % w
    # stripes along the plank, bent by noise that varies slowly along it
    bend = smooth_noise((h, w), (16, 3), rng)
    grain = np.sin((y % (h // rows)) / (h // rows) * 2 * np.pi * 2.5 + bend * 7 + plank * 1.7) * 0.5 + 0.5
    grain = grain ** 3
    tone = rng.uniform(0.8, 1.1, size=rows)[plank]
    light = np.array([196, 142, 92], dtype=np.float64)
    dark = np.array([128, 78, 42], dtype=np.float64)
    img = (light * (1 - grain[..., None]) + dark * grain[..., None]) * tone[..., None]
    seam = ((y % (h // rows)) < 2) | (xs % (w // 1) < 2)
    img = np.where(seam[..., None], img * 0.45, img)
    return img.clip(0, 255).round().astype(np.uint8)


def globe() -> np.ndarray:
    h, w = 128, 256
    v = (np.arange(h)[:, None] + 0.5) / h
    u = (np.arange(w)[None, :] + 0.5) / w
    band = np.floor(v * 6).astype(int) % 6
    colours = np.array([[60, 110, 200], [70, 170, 120], [230, 200, 90],
                        [220, 120, 70], [170, 90, 180], [80, 170, 200]], dtype=np.float64)
    img = colours[band] * np.ones((1, w, 1))
    checker = ((np.floor(u * 12) + np.floor(v * 6)) % 2)[..., None]
    img = img * (0.75 + 0.25 * checker)
    lines = (np.abs(u * 12 - np.round(u * 12)) < 0.04) | (np.abs(v * 6 - np.round(v * 6)) < 0.04)
    img = np.where(lines[..., None], 245.0, img)
    return img.clip(0, 255).round().astype(np.uint8)


def normal_map(height: np.ndarray, strength: float) -> np.ndarray:
    """The tangent-space normal map of a tileable height field (rows down the image): the
    normal (-dh/du, -dh/dv, 1) normalised, v up the image, stored as 255 (n + 1) / 2."""
    dh_du = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) / 2
    dh_dv = (np.roll(height, 1, axis=0) - np.roll(height, -1, axis=0)) / 2  # up the image: the row above
    n = np.stack([-dh_du * strength, -dh_dv * strength, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return ((n + 1) / 2 * 255).round().astype(np.uint8)


def tiles_height(rng) -> np.ndarray:
    size, tiles = 256, 4
    cell = size // tiles
    y = np.arange(size)[:, None] % cell
    x = np.arange(size)[None, :] % cell
    edge = np.minimum(np.minimum(x, cell - 1 - x), np.minimum(y, cell - 1 - y)).astype(np.float64)
    bevel = np.clip((edge - 2) / 6, 0, 1)  # mortar 2 texels wide, a 6-texel bevel up to the tile
    bevel = bevel * bevel * (3 - 2 * bevel)
    tilt = rng.normal(0, 0.6, size=(tiles, tiles, 2))  # each tile laid a little unevenly
    ty = np.arange(size)[:, None] // cell
    tx = np.arange(size)[None, :] // cell
    lean = (tilt[ty, tx, 0] * (x / cell - 0.5) + tilt[ty, tx, 1] * (y / cell - 0.5)) * bevel
    return 6 * bevel + lean + 1.5 * smooth_noise((size, size), (16, 16), rng) * bevel


def dimples_height(rng) -> np.ndarray:
    size = 256
    h = np.zeros((size, size))
    y = np.arange(size)[:, None]
    x = np.arange(size)[None, :]
    for cy, cx, r in zip(rng.uniform(0, size, 90), rng.uniform(0, size, 90), rng.uniform(10, 24, 90)):
        dy = (y - cy + size / 2) % size - size / 2  # tileable
        dx = (x - cx + size / 2) % size - size / 2
        d2 = (dx * dx + dy * dy) / (r * r)
        h = np.minimum(h, np.where(d2 < 1, -(1 - d2) * r * 0.35, 0))
    return h


def lattice() -> np.ndarray:
    size = 64
    y, x = np.mgrid[0:size, 0:size] + 0.5
    r = np.hypot(x - size / 2, y - size / 2) / size
    return np.where(r < 0.36, 0, 255).astype(np.uint8)


def main() -> None:
    rng = np.random.default_rng(7)
    Image.fromarray(spots(rng)).save(HERE / "spots.png", optimize=True)
    Image.fromarray(planks(rng)).save(HERE / "planks.jpg", quality=88)
    Image.fromarray(globe()).save(HERE / "globe.png", optimize=True)
    rng = np.random.default_rng(11)  # the normal maps' own, so that the images above stay as they were
    Image.fromarray(normal_map(tiles_height(rng), 1.0)).save(HERE / "tiles_normal.png", optimize=True)
    dimples = dimples_height(rng)
    grey = (dimples - dimples.min()) / (dimples.max() - dimples.min()) * 255
    Image.fromarray(grey.round().astype(np.uint8), mode="L").save(HERE / "dimples_height.png", optimize=True)
    Image.fromarray(lattice(), mode="L").save(HERE / "lattice_alpha.png", optimize=True)


if __name__ == "__main__":
    main()
