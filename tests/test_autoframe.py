"""A mesh file as the whole scene (`raylume render model.obj`): framed, facing the camera, lit.

The test model is authored right-handed, +y up, front towards +z (as glTF and most OBJ files):
a flat body, a nose sticking out of its front (+z) and an arm towards +x. A glTF viewer shows
it from the front: the nose towards the viewer, the arm on the right."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from test_cli import raylume as run_cli

import raylume
from raylume.scene.autoframe import MARGIN, frame


def _box(center, extents):
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(center)
    return box


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    body = _box((0, 0, 0), (2, 2, 0.5))  # z from -0.25 to 0.25
    nose = _box((0, 0, 0.625), (0.4, 0.4, 0.75))  # the front: out to z = 1
    arm = _box((1.5, 0, 0), (1, 0.4, 0.4))  # +x: out to x = 2
    path = tmp_path_factory.mktemp("model") / "model.obj"
    trimesh.util.concatenate([body, nose, arm]).export(path)
    return path


def _hits(image):
    return image.aovs["object"] == 0


def test_a_mesh_file_is_framed_with_its_front_and_right_side_as_a_viewer_shows_them(model):
    scene = raylume.load_scene(model)
    image = raylume.render(scene, width=96, height=72, spp=1)
    hit = _hits(image)
    rows, cols = np.nonzero(hit)
    # framed: the whole model is in view, away from the borders, and fills a good part of it
    assert rows.min() > 2 and cols.min() > 2 and rows.max() < 69 and cols.max() < 93
    assert (cols.max() - cols.min()) > 0.4 * 96
    # +x on the right: the right-hand columns hold the thin arm, the left-hand ones the tall body
    left, right = hit[:, cols.min() : cols.min() + 8].sum(axis=0), hit[:, cols.max() - 7 : cols.max() + 1].sum(axis=0)
    assert right.mean() < 0.5 * left.mean()
    # the front faces the camera: the nearest surface is the nose's small tip, not a whole side
    depth = image.aovs["depth"][hit]
    nearest = np.abs(depth - depth.min()) < 0.05
    assert 0 < nearest.sum() < 0.1 * hit.sum()
    assert scene.objects[0].handedness == "right"


def test_the_default_rig_lights_every_side_without_clipping(model):
    image = raylume.render(raylume.load_scene(model), width=64, height=48)
    lit = image.rgb[_hits(image)].mean(axis=1)
    assert lit.min() > 0.08  # ambient light: no side black
    assert np.median(lit) > 0.3 and lit.max() < 1.0  # key and fill light, no clipping
    assert len(raylume.load_scene(model).lights) == 3


def test_framing_fits_the_bounding_sphere_in_the_narrower_field_of_view():
    lo, hi = np.array([-1.0, -2.0, -3.0]), np.array([1.0, 2.0, 3.0])
    camera = raylume.Camera(fov=60)
    radius = np.linalg.norm(hi - lo) / 2
    landscape = frame(lo, hi, camera, 2.0)
    assert landscape["look_at"] == [0, 0, 0]
    assert np.linalg.norm(landscape["position"]) == pytest.approx(MARGIN * radius / np.sin(np.radians(30)))
    portrait = frame(lo, hi, camera, 0.5)  # the horizontal half-angle: atan(tan(30 deg) / 2)
    half = np.arctan(np.tan(np.radians(30)) * 0.5)
    assert np.linalg.norm(portrait["position"]) == pytest.approx(MARGIN * radius / np.sin(half))
    assert frame(lo, hi, camera, 1.0, {"position"}) == {"look_at": [0, 0, 0]}


def test_set_keys_edit_the_mesh_scene_and_the_framing_follows(model):
    scene = raylume.load_scene(model, overrides=["camera.fov=30", "render.mode=cast", "lights.1.intensity=0.3"])
    default = raylume.load_scene(model)
    assert scene.camera.fov == 30 and scene.render.mode == "cast" and scene.lights[1].intensity == (0.3,) * 3
    assert scene.camera.position[2] < default.camera.position[2] < 0  # narrower view: further away
    placed = raylume.load_scene(model, overrides=["camera.position=[0, 5, -5]"])
    assert placed.camera.position == (0, 5, -5) and placed.camera.look_at == default.camera.look_at


@pytest.mark.parametrize(("flags", "shape"), [(["--width", "24"], (24, 24)), (["--height", "20"], (20, 20))])
def test_one_side_given_keeps_a_mesh_file_s_square_image(model, tmp_path, flags, shape):
    # the default image is 600 x 600; a flag's one side made it 24 x 600 before
    result = run_cli("render", model, *flags, "--mode", "cast", "-o", "out.npy", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert np.load(tmp_path / "out.npy").shape[:2] == shape
    scene = raylume.load_scene(model, overrides=["render.height=30"])
    assert (scene.render.width, scene.render.height) == (600, 30)


def test_render_a_mesh_file_from_the_command_line_with_flags_and_set(model, tmp_path):
    result = run_cli(
        "render",
        model,
        "--width",
        40,
        "--height",
        60,
        "--mode",
        "cast",
        "--set",
        "camera.fov=30",
        "-o",
        "out.npy",
        "--aov",
        "object=o.npy",
        "--stats",
        "s.json",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr, result.stderr
    assert np.load(tmp_path / "out.npy").shape == (60, 40, 3)
    hit = np.load(tmp_path / "o.npy") == 0
    rows, cols = np.nonzero(hit)
    assert cols.min() > 0 and cols.max() < 39 and rows.min() > 0 and rows.max() < 59  # portrait: still framed
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["mode"] == "cast" and stats["triangles"] == 36


def test_a_missing_or_broken_mesh_file_is_refused_naming_it(tmp_path):
    from test_cli import assert_refused

    assert_refused(run_cli("render", "missing.obj", cwd=tmp_path), "missing.obj", "does not exist")
    (tmp_path / "broken.ply").write_text("ply\nformat nonsense\n")
    assert_refused(run_cli("render", "broken.ply", cwd=tmp_path), "broken.ply")
    assert list(tmp_path.iterdir()) == [tmp_path / "broken.ply"]
