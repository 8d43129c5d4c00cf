"""raylume's path tracer against Mitsuba 3 on the Cornell box (examples/cornell.toml).

The reference, tests/reference/cornell_mitsuba.npz, was rendered by Mitsuba 3 (scalar_rgb,
`path` integrator, the same triangles, materials, light, camera and max_depth) with
benchmarks/mitsuba_reference.py, which documents how; CI never needs Mitsuba. It holds the mean
of K = 16 independent renders (seeds) and, per seed, the image's mean and its 16 x 16-pixel
block means (per channel), so the standard error of each is estimated from the spread across
seeds, which is right whatever the correlation between a render's pixels.

The test renders raylume's image SEEDS_N = 32 times (seeds 0..31) with SPP = 32 samples per
pixel (1024 in all; ~20 s on 2 cores once compiled), estimates its standard errors the same way,
and for each channel tests

    z = (mean_raylume - mean_mitsuba) / sqrt(se_raylume^2 + se_mitsuba^2)

of the image mean (3 tests) and of each of the 16 blocks of 16 x 16 pixels (48 tests), leaving
out the 48 pixels that see any part of the light (their value is mostly the chance that a sample
lands on the light; the 20 pixels it covers entirely must be its radiance exactly, which the test
checks apart). With standard errors estimated from a few seeds, z follows Student's t with the
Welch-Satterthwaite degrees of freedom (~31 here: the reference holds 64 times raylume's
samples), not a normal distribution, so the limits are t quantiles, Bonferroni-corrected for a
family-wise false-alarm rate ALPHA = 0.001: half of it for the 3 image means, each |z| <
t.isf(0.0005 / 3 / 2) (3.76 for a normal z; 4.22-4.28 at 31-34 degrees of freedom), half for the
48 blocks, each |z| < t.isf(0.0005 / 48 / 2) (4.41 for a normal z; 5.1-5.25 here).

Verified with `benchmarks/mitsuba_reference.py control`, Mitsuba in raylume's place (new seeds,
the light's emission visible as raylume shows it), 3 trials per case, image-mean z per channel:
- at this budget (32 x 32 spp): new seeds pass 3/3 (|z| <= 1.9, block |z| <= 2.7); light x 1.005
  fails 2/3 (z 5.5-6.9; one trial 3.4, 3.5, 2.8), white reflectance x 1.01 fails 3/3 (z 14-22),
  red x 1.01 and green x 1.01 fail 2/3 each. Mitsuba's estimate is noisier than raylume's
  (one reason: its light is two one-sided emitters back to back, and a light sample that picks
  the upper one is wasted), so at 64 x 32 spp, about raylume's noise at 32 x 32:
- new seeds pass 3/3 (|z| <= 1.95, block z sd 0.94-1.20, |z| <= 2.6); light x 1.005 fails 3/3
  (z 6.8-9.9), white x 1.01 3/3 (z 20-32), red x 1.01 3/3 (R z 5.0-7.0), green x 1.01 3/3.
And with raylume's own path tracer at this budget (working tree of the path-mode branch):
  seeds 0..31 pass (|z| <= 1.4, block |z| <= 2.3), seeds 1000..1031 pass (|z| <= 1.24, block
  |z| <= 2.0); the light's emission x 1.005 fails (z 10.0, 13.0, 10.3), white x 1.01 fails
  (z 28-35), red x 1.01 fails (R z 8.0, block |z| 7.7), green x 1.01 fails (G z 8.5).
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "examples" / "cornell.toml"
REFERENCE = REPO / "tests" / "reference" / "cornell_mitsuba.npz"

SIZE = 64  # the image is SIZE x SIZE pixels (the reference's size)
BLOCK = 16  # block side in pixels: 4 x 4 blocks
SEEDS_N = 32  # raylume renders (seeds 0 .. SEEDS_N - 1) ...
SPP = 32  # ... of SPP samples per pixel each
ALPHA = 1e-3  # family-wise false-alarm rate (Bonferroni), half for image means, half for blocks


def scene_digest(path: Path = SCENE) -> str:
    """SHA-256 of what determines the expected image: the TOML's tables (without the picture
    settings of [render], which the test overrides) and the mesh files' bytes."""
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    render = doc.get("render", {})
    doc["render"] = {k: render.get(k) for k in ("mode", "max_depth", "filter")}
    h = hashlib.sha256(json.dumps(doc, sort_keys=True).encode())
    for obj in doc.get("objects", []):
        if "file" in obj:
            h.update(obj["file"].encode())
            h.update((path.parent / obj["file"]).read_bytes())
    return h.hexdigest()


