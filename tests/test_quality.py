"""Image quality: antialiasing and pixel filters, area lights, textures, depth of field and
HDR outputs, each checked against something independent of the renderer (analytic coverage,
penumbra geometry, the texel itself, the focus-plane invariant, the file formats' readers)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage

import raylume
from raylume.errors import SceneError
from raylume.image import Image, rgbe_encode
from raylume.kernels.film.film import FILTER_TABLE_SIZE

REPO = Path(__file__).resolve().parents[1]


def scene(**tables):
    return raylume.scene_from_dict(tables)


# ------------------------------------------------------------------ antialiasing


def _clip_area(square, m, c):
    """Area of the axis-aligned square [(x0, x1), (y0, y1)] where y > m x + c (Sutherland-Hodgman)."""
    (x0, x1), (y0, y1) = square
    poly = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    inside = [y - m * x - c for x, y in poly]
    out = []
    for k in range(4):
        (p, fp), (q, fq) = (poly[k], inside[k]), (poly[(k + 1) % 4], inside[(k + 1) % 4])
        if fp >= 0:
            out.append(p)
        if (fp >= 0) != (fq >= 0):
            t = fp / (fp - fq)
            out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    if len(out) < 3:
        return 0.0
    return 0.5 * abs(sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(out, out[1:] + out[:1])))


EDGE_M, EDGE_C, N = 0.37, 0.11, 16


def _edge_scene(spp, pixel_filter="box", seed=0):
    """A white triangle in the plane z = 1 covering y > m x + c; fov 90 makes that plane the
    image plane [-1, 1]^2, so a pixel's true value is the area fraction the half-plane covers."""
    line = lambda x: EDGE_M * x + EDGE_C  # noqa: E731
    return scene(
        render={"width": N, "height": N, "spp": spp, "mode": "cast", "filter": pixel_filter, "seed": seed},
        camera={"fov": 90},
        objects=[
            {
                "type": "triangle",
                "vertices": [[-3, line(-3), 1], [3, line(3), 1], [0, 100, 1]],
                "material": {"color": [1, 1, 1]},
            }
        ],
    )


def _coverage():
    cov = np.zeros((N, N))
    px = 2.0 / N
    for j in range(N):
        for i in range(N):
            square = ((-1 + i * px, -1 + (i + 1) * px), (1 - (j + 1) * px, 1 - j * px))
            cov[j, i] = _clip_area(square, EDGE_M, EDGE_C) / (px * px)
    return cov


def test_antialiased_edge_converges_to_coverage():
    cov = _coverage()
    edge = (cov > 0.02) & (cov < 0.98)
    assert edge.sum() >= N
    errors = {}
    for spp in (1, 4, 16, 64, 256):
        img = raylume.render(_edge_scene(spp), aovs=False).rgb[..., 0].astype(np.float64)
        errors[spp] = float(np.sqrt(np.mean((img[edge] - cov[edge]) ** 2)))
        # away from the edge every sample agrees
        np.testing.assert_array_equal(img[cov == 0], 0)
        np.testing.assert_array_equal(img[cov == 1], 1)
    assert errors[1] > 0.15  # one sample per pixel: 0 or 1, a jagged edge
    for a, b in zip((1, 4, 16, 64), (4, 16, 64, 256)):
        assert errors[b] < errors[a], errors
    assert errors[256] < 0.02, errors


