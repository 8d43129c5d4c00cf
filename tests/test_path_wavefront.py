"""Path mode's wavefront kernel (kernels/integrators/path_wavefront.py, the default) against the
scalar kernel that traces a path at a time (RAYLUME_PATH_KERNEL=scalar, path.py): on every
example scene the two agree per 8 x 8 block and channel over independent seeds
(test_bdpt._assert_blocks_agree: Welch's z within the Bonferroni-corrected t limit); the
wavefront's images are bit-identical across threads, tiles and crops; its diffuse stage is
vector code. The statistical tests of path mode (test_path.py, test_path_vs_mitsuba.py,
test_media.py, test_environment.py, ...) run on the wavefront, the default."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from numba import typeof
from test_bdpt import _assert_blocks_agree, _block_means
from test_bdpt_glint import _load_example

import raylume
from raylume.kernels.integrators import path_wavefront

EXAMPLES = sorted((Path(__file__).resolve().parent.parent / "examples").glob("*.toml"))
SEEDS = 6  # independent renders per kernel


def _renders(session, kernel, monkeypatch, **kw) -> np.ndarray:
    monkeypatch.setenv("RAYLUME_PATH_KERNEL", kernel)
    return np.stack([session.render(seed=k, aovs=False, threads=1, **kw).rgb for k in range(SEEDS)]).astype(np.float64)


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.stem)
def test_the_wavefront_agrees_with_the_scalar_kernel_on_every_example(example, tmp_path, monkeypatch):
    """Every example in path mode, 32 x 24, 4 samples per pixel, max_depth 6 (deep enough for
    glass and media, short enough for CI), 6 seeds per kernel: the block means agree. (Examples
    whose data a script generates: generated in a copy, test_bdpt_glint._load_example.)"""
    scene = _load_example(example, tmp_path)
    scene = scene.model_copy(update={"render": scene.render.model_copy(update={"mode": "path", "integrator": "path"})})
    session = raylume.Session(scene)
    kw = dict(width=32, height=24, spp=4, max_depth=6)
    wave = _renders(session, "wavefront", monkeypatch, **kw)
    scalar = _renders(session, "scalar", monkeypatch, **kw)
    _assert_blocks_agree(_block_means(wave), _block_means(scalar), f"{example.stem}, 8 x 8 blocks")


def test_wavefront_images_are_the_same_whatever_the_threads_tiles_and_crops():
    """A row of 40 pixels at 9 samples is 360 paths: two tiles of the wavefront (TILE 256). A
    crop starts the row's tiles at other samples, 2 threads take other rows: the same bits."""
    assert 40 * 9 > path_wavefront.TILE
    scene = raylume.load(EXAMPLES[0].parent / "cornell.toml")
    kw = dict(width=40, height=16, spp=9, mode="path", aovs=False)
    one = raylume.render(scene, threads=1, **kw).rgb
    two = raylume.render(scene, threads=2, **kw).rgb
    crop = raylume.render(scene, threads=2, crop=(7, 33, 3, 13), **kw).rgb
    assert np.array_equal(one, two)
    assert np.array_equal(crop, one[3:13, 7:33])


def test_the_diffuse_stage_is_vector_code():
    """Packed square roots and divisions in _shade_diffuse: 4 float64 lanes on AVX2 (ymm), 8 on
    AVX-512 (zmm). Should LLVM stop vectorising it, this fails (the images would not change)."""
    Q = np.zeros(path_wavefront.QUEUE_ROWS * path_wavefront.STRIDE)
    args = (Q, 16, True, True, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0))
    function = path_wavefront._shade_diffuse
    function.compile(tuple(typeof(a) for a in args))
    asm = function.overloads[tuple(typeof(a) for a in args)].library.get_asm_str()
    for op in ("vsqrtpd", "vdivpd"):
        assert re.search(rf"{op}\s+[^\n]*%[yz]mm", asm), f"no packed {op} in _shade_diffuse"
