"""Writes examples/smoke/smoke.npy: a rising smoke plume as a density grid (nz, ny, nx) for
examples/smoke.toml, from procedural noise (numpy only, deterministic).

    python examples/smoke/make_smoke.py [--size 64]

The plume is a column that widens and thins as it rises, its edge broken up by fractal value
noise (octaves of a random lattice, trilinearly interpolated) and bent sideways by a slow wind.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def value_noise(shape: tuple[int, int, int], cells: int, rng: np.random.Generator) -> np.ndarray:
    """Noise in [0, 1): a random lattice of cells^3 points, interpolated trilinearly over `shape`."""
    lattice = rng.random((cells + 1,) * 3)
    axes = [np.linspace(0, cells, n, endpoint=False) for n in shape]
    z, y, x = np.meshgrid(*axes, indexing="ij")
    i, j, k = z.astype(int), y.astype(int), x.astype(int)
    fz, fy, fx = (a - a.astype(int) for a in (z, y, x))
    fz, fy, fx = (f * f * (3 - 2 * f) for f in (fz, fy, fx))  # smoothstep: no creases at the cells
    out = np.zeros(shape)
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = (fz if dz else 1 - fz) * (fy if dy else 1 - fy) * (fx if dx else 1 - fx)
                out += w * lattice[i + dz, j + dy, k + dx]
    return out


def plume(size: int, seed: int = 7) -> np.ndarray:
    rng = np.random.default_rng(seed)
    nz, ny, nx = size, size * 3 // 2, size
    noise = sum(value_noise((nz, ny, nx), 2**o * 2, rng) / 2**o for o in range(4)) / 1.875
    z, y, x = np.meshgrid(
        np.linspace(-1, 1, nz), np.linspace(0, 1, ny), np.linspace(-1, 1, nx), indexing="ij"
    )  # y: height, 0 at the source
    drift = 0.35 * y**2  # the wind bends the plume towards +x as it rises
    radius = 0.1 + 0.4 * y  # and it widens
    r = np.sqrt((x - drift) ** 2 + z**2)
    body = np.clip(1 - r / radius, 0, 1) ** 0.7
    # puffs: the noise thresholded, so the plume breaks into billows with clear air between
    density = body * np.clip(noise * 2.2 - 0.75, 0, None) ** 1.5 * (1 - y) ** 2 * np.clip(y * 12, 0, 1)
    return (density / density.max()).astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", type=int, default=64, help="voxels across (height 1.5x)")
    args = parser.parse_args()
    out = HERE / "smoke.npy"
    np.save(out, plume(args.size))
    print(f"wrote {out} ({args.size} x {args.size * 3 // 2} x {args.size} voxels)")


if __name__ == "__main__":
    main()