def test_one_sample_without_jitter_is_the_pinhole_render():
    """spp = 1 is the ray through the pixel centre whatever the filter, seed or focus distance."""
    cov = _coverage()
    px = 2.0 / N
    centres = np.array(
        [
            [1.0 if (1 - (j + 0.5) * px) > EDGE_M * (-1 + (i + 0.5) * px) + EDGE_C else 0.0 for i in range(N)]
            for j in range(N)
        ]
    )
    for pixel_filter, seed in (("box", 0), ("gaussian", 7), ("mitchell", 123)):
        img = raylume.render(_edge_scene(1, pixel_filter, seed), aovs=False).rgb[..., 0]
        np.testing.assert_array_equal(img, centres)
    assert ((centres > 0) != (cov > 0.5)).sum() <= 2 * N  # sanity: the centres sample the edge
    seed_scene = raylume.builtin_scene("seed")
    base = raylume.render(seed_scene, width=48, height=48, aovs=False).rgb
    lens = seed_scene.model_copy(update={"camera": seed_scene.camera.model_copy(update={"focus_distance": 2.5})})
    other = raylume.render(lens, width=48, height=48, seed=99, aovs=False).rgb
    np.testing.assert_array_equal(base, other)


def test_filters_keep_flat_colour_and_are_deterministic():
    for pixel_filter in ("box", "gaussian", "mitchell"):
        flat = raylume.render(
            scene(render={"width": 6, "height": 5, "spp": 9, "filter": pixel_filter, "background": [0.25, 0.5, 1.0]}),
            aovs=False,
        ).rgb
        np.testing.assert_allclose(flat, np.broadcast_to([0.25, 0.5, 1.0], flat.shape), rtol=1e-6)
    a = raylume.render(_edge_scene(8, "gaussian", seed=3), aovs=False).rgb
    b = raylume.render(_edge_scene(8, "gaussian", seed=3), aovs=False, threads=1).rgb
    c = raylume.render(_edge_scene(8, "gaussian", seed=4), aovs=False).rgb
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_gaussian_filter_table_is_the_truncated_gaussian_inverse_cdf():
    from raylume.kernels.film.film import filter_table

    radius, sigma = 1.5, 0.5
    edge = math.exp(-(radius**2) / (2 * sigma**2))

    def cdf(x):  # integral of exp(-t^2 / 2 sigma^2) - edge over [-radius, x], normalised
        g = lambda t: sigma * math.sqrt(math.pi / 2) * math.erf(t / (sigma * math.sqrt(2))) - edge * t  # noqa: E731
        return (g(x) - g(-radius)) / (g(radius) - g(-radius))

    kind, negative, table = filter_table("gaussian")
    assert negative == math.inf and len(table) == FILTER_TABLE_SIZE
    for k, x in enumerate(table):
        assert cdf(x) == pytest.approx(k / (FILTER_TABLE_SIZE - 1), abs=2e-4)
    kind, negative, table = filter_table("mitchell")
    assert 1.0 < negative < 1.3  # Mitchell-Netravali (B = C = 1/3) changes sign near 1.14 of 2


def test_gaussian_filter_smooths_an_edge_more_than_the_box():
    box = raylume.render(_edge_scene(64, "box"), aovs=False).rgb[..., 0]
    gauss = raylume.render(_edge_scene(64, "gaussian"), aovs=False).rgb[..., 0]
    partial = lambda img: int(((img > 0.02) & (img < 0.98)).sum())  # noqa: E731
    assert partial(gauss) > partial(box)


# ------------------------------------------------------------------ area lights


