"""pbrt-v4 files against results computed by hand from pbrt's definitions: a point light's
irradiance on a plane, the projection of a point through pbrt's perspective camera (LookAt,
fov on the shorter side, raster +x to the right, a mirrored camera), Rotate's matrix, and the
band averages of the named spectra."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import raylume
from raylume.scene.pbrt_scene import pbrt_document
from raylume.scene.pbrt_spectra import NAMED_RGB
from raylume.scene.pbrt_transform import rotate


def camera_statements(eye, target, fov, width, height, mirror=False) -> str:
    """The pbrt statements of the camera the functions below compute with: LookAt (y up), a
    perspective camera, an RGB film; `Scale -1 1 1` before them when `mirror`."""
    return (
        ("Scale -1 1 1\n" if mirror else "")
        + f"""LookAt {" ".join(map(str, eye))}  {" ".join(map(str, target))}  0 1 0
Camera "perspective" "float fov" {fov}
Film "rgb" "integer xresolution" {width} "integer yresolution" {height}
"""
    )


def pbrt_camera_from_world(eye, target, up, mirror_x=False) -> np.ndarray:
    """pbrt's LookAt (pbrt-v4 transform.cpp): columns right = normalize(cross(up, dir)),
    newUp = cross(dir, right), dir, eye of world-from-camera; the CTM gets its inverse."""
    eye, target, up = (np.asarray(v, dtype=float) for v in (eye, target, up))
    d = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(up / np.linalg.norm(up), d)
    right /= np.linalg.norm(right)
    world_from_camera = np.eye(4)
    world_from_camera[:3, :3] = np.column_stack([right, np.cross(d, right), d])
    world_from_camera[:3, 3] = eye
    m = np.linalg.inv(world_from_camera)
    return np.diag([-1.0, 1, 1, 1]) @ m if mirror_x else m


def screen_window(width: int, height: int):
    """pbrt-v4's default screen window: the shorter side spans [-1, 1]."""
    frame = width / height
    return (-frame, frame, -1.0, 1.0) if frame > 1 else (-1.0, 1.0, -1 / frame, 1 / frame)


def pixel_ray(camera_from_world, fov, width, height, x, y):
    """Origin and direction of pbrt's ray through raster point (x, y) (pixel centres at +0.5)."""
    x0, x1, y0, y1 = screen_window(width, height)
    sx = x0 + x / width * (x1 - x0)
    sy = y1 - y / height * (y1 - y0)  # raster y grows downwards
    t = math.tan(math.radians(fov) / 2)
    world_from_camera = np.linalg.inv(camera_from_world)
    return world_from_camera[:3, 3], world_from_camera[:3, :3] @ np.array([sx * t, sy * t, 1.0])


def project(camera_from_world, fov, width, height, point):
    """The raster position of a world point through pbrt's perspective camera."""
    p = camera_from_world[:3, :3] @ np.asarray(point, dtype=float) + camera_from_world[:3, 3]
    t = math.tan(math.radians(fov) / 2)
    sx, sy = p[0] / p[2] / t, p[1] / p[2] / t
    x0, x1, y0, y1 = screen_window(width, height)
    return (sx - x0) / (x1 - x0) * width, (y1 - sy) / (y1 - y0) * height


@pytest.mark.parametrize(("width", "height"), [(40, 24), (24, 40)])
def test_point_light_irradiance_on_a_plane(tmp_path, width, height):
    """Direct light only (maxdepth 1): each pixel sees rho / pi * I cos(theta) / d^2."""
    eye, target, fov = (1.0, 3.0, -4.0), (0.0, 0.0, 0.5), 50.0
    light, intensity, rho = np.array([0.5, 2.0, 1.0]), np.array([3.0, 2.0, 1.0]), np.array([0.5, 0.25, 0.75])
    (tmp_path / "plane.pbrt").write_text(
        camera_statements(eye, target, fov, width, height)
        + f"""Sampler "independent" "integer pixelsamples" 1
Integrator "path" "integer maxdepth" 1
WorldBegin
LightSource "point" "rgb I" [{" ".join(map(str, intensity))}] "point3 from" [{" ".join(map(str, light))}]
Material "diffuse" "rgb reflectance" [{" ".join(map(str, rho))}]
Shape "bilinearmesh" "point3 P" [-50 0 -50  50 0 -50  -50 0 50  50 0 50]
"""
    )
    image = raylume.render(tmp_path / "plane.pbrt", aovs=False).rgb
    assert image.shape == (height, width, 3)
    m = pbrt_camera_from_world(eye, target, (0, 1, 0))
    checked = 0
    for y in range(height):
        for x in range(width):
            o, d = pixel_ray(m, fov, width, height, x + 0.5, y + 0.5)
            if d[1] >= -1e-3:
                continue
            hit = o - o[1] / d[1] * d
            if max(abs(hit[0]), abs(hit[2])) > 49:
                continue  # past the plane's edge
            to_light = light - hit
            dist2 = float(to_light @ to_light)
            expected = rho / math.pi * intensity * (to_light[1] / math.sqrt(dist2)) / dist2
            np.testing.assert_allclose(image[y, x], expected, rtol=2e-4, err_msg=f"pixel ({x}, {y})")
            checked += 1
    assert checked > width * height // 3


