"""bdpt's glint strategy (kernels/integrators/bdpt_glint.py): camera paths that see an emitter
through mirrors and glass alone, sampled where a guide says they are as well as by the pixels'
own samples. Checked against independent answers: bdpt without the strategy (Veach's
strategies, tested in test_bdpt.py) and path mode, per 8 x 8 block; the strategies' shares
summing to the image; and the determinism of the guide and the splats."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_bdpt import _assert_blocks_agree, _block_means

import raylume

STRATEGY = "RAYLUME_BDPT_STRATEGY"


def _glint_scene(bulb_radius: float, pixel_filter: str = "box", aperture: float = 0.0) -> raylume.Scene:
    """A small emissive sphere (a bulb) seen in a mirror sphere through a glass slab; a diffuse
    floor, a dim sky. The bulb's reflection is a glint of about two pixels (radius 0.1), or of a
    fraction of one (0.05)."""
    return raylume.scene_from_dict(
        {
            "render": {"width": 32, "height": 32, "max_depth": 5, "mode": "path", "filter": pixel_filter},
            "camera": {"position": [0, 0.6, -3], "look_at": [0, 0.4, 0], "fov": 35, "aperture": aperture},
            "lights": [{"type": "ambient", "intensity": 0.05}],
            "objects": [
                {"type": "quad", "position": [0, 0, 0], "u": [6, 0, 0], "v": [0, 0, 6],
                 "material": {"type": "diffuse", "color": [0.6, 0.6, 0.6]}},
                {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5,
                 "material": {"type": "conductor", "color": [0.9, 0.9, 0.9]}},
                {"type": "cylinder", "p0": [0.1, 0.8, -0.93], "p1": [0.1, 0.8, -0.87], "radius": 0.25,
                 "capped": True, "material": {"type": "dielectric", "ior": 1.5}},
                {"type": "sphere", "center": [-0.6, 1.3, -1.2], "radius": bulb_radius,
                 "material": {"type": "diffuse", "color": [0, 0, 0], "emission": [1.0 / bulb_radius**2] * 3}},
            ],
        }
    )  # fmt: skip


def _renders(session, spp: int, seeds, strategy: str, monkeypatch, **kwargs) -> np.ndarray:
    """(seeds, rows, cols, 3) bdpt images with RAYLUME_BDPT_STRATEGY = strategy ('' for all)."""
    if strategy:
        monkeypatch.setenv(STRATEGY, strategy)
    else:
        monkeypatch.delenv(STRATEGY, raising=False)
    images = [session.render(integrator="bdpt", spp=spp, seed=s, aovs=False, **kwargs).rgb for s in seeds]
    monkeypatch.delenv(STRATEGY, raising=False)
    return np.stack(images).astype(np.float64)


def test_the_guide_finds_the_glint_and_the_strategy_adds_to_it(monkeypatch):
    """The strategy takes part (its samples reach the bulb: --stats counts them) and its share
    is where the glint is: inside the mirror sphere's image, nothing on the floor far from it."""
    session = raylume.Session(_glint_scene(0.1))
    image = session.render(integrator="bdpt", spp=4, aovs=False)
    assert image.stats["bdpt_strategies"].get("glint", 0) > 0
    share = _renders(session, 4, [0], "glint", monkeypatch)[0]
    assert np.isfinite(share).all() and share.min() >= 0.0
    assert share.sum() > 0.0
    assert share[28:, :].sum() == 0.0  # the floor below the sphere: no mirror or glass there


