"""The Python API as a Python developer meets it: numpy's copy protocol, what a type checker reads
(the py.typed marker, pydantic defaults given by keyword, intersect's overloads), numpy values
and pathlib paths in scenes built in code, short reprs, and errors that are SceneErrors naming
the key wherever a scene is made or changed."""

from __future__ import annotations

import ast
import typing
import warnings
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage
from test_gltf import Builder, two_squares

import raylume
from raylume.image import encode_8bit

SRC = Path(__file__).parent.parent / "src" / "raylume"
EXAMPLES = Path(__file__).parent.parent / "examples"


@pytest.fixture(scope="module")
def image():
    return raylume.render("seed", width=16, height=12, mode="cast")


# ---------------------------------------------------------------- numpy's array protocol


def test_numpy_copies_of_an_image_are_copies(image):
    """numpy 2's protocol: np.copy and np.array copy (they had handed back the image's own
    buffer, so editing the copy changed the image); np.asarray does not; copy=False refuses a
    conversion that needs one."""
    before = image.rgb.copy()
    for copy in (np.copy(image), np.array(image), np.array(image, copy=True)):
        assert not np.shares_memory(copy, image.rgb)
        copy[:] = 7.0
    assert np.array_equal(image.rgb, before)
    assert np.shares_memory(np.asarray(image), image.rgb)
    assert np.asarray(image, dtype=np.float64).dtype == np.float64
    with pytest.raises(ValueError):
        np.array(image, dtype=np.float64, copy=False)


# ---------------------------------------------------------------- what type checkers read


def test_the_package_carries_the_pep_561_marker():
    """Without py.typed, mypy refuses to read the annotations (import-untyped)."""
    assert (SRC / "py.typed").is_file()


def test_model_defaults_are_given_by_keyword():
    """Type checkers (PEP 681) read a pydantic field's default from Field(default=...) alone:
    with Field(53.13, ...), `raylume.Camera(position=...)` was an error in mypy and pyright
    ("missing named argument fov")."""
    positional = []
    for path in sorted((SRC / "scene").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "Field" and node.args:
                positional.append(f"{path.name}:{node.lineno}")
    assert not positional, positional


def test_intersect_is_typed_by_its_instances_argument():
    """`t, obj, prim = raylume.intersect(...)`, the guide's call, checks as a 3-tuple."""
    overloads = typing.get_overloads(raylume.intersect)
    returns = {
        repr(o.__annotations__["instances"]): o.__annotations__["return"] for o in overloads
    }  # (annotations are strings: the module defers them)
    assert returns["'Literal[False]'"].count("np.ndarray") == 3
    assert returns["'Literal[True]'"].count("np.ndarray") == 4


# ---------------------------------------------------------------- scenes built in code


def _sphere_scene(material=None, light=None, background=None):
    document = {
        "lights": [light or {"type": "ambient", "intensity": 0.2}],
        "objects": [{"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": material or {}}],
    }
    if background is not None:
        document["render"] = {"background": background}
    return raylume.scene_from_dict(document)


def test_colours_computed_with_numpy_are_taken_as_lists_are():
    """Positions took numpy values; colours refused them ("colour components must be numbers,
    got np.int64(1)")."""
    plain = _sphere_scene(
        {"color": [1.0, 0.5, 0.0]}, {"type": "point", "position": [2, 2, 0], "intensity": 0.5}, [0.1] * 3
    )
    for colour, intensity, background in [
        (np.array([1.0, 0.5, 0.0]), np.float32(0.5), np.array([0.1, 0.1, 0.1])),
        ([np.int64(1), np.float32(0.5), 0], np.array([0.5, 0.5, 0.5]), [np.float64(0.1)] * 3),
    ]:
        light = {"type": "point", "position": [2, 2, 0], "intensity": intensity}
        scene = _sphere_scene({"color": colour}, light, background)
        assert scene.objects[0].material.color == plain.objects[0].material.color
        assert scene.lights[0].intensity == plain.lights[0].intensity
        assert scene.render.background == pytest.approx(plain.render.background)
    with pytest.raises(raylume.SceneError, match="colour components must be numbers"):
        _sphere_scene({"color": [np.True_, 0, 0]})  # numpy's bool is no number
    with pytest.raises(raylume.SceneError, match="a colour is"):
        _sphere_scene({"color": np.zeros(4)})


def test_paths_name_files_in_scenes_built_in_code():
    """A pathlib.Path where the scene names a file (it was "Input should be a valid string")."""
    by_path = raylume.scene_from_dict(
        {
            "lights": [{"type": "ambient", "intensity": 1}],
            "objects": [{"type": "mesh", "file": EXAMPLES / "meshes" / "teapot.obj"}],
            "environment": {"file": EXAMPLES / "sky.hdr"},
        }
    )
    assert by_path.objects[0].file == str(EXAMPLES / "meshes" / "teapot.obj")
    assert by_path.environment.file == str(EXAMPLES / "sky.hdr")


def test_a_large_inline_mesh_has_a_short_repr():
    """repr(scene) of a 100k-triangle numpy mesh was 21 MB of text (a notebook cell's `scene`)."""
    vertices = np.random.default_rng(1).random((30_000, 3))
    faces = np.arange(30_000).reshape(-1, 3)
    scene = raylume.scene_from_dict(
        {
            "lights": [{"type": "ambient", "intensity": 1}],
            "objects": [{"type": "mesh", "vertices": vertices, "faces": faces}],
        }
    )
    text = repr(scene)
    assert len(text) < 3000, len(text)
    assert "... 30000 items" in text and "... 10000 items" in text
    assert repr(raylume.builtin_scene("seed")).count("Sphere(") == 4  # short lists are shown whole


def test_float16_vertices_raise_no_numpy_warning_of_raylume_s_own():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        raylume.scene_from_dict(
            {
                "lights": [{"type": "ambient", "intensity": 1}],
                "objects": [{"type": "mesh", "vertices": np.eye(3, dtype=np.float16), "faces": [[0, 1, 2]]}],
            }
        )


# ---------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda seed: seed.with_render(widht=3), "Scene.with_render: render.widht: unknown key 'widht' (did you mean"),
        (lambda seed: seed.with_render(width=0), "Scene.with_render: render.width"),
        (lambda seed: seed.with_camera(fov=200), "Scene.with_camera: camera.fov"),
        (lambda seed: raylume.Camera(positon=(1, 2, 3)), "raylume.Camera: positon: unknown key 'positon'"),
        (lambda seed: raylume.Camera(fov=500), "raylume.Camera: fov: Input should be less than 180"),
        (lambda seed: raylume.Camera(up=(0, 0, 1)), "up must not be parallel"),
    ],
)
def test_scenes_made_or_changed_in_code_raise_one_line_scene_errors(make, words):
    """with_render and the models' constructors let pydantic's multi-line ValidationError out;
    the guide's `except raylume.SceneError` did not catch it."""
    with pytest.raises(raylume.SceneError) as info:
        make(raylume.builtin_scene("seed"))
    assert words in str(info.value) and "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)  # as pydantic's error was