def _penumbra_width(size, floor_y=0.0, occluder_y=1.0, light_y=3.0, light_x=-2.0):
    """10-90 % width (world units) of the shadow edge that a straight occluder edge casts from a
    quad light of side `size`, measured on one rendered row (looking straight down)."""
    W, H, height = 240, 2, 5.0
    half_w = 2.5 / height  # the row spans x in [-1.5, 3.5] on the floor
    fov = 2 * math.degrees(math.atan(half_w * H / W))
    base = {
        "render": {"width": W, "height": H, "spp": 4, "max_depth": 0},
        "camera": {"position": [1, height, 0], "look_at": [1, 0, 0], "up": [0, 0, 1], "fov": fov},
        "lights": [
            {
                "type": "quad",
                "position": [light_x, light_y, 0],
                "u": [size, 0, 0],
                "v": [0, 0, size],
                "intensity": 1.0,
                "samples": 64,
            }
        ],
        "objects": [{"type": "plane", "point": [0, floor_y, 0], "normal": [0, 1, 0]}],
    }
    occluder = {"type": "triangle", "vertices": [[0, occluder_y, -20], [0, occluder_y, 20], [-20, occluder_y, 0]]}
    lit = raylume.render(scene(**base), aovs=False).rgb[..., 0].mean(axis=0).astype(np.float64)
    shadowed = raylume.render(scene(**{**base, "objects": base["objects"] + [occluder]}), aovs=False)
    visibility = shadowed.rgb[..., 0].mean(axis=0) / lit
    x = 1 + ((np.arange(W) + 0.5) / W * 2 - 1) * half_w * height
    window = (x > 0) & (x < 2)  # floor the camera sees past the occluder
    xs, vs = x[window], visibility[window]
    assert vs[0] < 0.01 and vs[-1] > 0.99  # umbra on the left, full light on the right
    cross = lambda level: float(np.interp(level, np.maximum.accumulate(vs), xs))  # noqa: E731
    return cross(0.9) - cross(0.1)


def test_soft_shadow_penumbra_grows_with_light_size():
    sizes = (0.25, 0.5, 1.0)
    widths = [_penumbra_width(s) for s in sizes]
    assert widths[0] < widths[1] < widths[2]
    for s, w in zip(sizes, widths):
        # similar triangles: the penumbra spans size * h_occ / (h_light - h_occ) = size / 2,
        # and a linear ramp's 10-90 % part is 80 % of it (pixels are 0.02 wide)
        assert w == pytest.approx(0.8 * s / 2, rel=0.1), (s, w)


def test_tiny_area_lights_match_the_point_light():
    objects = [
        {"type": "plane", "normal": [0, 1, 0], "point": [0, -1, 0], "material": {"specular": 20}},
        {"type": "sphere", "center": [0, 0, 3], "radius": 0.8, "material": {"color": [1, 0.5, 0.2], "specular": 50}},
    ]
    render = {"width": 32, "height": 24, "spp": 1}
    pos = [1.5, 2.5, 0.5]
    point = raylume.render(
        scene(render=render, objects=objects, lights=[{"type": "point", "position": pos, "intensity": 0.8}]), aovs=False
    ).rgb
    for light in ({"type": "quad", "u": [1e-5, 0, 0], "v": [0, 0, 1e-5]}, {"type": "sphere", "radius": 1e-5}):
        area = raylume.render(
            scene(render=render, objects=objects, lights=[{**light, "position": pos, "intensity": 0.8, "samples": 4}]),
            aovs=False,
        )
        assert np.abs(area.rgb - point).max() < 1e-3
        assert (
            area.stats["rays"]
            > raylume.render(scene(render=render, objects=objects, lights=[]), aovs=False).stats["rays"]
        )


def test_area_light_samples_count_shadow_rays():
    objects = [{"type": "sphere", "center": [0, 0, 3], "radius": 1}]
    light = {"type": "sphere", "position": [0, 0, 0.5], "radius": 0.1}
    rays = [
        raylume.render(
            scene(render={"width": 1, "height": 1, "max_depth": 0}, objects=objects, lights=[{**light, "samples": n}]),
            aovs=False,
        ).stats["rays"]
        for n in (1, 9)
    ]
    assert rays == [2, 10]  # the camera ray, then one shadow ray per light sample


# ------------------------------------------------------------------ textures