@pytest.mark.parametrize("mirror", [False, True])
def test_a_point_lands_where_pbrts_projection_puts_it(tmp_path, mirror):
    """A small sphere at a known world point, seen by a tilted camera on a portrait film (fov
    spans the width); `Scale -1 1 1` before LookAt mirrors pbrt's image, and raylume's."""
    eye, target, fov, width, height = (0.2, 1.0, -3.0), (0.0, 0.3, 1.0), 35.0, 32, 48
    point = np.array([0.7, 0.4, 1.3])
    (tmp_path / "dot.pbrt").write_text(
        camera_statements(eye, target, fov, width, height, mirror)
        + f"""WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Translate {" ".join(map(str, point))}
Shape "sphere" "float radius" 0.15
"""
    )
    image = raylume.render(tmp_path / "dot.pbrt", mode="cast", spp=1)
    ys, xs = np.nonzero(image.aovs["object"] == 0)
    assert len(xs) >= 4
    expected = project(pbrt_camera_from_world(eye, target, (0, 1, 0), mirror), fov, width, height, point)
    centroid = (xs.mean() + 0.5, ys.mean() + 0.5)
    assert abs(centroid[0] - expected[0]) < 0.5 and abs(centroid[1] - expected[1]) < 0.5, (centroid, expected)
    unmirrored = project(pbrt_camera_from_world(eye, target, (0, 1, 0)), fov, width, height, point)
    if mirror:
        assert abs(expected[0] - unmirrored[0]) > 5  # the mirror moves the dot: the test can tell


def test_rotate_is_pbrts():
    """Rotate 90 about +y turns +x to -z and +z to +x (left-handed, clockwise seen from +y)."""
    m = rotate(90, (0, 2, 0))
    np.testing.assert_allclose(m[:3, :3] @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(m[:3, :3] @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    axis = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    np.testing.assert_allclose(rotate(120, (1, 1, 1))[:3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-12)  # x -> y -> z
    np.testing.assert_allclose(rotate(37, axis)[:3, :3] @ axis, axis, atol=1e-15)


def test_camera_and_depth_of_a_document(tmp_path):
    (tmp_path / "c.pbrt").write_text(
        """
LookAt 1 2 3  4 6 3  0 0 1
Camera "perspective" "float fov" 30 "float lensradius" 0.1 "float focaldistance" 7
Film "rgb" "integer xresolution" 20 "integer yresolution" 40
WorldBegin
"""
    )
    document, messages = pbrt_document(tmp_path / "c.pbrt")
    camera, render = document["camera"], document["render"]
    np.testing.assert_allclose(camera["position"], [1, 2, 3], atol=1e-12)
    np.testing.assert_allclose(np.subtract(camera["look_at"], camera["position"]), [0.6, 0.8, 0], atol=1e-12)
    np.testing.assert_allclose(camera["up"], [0, 0, 1], atol=1e-12)
    # fov spans the shorter side, the width: the height's is wider
    assert camera["fov"] == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(15)) * 2)))
    assert camera["aperture"] == pytest.approx(0.2) and camera["focus_distance"] == 7
    # pbrt-v4's defaults: 16 samples, maxdepth 5 (bounces), i.e. 6 path segments
    assert (render["width"], render["height"], render["spp"], render["max_depth"]) == (20, 40, 16, 6)
    assert render["mode"] == "path" and render["filter"] == "gaussian" and messages == []


def _tool():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    try:
        import pbrt_spectra_rgb
    finally:
        sys.path.pop(0)
    return pbrt_spectra_rgb


def test_named_spectra_are_band_means_of_pbrts_data():
    """Each entry of NAMED_RGB against a plain numpy mean of the spectrum sampled every 0.01 nm."""
    tool = _tool()
    assert set(NAMED_RGB) == set(tool.SOURCE)
    for name, text in tool.SOURCE.items():
        pairs = tool.samples(text)
        lam, val = np.array(pairs[0::2]), np.array(pairs[1::2])
        for band, (lo, hi) in zip(NAMED_RGB[name], ((600, 700), (500, 600), (400, 500))):
            grid = np.linspace(max(lo, lam[0]), min(hi, lam[-1]), 100001)
            assert band == pytest.approx(np.interp(grid, lam, val).mean(), rel=1e-5, abs=2e-6), name
    # gold reflects red more than blue: its k falls and its eta rises towards blue
    eta, k = NAMED_RGB["metal-Au-eta"], NAMED_RGB["metal-Au-k"]
    assert eta[0] < eta[1] < eta[2] and k[0] > k[1] > k[2]


