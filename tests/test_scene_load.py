"""Scene files: valid documents load; each kind of bad input names the file and the key path."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import raylume
from raylume.errors import SceneError
from raylume.scene.load import load_scene, scene_from_dict
from raylume.scene.overrides import apply_overrides

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_every_example_and_builtin_loads():
    files = sorted(EXAMPLES.glob("*.toml")) + sorted(EXAMPLES.glob("*.json"))
    assert len(files) >= 3
    for path in files:
        assert load_scene(path).objects, path
    for name in raylume.builtin_names():
        assert raylume.builtin_scene(name).objects


def test_example_seed_equals_builtin_seed():
    assert load_scene(EXAMPLES / "seed.toml").model_dump() == raylume.builtin_scene("seed").model_dump()


def test_toml_and_json_give_the_same_scene(tmp_path):
    doc = {
        "render": {"width": 8, "height": 4},
        "materials": {"red": {"color": "#ff0000", "specular": 10}},
        "lights": [{"type": "point", "position": [1, 2, 3], "intensity": [1, 0.5, 0.5]}],
        "objects": [{"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "red"}],
    }
    (tmp_path / "s.json").write_text(json.dumps(doc))
    (tmp_path / "s.toml").write_text(
        '[render]\nwidth = 8\nheight = 4\n[materials.red]\ncolor = "#ff0000"\nspecular = 10\n'
        '[[lights]]\ntype = "point"\nposition = [1, 2, 3]\nintensity = [1, 0.5, 0.5]\n'
        '[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = 1\nmaterial = "red"\n'
    )
    a, b = load_scene(tmp_path / "s.json"), load_scene(tmp_path / "s.toml")
    assert a == b
    assert a.materials["red"].color == (1.0, 0.0, 0.0)
    assert a.base_dir == tmp_path.resolve()
    # with a byte-order mark, as Windows' Notepad saves UTF-8 (both were "invalid" before)
    for name in ("s.json", "s.toml"):
        (tmp_path / f"bom_{name}").write_bytes(b"\xef\xbb\xbf" + (tmp_path / name).read_bytes())
        assert load_scene(tmp_path / f"bom_{name}").model_dump(exclude={"base_dir"}) == a.model_dump(
            exclude={"base_dir"}
        )


def test_a_key_twice_in_one_json_object_is_refused_as_in_toml(tmp_path):
    """json keeps the last of repeated keys: a material written twice lost the first silently."""
    (tmp_path / "twice.json").write_text('{"materials": {"m": {"color": [1, 0, 0]}, "m": {"color": [0, 1, 0]}}}')
    with pytest.raises(SceneError, match=r'twice.json: invalid JSON: the key "m" appears twice in one object$'):
        load_scene(tmp_path / "twice.json")
    (tmp_path / "twice.toml").write_text("[materials.m]\ncolor = [1, 0, 0]\n[materials.m]\ncolor = [0, 1, 0]\n")
    with pytest.raises(SceneError, match="twice.toml: invalid TOML"):
        load_scene(tmp_path / "twice.toml")


def test_defaults_of_an_empty_document():
    s = scene_from_dict({})
    assert (s.render.width, s.render.height, s.render.mode, s.camera.fov) == (600, 600, "trace", 53.13)


BAD = [
    ({"objects": [{"type": "sphere", "center": [0, 0, 3], "radius": -1}]}, "objects[0].radius", "greater than 0"),
    ({"objects": [{"type": "sphere", "center": [0, 0, 3], "radus": 1}]}, "objects[0].radus", "did you mean 'radius'"),
    ({"objects": [{"type": "cube"}]}, "objects[0].type", "sphere, plane, triangle, mesh"),
    ({"objects": [{"type": "sphere", "center": [0, 0], "radius": 1}]}, "objects[0].center", ""),
    (
        {"objects": [{"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "gold"}]},
        "objects[0].material",
        "no material named 'gold'",
    ),
    ({"lights": [{"type": "directional", "direction": [0, 0, 0]}]}, "lights[0].direction", "zero vector"),
    ({"lights": [{"type": "laser"}]}, "lights[0].type", "ambient, point, directional"),
    ({"camera": {"fov": 180}}, "camera.fov", "less than 180"),
    ({"camera": {"fov": 0}}, "camera.fov", "greater than 0"),
    ({"camera": {"look_at": [0, 0, 0]}}, "camera", "look_at must differ"),
    ({"camera": {"look_at": [0, 5, 0]}}, "camera", "parallel"),
    ({"materials": {"m": {"color": ["red", 0, 0]}}}, "materials.m.color", "must be numbers"),
    ({"materials": {"m": {"color": [2, 0, 0]}}}, "materials.m.color", "0..1"),
    ({"materials": {"m": {"color": "#12345"}}}, "materials.m.color", "#rrggbb"),
    ({"materials": {"m": {"reflective": 1.5}}}, "materials.m.reflective", "less than or equal to 1"),
    ({"materials": {"m": {"ior": 0}}}, "materials.m.ior", "greater than 0"),
    ({"render": {"width": 0}}, "render.width", "greater than or equal to 1"),
    ({"render": {"mode": "photon"}}, "render.mode", "'cast', 'trace', 'path' or 'raster'"),
    ({"render": {"spp": 1e9}}, "render.spp", ""),
    ({"rendr": {}}, "rendr", "did you mean 'render'"),
    (
        {"objects": [{"type": "triangle", "vertices": [[0, 0, 0], [1, 1, 1], [2, 2, 2]]}]},
        "objects[0].vertices",
        "collinear",
    ),
    ({"objects": [{"type": "plane", "normal": [0, 0, 0]}]}, "objects[0].normal", "zero vector"),
]


@pytest.mark.parametrize("document, key, words", BAD, ids=[b[1] + ":" + b[2][:12] for b in BAD])
def test_bad_documents_name_the_key(document, key, words):
    with pytest.raises(SceneError) as info:
        scene_from_dict(document, source="scene.toml")
    message = str(info.value)
    assert message.startswith("scene.toml: ")
    assert key in message
    assert words in message


def test_nan_is_rejected_in_json(tmp_path):
    path = tmp_path / "nan.json"
    path.write_text('{"objects": [{"type": "sphere", "center": [0, NaN, 3], "radius": 1}]}')
    with pytest.raises(SceneError, match=r"nan.json: objects\[0\].center"):
        load_scene(path)


def test_syntax_errors_give_line_and_column(tmp_path):
    (tmp_path / "bad.toml").write_text("[render]\nwidth = = 3\n")
    with pytest.raises(SceneError, match=r"bad.toml: invalid TOML: .*line 2"):
        load_scene(tmp_path / "bad.toml")
    (tmp_path / "bad.json").write_text('{"render": {"width": 3,}}')
    with pytest.raises(SceneError, match=r"bad.json: invalid JSON: .*line 1, column"):
        load_scene(tmp_path / "bad.json")


def test_missing_folder_and_wrong_extension(tmp_path):
    with pytest.raises(SceneError, match="no such scene file"):
        load_scene(tmp_path / "missing.toml")
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(SceneError, match="is a folder"):
        load_scene(tmp_path / "dir.toml")
    (tmp_path / "scene.yaml").write_text("render: {}")
    with pytest.raises(SceneError, match=r"\.toml, \.json or \.pbrt"):
        load_scene(tmp_path / "scene.yaml")


def test_unknown_builtin():
    with pytest.raises(SceneError, match="no built-in scene named 'nope'"):
        raylume.builtin_scene("nope")


def test_tiny_but_nonzero_vectors_are_normalised_without_underflow():
    from raylume.compile import compile_scene

    scene = scene_from_dict(
        {
            "lights": [{"type": "directional", "direction": [0, 1e-200, 0]}],
            "objects": [{"type": "plane", "point": [0, -1, 0], "normal": [0, 1e-200, 0]}],
        }
    )
    k = compile_scene(scene).kernel
    np.testing.assert_array_equal(k.shapes[0, 3:6], [0, 1, 0])  # the plane's normal
    np.testing.assert_array_equal(k.light_data[0, :3], [0, 1, 0])
    assert np.isfinite(raylume.render(scene, width=4, height=4).rgb).all()


def _message(document) -> str:
    with pytest.raises(SceneError) as info:
        scene_from_dict(document, source="scene.toml")
    return str(info.value)


SPHERE = {"type": "sphere", "center": [0, 0, 3], "radius": 1}


@pytest.mark.parametrize("key", ["instances", "normal", "zzz"])
def test_unknown_key_gets_no_far_fetched_suggestion(key):
    message = _message({"objects": [{**SPHERE, key: 3}]})
    assert f"objects[0].{key}: unknown key {key!r}" in message
    assert "did you mean" not in message, message


def test_suggestions_come_from_the_keys_valid_at_that_path():
    assert "did you mean 'focus_distance'" in _message({"camera": {"focus_distanse": 2}})
    assert "did you mean 'center'" in _message({"objects": [{**SPHERE, "centre": [0, 0, 3]}]})
    assert "did you mean 'color'" in _message({"materials": {"m": {"colour": [1, 0, 0]}}})
    assert "did you mean 'intensity'" in _message({"lights": [{"type": "ambient", "intensty": 0.1}]})


def test_a_misspelt_required_key_is_one_mistake_said_once():
    """'radus' for a sphere's radius: the unknown key and its suggestion, not also 'radius is
    required'; a required key missing beside an unrelated unknown key is still named."""
    typo = _message({"objects": [{"type": "sphere", "center": [0, 0, 3], "radus": 1}]})
    assert typo == "scene.toml: objects[0].radus: unknown key 'radus' (did you mean 'radius'?)", typo
    both = _message({"objects": [{"type": "sphere", "center": [0, 0, 3], "zzz": 1}]})
    assert "objects[0].radius: this key is required" in both and "unknown key 'zzz'" in both, both


