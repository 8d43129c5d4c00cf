"""raylume's participating media against Mitsuba 3's volpath (scalar_rgb), per 8 x 8 block.

tests/reference/media_mitsuba.npz was made by `python benchmarks/mitsuba_media.py reference`
(its docstring says how; CI never needs Mitsuba). It holds three scenes (a grey homogeneous
medium, a chromatic one, a grid) as raylume documents, the grid's densities, and for each scene
every Mitsuba seed's 8 x 8 block means and image mean. raylume renders each scene with SEEDS_N
seeds of SPP samples, and the test compares image and block means per channel with Welch's z and
Bonferroni-corrected t limits at a family-wise false-alarm rate of 0.001 per scene, as
test_path_vs_mitsuba.py does for the Cornell box (whose helpers it uses)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_path_vs_mitsuba import Reference, compare, masked_means

REFERENCE = Path(__file__).resolve().parent / "reference" / "media_mitsuba.npz"
SEEDS_N = 16
SPP = 32


def reference(name: str) -> tuple[Reference, dict, np.ndarray]:
    with np.load(REFERENCE) as f:
        meta = json.loads(str(f["meta"]))
        ref = Reference(
            f[f"{name}_mean"],
            f[f"{name}_blocks"],
            f[f"{name}_global"],
            np.zeros(f[f"{name}_mean"].shape[:2]),
            meta,
        )
        return ref, meta["scenes"][name], f["density"]


@pytest.mark.parametrize("name", ["homogeneous", "chromatic", "grid"])
def test_media_match_mitsuba_volpath(name, tmp_path):
    if not REFERENCE.exists():
        pytest.skip(f"the Mitsuba reference {REFERENCE} is missing (benchmarks/mitsuba_media.py makes it)")
    import trimesh

    import raylume
    from raylume.scene.document import scene_from_dict

    ref, document, density = reference(name)
    np.save(tmp_path / "density.npy", density)
    trimesh.creation.box(extents=(2, 2, 2)).export(tmp_path / "box.obj")
    scene = scene_from_dict(document).with_base_dir(tmp_path)
    images = np.stack([raylume.render(scene, spp=SPP, seed=seed, aovs=False).rgb for seed in range(SEEDS_N)]).astype(
        np.float64
    )
    assert np.all(np.isfinite(images)) and images.min() >= 0
    block = ref.meta["block"]
    result = compare(ref, *masked_means(images, np.zeros(images.shape[1:3], bool), block))
    assert result.passed, result.report()
