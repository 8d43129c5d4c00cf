"""raylume.denoise against images whose noise-free version is known (computed here with numpy).

The test picture is three shaded spheres (hard silhouettes, different albedos) on a grey wall lit
by a gradient, antialiased by 4 x 4 supersampling like a render's pixel filter; the noisy version
multiplies each pixel by the mean of k exponential samples (mean 1), the skewed, non-negative
noise of a Monte Carlo estimate with k samples per pixel.
"""

import sys

import numpy as np
import pytest

import raylume.denoise as rd
from raylume.errors import RaylumeError

N = 128
needs_oidn = pytest.mark.skipif(not rd.is_available(), reason="pyoidn (raylume[denoise]) is not installed")


def _scene(supersample=4):
    """Clean image, albedo, normal (N, N, 3) float32, and a mask of the pixels within 2.5 px of a silhouette."""
    m = N * supersample
    y, x = (np.mgrid[0:m, 0:m].astype(np.float64) + 0.5) / supersample
    albedo = np.empty((m, m, 3))
    albedo[:] = (0.6, 0.6, 0.6)
    normal = np.zeros((m, m, 3))
    normal[..., 2] = 1.0
    edge = np.zeros((m, m), bool)
    for cx, cy, r, colour in [
        (40, 44, 26, (0.9, 0.2, 0.2)),
        (90, 80, 30, (0.2, 0.7, 0.3)),
        (36, 100, 18, (0.2, 0.3, 0.9)),
    ]:
        d2 = (x - cx) ** 2 + (y - cy) ** 2
        inside = d2 < r * r
        n = np.stack([(x - cx) / r, -(y - cy) / r, np.sqrt(np.clip(1 - d2 / r**2, 0, 1))], -1)
        normal[inside] = n[inside]
        albedo[inside] = colour
        edge |= np.abs(np.sqrt(d2) - r) < 2.5
    light = np.array([0.4, 0.5, 0.77])
    light /= np.linalg.norm(light)
    shade = (0.15 + np.clip(normal @ light, 0, None)) * (1.0 + 0.5 * x / N) * 2.0
    clean = albedo * shade[..., None]

    def down(a):
        return a.reshape(N, supersample, N, supersample, *a.shape[2:]).mean(axis=(1, 3))

    f32 = np.float32
    return down(clean).astype(f32), down(albedo).astype(f32), down(normal).astype(f32), down(edge.astype(f32)) > 0


def _noisy(clean, k=4, seed=0):
    rng = np.random.default_rng(seed)
    return (clean * rng.exponential(1.0, (k, *clean.shape)).mean(axis=0)).astype(np.float32)


def _rmse(a, b, mask=None):
    d = (a - b) if mask is None else (a - b)[mask]
    return float(np.sqrt(np.mean(d.astype(np.float64) ** 2)))


@needs_oidn
def test_denoising_brings_a_noisy_image_close_to_the_clean_one():
    clean, albedo, normal, _ = _scene()
    noisy = _noisy(clean)
    before = _rmse(noisy, clean)  # measured 0.62 (mean pixel value 1.14)
    for guides in [(), (albedo,), (albedo, normal)]:
        out = rd.denoise(noisy, *guides)
        assert out.shape == noisy.shape and out.dtype == np.float32
        assert np.isfinite(out).all() and (out >= 0).all()
        # measured 0.067-0.069: about a ninth of the noisy image's error
        assert _rmse(out, clean) < 0.25 * before, len(guides)


@needs_oidn
def test_guides_keep_the_silhouettes():
    clean, albedo, normal, edge = _scene()
    noisy = _noisy(clean)
    plain = _rmse(rd.denoise(noisy), clean, edge)  # measured 0.116
    guided = _rmse(rd.denoise(noisy, albedo, normal), clean, edge)  # measured 0.097
    with_albedo = _rmse(rd.denoise(noisy, albedo), clean, edge)  # measured 0.104
    # seeds 0-3 gave guided / plain between 0.84 and 0.89
    assert guided < 0.95 * plain
    assert with_albedo <= plain


@needs_oidn
def test_non_finite_inputs_do_not_reach_the_output():
    clean, albedo, normal, _ = _scene()
    noisy = _noisy(clean)
    kept = (noisy.copy(), albedo.copy(), normal.copy())
    bad = np.zeros((N, N), bool)
    bad[::17, ::13] = True
    noisy[bad] = np.nan
    noisy[5, 7] = np.inf
    noisy[9, 3] = -np.inf
    albedo[bad.T] = np.nan
    albedo[0, 0] = np.inf
    normal[bad] = -np.inf
    normal[3, 3] = (np.nan, 5.0, -5.0)
    copies = (noisy.copy(), albedo.copy(), normal.copy())
    for guides in [(), (albedo,), (albedo, normal)]:
        out = rd.denoise(noisy, *guides)
        assert out.shape == (N, N, 3) and out.dtype == np.float32
        assert np.isfinite(out).all()
        assert _rmse(out, clean) < 0.25 * _rmse(kept[0], clean)
    # the inputs are not modified
    for given, copy in zip((noisy, albedo, normal), copies):
        np.testing.assert_array_equal(given, copy)


@needs_oidn
def test_other_dtypes_and_ldr():
    clean, albedo, normal, _ = _scene()
    ldr = np.clip(_noisy(clean) / 4.0, 0, 1)
    out = rd.denoise(ldr.astype(np.float64), albedo.astype(np.float64), normal, hdr=False)
    assert out.dtype == np.float32 and out.shape == ldr.shape
    assert _rmse(out, np.clip(clean / 4.0, 0, 1)) < 0.5 * _rmse(ldr, np.clip(clean / 4.0, 0, 1))


def test_wrong_shapes_name_the_argument():
    rgb = np.ones((16, 24, 3), np.float32)
    with pytest.raises(ValueError, match="albedo"):
        rd.denoise(rgb, np.ones((24, 16, 3), np.float32))
    with pytest.raises(ValueError, match="normal"):
        rd.denoise(rgb, np.ones_like(rgb), np.ones((16, 24, 4), np.float32))
    with pytest.raises(ValueError, match="rgb"):
        rd.denoise(np.ones((16, 24), np.float32))
    with pytest.raises(ValueError, match="normal needs albedo"):
        rd.denoise(rgb, None, np.ones_like(rgb))


def test_missing_package_is_a_raylume_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyoidn", None)  # `import pyoidn` raises ImportError
    assert rd.is_available() is False
    with pytest.raises(RaylumeError, match=r"raylume\[denoise\]") as info:
        rd.denoise(np.ones((8, 8, 3), np.float32))
    assert info.value.__cause__ is None and info.value.__suppress_context__


@needs_oidn
def test_broken_native_library_is_a_raylume_error(monkeypatch):
    import pyoidn

    def fail():
        raise OSError("cannot open shared object file: libOpenImageDenoise.so")

    monkeypatch.setattr(pyoidn.Device, "is_cpu_available", staticmethod(fail))
    assert rd.is_available() is False
    with pytest.raises(RaylumeError, match=r"libOpenImageDenoise.*raylume\[denoise\]"):
        rd.denoise(np.ones((8, 8, 3), np.float32))
