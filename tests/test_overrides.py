"""--set KEY=VALUE: dotted key paths into the scene document, values parsed as TOML, applied
before validation (DESIGN.md section 6)."""

from __future__ import annotations

import json

import pytest
from test_cli import raylume as run_cli

import raylume
from raylume.errors import SceneError
from raylume.scene.load import load_scene
from raylume.scene.overrides import apply_overrides, parse_assignment

DOC = {
    "camera": {"fov": 50},
    "materials": {"glass": {"ior": 1.5}},
    "objects": [{"type": "sphere", "center": [0, 0, 3], "radius": 1}] * 3,
}


@pytest.mark.parametrize(
    "text, path, value",
    [
        ("camera.fov=40", ["camera", "fov"], 40),
        ("materials.glass.ior=1.33", ["materials", "glass", "ior"], 1.33),
        ("camera.position=[0, 1, -3]", ["camera", "position"], [0, 1, -3]),
        ('render.mode="cast"', ["render", "mode"], "cast"),
        ("render.mode=cast", ["render", "mode"], "cast"),
        ("render.mode = cast ", ["render", "mode"], "cast"),
        ("m.t={ type = 'checker', scale = 2 }", ["m", "t"], {"type": "checker", "scale": 2}),
        ("render.background=#ff0000", ["render", "background"], "#ff0000"),
        ("render.denoise=true", ["render", "denoise"], True),
        ("a.b=x=y", ["a", "b"], "x=y"),
    ],
)
def test_parse_assignment(text, path, value):
    assert parse_assignment(text) == (path, value)


@pytest.mark.parametrize("text", ["camera.fov", "=3", "camera..fov=3", ".fov=3", "camera.=3"])
def test_parse_assignment_refuses_malformed_keys(text):
    with pytest.raises(SceneError, match="--set"):
        parse_assignment(text)


def test_apply_edits_a_copy():
    doc = json.loads(json.dumps(DOC))
    out = apply_overrides(doc, ["camera.fov=40", "materials.glass.ior=1.33", "objects.2.radius=0.5"])
    assert out["camera"]["fov"] == 40 and out["materials"]["glass"]["ior"] == 1.33
    assert [o["radius"] for o in out["objects"]] == [1, 1, 0.5]
    assert doc == DOC  # the input is untouched


def test_missing_tables_are_created():
    out = apply_overrides({}, ["camera.fov=30", "materials.new.color=[1, 0, 0]"])
    assert out == {"camera": {"fov": 30}, "materials": {"new": {"color": [1, 0, 0]}}}


@pytest.mark.parametrize(
    "assignment, words",
    [
        ("objects.3.radius=1", ["objects.3", "out of range", "3 items"]),
        ("objects.x.radius=1", ["objects.x", "index"]),
        ("objects.-1.radius=1", ["objects.-1"]),
        ("camera.fov.x=1", ["camera.fov", "not a table"]),
        ("lights.0.type=point", ["lights.0", "no list"]),
    ],
)
def test_bad_paths_name_the_key_path(assignment, words):
    with pytest.raises(SceneError) as info:
        apply_overrides(DOC, [assignment])
    for word in ["--set", *words]:
        assert word in str(info.value), (word, str(info.value))


def test_load_scene_validates_after_overrides(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = 1\n')
    scene = load_scene(path, overrides=["camera.fov=30", "objects.0.radius=0.5", "render.mode=cast"])
    assert scene.camera.fov == 30 and scene.objects[0].radius == 0.5 and scene.render.mode == "cast"
    assert scene.base_dir == tmp_path.resolve()
    with pytest.raises(SceneError) as info:
        load_scene(path, overrides=["objects.0.radius=-2"])
    message = str(info.value)
    assert message.startswith(f"{path}") and "objects[0].radius" in message and "--set objects.0.radius=-2" in message
    with pytest.raises(SceneError, match=r"camera.zoom: unknown key 'zoom'"):
        load_scene(path, overrides=["camera.zoom=2"])


def test_an_error_a_set_caused_names_it(tmp_path):
    """command-line.md: "an error caused by a --set says which one": also where the --set
    changed a table's type (every key of the table is then judged by it), and where the error
    is found after validation (a texture file that does not exist)."""
    path = tmp_path / "s.toml"
    path.write_text('[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = 1\n')
    with pytest.raises(
        SceneError, match=r"objects\[0\].radius: unknown key 'radius' \(set by --set objects.0.type=plane\)"
    ):
        load_scene(path, overrides=["objects.0.type=plane"])
    texture = 'objects.0.material.texture={type="image", file="gone.png"}'
    result = run_cli("render", path, "-o", "o.png", "-q", "--mode", "cast", "--set", "render.width=8", "--set", texture,
                     cwd=tmp_path)  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert result.stderr.rstrip().endswith(
        """ does not exist (set by --set objects.0.material.texture={type="image", file="gone.png"})"""
    ), result.stderr


def test_json_scenes_and_builtins_take_overrides(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"camera": {"fov": 50}}))
    assert load_scene(path, overrides={"camera.fov": 20}).camera.fov == 20
    seed = raylume.builtin_scene("seed", overrides=["render.width=64", "objects.0.radius=0.5"])
    assert seed.render.width == 64 and seed.objects[0].radius == 0.5