def _srgb_to_linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def test_texture_lookup_returns_texels_at_centres_and_blends_between():
    from raylume.kernels.shading.textures import texture_lookup

    rng = np.random.default_rng(1)
    w, h = 5, 3
    texels = rng.random((h, w, 3)).astype(np.float32)
    atlas = np.concatenate([np.zeros((7, 3), np.float32), texels.reshape(-1, 3)])  # offset 7
    for y in range(h):
        for x in range(w):
            u, v = (x + 0.5) / w, 1 - (y + 0.5) / h
            np.testing.assert_allclose(texture_lookup(atlas, 7, w, h, u, v), texels[y, x], atol=1e-6)
            # repeating: a whole number of tiles away is the same texel
            np.testing.assert_allclose(texture_lookup(atlas, 7, w, h, u + 3, v - 2), texels[y, x], atol=1e-5)
    # halfway between two texel centres: their mean; across the right border it wraps to column 0
    np.testing.assert_allclose(
        texture_lookup(atlas, 7, w, h, 2.0 / w, 1 - 0.5 / h), texels[0, 1:3].mean(axis=0), atol=1e-6
    )
    np.testing.assert_allclose(
        texture_lookup(atlas, 7, w, h, 1.0, 1 - 0.5 / h), (texels[0, 0] + texels[0, -1]) / 2, atol=1e-6
    )


def _quad_obj(path: Path):
    """The square [-1, 1]^2 at z = 1 with UVs (x + 1) / 2, (y + 1) / 2, as a fan around an inner
    vertex: no triangle edge passes through a pixel centre of the 4 x 4 test image (a ray
    exactly along an edge shared by two triangles is the traversal's business, not this test's)."""
    path.write_text(
        "v -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\nv 0.1 0.2 1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.55 0.6\n"
        "f 1/1 2/2 5/5\nf 2/2 3/3 5/5\nf 3/3 4/4 5/5\nf 4/4 1/1 5/5\n"
    )


def test_image_texture_on_a_mesh_shows_its_texels(tmp_path):
    """A 4 x 4 texture on a UV-mapped quad filling a 4 x 4 image (fov 90 at distance 1): each
    pixel centre is a texel centre, so the cast image is the texture, sRGB-decoded (point
    lookups: texture_filter off; filtering is tested in test_texture_filtering.py)."""
    rng = np.random.default_rng(2)
    texels = rng.integers(0, 256, size=(4, 4, 3), dtype=np.uint8)
    PILImage.fromarray(texels).save(tmp_path / "tex.png")
    _quad_obj(tmp_path / "quad.obj")
    path = tmp_path / "scene.toml"
    path.write_text("""
[render]
width = 4
height = 4
mode = "cast"
texture_filter = false
[camera]
fov = 90
[[objects]]
type = "mesh"
file = "quad.obj"
material = { texture = { type = "image", file = "tex.png" } }
""")
    img = raylume.render(raylume.load_scene(path))
    expected = _srgb_to_linear(texels / 255.0)
    np.testing.assert_allclose(img.rgb, expected, atol=2e-6)
    np.testing.assert_allclose(img.aovs["albedo"], expected, atol=2e-6)
    # the rasterizer interpolates the same UVs (perspective-correct) and looks up the same texels
    raster = raylume.render(raylume.load_scene(path), mode="raster")
    np.testing.assert_allclose(raster.aovs["albedo"], expected, atol=1e-5)
    # scale [2, 2] tiles the image twice across: pixel (i, j) shows texel (2i mod 4, 2j mod 4)
    # blended half-way with its neighbour (the pixel centre falls on a texel border)
    text = path.read_text().replace('file = "tex.png" }', 'file = "tex.png", scale = [2, 2] }')
    path.write_text(text)
    tiled = raylume.render(raylume.load_scene(path)).rgb
    assert np.allclose(tiled[:2, :2], tiled[2:, 2:], atol=1e-6)