def test_the_guides_pilot_rays_are_counted_in_the_stats(monkeypatch):
    """--stats' rays include the guide's pilots: in a scene without mirrors or glass every pixel
    takes PILOTS_FIRST pilots of one ray each and the strategy finds nothing to sample, so the
    render traces exactly that many rays more than with the strategy switched off."""
    from raylume.kernels.integrators.bdpt_glint import PILOTS_FIRST

    scene = raylume.scene_from_dict(
        {
            "render": {"width": 12, "height": 10, "max_depth": 3, "mode": "path"},
            "camera": {"position": [0, 1, -3], "look_at": [0, 0.5, 0], "fov": 40},
            "lights": [{"type": "point", "position": [1, 3, -1], "intensity": 8}],
            "objects": [
                {"type": "quad", "position": [0, 0, 0], "u": [4, 0, 0], "v": [0, 0, 4],
                 "material": {"type": "diffuse", "color": [0.6, 0.6, 0.6]}},
                {"type": "sphere", "center": [0, 0.5, 0], "radius": 0.5,
                 "material": {"type": "diffuse", "color": [0.8, 0.3, 0.2]}},
            ],
        }
    )  # fmt: skip
    session = raylume.Session(scene)
    monkeypatch.setenv(STRATEGY, "noglint")
    without = session.render(integrator="bdpt", spp=2, aovs=False).stats
    monkeypatch.delenv(STRATEGY)
    with_guide = session.render(integrator="bdpt", spp=2, aovs=False).stats
    assert with_guide["bdpt_strategies"].get("glint", 0) == 0
    assert with_guide["rays"] - without["rays"] == 12 * 10 * PILOTS_FIRST


@pytest.mark.parametrize("pixel_filter, aperture", [("box", 0.0), ("gaussian", 0.0), ("box", 0.1)])
def test_bdpt_with_glints_agrees_with_bdpt_without_and_with_path_mode(pixel_filter, aperture, monkeypatch):
    """Per 8 x 8 block and channel (Welch's z within the Bonferroni-corrected t limit), bdpt with
    the glint strategy against bdpt without it (RAYLUME_BDPT_STRATEGY=noglint: the pixels' own
    samples alone make these paths) and against path mode at 8x the samples; a glint of a few
    pixels, so that all three estimate it with a finite spread; a pinhole with two filters, and
    a thin lens (the strategy's lens points uniform, the pixels' stratified)."""
    session = raylume.Session(_glint_scene(0.1, pixel_filter, aperture))
    seeds = range(10)
    glint = _block_means(_renders(session, 16, seeds, "", monkeypatch))
    plain = _block_means(_renders(session, 16, [100 + s for s in seeds], "noglint", monkeypatch))
    path = _block_means(
        np.stack([session.render(spp=128, seed=200 + s, aovs=False).rgb for s in seeds]).astype(np.float64)
    )
    _assert_blocks_agree(glint, plain, f"glint / noglint, {pixel_filter}, aperture {aperture}")
    _assert_blocks_agree(glint, path, f"glint / path, {pixel_filter}, aperture {aperture}")


def test_a_glint_smaller_than_a_pixel_has_far_less_noise(monkeypatch):
    """A bulb whose reflection is a fraction of a pixel (the pixels' own samples meet it in a few
    of the 10 renders: their block means over seeds range 0.05-1.1): at the same 16 samples per
    pixel the variance over seeds of the glint's block (the block where bdpt without the
    strategy varies most) is under a tenth of bdpt's without it (measured 0.008-0.072 over four
    sets of 10 seeds), and the two agree per block. The whole image's variance is no measure:
    a rare caustic through the glass elsewhere, which neither way samples well, made it 0.01-0.18
    of bdpt's without the strategy, by the seeds that met it."""
    session = raylume.Session(_glint_scene(0.05))
    seeds = range(10)
    glint = _block_means(_renders(session, 16, seeds, "", monkeypatch))
    plain = _block_means(_renders(session, 16, [100 + s for s in seeds], "noglint", monkeypatch))
    _assert_blocks_agree(glint, plain, "sub-pixel glint")
    plain_var = plain.var(axis=0, ddof=1).sum(axis=-1)
    at = np.unravel_index(plain_var.argmax(), plain_var.shape)
    assert glint.var(axis=0, ddof=1).sum(axis=-1)[at] < 0.1 * plain_var[at]


