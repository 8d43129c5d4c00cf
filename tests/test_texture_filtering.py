"""Texture filtering (ray cones, a box-filtered checker, mip-mapped images), checked against
brute-force averages and against supersampled renders of the same scenes: a filtered image at
one sample per pixel must be far closer to the pixel averages than point lookups are."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image as PILImage

import raylume
from raylume.compile import mip_levels
from raylume.kernels.shading.textures import TEX_CELL, TEX_COLOR_A, TEX_COLOR_B, TEX_WIDTH, filtered_checker, mip_lookup
from raylume.scene.checks import SceneWarning

A = (0.9, 0.8, 0.7)
B = (0.1, 0.2, 0.3)


def _checker_row(cell: float) -> np.ndarray:
    row = np.zeros((1, TEX_WIDTH))
    row[0, TEX_CELL] = cell
    row[0, TEX_COLOR_A : TEX_COLOR_A + 3] = A
    row[0, TEX_COLOR_B : TEX_COLOR_B + 3] = B
    return row


@pytest.mark.parametrize("case", range(6))
def test_filtered_checker_is_the_average_over_the_footprint_box(case):
    """The closed form against a midpoint-rule average of the point checker over the same box
    (p +- the footprint's extent along each axis), N points per axis: each of the box's
    checker boundaries moves the rule by at most 1/N of the colour difference per axis."""
    rng = np.random.default_rng(case)
    cell = float(rng.uniform(0.3, 2.0))
    p = rng.uniform(-5, 5, size=3)
    a1 = rng.normal(size=3) * rng.uniform(0.05, 2.0)
    a2 = rng.normal(size=3) * rng.uniform(0.05, 2.0)
    got = np.array(filtered_checker(_checker_row(cell), 0, tuple(p), tuple(a1), tuple(a2)))

    n = 160
    half = np.sqrt(a1**2 + a2**2)
    axes = [p[k] + half[k] * ((np.arange(n) + 0.5) / n * 2 - 1) for k in range(3)]
    parity = sum(np.floor(g / cell).reshape(shape) for g, shape in zip(axes, [(-1, 1, 1), (1, -1, 1), (1, 1, -1)]))
    share_a = float(np.mean(parity % 2 == 0))
    expected = share_a * np.array(A) + (1 - share_a) * np.array(B)
    bound = 3 * (2 * half / cell + 2).max() / n  # boundaries crossed per axis, 1/n each
    np.testing.assert_allclose(got, expected, atol=bound * 0.8 + 1e-12)


def test_filtered_checker_without_footprint_is_the_point_checker():
    row = _checker_row(1.0)
    zero = (0.0, 0.0, 0.0)
    for p, colour in [((0.5, 0.5, 0.5), A), ((1.5, 0.5, 0.5), B), ((1.5, -0.5, 0.5), A), ((0.2, 0.0, 0.3), A)]:
        assert filtered_checker(row, 0, p, zero, zero) == pytest.approx(colour)


def test_mip_levels_are_block_averages_down_to_one_texel():
    rng = np.random.default_rng(1)
    base = rng.uniform(size=(8, 16, 3)).astype(np.float32)
    levels = mip_levels(base)
    assert [lv.shape[:2] for lv in levels] == [(8, 16), (4, 8), (2, 4), (1, 2), (1, 1)]
    np.testing.assert_allclose(levels[1], base.reshape(4, 2, 8, 2, 3).mean(axis=(1, 3)), atol=1e-6)
    np.testing.assert_allclose(levels[-1][0, 0], base.reshape(-1, 3).mean(axis=0), atol=1e-6)


def test_mip_lookup_reads_the_level_and_blends_between_levels():
    """At a texel centre of level 1, level 1 returns that texel (a 2 x 2 block mean of level 0);
    level 0.25 is a quarter of the way from the bilinear level-0 value to it."""
    rng = np.random.default_rng(3)
    base = rng.uniform(size=(8, 8, 3)).astype(np.float32)
    levels = mip_levels(base)
    atlas = np.concatenate([lv.reshape(-1, 3) for lv in levels])
    blocks = base.reshape(4, 2, 4, 2, 3).mean(axis=(1, 3))
    for y in range(4):
        for x in range(4):
            u, v = (x + 0.5) / 4, 1 - (y + 0.5) / 4
            np.testing.assert_allclose(mip_lookup(atlas, 0, 8, 8, len(levels), u, v, 1.0), blocks[y, x], atol=1e-6)
            level0 = base[2 * y : 2 * y + 2, 2 * x : 2 * x + 2].reshape(-1, 3).mean(axis=0)  # bilinear at a corner
            quarter = mip_lookup(atlas, 0, 8, 8, len(levels), u, v, 0.25)
            np.testing.assert_allclose(quarter, level0 + 0.25 * (blocks[y, x] - level0), atol=1e-6)
    # beyond the last level: the 1 x 1 level, the mean
    np.testing.assert_allclose(
        mip_lookup(atlas, 0, 8, 8, len(levels), 0.3, 0.6, 99.0), base.mean(axis=(0, 1)), atol=1e-6
    )


# --- whole renders against supersampled references --------------------------------------------

W, H = 64, 40
REFERENCE_SPP = 256


def _errors(make_scene) -> tuple[float, float, float]:
    """Mean squared error against the supersampled (point-lookup) reference of: point lookups
    at 1 spp, filtered lookups at 1 spp, filtered at 16 spp; over the pixels inside the
    objects (a pixel and its 8 neighbours hit something), so that the silhouettes' own
    aliasing, the same with and without texture filtering, stays out of the measure."""
    reference = raylume.render(make_scene(REFERENCE_SPP, False), aovs=False).rgb
    point = raylume.render(make_scene(1, False), aovs=False).rgb
    first = raylume.render(make_scene(1, True))
    filtered = first.rgb
    filtered16 = raylume.render(make_scene(16, True), aovs=False).rgb
    assert np.isfinite(filtered).all() and np.isfinite(filtered16).all()
    hit = np.pad(first.aovs["object"] >= 0, 1)
    inside = np.ones((H, W), dtype=bool)
    for dy in range(3):
        for dx in range(3):
            inside &= hit[dy : dy + H, dx : dx + W]
    assert inside.sum() > W * H / 20
    return tuple(float(np.mean((x - reference)[inside] ** 2)) for x in (point, filtered, filtered16))


def _floor_scene(objects, textures_filtered: bool, spp: int, mode: str = "cast", extra=None):
    return raylume.scene_from_dict(
        {
            "render": {"width": W, "height": H, "spp": spp, "mode": mode, "texture_filter": textures_filtered},
            "camera": {"position": [0, 1, -2], "look_at": [0, 0.6, 6], "fov": 60},
            "objects": objects,
            "lights": [{"type": "ambient", "intensity": 1.0}],
            **(extra or {}),
        }
    )


def test_checker_floor_to_the_horizon_stops_aliasing():
    """A checker plane seen to the horizon: point lookups alias (moire) far away; filtered ones
    must cut the squared error against the pixel averages by at least 4x at 1 spp, and 16
    filtered samples must beat 1."""
    floor = [
        {
            "type": "plane",
            "point": [0, 0, 0],
            "normal": [0, 1, 0],
            "material": {"texture": {"type": "checker", "scale": 0.5}},
        }
    ]
    point, filtered, filtered16 = _errors(lambda spp, on: _floor_scene(floor, on, spp))
    assert filtered < point / 4, (point, filtered)
    assert filtered16 < filtered


def test_checker_seen_in_a_mirror_is_filtered_too():
    """Trace mode: the cone goes on growing along the reflected ray."""
    objects = [
        {
            "type": "plane",
            "point": [0, 0, 0],
            "normal": [0, 1, 0],
            "material": {"texture": {"type": "checker", "scale": 0.5}},
        },
        {
            "type": "plane",
            "point": [0, 0, 40],
            "normal": [0, 0, -1],
            "material": {"color": [0, 0, 0], "reflective": 1.0},
        },
    ]
    point, filtered, _ = _errors(lambda spp, on: _floor_scene(objects, on, spp, mode="trace"))
    assert filtered < point / 4, (point, filtered)


def _stripes(path, size=256):
    """One-texel black and white stripes both ways (a fine grid): the worst case for aliasing."""
    y, x = np.mgrid[0:size, 0:size]
    grey = ((x + y) % 2 * 255).astype(np.uint8)
    PILImage.fromarray(np.stack([grey] * 3, axis=-1)).save(path)


@pytest.mark.parametrize("shape", ["mesh", "quad", "sphere"])
def test_fine_image_texture_is_read_from_the_right_mip_level(tmp_path, shape):
    """A 256 x 256 texture of one-texel stripes, hundreds of texels per pixel far away: mip
    lookups (triangles' exact UV change; the quad's and the sphere's finite differences, across
    the sphere's seam) must cut the error against the pixel averages at least 4x."""
    _stripes(tmp_path / "fine.png")
    texture = {"type": "image", "file": str(tmp_path / "fine.png"), "scale": [8, 8]}
    if shape == "mesh":
        (tmp_path / "floor.obj").write_text(
            "v -20 0 -2\nv 20 0 -2\nv 20 0 60\nv -20 0 60\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 4/4 3/3\nf 1/1 3/3 2/2\n"
        )
        objects = [{"type": "mesh", "file": str(tmp_path / "floor.obj"), "material": {"texture": texture}}]
    elif shape == "quad":
        objects = [
            {"type": "quad", "position": [0, 0, 29], "u": [40, 0, 0], "v": [0, 0, 62], "material": {"texture": texture}}
        ]
    else:  # the seam (u = 0 = 1) faces this camera, at +z
        objects = [{"type": "sphere", "center": [0, 0.6, -8], "radius": 1.5, "material": {"texture": texture}}]
    extra = {"camera": {"position": [0, 0.6, -2], "look_at": [0, 0.6, -8], "fov": 40}} if shape == "sphere" else None
    point, filtered, filtered16 = _errors(lambda spp, on: _floor_scene(objects, on, spp, extra=extra))
    assert filtered < point / 4, (point, filtered)
    assert filtered16 < point / 4


def test_a_16_bit_grey_texture_reads_as_its_8_bit_twin(tmp_path):
    """A 16-bit greyscale PNG (Pillow's I;16) is scaled from 0..65535: 32896 is 8-bit 128's
    grey (Pillow's conversion to RGB clips at 255, and such a texture had rendered white)."""
    from PIL import Image as PILImage

    import raylume

    PILImage.fromarray(np.full((4, 4), 32896, np.uint16)).save(tmp_path / "grey16.png")
    PILImage.fromarray(np.full((4, 4), 128, np.uint8)).save(tmp_path / "grey8.png")
    assert PILImage.open(tmp_path / "grey16.png").mode.startswith("I")

    def shown(name):
        quad = {
            "type": "quad",
            "u": [4, 0, 0],
            "v": [0, 3, 0],
            "material": {"texture": {"type": "image", "file": name}},
        }
        scene = raylume.scene_from_dict(
            {"render": {"width": 8, "height": 6, "mode": "cast"}, "camera": {"position": [0, 0, -2]}, "objects": [quad]}
        ).with_base_dir(tmp_path)
        return raylume.render(scene, aovs=False).rgb

    grey8 = shown("grey8.png")
    assert 0.2 < grey8.mean() < 0.23  # sRGB 128 is linear 0.216
    np.testing.assert_array_equal(shown("grey16.png"), grey8)
    # float greyscale (a TIFF's F mode) as it is: converted by Pillow it was 0 or 1/255
    PILImage.fromarray(np.full((4, 4), 128 / 255, np.float32)).save(tmp_path / "grey.tif")
    assert PILImage.open(tmp_path / "grey.tif").mode == "F"
    np.testing.assert_allclose(shown("grey.tif"), grey8, rtol=1e-6)
    # 16-bit colour, which Pillow decodes to 8 bits: read so, with a warning that says it
    _write_png16_rgb(tmp_path / "rgb16.png", np.full((4, 4, 3), 32896, np.uint16))
    assert PILImage.open(tmp_path / "rgb16.png").mode == "RGB"
    with pytest.warns(SceneWarning, match="rgb16.png is a PNG of 16-bit colour, which is read at 8 bits"):
        np.testing.assert_array_equal(shown("rgb16.png"), grey8)


def _write_png16_rgb(path, rgb: np.ndarray) -> None:
    """A PNG of 16-bit RGB (colour type 2), which Pillow cannot write: unfiltered rows."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    h, w, _ = rgb.shape
    rows = b"".join(b"\x00" + rgb[y].astype(">u2").tobytes() for y in range(h))
    header = struct.pack(">IIBBBBB", w, h, 16, 2, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    )


@pytest.mark.parametrize("u", [np.inf, -np.inf, np.nan, 1e300, 1e17 + 0.3, -1e-17, 0.999999999999])
def test_any_uv_reads_a_texel_of_the_texture(u):
    """UVs that are not finite, or so large their wrap loses every bit (a texture scaled by
    1e17, a mesh's vt of 1e30), read the texture, never memory beside it: an index from NaN is
    undefined, and such UVs had given colours of 1e24 and -3e38."""
    texels = np.zeros((2 * 2, 3), np.float32)
    texels[:, 0] = [0.1, 0.2, 0.3, 0.4]
    colour = mip_lookup(texels, 0, 2, 2, 1, u, 0.25, 0.0)
    assert 0.1 <= colour[0] <= 0.4 and colour[1] == colour[2] == 0.0