def test_sphere_and_plane_uvs():
    from raylume.compile import compile_scene
    from raylume.kernels.geometry.shapes import uv
    from raylume.kernels.scene import geometry_of
    from raylume.kernels.variants import features

    s = scene(
        objects=[
            {"type": "sphere", "center": [1, 2, 3], "radius": 2},
            {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]},
            {"type": "plane", "point": [0, 0, 5], "normal": [0, 0, -1]},
        ]
    )
    S = compile_scene(s).kernel
    G = geometry_of(S)  # primitives: the sphere (in the BVH), then the two planes
    X = features(S)
    c = np.array([1.0, 2.0, 3.0])
    cases = {
        (0, 0, -1): (0.5, 0.5),
        (1, 0, 0): (0.75, 0.5),
        (-1, 0, 0): (0.25, 0.5),
        (0, 1, 0): (None, 1.0),
        (0, -1, 0): (None, 0.0),
        (0, math.sqrt(0.5), -math.sqrt(0.5)): (0.5, 0.75),
    }
    for n, (u, v) in cases.items():
        p = tuple(c + 2 * np.array(n))
        got = uv(G, X, 0, 0.0, 0.0, p)
        if u is not None:
            assert got[0] == pytest.approx(u, abs=1e-12)
        assert got[1] == pytest.approx(v, abs=1e-12)
    # floor: u along +x, v along +z; wall facing the camera: u to the right (+x), v up (+y)
    assert uv(G, X, 1, 0.0, 0.0, (0.3, -1.0, 0.7)) == pytest.approx((0.3, 0.7), abs=1e-12)
    assert uv(G, X, 2, 0.0, 0.0, (0.3, 0.4, 5.0)) == pytest.approx((0.3, 0.4), abs=1e-12)


def test_texture_errors_name_the_key(tmp_path):
    _quad_obj(tmp_path / "quad.obj")
    (tmp_path / "nouv.obj").write_text("v 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\n")
    (tmp_path / "bad.png").write_text("not an image")
    cases = [
        ("materials.wood.texture.file", 'material = "wood"', "missing.png", "quad.obj"),
        ("materials.wood.texture.file", 'material = "wood"', "bad.png", "quad.obj"),
        ("objects[0].file", 'material = "wood"', None, "nouv.obj"),
    ]
    for key, material, tex, mesh in cases:
        path = tmp_path / "scene.toml"
        path.write_text(f"""
[materials.wood]
texture = {{ type = "image", file = "{tex or "ok.png"}" }}
[[objects]]
type = "mesh"
file = "{mesh}"
{material}
""")
        PILImage.fromarray(np.zeros((2, 2, 3), np.uint8)).save(tmp_path / "ok.png")
        with pytest.raises(SceneError, match=key.replace("[", r"\[").replace("]", r"\]")):
            raylume.render(raylume.load_scene(path))


# ------------------------------------------------------------------ depth of field


def _wall_scene(wall_z, aperture):
    # point texture lookups: the test is about the rays' geometry (a lens ray's footprint is
    # not the pinhole ray's, so filtered lookups would differ on the focus plane too)
    return scene(
        render={"width": 32, "height": 32, "spp": 16, "mode": "cast", "seed": 5, "texture_filter": False},
        camera={"fov": 40, "aperture": aperture, "focus_distance": 4.0},
        objects=[
            {
                "type": "plane",
                "point": [0, 0, wall_z],
                "normal": [0, 0, -1],
                "material": {
                    "texture": {"type": "checker", "scale": 0.6 * wall_z / 4, "colors": [[1, 1, 1], [0, 0, 0]]}
                },
            }
        ],
    )


def test_depth_of_field_keeps_the_focus_plane_sharp_and_blurs_the_rest():
    pinhole = raylume.render(_wall_scene(4.0, 0.0), aovs=False).rgb
    lens = raylume.render(_wall_scene(4.0, 0.8), aovs=False).rgb
    # every lens ray of a camera sample meets the pinhole ray on the focus plane
    np.testing.assert_allclose(lens, pinhole, atol=1e-6)
    far_pin = raylume.render(_wall_scene(8.0, 0.0), aovs=False).rgb
    far_lens = raylume.render(_wall_scene(8.0, 0.8), aovs=False).rgb
    assert np.abs(far_lens - far_pin).max() > 0.3
    assert far_lens.std() < 0.75 * far_pin.std()  # the checker's contrast is blurred away
    near_lens = raylume.render(_wall_scene(2.5, 0.8), aovs=False).rgb
    near_pin = raylume.render(_wall_scene(2.5, 0.0), aovs=False).rgb
    assert near_lens.std() < 0.75 * near_pin.std()


