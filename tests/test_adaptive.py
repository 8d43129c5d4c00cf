"""Adaptive sampling (raylume/adaptive.py) against what it promises.

* Its noise estimate is the standard error of a mean from two streams of unequal size:
  checked on synthetic streams of known variance, within the spread of the estimate.
* Its image is the sample-weighted mean of two plain renders, one a stream, each with the
  stream's seed and samples: checked against those renders made one by one.
* A tile that stops is as quiet as the threshold says: its error against a reference of
  8192 samples, measured as the threshold measures it (Cycles' measure), stays below the
  threshold. The estimate is a standard error, and a Gaussian error's mean magnitude is
  sqrt(2 / pi) = 0.80 of its standard error, so the measured error of a stopped tile is
  expected near 0.8 x the threshold; the reference's own noise (about a quarter of a
  stopped tile's at these sample counts) raises it by a few percent.
* Tiles of constant colour stop after the first check; no tile stops before min_spp (Cycles'
  rule unless set); the image is the same on any number of threads; a time limit stops with
  whole rounds; where adaptive sampling cannot apply (raster mode, bdpt, a time limit alone on a cluster) it is
  ignored with a warning; bad values are refused with one line and exit status 2."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from test_cli import assert_refused
from test_cli import raylume as run_cli

import raylume
from raylume.adaptive import FIRST_CHECK, TILE, _Streams, round_sizes, stream_seed, stream_sizes, tile_errors
from raylume.render_window import RenderInterrupted

REPO = Path(__file__).resolve().parents[1]
CORNELL = REPO / "examples" / "cornell.toml"
SEED = REPO / "src" / "raylume" / "scenes" / "seed.toml"
Z = 5.0  # standard errors allowed


def cycles_error(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Each pixel's error against the reference, as the threshold measures it."""
    ref = reference.astype(np.float64)
    return np.abs(image.astype(np.float64) - ref).sum(axis=2) / (1e-4 + np.sqrt(np.maximum(ref.sum(axis=2), 0.0)))


@pytest.fixture(scope="module")
def cornell():
    return raylume.load_scene(CORNELL)


def test_round_sizes_add_up_and_grow_by_a_quarter():
    assert round_sizes(1) == [1]
    for spp in (2, 3, 4, 9, 16, 100, 1024, 4095, 4096):
        sizes = round_sizes(spp)
        assert sum(sizes) == spp and min(sizes) >= 2, (spp, sizes)  # both streams take a sample of every round
        first = max(2, math.ceil(spp / 256))
        for r, size in enumerate(sizes):
            rule = first if r < FIRST_CHECK else max(first, math.ceil(sum(sizes[:r]) / 4))
            if r < len(sizes) - 1:
                assert size == rule, (spp, sizes)
            else:  # the last is what is left, or the rule's and one more that would have been left
                assert size <= rule + 1, (spp, sizes)
    assert len(round_sizes(4096)) < 30  # a few dozen windows' calls at most, not thousands


def synthetic_sums(rng: np.random.Generator, n: int, level: float, sigma: float, shape: tuple) -> np.ndarray:
    """Film sums (r, g, b, weight; the box filter's weights of 1) of n samples a pixel, each
    channel level + N(0, sigma): their sum drawn at once, as N(n level, n sigma^2)."""
    sums = np.empty(shape + (4,))
    sums[..., :3] = rng.normal(n * level, sigma * math.sqrt(n), shape + (3,))
    sums[..., 3] = n
    return sums


def test_the_standard_error_of_a_mean_from_two_unequal_streams():
    """Streams of 30 and 10 samples of known variance: the estimate's mean over many pixels is
    sigma / sqrt(N). One pixel's estimate is |m_A - m_B| sqrt(pi / 2) sqrt(n_A n_B) / N, whose
    spread is sqrt(pi / 2 - 1) of its mean (a folded normal's)."""
    rng = np.random.default_rng(5)
    h, w, sigma, level = 60, 80, 0.3, 0.6
    streams = _Streams(h, w)
    for k, n in enumerate((30, 10)):
        streams.add(k, slice(None), slice(None), synthetic_sums(rng, n, level, sigma, (h, w)), n)
    estimate = streams.standard_error()
    expected = sigma / math.sqrt(40)
    spread = expected * math.sqrt(math.pi / 2 - 1) / math.sqrt(estimate.size)
    assert abs(estimate.mean() - expected) < Z * spread, (estimate.mean(), expected, spread)
    # the control: the streams taken as halves (sqrt(n_A n_B) / N = 1 / 2) miss it by far
    halves = estimate * 0.5 / (math.sqrt(300) / 40)
    assert abs(halves.mean() - expected) > 3 * Z * spread
    # the image is every sample's mean, as one film of both streams' sums
    both = (streams.sums[0][..., :3] + streams.sums[1][..., :3]) / 40
    np.testing.assert_allclose(streams.mean(), both, rtol=1e-6)


