"""Image encodings, writers and the notebook representation."""

from __future__ import annotations

import io
import subprocess
import sys

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
    assert set(img.aovs) == {"depth", "normal", "object", "prim", "albedo", "instance"}
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


def _smooth_image(h=6, w=9) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w]
    return np.dstack([x / (w - 1), y / (h - 1), 0.25 + 0 * x]).astype(np.float32) * 1.1


def test_jpeg_is_the_8_bit_encoding_at_quality_95(tmp_path):
    rgb = _smooth_image(32, 48) * 0.5
    Image(rgb, encoding="srgb").save(tmp_path / "a.jpg")
    expected = io.BytesIO()
    PILImage.fromarray(encode_8bit(rgb, "srgb")).save(expected, format="JPEG", quality=95)
    assert (tmp_path / "a.jpg").read_bytes() == expected.getvalue()
    back = np.asarray(PILImage.open(tmp_path / "a.jpg")).astype(int)
    assert np.abs(back - encode_8bit(rgb, "srgb")).mean() < 3


def _png_16_pixels(data: bytes) -> np.ndarray:
    """Decode an 8-bit-free, non-interlaced 16-bit RGB PNG with zlib (filters none/sub/up)."""
    import struct
    import zlib

    pos, idat, (w, h) = 8, b"", (0, 0)
    while pos < len(data):
        (n,), kind = struct.unpack(">I", data[pos : pos + 4]), data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour = struct.unpack(">IIBB", body[:10])
            assert (depth, colour) == (16, 2)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * 6)
    rows = np.zeros((h, w * 6), np.uint8)
    for j in range(h):
        f, line = raw[j, 0], raw[j, 1:].copy()
        if f == 1:
            for k in range(6, len(line)):
                line[k] = (int(line[k]) + int(line[k - 6])) & 255
        elif f == 2 and j:
            line = (line.astype(int) + rows[j - 1]).astype(np.uint8)
        else:
            assert f in (0, 2)
        rows[j] = line
    return rows.view(">u2").reshape(h, w, 3).astype(np.uint16)


@pytest.mark.parametrize("encoding", ["clamp", "srgb"])
def test_16_bit_png_has_the_same_curve(tmp_path, encoding):
    rgb = np.random.default_rng(1).uniform(-0.1, 1.1, size=(6, 9, 3)).astype(np.float32)
    Image(rgb, encoding=encoding).save(tmp_path / "a.png", bit_depth=16)
    img = PILImage.open(tmp_path / "a.png")
    assert img.size == (9, 6)
    eight = encode_8bit(rgb, encoding).astype(int)
    assert np.abs(np.asarray(img.convert("RGB")).astype(int) - eight).max() <= 1  # Pillow keeps the high bytes
    pixels = _png_16_pixels((tmp_path / "a.png").read_bytes())
    np.testing.assert_allclose(pixels / 65535.0, eight / 255.0, atol=0.5 / 255 + 1e-6)
    assert len(np.unique(pixels)) > len(np.unique(eight))  # more levels than 8 bits


def test_write_failure_is_an_output_error_in_words(tmp_path, monkeypatch):
    import errno

    import raylume.image as image_module

    def full_disk(src, dst):
        raise OSError(errno.ENOSPC, "No space left on device", src)

    monkeypatch.setattr(image_module.os, "replace", full_disk)
    with pytest.raises(OutputError) as info:
        Image(np.zeros((2, 2, 3), np.float32)).save(tmp_path / "a.png")
    message = str(info.value)
    assert "a.png" in message and "No space left on device" in message
    assert ".part" not in message and "OSError" not in message
    assert list(tmp_path.iterdir()) == []  # the temporary file is gone


NPY_PAST_A_LIMIT = """
import resource, signal, sys
import numpy as np
from raylume.errors import OutputError
from raylume.image import Image
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails (EFBIG)
resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
try:
    Image(np.zeros((96, 128, 3), np.float32)).save(sys.argv[1])
except OutputError as exc:
    print(exc)
"""


def test_npy_cut_short_gives_the_systems_reason(tmp_path):
    """A full disk takes the first bytes of an .npy and refuses the rest. numpy's own short write
    (C's fwrite) said only "36864 requested and 992 written"; the reason is now the system's,
    as for every output. A file size limit (in a child process) cuts the write short the same
    way, with its own reason (EFBIG)."""
    path = tmp_path / "x.npy"
    done = subprocess.run([sys.executable, "-c", NPY_PAST_A_LIMIT, str(path)], capture_output=True, text=True)
    assert done.stdout.strip() == f"{path}: cannot write the file (File too large)", done.stderr
    assert list(tmp_path.iterdir()) == []


def test_output_folder_must_be_writable(tmp_path, monkeypatch):
    from raylume.image import check_output_path

    monkeypatch.setattr("os.access", lambda path, mode, **kw: False)
    with pytest.raises(OutputError, match="cannot write") as info:
        check_output_path(tmp_path / "a.png")
    assert str(tmp_path) in str(info.value)


def test_output_folder_probe_catches_what_access_misses(tmp_path, monkeypatch):
    import tempfile

    from raylume.image import check_output_path

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(tmp_path / ".probe"))

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    with pytest.raises(OutputError, match="cannot write") as info:
        check_output_path(tmp_path / "a.png")
    assert ".probe" not in str(info.value) and "PermissionError" not in str(info.value)


def test_a_folder_is_not_an_output_file(tmp_path):
    from raylume.image import check_output_path

    (tmp_path / "adir").mkdir()
    with pytest.raises(OutputError, match="is a folder") as info:
        check_output_path(tmp_path / "adir")
    assert "(none)" not in str(info.value)


def test_exr_layers_round_trip(tmp_path):
    OpenEXR = pytest.importorskip("OpenEXR")
    rgb = _smooth_image()
    ids = np.full(rgb.shape[:2], -1, np.int32)
    ids[2, 3] = 2**31 - 1
    layers = {
        "depth": np.full(rgb.shape[:2], np.inf, np.float32),
        "normal": rgb[..., ::-1].copy(),
        "object": ids,
        "prim": np.zeros_like(ids),
    }
    Image(rgb, aovs=layers).save(tmp_path / "a.exr", layers=["depth", "normal", "object", "prim"])
    with OpenEXR.File(str(tmp_path / "a.exr"), separate_channels=True) as f:
        ch = {name: c.pixels for name, c in f.channels().items()}
    assert set(ch) == {"R", "G", "B", "depth.Z", "normal.X", "normal.Y", "normal.Z", "object.id", "prim.id"}
    np.testing.assert_array_equal(np.dstack([ch[c] for c in "RGB"]), rgb)
    np.testing.assert_array_equal(np.dstack([ch[f"normal.{c}"] for c in "XYZ"]), layers["normal"])
    np.testing.assert_array_equal(ch["object.id"].view(np.int32), ids)
    assert np.isinf(ch["depth.Z"]).all()
