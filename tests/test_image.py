"""Image encodings, writers and the notebook representation."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image as PILImage

import raylume
from raylume.errors import OutputError
from raylume.image import Image, encode_8bit


def test_clamp_encoding_is_the_seeds():
    rgb = np.array([[[-0.5, 0.5, 2.0], [1.0, 0.2, 0.0]]], dtype=np.float32)
    np.testing.assert_array_equal(encode_8bit(rgb, "clamp"), [[[0, 128, 255], [255, 51, 0]]])


def test_srgb_encoding_matches_the_standard_curve():
    x = np.array([0.0, 0.002, 0.0031308, 0.18, 0.5, 1.0])
    expected = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    got = encode_8bit(np.repeat(x[None, :, None], 3, axis=2), "srgb")[0, :, 0]
    np.testing.assert_array_equal(got, np.round(expected * 255).astype(np.uint8))
    assert got[3] == 118  # mid-grey 18% encodes to ~46%


def test_non_finite_values_never_reach_the_file():
    rgb = np.array([[[np.nan, np.inf, -np.inf]]], dtype=np.float32)
    np.testing.assert_array_equal(encode_8bit(rgb), [[[0, 255, 0]]])


def test_save_png_npy_exr_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.uniform(0, 2, size=(5, 7, 3)).astype(np.float32)
    img = Image(rgb, encoding="clamp")
    img.save(tmp_path / "a.png")
    png = np.asarray(PILImage.open(tmp_path / "a.png"))
    np.testing.assert_array_equal(png, encode_8bit(rgb, "clamp"))
    img.save(tmp_path / "a.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), rgb)
    OpenEXR = pytest.importorskip("OpenEXR")
    img.save(tmp_path / "a.exr")
    with OpenEXR.File(str(tmp_path / "a.exr")) as f:
        channels = f.channels()
        back = channels["RGB"].pixels if "RGB" in channels else np.dstack([channels[c].pixels for c in "RGB"])
    np.testing.assert_array_equal(back.astype(np.float32), rgb)


def test_bad_output_paths(tmp_path):
    img = Image(np.zeros((2, 2, 3), np.float32))
    with pytest.raises(OutputError, match="unknown output format"):
        img.save(tmp_path / "a.gif")
    with pytest.raises(OutputError, match="does not exist"):
        img.save(tmp_path / "missing" / "a.png")
    with pytest.raises(OutputError, match="is a folder"):
        (tmp_path / "d.png").mkdir()
        img.save(tmp_path / "d.png")


def test_api_render_returns_image_with_arrays_and_png_repr():
    img = raylume.render(raylume.builtin_scene("seed"), width=20, height=10)
    assert isinstance(img, raylume.Image)
    assert img.rgb.shape == (10, 20, 3) and img.rgb.dtype == np.float32
    assert set(img.aovs) == {"depth", "normal", "object", "prim", "albedo"}
    assert np.asarray(img).shape == (10, 20, 3)
    png = PILImage.open(io.BytesIO(img._repr_png_()))
    assert png.size == (20, 10)
    assert img.stats["width"] == 20 and img.stats["mode"] == "trace"
    assert "20x10" in repr(img)


def test_written_files_get_ordinary_permissions(tmp_path):
    import os
    import stat

    umask = os.umask(0o022)
    try:
        Image(np.zeros((2, 2, 3), np.float32)).save(tmp_path / "a.png")
        assert stat.S_IMODE((tmp_path / "a.png").stat().st_mode) == 0o644
        (tmp_path / "a.png").chmod(0o600)
        Image(np.ones((2, 2, 3), np.float32)).save(tmp_path / "a.png")  # a replaced file keeps its mode
        assert stat.S_IMODE((tmp_path / "a.png").stat().st_mode) == 0o600
    finally:
        os.umask(umask)