def test_image_display_settings_are_checked_when_given(image):
    for bad, words in [
        ({"encoding": "sRGB"}, "unknown encoding"),
        ({"tonemap": "bogus"}, "unknown tonemap"),
        ({"exposure": 1e9}, "exposure must be"),
    ]:
        with pytest.raises(ValueError, match=words):
            raylume.Image(image.rgb, **bad)
        with pytest.raises(ValueError, match=words):
            image.to_uint8(**bad)
    with pytest.raises(ValueError, match=r"shape \(H, W, 3\)"):
        raylume.Image(np.zeros((4, 4)))


def test_save_takes_a_tonemap(image, tmp_path):
    bright = raylume.Image(image.rgb * 8)
    bright.save(tmp_path / "aces.png", tonemap="aces")
    written = np.asarray(PILImage.open(tmp_path / "aces.png").convert("RGB"))
    assert np.array_equal(written, encode_8bit(bright.rgb, "clamp", 0.0, "aces"))
    assert not np.array_equal(written, bright.to_uint8())  # (the image's own tonemap is none)


# ---------------------------------------------------------------- what the command line has


def test_render_and_session_default_to_the_seed_scene():
    small = dict(width=12, height=8, mode="cast", aovs=False)
    seed = raylume.render("seed", **small)
    assert np.array_equal(raylume.render(**small).rgb, seed.rgb)
    assert np.array_equal(raylume.Session().render(**small).rgb, seed.rgb)


def test_a_gltf_camera_is_chosen_by_name_from_python(tmp_path):
    """As `raylume render FILE.glb --camera NAME`; files without cameras refuse the argument, and
    arguments a Scene object cannot take are refused (defines= had been ignored)."""
    b = Builder()
    two_squares(b)
    b.camera(0.5, name="wide", translation=[0, 0, 9])
    b.camera(0.7, name="close", translation=[0, 0, 4])
    path = b.glb(tmp_path / "cams.glb")
    assert raylume.load(path).camera.position == (0.0, 0.0, -9.0)
    assert raylume.load(path, camera="close").camera.position == (0.0, 0.0, -4.0)
    with pytest.raises(raylume.SceneError, match="glTF files alone"):
        raylume.load(EXAMPLES / "glass.toml", camera="close")
    with pytest.raises(raylume.SceneError, match="defines= applies to a file"):
        raylume.render(raylume.builtin_scene("seed"), defines={"spp": "4"})