def test_camera_validation():
    with pytest.raises(SceneError, match="camera.aperture"):
        raylume.scene_from_dict({"camera": {"aperture": -0.1}})
    with pytest.raises(SceneError, match="camera.focus_distance"):
        raylume.scene_from_dict({"camera": {"focus_distance": 0}})
    with pytest.raises(SceneError, match=r"lights\[0\]"):
        raylume.scene_from_dict({"lights": [{"type": "quad", "position": [0, 1, 0], "u": [1, 0, 0], "v": [2, 0, 0]}]})
    with pytest.raises(SceneError, match=r"lights\[0\].radius"):
        raylume.scene_from_dict({"lights": [{"type": "sphere", "position": [0, 1, 0], "radius": 0}]})
    assert raylume.scene_from_dict({"camera": {"position": [0, 0, -2], "look_at": [0, 0, 1]}}).camera.focus == 3


# ------------------------------------------------------------------ outputs


def _read_hdr(path: Path) -> np.ndarray:
    """An independent Radiance .hdr reader (flat and run-length scanlines)."""
    data = path.read_bytes()
    pos = 0
    lines = []
    while True:
        end = data.index(b"\n", pos)
        line, pos = data[pos:end], end + 1
        if not line:
            break
        lines.append(line)
    assert lines[0].startswith(b"#?") and b"FORMAT=32-bit_rle_rgbe" in lines
    end = data.index(b"\n", pos)
    sy, h, sx, w = data[pos:end].split()
    pos = end + 1
    assert (sy, sx) == (b"-Y", b"+X")
    h, w = int(h), int(w)
    out = np.zeros((h, w, 4), np.uint8)
    for y in range(h):
        if 8 <= w <= 0x7FFF and data[pos] == 2 and data[pos + 1] == 2 and data[pos + 2] < 128:
            assert data[pos + 2] << 8 | data[pos + 3] == w
            pos += 4
            for c in range(4):
                x = 0
                while x < w:
                    n = data[pos]
                    pos += 1
                    if n > 128:
                        out[y, x : x + n - 128, c] = data[pos]
                        pos += 1
                        x += n - 128
                    else:
                        out[y, x : x + n, c] = np.frombuffer(data[pos : pos + n], np.uint8)
                        pos += n
                        x += n
        else:
            out[y] = np.frombuffer(data[pos : pos + 4 * w], np.uint8).reshape(w, 4)
            pos += 4 * w
    assert pos == len(data)
    e = out[..., 3].astype(np.int64)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return (out[..., :3] + 0.5) * scale[..., None] * (e[..., None] > 0)


@pytest.mark.parametrize("shape", [(3, 5), (4, 300), (2, 8)])
def test_hdr_round_trip(tmp_path, shape):
    rng = np.random.default_rng(3)
    rgb = (rng.random(shape + (3,)) * np.exp(rng.uniform(-20, 20, size=shape + (1,)))).astype(np.float32)
    rgb[0, 0] = 0
    rgb[-1, -1] = [1e-40, 0, 0]
    Image(rgb).save(tmp_path / "a.hdr")
    back = _read_hdr(tmp_path / "a.hdr")
    top = rgb.max(axis=2, keepdims=True).astype(np.float64)
    assert np.all(np.abs(back - rgb) <= top * 2.0**-8 + 1e-30)  # 8-bit mantissa of the largest channel
    assert back[0, 0].max() == 0
    np.testing.assert_array_equal(rgbe_encode(np.array([[[1.0, 0.5, 0.0]]])), [[[128, 64, 0, 129]]])


