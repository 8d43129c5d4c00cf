"""Tone mapping (`[render] tonemap`, `--tonemap`) against what each operator is defined to do.

* `reinhard` (Reinhard et al. 2002, the simple operator on luminance): the output's luminance
  is L / (1 + L) and its hue is the input's, where no channel exceeds 1.
* `aces` (Hill's fit of the ACES RRT + sRGB ODT): greys stay grey, brighter stays brighter, black
  stays black, and a saturated colour goes smoothly towards white as it brightens (the shoulder
  compresses its strong channel before the weak ones).
* `neutral` (Khronos PBR Neutral, its specification's algorithm): a colour whose channels lie
  in 0.08..0.8 comes out as itself less 0.04, exactly (base colours as authored); black stays
  black; brighter colours are compressed below 1, keeping their order.
* `agx` (Blender's AgX, Filament's fit): greys stay grey, order is kept, middle grey lands near
  0.2 (0.5 on a 2.2 display), saturated colours go towards white as they brighten.
* Every operator gives values in 0..1 and no NaN for any input, inf and NaN included; `none`
  is the seed's clip; the order is exposure, tone map, encoding, in the PNG as in the live view.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from PIL import Image as PILImage
from test_cli import assert_refused
from test_cli import raylume as run_cli

from raylume.image import Image, encode_levels
from raylume.tonemap import TONEMAPS, tone_map

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709, independent of raylume's copy


def test_reinhard_compresses_luminance_and_keeps_hue():
    rng = np.random.default_rng(3)
    rgb = rng.uniform(0.0, 1.0, (500, 3)) * rng.uniform(0.0, 8.0, (500, 1))
    out = tone_map(rgb, "reinhard")
    L = rgb @ LUMINANCE
    unclipped = (rgb / (1 + L)[:, None]).max(axis=1) <= 1.0
    assert unclipped.sum() > 300
    np.testing.assert_allclose((out @ LUMINANCE)[unclipped], (L / (1 + L))[unclipped], rtol=1e-12)
    ratios_in = rgb[unclipped] / rgb[unclipped].sum(axis=1, keepdims=True)
    ratios_out = out[unclipped] / out[unclipped].sum(axis=1, keepdims=True)
    np.testing.assert_allclose(ratios_out, ratios_in, rtol=1e-12)


def test_aces_keeps_greys_grey_and_order():
    greys = np.repeat(np.geomspace(1e-4, 1e4, 200)[:, None], 3, axis=1)
    out = tone_map(greys, "aces")
    assert np.ptp(out, axis=1).max() < 1e-4  # the matrices' rows sum to 1
    assert np.all(np.diff(out[:, 0]) >= 0) and out[-1, 0] == 1.0 and out[0, 0] < 1e-3
    assert tone_map(np.zeros((1, 3)), "aces").max() == 0.0
    # a film-like curve: mid grey darker than linear, 1.0 below white (no clip there), white reached later
    mid, one = tone_map(np.full((2, 3), [[0.18], [1.0]]), "aces")[:, 0]
    assert 0.0 < mid < 0.18 and 0.5 < one < 0.9


def test_aces_turns_bright_colours_towards_white():
    red = np.array([1.0, 0.1, 0.1])
    out = tone_map(red * np.geomspace(0.5, 500, 12)[:, None], "aces")
    weak_over_strong = out[:, 1] / out[:, 0]
    assert np.all(np.diff(weak_over_strong) >= 0) and np.all(np.diff(weak_over_strong[:9]) > 0)
    assert weak_over_strong[-1] > 0.8
    # the clip keeps the hue until the strong channel reaches 1, and then jumps: 0.1 at 1x, 0.5 at 5x
    clipped = tone_map(np.array([red, red * 5]), "none")
    assert clipped[0, 1] / clipped[0, 0] == pytest.approx(0.1) and clipped[1, 1] / clipped[1, 0] == 0.5


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float32, (4, 5, 3), elements=st.floats(width=32, allow_nan=True, allow_infinity=True)),
    st.sampled_from(TONEMAPS),
    st.sampled_from(["clamp", "srgb"]),
    st.floats(-8, 8),
)
def test_every_input_encodes_into_0_1(rgb, tonemap, encoding, exposure):
    with np.errstate(over="ignore", invalid="ignore"):
        levels = encode_levels(rgb, encoding, exposure, tonemap)
    assert np.isfinite(levels).all() and levels.min() >= 0.0 and levels.max() <= 1.0


def test_none_is_the_clip_and_the_png_applies_exposure_then_tone_map_then_encoding(tmp_path):
    rgb = np.random.default_rng(1).uniform(0, 3, (6, 7, 3)).astype(np.float32)
    np.testing.assert_array_equal(encode_levels(rgb, "srgb", 0.0, "none"), encode_levels(rgb, "srgb"))
    image = Image(rgb, encoding="srgb", exposure=1.0, tonemap="aces")
    image.save(tmp_path / "a.png")
    mapped = tone_map(rgb * 2.0, "aces")
    srgb = np.where(mapped <= 0.0031308, 12.92 * mapped, 1.055 * mapped ** (1 / 2.4) - 0.055)
    with PILImage.open(tmp_path / "a.png") as png:
        np.testing.assert_array_equal(np.asarray(png), np.round(srgb * 255).astype(np.uint8))


def test_a_huge_value_is_white_and_the_api_takes_the_keyword():
    import raylume

    assert np.array_equal(tone_map(np.full((1, 3), 1e200), "aces"), np.ones((1, 3)))  # (v * v had overflowed)
    image = raylume.render("seed", width=8, height=8, tonemap="agx")
    assert image.tonemap == "agx"
    assert np.array_equal(image.to_uint8(), Image(image.rgb, tonemap="agx").to_uint8())
    assert not np.array_equal(image.to_uint8(), image.to_uint8(tonemap="none"))


def test_videos_are_tone_mapped_without_a_warning_and_overflow_is_quiet(tmp_path):
    flight = Path(__file__).resolve().parents[1] / "examples" / "flight.toml"
    gif = run_cli(
        "render", flight, "--frames", "0:1", "--width", 16, "--height", 12, "--tonemap", "aces", "-o", "a.gif",
        cwd=tmp_path,
    )  # fmt: skip
    assert gif.returncode == 0 and "warning" not in gif.stderr, gif.stderr
    bright = run_cli(
        "render", "--width", 8, "--height", 8, "--set", "render.background=[1e38, 1e38, 1e38]", "--exposure", 2,
        "-o", "b.png", cwd=tmp_path,
    )  # fmt: skip
    assert bright.returncode == 0 and "RuntimeWarning" not in bright.stderr, bright.stderr


def test_the_command_line(tmp_path):
    result = run_cli("render", "--tonemap", "aces", "--width", 16, "--height", 16, "-o", "a.png", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    warned = run_cli("render", "--tonemap", "aces", "--width", 16, "--height", 16, "-o", "a.exr", cwd=tmp_path)
    assert warned.returncode == 0 and "--tonemap applies to .png" in warned.stderr
    assert_refused(run_cli("render", "--tonemap", "filmic", cwd=tmp_path), "--tonemap", "reinhard", "aces")


def test_pbr_neutral_keeps_authored_colours_and_compresses_highlights():
    rng = np.random.default_rng(7)
    authored = rng.uniform(0.08, 0.79, (400, 3))
    np.testing.assert_allclose(tone_map(authored, "neutral"), authored - 0.04, rtol=0, atol=1e-12)
    assert tone_map(np.zeros((1, 3)), "neutral").max() == 0.0
    bright = np.repeat(np.geomspace(0.9, 1e4, 50)[:, None], 3, axis=1) * [1.0, 0.6, 0.3]
    out = tone_map(bright, "neutral")
    assert np.all(out < 1.0) and np.all(np.diff(out[:, 0]) > 0)
    assert np.all(out[:, 0] >= out[:, 1]) and np.all(out[:, 1] >= out[:, 2])  # the channels' order kept


def test_agx_keeps_greys_grey_and_order_and_whitens_bright_colours():
    greys = np.repeat(np.geomspace(1e-3, 1e3, 200)[:, None], 3, axis=1)
    out = tone_map(greys, "agx")
    assert np.ptp(out, axis=1).max() < 1e-3 and np.all(np.diff(out[:, 0]) >= 0)
    assert tone_map(np.zeros((1, 3)), "agx").max() == 0.0
    middle = tone_map(np.full((1, 3), 0.18), "agx")[0, 0]
    assert 0.45 < middle ** (1 / 2.2) < 0.55  # middle grey at half the display's range
    red = np.array([1.0, 0.1, 0.1])
    shown = tone_map(red * np.geomspace(0.5, 500, 12)[:, None], "agx")
    assert np.all(np.diff(shown[:, 1] / shown[:, 0]) >= 0) and shown[-1, 1] / shown[-1, 0] > 0.9
