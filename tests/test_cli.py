"""The `raylume` command end to end, as a subprocess: outputs, stats, AOVs, exit codes, no litter."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image as PILImage

GOOD_SCENE = """
[render]
width = 24
height = 16
[[lights]]
type = "point"
position = [0, 3, 0]
intensity = 0.8
[[objects]]
type = "sphere"
center = [0, 0, 3]
radius = 1
material = { color = [1, 0, 0], specular = 50 }
"""


def raylume(*args, cwd):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.run(
        [sys.executable, "-m", "raylume.cli", *map(str, args)], cwd=cwd, capture_output=True, text=True, env=env, timeout=300
    )


def assert_refused(result, *words):
    """The bad-input contract: exit status 2, a message naming each of `words`, no traceback."""
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    for word in words:
        assert word in result.stderr, (word, result.stderr)


@pytest.fixture
def good(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(GOOD_SCENE)
    return path


def test_no_arguments_renders_the_seed_scene_to_render_png(tmp_path):
    result = raylume("render", "--width", 60, "--height", 60, "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    image = np.asarray(PILImage.open(tmp_path / "render.png"))
    assert image.shape == (60, 60, 3)
    assert image[0].max() == 0  # black sky
    assert image[40:, :, 0].mean() > 100  # red sphere and yellow ground


def test_outputs_stats_and_aovs(tmp_path, good):
    result = raylume(
        "render", good, "-o", "out.npy", "--stats", "stats.json", "--aov", "depth=d.npy", "--aov", "normal=n.npy",
        "--aov", "object=o.npy", "--aov", "prim=p.npy", "--quiet", cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    rgb = np.load(tmp_path / "out.npy")
    assert rgb.dtype == np.float32 and rgb.shape == (16, 24, 3)
    depth, normal = np.load(tmp_path / "d.npy"), np.load(tmp_path / "n.npy")
    obj, prim = np.load(tmp_path / "o.npy"), np.load(tmp_path / "p.npy")
    assert depth.dtype == np.float32 and depth.shape == (16, 24)
    assert normal.dtype == np.float32 and normal.shape == (16, 24, 3)
    assert obj.dtype == np.int32 and prim.dtype == np.int32
    hit = obj == 0
    assert hit.any() and (~hit).any()
    assert np.isinf(depth[~hit]).all() and (prim[~hit] == -1).all() and (prim[hit] == 0).all()
    assert depth[hit].min() == pytest.approx(2.0, abs=0.02)  # sphere front at z = 2
    np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=-1), 1, atol=1e-5)
    assert (normal[hit][:, 2] < 0).all()  # faces the camera
    stats = json.loads((tmp_path / "stats.json").read_text())
    for key in ("width", "height", "spp", "mode", "threads", "primitives", "triangles", "rays", "primary_rays",
                "build_seconds", "render_seconds", "mrays_per_second", "bvh_nodes", "bvh_bytes"):
        assert key in stats, key
    assert stats["primary_rays"] == 16 * 24 and stats["rays"] > stats["primary_rays"]
    assert stats["primitives"] == 1 and stats["triangles"] == 0 and stats["mode"] == "trace"


def test_flags_override_the_scene_render_table(tmp_path, good):
    result = raylume("render", good, "--width", 10, "--height", 5, "--mode", "cast", "-o", "c.npy", "-q", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    rgb = np.load(tmp_path / "c.npy")
    assert rgb.shape == (5, 10, 3)
    assert set(np.unique(rgb[..., 0])) <= {0.0, 1.0}  # cast: unlit colour or background


def test_scenes_lists_builtins(tmp_path):
    result = raylume("scenes", cwd=tmp_path)
    assert result.returncode == 0
    assert "seed" in result.stdout and "(default)" in result.stdout


BAD_SCENES = {
    "radius.toml": ('[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = -2\n', "objects[0].radius"),
    "syntax.toml": ("[render\nwidth = 3\n", "line 1"),
    "unknown.toml": ('[camera]\nfov = 40\nzoom = 2\n', "camera.zoom"),
    "material.json": ('{"objects": [{"type": "sphere", "center": [0,0,3], "radius": 1, "material": "x"}]}', "objects[0].material"),
    "mesh.toml": ('[[objects]]\ntype = "mesh"\nfile = "missing.obj"\n', "objects[0].file"),
}


@pytest.mark.parametrize("name", sorted(BAD_SCENES))
def test_bad_scene_exits_2_with_message_and_writes_nothing(tmp_path, name):
    text, key = BAD_SCENES[name]
    (tmp_path / name).write_text(text)
    result = raylume("render", name, "-o", "out.png", "--stats", "s.json", cwd=tmp_path)
    assert_refused(result, name, key)
    assert not (tmp_path / "out.png").exists() and not (tmp_path / "s.json").exists()


@pytest.mark.parametrize(
    "args, words",
    [
        (["--width", "0"], "--width"),
        (["--mode", "photon"], "--mode"),
        (["--spp", "abc"], "spp"),
        (["-o", "out.jpg"], "unknown output format"),
        (["-o", "missing/out.png"], "does not exist"),
        (["--aov", "color=c.npy"], "unknown AOV"),
        (["--aov", "depth"], "NAME=PATH"),
        (["--threads", "0"], "--threads"),
        (["no_such_builtin"], "not a scene file"),
    ],
)
def test_bad_flags_exit_2(tmp_path, args, words):
    result = raylume("render", *args, cwd=tmp_path)
    assert_refused(result, words)
    assert not (tmp_path / "render.png").exists()


def test_existing_output_is_untouched_on_error(tmp_path, good):
    out = tmp_path / "keep.png"
    out.write_bytes(b"precious")
    (tmp_path / "bad.toml").write_text("[render]\nwidth = -1\n")
    assert raylume("render", "bad.toml", "-o", out, cwd=tmp_path).returncode == 2
    assert out.read_bytes() == b"precious"
    # and a good render replaces it completely, leaving no temporary files behind
    assert raylume("render", good, "-o", out, "-q", cwd=tmp_path).returncode == 0
    assert PILImage.open(out).size == (24, 16)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml", "keep.png", "scene.toml"]


def test_output_may_not_overwrite_the_scene(tmp_path, good):
    result = raylume("render", "scene.toml", "--aov", "depth=scene.npy", "-o", "scene.npy", cwd=tmp_path)
    assert result.returncode == 2
    assert good.read_text() == GOOD_SCENE


# Every scene-file entry of the catalogue of bad inputs (docs/errors.md), end to end.
from test_scene_load import BAD as BAD_DOCUMENTS  # noqa: E402


@pytest.mark.parametrize("document, key, words", BAD_DOCUMENTS, ids=[b[1] + ":" + b[2][:12] for b in BAD_DOCUMENTS])
def test_catalogue_of_bad_scene_files_end_to_end(tmp_path, document, key, words):
    (tmp_path / "bad.json").write_text(json.dumps(document))
    result = raylume("render", "bad.json", "-o", "out.png", "--stats", "s.json", cwd=tmp_path)
    assert_refused(result, "bad.json", key, words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]


BAD_MESHES = {
    "empty.obj": ("", "empty"),
    "points.ply": ("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                   "end_header\n0 0 0\n1 1 1\n", "no triangles"),
    "range.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", ""),
    "nan.obj": ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", ""),
    "notply.ply": ("this is not a ply file at all\n", ""),
}


@pytest.mark.parametrize("name", sorted(BAD_MESHES))
def test_catalogue_of_bad_meshes_end_to_end(tmp_path, name):
    text, words = BAD_MESHES[name]
    (tmp_path / name).write_text(text)
    (tmp_path / "scene.toml").write_text(f'[[objects]]\ntype = "mesh"\nfile = "{name}"\n')
    result = raylume("render", "scene.toml", "-o", "out.png", cwd=tmp_path)
    assert_refused(result, "objects[0].file", name, words)
    assert not (tmp_path / "out.png").exists()


def test_mesh_folder_instead_of_file_end_to_end(tmp_path):
    (tmp_path / "dir.obj").mkdir()
    (tmp_path / "scene.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "dir.obj"\n')
    assert_refused(raylume("render", "scene.toml", cwd=tmp_path), "dir.obj")


def test_debug_shows_the_traceback(tmp_path):
    (tmp_path / "bad.toml").write_text("[render]\nwidth = -1\n")
    result = raylume("render", "bad.toml", "--debug", cwd=tmp_path)
    assert result.returncode != 0 and "Traceback" in result.stderr