def test_the_shares_sum_to_the_image(monkeypatch):
    """The glint strategy's share and every (s, t) strategy's share, each rendered alone with its
    weight, sum to the image (the weights are a partition of unity)."""
    session = raylume.Session(_glint_scene(0.1))
    size = {"width": 16, "height": 16, "max_depth": 3}
    whole = _renders(session, 8, [0], "", monkeypatch, **size)[0]
    shares = _renders(session, 8, [0], "glint", monkeypatch, **size)[0]
    for k in (1, 2, 3):
        for s in range(0, k + 1):
            if not (s == 1 and k == 1):
                shares += _renders(session, 8, [0], f"{s},{k + 1 - s}", monkeypatch, **size)[0]
    np.testing.assert_allclose(shares, whole, rtol=1e-5, atol=1e-6)


def test_glint_images_are_the_same_on_any_threads_passes_and_crops():
    """The guide is made on one thread in pixel order and the splats are summed exactly: 1 or
    2 threads, two passes and a crop give the same bits."""
    scene = _glint_scene(0.05)
    one = raylume.render(scene, integrator="bdpt", spp=4, threads=1, aovs=False).rgb
    two = raylume.render(scene, integrator="bdpt", spp=4, threads=2, aovs=False).rgb
    assert np.array_equal(one, two)
    crop = raylume.render(scene, integrator="bdpt", spp=4, threads=2, crop=(5, 27, 3, 20), aovs=False).rgb
    assert np.array_equal(crop, one[3:20, 5:27])
    session = raylume.Session(scene)
    film = raylume.Film(32, 32, "box", total_spp=4)
    session.add_samples(film, 1, integrator="bdpt")
    session.add_samples(film, 3, integrator="bdpt")
    assert np.array_equal(film.rgb(), one)


EXAMPLES = sorted((Path(__file__).resolve().parent.parent / "examples").glob("*.toml"))


def _load_example(example: Path, tmp_path: Path) -> raylume.Scene:
    """The example's scene; one whose data a script generates (examples/NAME/make_NAME.py) from
    a copy of examples/ in tmp_path where the script has run, whatever the checkout holds."""
    script = Path(example.stem) / f"make_{example.stem}.py"
    if not (example.parent / script).exists():
        return raylume.load(example)
    copy = tmp_path / "examples"
    shutil.copytree(example.parent, copy)
    subprocess.run([sys.executable, str(copy / script)], check=True, capture_output=True)
    return raylume.load(copy / example.name)


@pytest.mark.parametrize("example", EXAMPLES, ids=lambda p: p.stem)
def test_every_example_agrees_with_and_without_glints(example, tmp_path, monkeypatch):
    """Every example by bdpt, 32 x 24, 4 samples per pixel, max_depth 6, 6 seeds each way: with
    the glint strategy against without it, per 8 x 8 block and channel (where the guide finds
    nothing, or the scene has media, the two are the same bits). The head lamp's beam seen
    through its glass is the glint the strategy is for: the pixels' own samples meet it from
    about 1024 a pixel (at 4 and 64, six seeds of one block all missed it, 0.0117 against
    0.07-0.10, and their spread was no standard error), so its renders without the strategy
    take 1024."""
    scene = _load_example(example, tmp_path)
    scene = scene.model_copy(update={"render": scene.render.model_copy(update={"mode": "path", "integrator": "bdpt"})})
    session = raylume.Session(scene)
    kw = dict(width=32, height=24, max_depth=6, threads=1)
    glint = _renders(session, 4, range(6), "", monkeypatch, **kw)
    plain_spp = 1024 if example.stem == "headlamp" else 4
    plain = _renders(session, plain_spp, range(6), "noglint", monkeypatch, **kw)
    _assert_blocks_agree(_block_means(glint), _block_means(plain), f"{example.stem}, 8 x 8 blocks")