def masked_means(images: np.ndarray, mask: np.ndarray, block: int = BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """(S, H, W, 3) images -> the means of their BLOCK x BLOCK blocks (S, H/block, W/block, 3)
    and of the whole image (S, 3), leaving out the pixels where `mask` (H, W) is true."""
    s, h, w, c = images.shape
    keep = (~mask).astype(np.float64)[None, :, :, None]
    sums = (images * keep).reshape(s, h // block, block, w // block, block, c).sum(axis=(2, 4))
    counts = keep.reshape(1, h // block, block, w // block, block, 1).sum(axis=(2, 4))
    return sums / counts, (images * keep).sum(axis=(1, 2)) / keep.sum()


@dataclass
class Reference:
    mean: np.ndarray  # (H, W, 3) mean image over the seeds
    seed_block_means: np.ndarray  # (K, H/BLOCK, W/BLOCK, 3)
    seed_global_means: np.ndarray  # (K, 3)
    light_coverage: np.ndarray  # (H, W) the fraction of each pixel that sees the light
    meta: dict


def load_reference(path: Path = REFERENCE) -> Reference:
    with np.load(path) as f:
        return Reference(
            f["mean"].astype(np.float64),
            f["seed_block_means"].astype(np.float64),
            f["seed_global_means"].astype(np.float64),
            f["light_coverage"].astype(np.float64),
            json.loads(str(f["meta"])),
        )


@dataclass
class Comparison:
    z_global: np.ndarray  # (3,)
    z_blocks: np.ndarray  # (H/BLOCK, W/BLOCK, 3)
    limit_global: np.ndarray  # (3,) the |z| limit of each test, from its degrees of freedom
    limit_blocks: np.ndarray
    dof_min: float

    @property
    def passed(self) -> bool:
        return bool(
            np.all(np.abs(self.z_global) < self.limit_global) and np.all(np.abs(self.z_blocks) < self.limit_blocks)
        )

    @property
    def limit(self) -> float:
        return float(self.limit_blocks.min())

    def report(self) -> str:
        worst = np.unravel_index(np.argmax(np.abs(self.z_blocks) / self.limit_blocks), self.z_blocks.shape)
        return (
            f"image-mean z per channel {np.round(self.z_global, 2)} (limits {np.round(self.limit_global, 2)}); "
            f"worst block (row {worst[0]}, column {worst[1]}, channel {'RGB'[worst[2]]}): "
            f"z {self.z_blocks[worst]:.2f} (limit {self.limit_blocks[worst]:.2f}); "
            f"blocks over their limit: {int(np.sum(np.abs(self.z_blocks) >= self.limit_blocks))} "
            f"of {self.z_blocks.size}"
        )


def _z(ours: np.ndarray, theirs: np.ndarray):
    """Welch's z (and degrees of freedom) of the difference of means, over axis 0 (seeds)."""
    n, k = len(ours), len(theirs)
    a = ours.var(axis=0, ddof=1) / n
    b = theirs.var(axis=0, ddof=1) / k
    z = (ours.mean(axis=0) - theirs.mean(axis=0)) / np.sqrt(a + b)
    dof = (a + b) ** 2 / (a**2 / (n - 1) + b**2 / (k - 1))
    return z, dof


def compare(ref: Reference, seed_block_means: np.ndarray, seed_global_means: np.ndarray) -> Comparison:
    """Per-channel z-scores of the image means and block means of renders (one row per seed)
    against the reference, with their Bonferroni limits (module docstring)."""
    from scipy.stats import t

    z_global, dof_global = _z(seed_global_means, ref.seed_global_means)
    z_blocks, dof_blocks = _z(seed_block_means, ref.seed_block_means)
    limit_global = t.isf(ALPHA / 2 / z_global.size / 2, dof_global)
    limit_blocks = t.isf(ALPHA / 2 / z_blocks.size / 2, dof_blocks)
    return Comparison(z_global, z_blocks, limit_global, limit_blocks, float(min(dof_global.min(), dof_blocks.min())))


def test_path_tracer_matches_mitsuba_on_the_cornell_box():
    if not REFERENCE.exists():
        pytest.skip(f"the Mitsuba reference {REFERENCE} is missing (benchmarks/mitsuba_reference.py makes it)")
    import raylume

    ref = load_reference()
    assert ref.meta["scene_digest"] == scene_digest(), (
        "examples/cornell.toml or its meshes changed since the Mitsuba reference was rendered: "
        "render it again (benchmarks/mitsuba_reference.py reference)"
    )
    assert (ref.meta["width"], ref.meta["height"], ref.meta["block"]) == (SIZE, SIZE, BLOCK)

    scene = raylume.load_scene(SCENE)
    images = np.stack(
        [
            raylume.render(scene, mode="path", width=SIZE, height=SIZE, spp=SPP, seed=s, aovs=False).rgb
            for s in range(SEEDS_N)
        ]
    ).astype(np.float64)
    assert np.all(np.isfinite(images)) and images.min() >= 0

    # the red wall on the image's left, the green one on its right (the handedness, before any statistics)
    mean = images.mean(axis=0)
    left, right = mean[SIZE // 2, : SIZE // 8].mean(axis=0), mean[SIZE // 2, -SIZE // 8 :].mean(axis=0)
    assert left[0] > 2 * left[1] and right[1] > 2 * right[0], f"left edge rgb {left}, right edge rgb {right}"

    # pixels that see nothing but the (black, emitting) light are its radiance in every sample
    full = ref.light_coverage > 1 - 1e-6
    emission = np.array(scene.materials["light"].emission)
    assert full.sum() >= 10
    np.testing.assert_allclose(images[:, full], np.broadcast_to(emission, images[:, full].shape), rtol=1e-5)

    # everything else against Mitsuba, the light's pixels left out
    result = compare(ref, *masked_means(images, ref.light_coverage > 0))
    assert result.passed, result.report()