def octant_map(n: int) -> np.ndarray:
    """An equal-area octahedral map coloured by the octant it covers, from the mapping's geometry
    alone: u > 1/2 holds x > 0, v > 1/2 holds y > 0, the inner diamond z > 0."""
    c = (np.arange(n) + 0.5) / n * 2 - 1  # texel centres in [-1, 1]
    u, v = np.meshgrid(c, c)  # u along columns, v down the rows
    return np.stack([u > 0, v > 0, np.abs(u) + np.abs(v) < 1], -1).astype(np.float32)


def test_equal_area_maps_become_equirectangular():
    from raylume.compile.equal_area import equal_area_to_equirectangular

    sky = equal_area_to_equirectangular(octant_map(64))
    assert sky.shape == (64, 128, 3)
    height, width = sky.shape[:2]
    theta = np.pi * (np.arange(height) + 0.5) / height
    phi = 2 * np.pi * ((np.arange(width) + 0.5) / width - 0.5)
    d = np.stack(
        [
            np.outer(np.sin(theta), np.sin(phi)),
            np.outer(np.cos(theta), np.ones(width)),
            np.outer(np.sin(theta), np.cos(phi)),
        ],
        -1,
    )  # raylume's equirectangular directions (kernels/shading/environment.py)
    clear = (np.abs(d) > 0.15).all(axis=-1)
    np.testing.assert_array_equal(sky[clear], (d[clear] > 0).astype(np.float32))


@pytest.mark.filterwarnings("ignore:the scene has no objects")
@pytest.mark.parametrize("mirror", [False, True])
def test_an_image_infinite_light_is_seen_where_pbrt_shows_it(tmp_path, mirror):
    """pbrt's z-up sky turned to y-up by the light's transform (+z of the map to world +y, +y of
    the map to world -z): each pixel's colour is the octant of the light-space direction of
    pbrt's ray through it, mirrored camera included."""
    from raylume.image import save_array

    save_array(tmp_path / "octants.exr", octant_map(64))
    eye, target, fov, width, height = (0.0, 0.0, 0.0), (1.0, 0.5, 1.0), 100.0, 48, 32
    (tmp_path / "sky.pbrt").write_text(
        camera_statements(eye, target, fov, width, height, mirror)
        + """WorldBegin
AttributeBegin
  ConcatTransform [1 0 0 0  0 0 -1 0  0 1 0 0  0 0 0 1]
  LightSource "infinite" "string filename" "octants.exr" "float scale" 2
AttributeEnd
"""
    )
    image = raylume.render(tmp_path / "sky.pbrt", mode="cast", spp=1, aovs=False).rgb
    light_from_world = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # the inverse of the ConcatTransform
    m = pbrt_camera_from_world(eye, target, (0, 1, 0), mirror)
    checked = 0
    for y in range(height):
        for x in range(width):
            _, d = pixel_ray(m, fov, width, height, x + 0.5, y + 0.5)
            w = light_from_world @ (d / np.linalg.norm(d))
            if (np.abs(w) > 0.2).all():
                np.testing.assert_allclose(image[y, x], 2.0 * (w > 0), atol=1e-6, err_msg=f"pixel ({x}, {y})")
                checked += 1
    assert checked > width * height // 4


def test_spectrum_files_are_band_means(tmp_path):
    """`"spectrum eta" "spds/x.spd"`: a file of wavelength, value pairs (pbrt-v4 reads them relative
    to the main file's folder), here a step from 2 to 1 at 550 nm."""
    (tmp_path / "spds").mkdir()
    (tmp_path / "spds" / "step.spd").write_text("# eta\n380 2\n550 2\n550.5 1  # the step\n720 1\n")
    (tmp_path / "s.pbrt").write_text(
        'WorldBegin\nMaterial "conductor" "spectrum eta" "spds/step.spd" "spectrum k" [400 3 700 3]\nShape "sphere"\n'
    )
    document, messages = pbrt_document(tmp_path / "s.pbrt")
    (material,) = document["materials"].values()
    green = (50 * 2 + 0.5 * 1.5 + 49.5 * 1) / 100
    assert material["eta"] == pytest.approx([1.0, green, 2.0]) and material["k"] == pytest.approx([3, 3, 3])
    assert messages == []