def test_an_adaptive_image_is_the_mean_of_its_streams(cornell):
    """With nothing to stop it early (a time limit never reached), the image is the
    sample-weighted mean of one plain render a stream, with the stream's seed and samples:
    every round went on with each stream's sequence."""
    W, spp, seed = 24, 12, 3
    image = raylume.render(cornell, width=W, height=W, spp=spp, seed=seed, time_limit=1e6, threads=2)
    assert image.stats["adaptive"]["stopped_by"] == "spp"
    taken = np.array([stream_sizes(n) for n in round_sizes(spp)]).sum(axis=0)
    assert taken.tolist() == [6, 6]
    total = np.zeros((W, W, 3))
    for k, n in enumerate(taken):
        part = raylume.render(cornell, width=W, height=W, spp=int(n), seed=stream_seed(seed, k), threads=2, aovs=False)
        total += n * part.rgb.astype(np.float64)
    np.testing.assert_allclose(image.rgb, total / spp, rtol=2e-6, atol=1e-7)
    assert (image.aovs["spp"] == spp).all()
    assert image.stats["primary_rays"] == W * W * spp


def test_stopped_tiles_are_as_quiet_as_the_threshold(cornell):
    W, threshold = 48, 0.05
    reference = (
        sum(
            raylume.render(cornell, width=W, height=W, spp=4096, seed=s, threads=2, aovs=False).rgb.astype(np.float64)
            for s in (101, 102)
        )
        / 2
    )
    image = raylume.render(cornell, width=W, height=W, spp=2048, noise_threshold=threshold, threads=2)
    stats = image.stats["adaptive"]
    tile_spp = tile_errors(image.aovs["spp"].astype(np.float64))
    stopped = tile_spp < 2048
    assert stopped.all() and stats["stopped_by"] == "noise", stats
    assert tile_spp.max() > 2 * tile_spp.min(), tile_spp  # the box's tiles differ in noise
    assert stats["mean_spp"] < 0.5 * 2048
    measured = tile_errors(cycles_error(image.rgb, reference))
    assert measured.mean() < threshold, measured
    assert measured.max() < 1.2 * threshold, measured  # 0.8 x, with the estimate's and the tile's noise
    # the control: every pixel at the least any tile took is noisier than the threshold somewhere
    least = raylume.render(cornell, width=W, height=W, spp=int(tile_spp.min()), threads=2, aovs=False)
    assert tile_errors(cycles_error(least.rgb, reference)).max() > threshold