@pytest.mark.parametrize(
    "document, value",
    [
        ({"lights": [{"type": "ambient", "intensity": -1}]}, "-1"),
        ({"materials": {"m": {"color": "#12345"}}}, "'#12345'"),
        ({"render": {"background": "red"}}, "'red'"),
        ({"render": {"width": -1}}, "-1"),
    ],
)
def test_messages_name_the_bad_value_once(document, value):
    message = _message(document)
    assert message.count(value) == 1, message


# ---------------------------------------------------------------- Scene.replace, Scene.with_camera


def test_replace_merges_tables_and_validates_a_copy(tmp_path):
    seed = raylume.builtin_scene("seed")
    scene = seed.replace(camera={"fov": 40}, render={"width": 64}, materials={"red": {"reflective": 0.5}})
    assert scene.camera.fov == 40 and scene.camera.position == seed.camera.position
    assert scene.render.width == 64 and scene.render.height == seed.render.height
    assert scene.materials["red"].reflective == 0.5 and scene.materials["red"].specular == 500
    assert seed.camera.fov == pytest.approx(53.13) and seed.render.width == 600  # the original is unchanged
    lights = scene.replace(lights=[{"type": "ambient", "intensity": 1}]).lights
    assert len(lights) == 1 and lights[0].type == "ambient"  # a list replaces the list
    moved = load_scene(EXAMPLES / "meshes.toml").replace(render={"width": 8})
    assert moved.base_dir == EXAMPLES  # mesh files still found beside the scene file


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"camera": {"fov": 200}}, "camera.fov"),
        ({"camera": {"fovv": 40}}, "did you mean 'fov'"),
        ({"render": {"mode": "paint"}}, "render.mode"),
        ({"objects": [{"type": "sphere", "center": [0, 0, 1]}]}, "objects[0].radius"),
        ({"cameras": {}}, "unknown key 'cameras'"),
    ],
)
def test_replace_errors_name_the_key(changes, words):
    with pytest.raises(SceneError) as info:
        raylume.builtin_scene("seed").replace(**changes)
    assert words in str(info.value)