def test_exposure_scales_png_only(tmp_path):
    rgb = np.array([[[0.1, 0.2, 0.4]]], dtype=np.float32)
    img = Image(rgb, encoding="clamp", exposure=1.0)
    img.save(tmp_path / "a.png")
    np.testing.assert_array_equal(np.asarray(PILImage.open(tmp_path / "a.png")), [[[51, 102, 204]]])
    img.save(tmp_path / "a.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), rgb)


def _cli(*args, cwd):
    from test_cli import raylume as run_cli  # the CLI-as-a-subprocess helper

    return run_cli("render", *args, cwd=cwd)


def test_cli_quality_flags_and_float_outputs(tmp_path):
    OpenEXR = pytest.importorskip("OpenEXR")
    scene_file = tmp_path / "s.toml"
    scene_file.write_text("""
[render]
width = 20
height = 12
spp = 4
encoding = "srgb"
[[lights]]
type = "quad"
position = [0, 3, 1]
u = [2, 0, 0]
v = [0, 0, 2]
intensity = 3.0
[[objects]]
type = "sphere"
center = [0, 0, 3]
radius = 1
""")
    for out in ("a.exr", "a.hdr", "a.png", "b.png", "c.png", "d.png"):
        extra = {"b.png": ["--exposure", "-1"], "c.png": ["--filter", "mitchell"], "d.png": ["--seed", "9"]}.get(
            out, []
        )
        r = _cli(scene_file, "-o", out, "--quiet", "--seed", "1", *extra, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
    with OpenEXR.File(str(tmp_path / "a.exr")) as f:
        channels = f.channels()
        exr = channels["RGB"].pixels if "RGB" in channels else np.dstack([channels[c].pixels for c in "RGB"])
    assert exr.dtype == np.float32 and exr.max() > 1.0  # linear, not clamped
    img = raylume.render(raylume.load_scene(scene_file), seed=1, aovs=False)
    np.testing.assert_array_equal(exr, img.rgb)  # float32 survives the file exactly
    hdr = _read_hdr(tmp_path / "a.hdr")
    assert np.all(np.abs(hdr - img.rgb) <= img.rgb.max(axis=2, keepdims=True) * 2.0**-8 + 1e-30)
    png = np.asarray(PILImage.open(tmp_path / "a.png"))
    darker = np.asarray(PILImage.open(tmp_path / "b.png"))
    np.testing.assert_array_equal(png, img.to_uint8())
    np.testing.assert_array_equal(darker, img.to_uint8(exposure=-1.0))
    assert not np.array_equal(png, np.asarray(PILImage.open(tmp_path / "c.png")))
    assert not np.array_equal(png, np.asarray(PILImage.open(tmp_path / "d.png")))  # another seed
    again = _cli(scene_file, "-o", "e.png", "--quiet", "--seed", "1", cwd=tmp_path)
    assert again.returncode == 0
    assert (tmp_path / "e.png").read_bytes() == (tmp_path / "a.png").read_bytes()  # deterministic
    bad = _cli(scene_file, "-o", "f.png", "--filter", "tent", cwd=tmp_path)
    assert bad.returncode == 2 and "--filter" in bad.stderr and not (tmp_path / "f.png").exists()


def test_quality_example_loads_and_renders_small():
    example = raylume.load_scene(REPO / "examples" / "quality.toml")
    img = raylume.render(example, width=40, height=25, spp=2, aovs=False)
    assert np.isfinite(img.rgb).all() and img.rgb.max() > 0.1


# ------------------------------------------------------------------ properties

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_FLOATS = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(u=_FLOATS | st.just(float("nan")), v=_FLOATS, w=st.integers(1, 5), h=st.integers(1, 5))
def test_texture_lookup_is_a_convex_blend_of_texels(u, v, w, h):
    from raylume.kernels.shading.textures import texture_lookup

    texels = np.random.default_rng(w * 7 + h).random((w * h, 3)).astype(np.float32)
    got = np.array(texture_lookup(texels, 0, w, h, u, v))
    assert np.isfinite(got).all()
    assert np.all(got >= texels.min(axis=0) - 1e-6) and np.all(got <= texels.max(axis=0) + 1e-6)


@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), pixel=st.integers(0, 2**40), s=st.integers(0, 4095))
def test_samples_stay_in_the_unit_square_and_the_lens_disk(seed, pixel, s):
    from raylume.kernels.film.sampler import concentric_disk, lens_sample, pixel_sample, sample_key

    key = np.uint64(sample_key(seed, pixel, s))  # back from Python as an int, which may not fit int64
    for x, y in (pixel_sample(key), lens_sample(key)):
        assert 0.0 <= x < 1.0 and 0.0 <= y < 1.0
        dx, dy = concentric_disk(x, y)
        assert dx * dx + dy * dy <= 1.0 + 1e-12


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=3, max_size=3))
def test_rgbe_never_fails(rgb):
    out = rgbe_encode(np.array([[rgb]], dtype=np.float32))
    assert out.dtype == np.uint8 and out.shape == (1, 1, 4)