def test_tiles_of_constant_colour_stop_at_the_first_check():
    """The seed scene in trace mode, 64 samples a pixel: tiles of background alone have no
    noise and stop after FIRST_CHECK rounds of two samples; tiles with a sphere's edge go on."""
    image = raylume.render("seed", width=64, height=64, spp=64, noise_threshold=0.002, min_spp=8, threads=2)
    spp = image.aovs["spp"]
    tiles_spp = spp.reshape(64 // TILE, TILE, 64 // TILE, TILE)
    # pixels whose centre or a centre within 2 pixels sees an object (samples spread over a pixel)
    seen = np.pad(image.aovs["object"] >= 0, 2)
    near = np.zeros((64, 64), dtype=bool)
    for dy in range(5):
        for dx in range(5):
            near |= seen[dy : dy + 64, dx : dx + 64]
    hits = near.reshape(64 // TILE, TILE, 64 // TILE, TILE).any(axis=(1, 3))
    assert (tiles_spp.min(axis=(1, 3)) == tiles_spp.max(axis=(1, 3))).all()  # a tile stops whole
    empty = ~hits
    assert empty.any() and hits.any()
    assert (tiles_spp.max(axis=(1, 3))[empty] == 2 * FIRST_CHECK).all()
    assert tiles_spp.max() > 2 * FIRST_CHECK  # edges are antialiased by more samples
    bg = np.asarray(raylume.load_scene(SEED).render.background, dtype=np.float32)
    for ty, tx in zip(*np.nonzero(empty), strict=True):
        tile = image.rgb[ty * TILE : (ty + 1) * TILE, tx * TILE : (tx + 1) * TILE]
        assert np.all(tile == bg)


def test_the_same_image_on_any_number_of_threads(cornell):
    one = raylume.render(cornell, width=32, height=32, spp=256, noise_threshold=0.08, threads=1)
    two = raylume.render(cornell, width=32, height=32, spp=256, noise_threshold=0.08, threads=2)
    assert np.array_equal(one.rgb, two.rgb)
    assert np.array_equal(one.aovs["spp"], two.aovs["spp"])
    assert one.stats["adaptive"]["min_spp"] < 256


def test_a_time_limit_stops_with_whole_rounds(cornell):
    image = raylume.render(cornell, width=32, height=32, spp=4096, time_limit=0.2, threads=2)
    stats = image.stats["adaptive"]
    assert stats["stopped_by"] == "time"
    totals = set(np.cumsum(round_sizes(4096)).tolist())
    assert set(np.unique(image.aovs["spp"]).astype(int).tolist()) <= totals  # every pixel whole rounds
    assert stats["min_spp"] >= round_sizes(4096)[0] and stats["max_spp"] < 4096
    assert np.isfinite(image.rgb).all() and image.rgb.mean() > 0


def test_ctrl_c_keeps_the_rounds_done(cornell):
    """Interrupted after its first rounds, the render returns every pixel with the samples it
    has (a whole image, noisier), not rows."""

    def stop_late(done: int, total: int) -> None:
        if done > 0.1 * total:
            raise KeyboardInterrupt

    with pytest.raises(RenderInterrupted) as caught:
        raylume.render(cornell, width=32, height=32, spp=256, time_limit=1e6, threads=2, progress=stop_late)
    partial = caught.value.image
    assert partial.rgb.shape == (32, 32, 3) and (partial.rgb.sum(axis=2) > 0).mean() > 0.9
    assert "samples in every pixel" in caught.value.done
    # the rounds said are those every pixel has, as its spp AOV shows them
    rounds, least = (int(word) for word in caught.value.done.replace(",", "").split()[0:3:2])
    assert rounds >= 1 and sum(round_sizes(256)[:rounds]) == least == int(partial.aovs["spp"].min())


def test_tiles_quiet_only_with_every_sample_stopped_by_spp(cornell):
    """With too few samples for any tile to stop early (the warning says so), the render took
    every sample: its stats say "spp", though its tiles end below the threshold."""
    said = "judges a tile from its 4th round and 8 samples a pixel on; spp 8 is 4 rounds, so every pixel takes them all"
    with pytest.warns(raylume.SceneWarning, match=said):
        image = raylume.render(cornell, width=32, height=32, spp=8, noise_threshold=0.5, threads=2)
    stats = image.stats["adaptive"]
    assert stats["min_spp"] == 8 and stats["stopped_by"] == "spp", stats


def test_the_command_line(tmp_path):
    out = tmp_path / "a.png"
    stats = tmp_path / "s.json"
    result = run_cli(
        "render", CORNELL, "--width", 32, "--height", 32, "--spp", 128, "--noise-threshold", 0.1,
        "-o", out, "--stats", stats, "--aov", f"spp={tmp_path / 'spp.npy'}", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "adaptive:" in result.stderr and "spp a pixel on average" in result.stderr
    written = json.loads(stats.read_text())["adaptive"]
    spp = np.load(tmp_path / "spp.npy")
    assert written["min_spp"] == spp.min() and written["max_spp"] == spp.max()
    for flags, why in (
        (("--mode", "raster"), "raster mode draws every pixel once"),
        ((CORNELL, "--integrator", "bdpt", "--spp", 2, "--width", 8, "--height", 8), "bdpt's light paths"),
    ):
        ignored = run_cli("render", *flags, "--noise-threshold", 0.1, "-o", "x.png", cwd=tmp_path)
        assert ignored.returncode == 0 and "noise_threshold is ignored: " + why in ignored.stderr  # (what was given)
    assert_refused(run_cli("render", "--aov", "spp=x.npy", cwd=tmp_path), "--aov spp", "--noise-threshold")
    assert_refused(  # before any cluster is started or reached
        run_cli("render", "--cluster", "local", "--time-limit", 5, "--aov", "spp=x.npy", cwd=tmp_path),
        "--aov spp",
        "a cluster's tiles share no clock for a time limit",
    )
    assert_refused(run_cli("render", "--noise-threshold", 0, cwd=tmp_path), "--noise-threshold")
    assert_refused(run_cli("render", "--min-spp", 0, cwd=tmp_path), "--min-spp")
    assert not (tmp_path / "render.png").exists()


def test_a_crop_is_that_window_of_the_whole_adaptive_render(cornell):
    """Tiles lie on the whole image's grid: a crop renders the tiles it touches whole, so each
    stops as in the whole image (a crop of a plain render is that window of it, bit for bit)."""
    settings = dict(width=40, height=36, spp=128, noise_threshold=0.06, threads=2)
    whole = raylume.render(cornell, **settings)
    crop = raylume.render(cornell, **settings, crop=(5, 30, 3, 21))
    assert np.array_equal(crop.rgb, whole.rgb[3:21, 5:30])
    assert np.array_equal(crop.aovs["spp"], whole.aovs["spp"][3:21, 5:30])
    assert crop.stats["adaptive"]["max_spp"] == crop.aovs["spp"].max()
    assert len(np.unique(whole.aovs["spp"])) > 1  # tiles stopped apart


def test_no_tile_stops_before_min_spp(cornell):
    """Cycles' rule, ceil(16 / threshold^0.3), unless min_spp is given: every pixel of a scene
    whose tiles would stop sooner takes at least that many samples."""
    from raylume.adaptive import least_spp
    from raylume.scene.model import RenderSettings

    assert least_spp(RenderSettings(spp=1024, noise_threshold=0.1)) == 32
    assert least_spp(RenderSettings(spp=1024, noise_threshold=0.01)) == 64
    assert least_spp(RenderSettings(spp=16, noise_threshold=0.01)) == 16  # never above spp
    sizes = np.cumsum(round_sizes(1024))
    for min_spp, expected in ((None, 40), (100, 100)):
        # cast mode: the tiles without an edge have no noise and stop as soon as they may
        image = raylume.render(
            cornell, width=32, height=32, spp=1024, mode="cast", noise_threshold=0.05, min_spp=min_spp
        )
        least = sizes[np.searchsorted(sizes, expected)]  # the first round boundary at or past it
        assert image.aovs["spp"].min() == least, (min_spp, image.aovs["spp"].min(), least)


def test_an_animation_samples_each_frame_adaptively(tmp_path):
    stats = tmp_path / "s.json"
    result = run_cli(
        "render", REPO / "examples" / "flight.toml", "--frames", "0:2", "--width", 32, "--height", 24,
        "--spp", 64, "--noise-threshold", 0.05, "-o", tmp_path / "f_%04d.png", "--stats", stats, cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    adaptive = json.loads(stats.read_text())["adaptive"]
    assert len(adaptive["frames_mean_spp"]) == 2 and adaptive["mean_spp"] < 64
    assert "adaptive:" in result.stderr


def test_a_sliver_at_the_image_edge_joins_its_neighbour(cornell):
    """An image 16k + 1 pixels wide would end in tiles one pixel wide, too few pixels for a
    mean error (a QA run measured them stopping above the threshold in 14% of cases): they join
    the tiles beside them, in the whole image and in a crop alike."""
    from raylume.adaptive import tile_edges

    assert tile_edges(33).tolist() == [0, 16, 33] and tile_edges(40).tolist() == [0, 16, 32, 40]
    settings = dict(width=33, height=17, spp=128, noise_threshold=0.06, threads=2)
    whole = raylume.render(cornell, **settings)
    spp = whole.aovs["spp"]
    assert (spp[:, 16:] == spp[:, 32:33]).all() and (spp[16:] == spp[15:16]).all()  # one tile each
    crop = raylume.render(cornell, **settings, crop=(20, 33, 0, 17))
    assert np.array_equal(crop.rgb, whole.rgb[:, 20:33])


def test_warnings_come_once_and_progress_only_moves_on(tmp_path, cornell):
    result = run_cli(
        "render", REPO / "examples" / "flight.toml", "--frames", "0:3", "--width", 16, "--height", 12, "--mode",
        "raster", "--noise-threshold", 0.05, "-o", tmp_path / "f_%04d.png", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0 and result.stderr.count("noise_threshold is ignored: raster mode") == 1, result.stderr
    alone = run_cli("render", "--width", 8, "--height", 8, "--min-spp", 8, "-o", "m.png", cwd=tmp_path)
    assert "--min-spp has no effect without a noise threshold" in alone.stderr
    seen = []
    raylume.render(cornell, width=32, height=32, spp=4096, time_limit=0.3, progress=lambda d, t: seen.append(d))
    assert seen == sorted(seen) and len(seen) > 2
