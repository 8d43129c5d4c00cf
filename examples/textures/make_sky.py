"""Generate ``examples/sky.hdr``, the environment of the environment-lit example (deterministic;
numpy and raylume only).

    python examples/textures/make_sky.py

A 256 x 128 equirectangular image in linear radiance, in raylume's convention (the centre column
looks along +z, the top row along +y, +x to the right of the centre; see
raylume/kernels/environment.py): a blue gradient sky, paler towards the horizon, a warm sun
disk high behind a camera that looks along +z, over its left shoulder (bright enough to cast
crisp shadows: on a surface facing it, about five times the irradiance of the rest of the sky), and
a darker ground below the horizon. Written with raylume's own Radiance .hdr writer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from raylume.image import save_array

OUT = Path(__file__).resolve().parents[1] / "sky.hdr"

WIDTH, HEIGHT = 256, 128
SUPERSAMPLE = 4  # per axis, so the sun's edge is anti-aliased

SUN_ELEVATION = np.radians(35.0)
SUN_AZIMUTH = np.radians(-135.0)  # phi: 0 is +z, +90 is +x; -135: behind the camera, to its left
SUN_RADIUS = np.radians(3.0)  # angular radius; larger than the real sun's so it covers a few texels
SUN_RADIANCE = np.array([1.0, 0.86, 0.62]) * 1000.0
GLOW = np.array([0.6, 0.5, 0.35])  # a faint warm halo, falling off as cos^64 of the angle to the sun

ZENITH = np.array([0.16, 0.32, 0.78])
HORIZON = np.array([0.72, 0.80, 0.92])
GROUND = np.array([0.16, 0.13, 0.10])
GROUND_NADIR = np.array([0.08, 0.07, 0.06])


def directions(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Image coordinates (0..1, left to right; 0..1, top to bottom) -> unit directions (..., 3)."""
    u, v = np.broadcast_arrays(u, v)
    phi = 2.0 * np.pi * (u - 0.5)
    theta = np.pi * v
    return np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), np.cos(phi) * np.sin(theta)], axis=-1)


def sky(d: np.ndarray) -> np.ndarray:
    """Linear radiance of the sky and ground (no sun) in directions d (..., 3)."""
    y = d[..., 1:2]
    up = np.clip(y, 0.0, 1.0)
    sky = HORIZON + (ZENITH - HORIZON) * np.sqrt(up)
    down = np.clip(-y, 0.0, 1.0)
    ground = GROUND + (GROUND_NADIR - GROUND) * np.sqrt(down)
    # a soft horizon, about two degrees wide
    t = np.clip(0.5 + y / np.sin(np.radians(2.0)) * 0.5, 0.0, 1.0)
    t = t * t * (3.0 - 2.0 * t)
    return ground + (sky - ground) * t


def sun_direction() -> np.ndarray:
    c = np.cos(SUN_ELEVATION)
    return np.array([np.sin(SUN_AZIMUTH) * c, np.sin(SUN_ELEVATION), np.cos(SUN_AZIMUTH) * c])


def make_sky() -> np.ndarray:
    """float32 (HEIGHT, WIDTH, 3): the mean radiance over each texel (supersampled)."""
    k = SUPERSAMPLE
    offsets = (np.arange(k) + 0.5) / k
    u = (np.arange(WIDTH)[:, None] + offsets[None, :]).reshape(-1) / WIDTH
    v = (np.arange(HEIGHT)[:, None] + offsets[None, :]).reshape(-1) / HEIGHT
    d = directions(u[None, :], v[:, None])  # (HEIGHT k, WIDTH k, 3)
    cos_sun = d @ sun_direction()
    radiance = sky(d)
    # a faint warm glow around the sun, then the disk itself
    radiance += GLOW * np.clip(cos_sun, 0.0, 1.0)[..., None] ** 64
    radiance = np.where((cos_sun >= np.cos(SUN_RADIUS))[..., None], SUN_RADIANCE, radiance)
    return radiance.reshape(HEIGHT, k, WIDTH, k, 3).mean(axis=(1, 3)).astype(np.float32)


def main() -> None:
    image = make_sky()
    save_array(OUT, image)
    print(f"wrote {OUT} ({OUT.stat().st_size} bytes, {WIDTH} x {HEIGHT})")


if __name__ == "__main__":
    main()