def test_with_camera_takes_keys_or_a_camera():
    seed = raylume.builtin_scene("seed")
    assert seed.with_camera(fov=30).camera.fov == 30
    moved = seed.with_camera({"position": [0, 1, -3]}, look_at=[0, 0, 3])
    assert moved.camera.position == (0, 1, -3) and moved.camera.look_at == (0, 0, 3)
    camera = raylume.Camera(position=(1, 2, 3), fov=20)
    assert seed.with_camera(camera).camera == camera
    with pytest.raises(SceneError, match="camera"):
        seed.with_camera(up=[0, 0, 1])  # parallel to the view direction


# A value of the wrong type is refused, not coerced as pydantic's lax mode would ("32" -> 32,
# true -> 1, "off" -> False): the document is checked against what each key's words say it takes.
WRONG_TYPES = [
    ({"render": {"width": True}}, "render.width", "a number is needed, got true"),
    ({"render": {"width": "32"}}, "render.width", 'a number is needed, got "32"'),
    ({"render": {"spp": np.True_}}, "render.spp", "a number is needed, got np.True_"),  # (no bool to Python)
    # a list cut short, said of the list (pydantic names each missing place as a required key)
    (
        {"objects": [{"type": "sphere", "center": [0, 3], "radius": 1}]},
        "objects[0].center",
        "too few values: 2 given, 3 needed",
    ),
    ({"camera": {"position": [1]}}, "camera.position", "too few values: 1 given, 3 needed"),
    ({"render": {"texture_filter": "off"}}, "render.texture_filter", 'true or false is needed, got "off"'),
    ({"render": {"denoise": 1}}, "render.denoise", "true or false is needed, got 1"),
    ({"camera": {"fov": "40"}}, "camera.fov", "Input should be a valid number (got '40')"),
    (
        {"objects": [{"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 1, 0], "radius": 1, "capped": "no"}]},
        "objects[0].capped",
        'true or false is needed, got "no"',
    ),
    # untagged unions read as one choice, without pydantic's names of their members
    (
        {
            "objects": [
                {
                    "type": "mesh",
                    "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
                    "faces": [[0, 1, 2]],
                    "transform": {"scale": "big"},
                }
            ]
        },
        "objects[0].transform.scale",
        "expected a number or a list (got 'big')",
    ),
    (
        {
            "objects": [
                {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]], "instances": 5}
            ]
        },
        "objects[0].instances",
        "expected a string or a list (got 5)",
    ),
    # numbers beyond float32's range, in which the kernels store them
    ({"objects": [{"type": "sphere", "center": [0, 0, 1e39], "radius": 1}]}, "objects[0].center[2]", "float32"),
    ({"lights": [{"type": "point", "position": [0, 0, 0], "intensity": 1e39}]}, "lights[0].intensity", "float32"),
]


@pytest.mark.parametrize("document, key, words", WRONG_TYPES, ids=[w[1] + ":" + w[2][:16] for w in WRONG_TYPES])
def test_wrong_types_and_ranges_are_refused_in_words(document, key, words):
    with pytest.raises(SceneError) as info:
        scene_from_dict(document, source="scene.toml")
    message = str(info.value)
    assert message.startswith(f"scene.toml: {key}: "), message
    assert words in message
    assert "function-after" not in message and "tuple[" not in message and "list[" not in message


def test_numbers_of_the_right_type_still_pass():
    s = scene_from_dict(
        {
            "render": {"width": 32.0, "height": np.int64(24), "denoise": np.bool_(False)},
            "camera": {"fov": 40},
            "objects": [{"type": "sphere", "center": [0, 0, 3.4e38], "radius": np.float32(1)}],
        }
    )
    assert (s.render.width, s.render.height, s.render.denoise, s.camera.fov) == (32, 24, False, 40.0)


def test_keys_that_are_no_identifiers_stay_in_the_key_path():
    """A material's name may be any text; only pydantic's names of union members are dropped."""
    with pytest.raises(SceneError) as info:
        scene_from_dict({"materials": {"my-glass": {"ior": -1}, "glass 2": {"colr": 1}}}, source="s.toml")
    assert str(info.value).startswith("s.toml: materials.my-glass.ior: Input should be greater than 0")
    assert "materials.glass 2.colr: unknown key 'colr'" in str(info.value)


def test_a_union_member_the_value_has_reports_its_own_problem():
    """instances given as a list: the list's problems, named by index, not the string member's."""
    bad = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    singular = [[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    mesh = {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}
    with pytest.raises(SceneError) as info:
        scene_from_dict({"objects": [{**mesh, "instances": [{"matrix": bad}, {"matrix": singular}]}]}, source="s.toml")
    assert str(info.value) == "s.toml: objects[0].instances[1]: matrix is singular (it flattens the object)"


@pytest.fixture
def default_recursion_limit():
    """Python's default recursion limit, which the `raylume` command runs under (a test worker's
    may be raised, and deep documents would then parse and copy)."""
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(1000)
    yield
    sys.setrecursionlimit(old)


def test_documents_nested_too_deeply_name_the_file_and_the_key(tmp_path, default_recursion_limit):
    """Python's recursion gives out in the parser (TOML past ~1000 levels, JSON sooner under a deep
    stack), or in the copy and the validation: one line naming the file, and the key where the
    document can be walked to."""
    deep: list = []
    inner = deep
    for _ in range(2000):
        inner.append([])
        inner = inner[0]
    with pytest.raises(
        SceneError, match=r"^s.toml: extra\[0\]\[0\]\[0\]\.\.\.: tables or lists nested more than 64 levels"
    ):
        apply_overrides({"render": {"width": 8}, "extra": deep}, None, "s.toml")
    (tmp_path / "deep.json").write_text('{"render": {"width": 8}, "extra": ' + "[" * 2000 + "]" * 2000 + "}")
    with pytest.raises(
        SceneError, match=r"deep.json: (extra\[0\]\[0\]\[0\]\.\.\.: tables or lists nested more|invalid JSON: tables)"
    ):
        load_scene(tmp_path / "deep.json")
    (tmp_path / "deep.toml").write_text("[camera]\nfov = " + "[" * 1200 + "]" * 1200 + "\n")
    with pytest.raises(SceneError, match=r"deep.toml: invalid TOML: tables or lists nested too deeply"):
        load_scene(tmp_path / "deep.toml")
    with pytest.raises(SceneError, match=r"--set camera.fov: tables or lists nested too deeply"):
        load_scene(EXAMPLES / "seed.toml", overrides=["camera.fov=" + "[" * 1200 + "]" * 1200])


def test_integers_of_thousands_of_digits_name_the_file_and_line(tmp_path):
    """Python converts integers of at most 4300 digits; past that, its own advice (sys.set_int_max_str_digits)
    is no help to a user."""
    (tmp_path / "big.toml").write_text("[render]\nwidth = " + "9" * 5000 + "\n")
    with pytest.raises(SceneError, match=r"^.*big.toml: invalid TOML: line 2: a number of 5000 digits$"):
        load_scene(tmp_path / "big.toml")
    (tmp_path / "big.json").write_text('{"render": {"width": ' + "9" * 5000 + "}}")
    with pytest.raises(SceneError, match=r"^.*big.json: invalid JSON: line 1: a number of 5000 digits$"):
        load_scene(tmp_path / "big.json")
    with pytest.raises(SceneError, match=r"^--set render.width: a number of more than \d+ digits$"):
        load_scene(EXAMPLES / "seed.toml", overrides=["render.width=" + "9" * 5000])