@pytest.mark.parametrize("by_kernel", [True, False])
@pytest.mark.parametrize("pixel_filter", ["box", "mitchell"])
def test_film_image_is_the_weighted_mean_of_its_sums(pixel_filter, by_kernel, monkeypatch):
    """Film.rgb against its definition written in numpy: each pixel's weighted mean (weights
    below 0.5 count as 1), the plain mean of the samples where a negative-lobed filter's
    weights cancel, negative values clipped to 0; NaN kept, -0.0 as 0.0. Both ways rgb() takes:
    the kernel (signed sums, large films, or once it is compiled) and numpy (small films of
    unsigned sums before that; signed sums through film_rgb_numpy itself)."""
    from raylume.kernels.film import film as film_module
    from raylume.kernels.film.film import FILM_ABS_RGB, FILM_COUNT, FILM_RGB, FILM_WEIGHT, FILM_WIDTH, Film

    numpy = film_module.film_rgb_numpy
    if by_kernel:
        monkeypatch.setattr(film_module, "RGB_KERNEL_PIXELS", 1)
    else:  # as before _film_rgb is compiled in the process
        monkeypatch.setattr(film_module, "RGB_KERNEL_PIXELS", 1 << 40)
        monkeypatch.setattr(film_module, "_film_rgb", _NotCompiled())

    rng = np.random.default_rng(3)
    film = Film(37, 23, pixel_filter, total_spp=8)
    s = film.sums
    s[...] = rng.normal(size=s.shape) * 3
    s[..., FILM_WEIGHT] = rng.integers(-3, 9, size=s.shape[:2])
    if s.shape[2] > FILM_WIDTH:
        s[..., FILM_COUNT] = rng.integers(0, 9, size=s.shape[:2])
    s[0, 0, FILM_RGB] = np.nan
    s[0, 1, FILM_RGB] = -0.0
    s[0, 1, FILM_WEIGHT] = 1.0
    w = s[..., FILM_WEIGHT]
    want = s[..., FILM_RGB : FILM_RGB + 3] * (1.0 / np.where(w < 0.5, 1.0, w))[..., None]
    if s.shape[2] > FILM_WIDTH:
        count = s[..., FILM_COUNT]
        cancelled = (w < 0.5 * count) & (count > 0)
        assert cancelled.any()
        plain = s[..., FILM_ABS_RGB : FILM_ABS_RGB + 3] / np.maximum(count, 1.0)[..., None]
        want = np.where(cancelled[..., None], plain, want)
    want = np.maximum(want, 0.0).astype(np.float32)
    got = film.rgb() if by_kernel or s.shape[2] == FILM_WIDTH else numpy(s)
    assert got.dtype == np.float32 and got.shape == (23, 37, 3)
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))  # to the bit, NaN too


class _NotCompiled:
    """Stands for the film's kernel before it is compiled: no signatures, and never called."""

    signatures: list = []

    def __call__(self, *args):
        raise AssertionError("the kernel ran")