SPHERE_PLACEMENT = "Translate 0.3 -0.2 4\nRotate 40 1 2 3\nScale -1.5 1.5 1.5\n"  # a mirror in the CTM too


def textured_sphere_file(path: Path, mirror: bool, radius: float = 0.5) -> None:
    """A sphere under SPHERE_PLACEMENT, an image texture on it, seen from -z."""
    from raylume.image import save_array

    gradient = np.stack([*np.meshgrid(np.linspace(0, 1, 16), np.linspace(0, 1, 8)), np.full((8, 16), 0.5)], -1)
    save_array(path.parent / "uv.png", gradient.astype(np.float32))
    path.write_text(
        camera_statements((0, 0, -1), (0.3, -0.2, 4), 25, 24, 24, mirror)
        + f"""WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Texture "uv" "spectrum" "imagemap" "string filename" "uv.png"
Material "diffuse" "texture reflectance" "uv"
{SPHERE_PLACEMENT}Shape "sphere" "float radius" {radius}
"""
    )


@pytest.mark.parametrize("mirror", [False, True])
def test_a_turned_textured_sphere_has_pbrts_uv(tmp_path, mirror):
    """pbrt-v4's sphere (shapes.h): phi = atan2(y, x) in [0, 2pi) and theta = acos(z / r) in object
    space, u = phi / phimax, v = (theta - thetaZMin) / (thetaZMax - thetaZMin), thetaZMin = pi for
    a whole sphere. Each point of the sphere, placed by the CTM (and a mirrored camera's flip),
    has that (u, v) in raylume: the sphere stays analytic, turned, not tessellated."""
    from raylume.compile import compile_scene
    from raylume.kernels.geometry.shape_sphere import uv as sphere_uv
    from raylume.scene.pbrt_transform import scale, translate

    textured_sphere_file(tmp_path / "ball.pbrt", mirror)
    scene = raylume.load(tmp_path / "ball.pbrt")
    assert [o.type for o in scene.objects] == ["sphere"]
    rows = compile_scene(scene).kernel.shapes
    ctm = translate(0.3, -0.2, 4) @ rotate(40, (1, 2, 3)) @ scale(-1.5, 1.5, 1.5)
    camera = pbrt_camera_from_world((0, 0, -1), (0.3, -0.2, 4), (0, 1, 0))
    # a mirrored camera: raylume mirrors the world in the camera's yz plane instead (pbrt.md)
    flip = np.linalg.inv(camera) @ np.diag([-1.0, 1, 1, 1]) @ camera if mirror else np.eye(4)
    for p in np.random.default_rng(7).normal(size=(100, 3)):
        p = 0.5 * p / np.linalg.norm(p)
        u = (math.atan2(p[1], p[0]) % (2 * math.pi)) / (2 * math.pi)
        v = (math.acos(p[2] / 0.5) - math.pi) / (0.0 - math.pi)
        got_u, got_v = sphere_uv(rows, 0, tuple((flip @ ctm @ [*p, 1.0])[:3]))
        assert (got_u - u + 0.5) % 1.0 - 0.5 == pytest.approx(0.0, abs=1e-9)
        assert got_v == pytest.approx(v, abs=1e-9)


def test_a_turned_textured_sphere_renders_as_the_sphere_written_with_its_transform(tmp_path):
    """The pbrt sphere's picture is that of raylume's sphere given the CTM and pbrt's z-up frame
    (raylume's object x, y, z = pbrt's -y, z, x) as its transform matrix."""
    from raylume.scene.pbrt_transform import scale, translate

    textured_sphere_file(tmp_path / "ball.pbrt", mirror=False)
    imported = raylume.load(tmp_path / "ball.pbrt")
    frame = np.eye(4)
    frame[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, 1, 0]]
    matrix = translate(0.3, -0.2, 4) @ rotate(40, (1, 2, 3)) @ scale(-1.5, 1.5, 1.5) @ frame
    assert_renders_as_the_sphere_written_with(imported, matrix)


def assert_renders_as_the_sphere_written_with(imported, matrix: np.ndarray) -> None:
    """`imported`, one textured sphere of radius 0.5, renders (cast mode) as raylume's sphere of
    the same material and radius placed by `matrix` (4 x 4), written out, where it fills much of
    the picture."""
    written = imported.replace(
        objects=[
            {
                "type": "sphere",
                "center": [0, 0, 0],
                "radius": 0.5,
                "material": imported.objects[0].material,
                "transform": {"matrix": matrix.tolist()},
            }
        ]
    )
    a = raylume.render(imported, mode="cast", spp=1)
    b = raylume.render(written, mode="cast", spp=1).rgb
    assert (a.aovs["object"] == 0).sum() > 100  # the sphere fills much of the picture
    np.testing.assert_allclose(a.rgb, b, atol=1e-5)
