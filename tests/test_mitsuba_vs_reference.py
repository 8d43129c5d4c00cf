"""Mitsuba 3 XML scenes rendered by raylume against Mitsuba 3's own renders of the same files.

tests/reference/mitsuba_xml_scenes.py writes each scene (one per BSDF family, an environment
map (also seen through a mirrored sensor), instances, a serialized mesh, a sensor mirrored as
Blender exports it, point, spot and directional lights, an image texture on a rectangle, a
homogeneous medium, a normal map on an OBJ board); the
references in
tests/reference/mitsuba_xml/ were rendered by Mitsuba 3 scalar_rgb from those very files by
tools/mitsuba_xml_references.py (16 seeds x 1024 spp; CI never needs Mitsuba). raylume renders
SEEDS_N seeds x SPP spp, and per channel the image mean and each 8 x 8 block's mean are z-tested
against Mitsuba's, the standard errors estimated from the spread across seeds, with the
Bonferroni-corrected Student t limits of tests/test_path_vs_mitsuba.py (its helpers).

A mirror image fails at once: every scene has a red sphere on the image's left.

Controls (raylume changed on purpose, seeds 100..115, the diffuse scene unless named): new seeds
pass (image-mean |z| <= 0.8, blocks <= 3.8); the light's radiance x 1.01 passes narrowly
(image-mean z 3.2-3.4 against limits of 4.85); the floor's reflectance x 1.02 fails (z 10-15, 6
blocks over); the envmap's intensity x 1.01 fails narrowly (blue image-mean z 4.96, limit 4.93);
the environment turned the wrong way (-40 degrees for +40) is 25 % off in some blocks. A
normal-less mesh shaded with raylume's area-weighted vertex normals instead of Mitsuba's
angle-weighted ones failed (block z -7.5), which is why the serialized scene asks for face normals.

The normal map, with Mitsuba's shadowing function for normal maps switched off (raylume has
none; on, it darkens Mitsuba's image by 0.12-0.13%, mostly the sky's grazing light), and a black
rectangle just behind the board: the board's back faces the floor, black in Mitsuba's one-sided
BSDF and diffuse in raylume, whose surfaces are two-sided (docs/guide/mitsuba.md); without the
rectangle raylume's floor was 0.6% brighter, the image 0.3-0.45%, image-mean z up to 3.9. With
it: image-mean z 0.6 / 0.8 / 0.7 (R, G, B; limits 4.9), worst block 4.1 (limit 6.2), seeds
100..115 and 200..215 |z| <= 0.5, worst block 1.6; raylume's mean over 32 seeds x 256 spp is
0.998-0.999 of Mitsuba's (0.9995-1.0004 of Mitsuba's with the shadowing function on). The map
read with y the other way fails (image-mean z -19 to -21, 9 blocks over); a flat map fails (z
-7.7 to -8.1).
The environment map's scene does not show the sky directly, only by reflection and lighting:
Mitsuba's envmap spreads its rows from pole to pole (row j of H at v = j / (H - 1); measured with
its emitter's eval), raylume's sit at the rows' centres ((j + 0.5) / H), and the sky seen directly
is nearly noiseless in both renders, so that half row (a relative difference of 5e-4 here) would
fail a z-test that measures nothing else.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from reference.mitsuba_xml_scenes import SCENES, SIZE, write_scene
from test_path_vs_mitsuba import Reference, compare, masked_means

REFERENCES = Path(__file__).resolve().parent / "reference" / "mitsuba_xml"
BLOCK = 8
SEEDS_N = 16
SPP = 16


def load_reference(name: str) -> Reference:
    with np.load(REFERENCES / f"{name}.npz") as f:
        return Reference(
            f["mean"].astype(np.float64),
            f["seed_block_means"].astype(np.float64),
            f["seed_global_means"].astype(np.float64),
            np.zeros((SIZE, SIZE)),
            json.loads(str(f["meta"])),
        )


def settle_silent_blocks(result, ours_blocks, ref: Reference):
    """Blocks without noise in either renderer (a constant environment alone) have z = 0/0: they
    must then agree to float32 rounding, which counts as z = 0."""
    silent = ~np.isfinite(result.z_blocks)
    ours, theirs = ours_blocks.mean(axis=0), ref.seed_block_means.mean(axis=0)
    same = np.isclose(ours, theirs, rtol=1e-5, atol=1e-7)
    result.z_blocks[silent & same] = 0.0
    result.limit_blocks[silent] = np.inf  # z is then 0 (passes) or not finite (fails)
    return result


@pytest.mark.parametrize("name", list(SCENES))
def test_mitsuba_scene_matches_mitsuba(name, tmp_path):
    import raylume

    ref = load_reference(name)
    path, digest = write_scene(name, tmp_path)
    assert ref.meta["scene_digest"] == digest, (
        f"the {name} scene changed since its Mitsuba reference was rendered: "
        f"python tools/mitsuba_xml_references.py {name}"
    )
    scene = raylume.load_scene(path)
    assert (scene.render.width, scene.render.height) == (SIZE, SIZE)
    images = np.stack([raylume.render(scene, spp=SPP, seed=s, aovs=False).rgb for s in range(SEEDS_N)]).astype(
        np.float64
    )
    assert np.all(np.isfinite(images)) and images.min() >= 0

    # the red sphere on the left, as Mitsuba shows it (before any statistics)
    left = images.mean(axis=0)[SIZE // 2 :, : SIZE // 3].mean(axis=(0, 1))
    mitsuba_left = ref.mean[SIZE // 2 :, : SIZE // 3].mean(axis=(0, 1))
    assert (left[0] > left[2]) == (mitsuba_left[0] > mitsuba_left[2]), (
        f"left third rgb {left}, Mitsuba's {mitsuba_left}"
    )

    blocks, means = masked_means(images, np.zeros((SIZE, SIZE), dtype=bool), BLOCK)
    with np.errstate(divide="ignore", invalid="ignore"):
        result = settle_silent_blocks(compare(ref, blocks, means), blocks, ref)
    assert result.passed, result.report()
