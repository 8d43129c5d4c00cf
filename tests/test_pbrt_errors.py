"""pbrt-v4 files that raylume refuses (one line naming the file, the line and the directive; exit
status 2 and no output from the command line) or reads with a warning naming what it replaced."""

from __future__ import annotations

import os
import sys
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_cli import assert_refused, raylume

from raylume.compile import compile_scene
from raylume.errors import SceneError
from raylume.scene.checks import SceneWarning
from raylume.scene.load import load_scene
from raylume.scene.pbrt_scene import pbrt_document
from raylume.scene.pbrt_tokens import PbrtError, tokenize

# the command line in a new process imports the raylume these tests import
THIS_RAYLUME = {"PYTHONPATH": os.pathsep.join(sys.path)}

CAMERA = 'Film "rgb" "integer xresolution" 8 "integer yresolution" 8\nWorldBegin\n'


def refused(tmp_path, text: str, *words: str, name: str = "bad.pbrt"):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(PbrtError) as info:
        pbrt_document(path)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, (word, message)
    return message


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (CAMERA + 'Shape "sphere" "float radius" [ 1\n', ["bad.pbrt:3", "Shape", '"float radius"', "]"]),
        (CAMERA + 'Shape "sphere"\n  "float radius" "one"\n', ["bad.pbrt:4", "Shape", "expected numbers"]),
        (CAMERA + 'Shape "sphere" "radius" 1\n', ["bad.pbrt:3", '"radius"', "type name"]),
        (CAMERA + 'Shape "sphere" "real radius" 1\n', ["bad.pbrt:3", "unknown type 'real'"]),
        (CAMERA + 'Material "diffuse" "rgb reflectance" [1 0]\n', ["bad.pbrt:3", "rgb", "whole number"]),
        (CAMERA + 'Shape "sphere" "float radius" 1 "float radius" 2\n', ["bad.pbrt:3", 'Shape "sphere"', "twice"]),
        (CAMERA + "Frobnicate 1 2 3\n", ["bad.pbrt:3", "unknown directive 'Frobnicate'"]),
        (CAMERA + "Translate 1 2\nShape", ["bad.pbrt:4", "Translate", "expected a number, got 'Shape'"]),
        (CAMERA + 'Texture "t" "spectrum" "imagemap" "string filename" "nope.png"\n', ["bad.pbrt:3", "nope.png"]),
        (
            CAMERA + 'Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 3]\n',
            ["bad.pbrt:3", 'Shape "trianglemesh"', "indices", "vertex 3"],
        ),
        (CAMERA + 'Shape "plymesh" "string filename" "missing.ply"\n', ["bad.pbrt:3", "plymesh", "missing.ply"]),
        (CAMERA + 'NamedMaterial "glass"\n', ["bad.pbrt:3", "NamedMaterial", "'glass'"]),
        (CAMERA + 'ObjectInstance "tree"\n', ["bad.pbrt:3", "ObjectInstance", "'tree'"]),
        (CAMERA + "AttributeEnd\n", ["bad.pbrt:3", "AttributeEnd", "no matching"]),
        (CAMERA + "AttributeBegin\nTranslate 1 0 0\n", ["bad.pbrt:3", "AttributeBegin", "never closed"]),
        ('Camera "orthographic"\n' + CAMERA, ["bad.pbrt:1", 'Camera "orthographic"', "perspective"]),
        (CAMERA + 'Material "conductor" "spectrum eta" "metal-Unobtainium-eta"\n', ["bad.pbrt:3", "Unobtainium"]),
        (CAMERA + "LookAt 0 0 0  0 0 0  0 1 0\n", ["bad.pbrt:3", "LookAt", "same"]),
        (CAMERA + 'Include "nowhere.pbrt"\n', ["bad.pbrt:3", "Include", "nowhere.pbrt"]),
        (CAMERA + 'Include "bad.pbrt"\n', ["bad.pbrt:3", "includes itself"]),
        (CAMERA + 'LightSource "infinite" "string filename" "sky.exr"\n', ["bad.pbrt:3", "sky.exr"]),
    ],
)
def test_bad_files_are_refused_with_file_and_line(tmp_path, text, words):
    refused(tmp_path, text, *words)


def test_tokenizer_errors_name_the_line(tmp_path):
    with pytest.raises(PbrtError, match=r"x.pbrt:2: unterminated string"):
        tokenize('WorldBegin\nShape "sphere\n', tmp_path / "x.pbrt")
    with pytest.raises(PbrtError, match=r"x.pbrt:3: unexpected '@1'"):
        tokenize('# a comment with "quotes" and [brackets\n\nTranslate @1 0 0\n', tmp_path / "x.pbrt")
    tokens = tokenize('Shape "a # not a \\"comment\\"" [ 1\n -2.5e1 ] # comment\ntrue ["x" 2] 3', tmp_path / "x.pbrt")
    assert [(t.kind, t.value, t.line) for t in tokens] == [
        ("word", "Shape", 1),
        ("string", 'a # not a "comment"', 1),
        ("numbers", [1.0, -25.0], 1),  # a list of numbers is one token
        ("word", "true", 3),
        ("[", "[", 3),
        ("string", "x", 3),
        ("number", 2.0, 3),
        ("]", "]", 3),
        ("number", 3.0, 3),
    ]
    with pytest.raises(PbrtError, match=r"x.pbrt:2: unexpected '1.2.3'"):
        tokenize("\n[0 1.2.3]", tmp_path / "x.pbrt")


def test_an_error_in_an_included_file_names_that_file(tmp_path):
    (tmp_path / "inc").mkdir()
    (tmp_path / "inc" / "part.pbrt").write_text('\n\nShape "sphere" "float radius" -1\n')
    message = refused(tmp_path, CAMERA + 'Include "inc/part.pbrt"\n', "part.pbrt:3", 'Shape "sphere"', "radius")
    assert "bad.pbrt" not in message


def test_image_infinite_lights_need_exr_or_hdr(tmp_path):
    (tmp_path / "sky.png").write_bytes(b"")
    refused(tmp_path, CAMERA + 'LightSource "infinite" "string filename" "sky.png"\n', "bad.pbrt:3", ".exr or .hdr")


OPTIONS = ("Camera", "Film", "Sampler", "Integrator", "PixelFilter", "Accelerator", "Option")


def warned(tmp_path, text: str) -> list[str]:
    path = tmp_path / "w.pbrt"
    option = text.split(" ", 1)[0] in OPTIONS  # (pbrt sets options before WorldBegin)
    path.write_text(text + CAMERA if option else CAMERA + text)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_scene(path)
    return [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('Shape "curve" "point3 P" [0 0 0 1 0 0 1 1 0 0 1 0]\n', ['w.pbrt:3: Shape "curve"', "left out"]),
        ('Shape "sphere" "float radius" 1 "float wobble" 2\n', ['Shape "sphere"', '"float wobble"', "ignored"]),
        ('Shape "sphere" "float phimax" 180\n', ['Shape "sphere"', "partial sphere", "tessellated"]),
        ('Scale 1 2 1\nShape "sphere"\n', ["w.pbrt:4", "non-uniform scale", "tessellated"]),
        ('MakeNamedMedium "fog" "string type" "homogeneous"\n', ["MakeNamedMedium", "media", "ignored"]),
        ('Material "hair"\nShape "sphere"\n', ['Material "hair"', "grey diffuse"]),
        ('AreaLightSource "diffuse" "rgb L" [1 1 1]\nShape "disk"\n', ["w.pbrt:4", "both sides"]),
        ('AreaLightSource "diffuse"\nReverseOrientation\nShape "sphere"\n', ["w.pbrt:5", "inwards"]),
        (
            'Texture "c" "spectrum" "checkerboard" "float uscale" 4 "float vscale" 4\n'
            'Material "diffuse" "texture reflectance" "c"\nShape "sphere"\n',
            ['Texture "c"', "2D (uv) checkerboard", "0.25"],
        ),
        ('PixelFilter "sinc"\n', ['PixelFilter "sinc"', "gaussian"]),
        ('LightSource "goniometric"\n', ["goniometric", "left out"]),
        ('Integrator "sppm"\n', ['Integrator "sppm"', "path tracer"]),
    ],
)
def test_unsupported_input_is_named_in_a_warning(tmp_path, text, words):
    messages = warned(tmp_path, text)
    assert any(all(word in m for word in words) for m in messages), messages


@pytest.mark.parametrize(
    ("shape", "why"),
    [
        ('"sphere" "float zmin" 0.5 "float zmax" 0.5', "zmin 0.5 and zmax 0.5 cut the whole sphere"),
        ('"sphere" "float zmin" 2 "float zmax" 3', "zmin 2 and zmax 3 cut the whole sphere"),
        ('"sphere" "float phimax" 0', "phimax 0"),
        ('"cylinder" "float phimax" -10', "phimax -10"),
        ('"disk" "float radius" 1 "float innerradius" 1', "innerradius 1 is not less than radius 1"),
    ],
)
def test_a_shape_without_surface_is_left_out_with_a_warning(tmp_path, shape, why):
    """pbrt's sphere between thetaZMin = thetaZMax, a sweep of phimax <= 0 and a disk whose hole
    is as wide as it have no area: pbrt draws nothing of them. raylume leaves them out and says
    so (it refused them with an error about an inline mesh's missing faces)."""
    messages = warned(tmp_path, f'Shape {shape}\nShape "sphere" "float radius" 0.5\n')
    assert any("w.pbrt:3" in m and why in m and "has no surface; it is left out" in m for m in messages), messages
    path = tmp_path / "w.pbrt"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(path)
    assert [(o.type, o.radius) for o in scene.objects] == [("sphere", 0.5)]


def test_options_inside_the_world_block_and_a_second_world_are_refused(tmp_path):
    """pbrt-v4: "Options cannot be set inside world block". A Camera there had silently replaced
    the first; a second WorldBegin passed too."""
    for option in (
        'Camera "perspective" "float fov" 10\n',
        'Film "rgb"\n',
        'Integrator "path"\n',
        'Sampler "halton"\n',
    ):
        refused(tmp_path, CAMERA + option, "bad.pbrt:3:", "options are set before WorldBegin (", "bad.pbrt:2)")
    refused(
        tmp_path,
        CAMERA + "WorldBegin\n",
        "bad.pbrt:3: WorldBegin",
        "a second WorldBegin (the first is at",
        "bad.pbrt:2",
    )


def test_bdpt_is_read_as_raylume_s_bdpt_integrator(tmp_path):
    path = tmp_path / "b.pbrt"
    path.write_text('Integrator "bdpt" "integer maxdepth" 2\n' + CAMERA)
    scene = load_scene(path)
    assert scene.render.integrator == "bdpt" and scene.render.max_depth == 3


def test_a_supported_file_reads_without_warnings(tmp_path):
    text = (
        'AttributeBegin\nAreaLightSource "diffuse" "rgb L" [1 1 1] "bool twosided" true\nShape "disk"\nAttributeEnd\n'
        'Material "coateddiffuse" "rgb reflectance" [0.2 0.3 0.4]\nShape "sphere"\n'
    )
    assert warned(tmp_path, text) == []


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.lists(
        st.sampled_from(
            [
                "Shape",
                '"sphere"',
                '"float radius"',
                '"point3 P"',
                "[",
                "]",
                "1",
                "-2",
                "0",
                "AttributeBegin",
                "AttributeEnd",
                "Translate",
                "Scale",
                '"trianglemesh"',
                '"integer indices"',
                "WorldBegin",
                "LookAt",
                '"rgb reflectance"',
                "Material",
                '"diffuse"',
                "ObjectBegin",
                "ObjectEnd",
                "ObjectInstance",
                '"a"',
                "#",
                "\n",
                '"',
                "Rotate",
                "ConcatTransform",
                '"bool twosided"',
                "true",
                "LightSource",
                '"point"',
            ]
        ),
        max_size=40,
    )
)
def test_random_token_soup_reads_or_is_refused(tmp_path, words):
    path = tmp_path / "soup.pbrt"
    path.write_text(" ".join(words))
    try:
        pbrt_document(path)
    except SceneError:
        pass


def test_command_line_refuses_with_exit_2_and_writes_nothing(tmp_path):
    (tmp_path / "bad.pbrt").write_text(CAMERA + 'Shape "sphere" "float radius" [1\n')
    result = raylume("render", "bad.pbrt", "-o", "out.png", cwd=tmp_path, env=THIS_RAYLUME)
    assert_refused(result, "bad.pbrt:3")
    assert not (tmp_path / "out.png").exists()


BAD_PLY = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2\n"


def test_a_value_the_scene_model_refuses_names_the_pbrt_line(tmp_path):
    text = CAMERA + 'AttributeBegin\nScale 0 0 0\nShape "sphere"\nAttributeEnd\n'
    (tmp_path / "bad.pbrt").write_text(text)
    with pytest.raises(SceneError) as caught:
        load_scene(tmp_path / "bad.pbrt")
    message = str(caught.value)
    assert "objects[0].transform (" in message and 'bad.pbrt:5: Shape "sphere"): matrix is singular' in message
    # an instanced shape is named by its Shape line inside ObjectBegin/End
    text = CAMERA + 'Shape "sphere"\nObjectBegin "o"\nShape "sphere"\nObjectEnd\nScale 0 0 0\nObjectInstance "o"\n'
    (tmp_path / "bad.pbrt").write_text(text)
    with pytest.raises(
        SceneError, match=r'objects\[1\]\.transform \(.*bad\.pbrt:5: Shape "sphere"\): matrix is singular'
    ):
        load_scene(tmp_path / "bad.pbrt")


def test_a_mesh_file_that_fails_when_compiled_names_the_pbrt_line(tmp_path):
    (tmp_path / "bad.ply").write_text(BAD_PLY)
    (tmp_path / "bad.pbrt").write_text(CAMERA + 'Shape "sphere"\nShape "plymesh" "string filename" "bad.ply"\n')
    scene = load_scene(tmp_path / "bad.pbrt")
    with pytest.raises(SceneError) as caught:
        compile_scene(scene, source="bad.pbrt")
    message = str(caught.value)
    assert message.startswith("bad.pbrt: objects[1].file (") and 'bad.pbrt:4: Shape "plymesh"): Mesh file' in message
    result = raylume("render", "bad.pbrt", "-o", "out.png", cwd=tmp_path, env=THIS_RAYLUME)
    assert_refused(result, 'bad.pbrt:4: Shape "plymesh"', "could not be parsed as PLY")
    assert result.stderr.count("\n") == 1 and not (tmp_path / "out.png").exists()


def test_command_line_renders_a_pbrt_file_with_flags_and_warnings(tmp_path):
    (tmp_path / "ok.pbrt").write_text(
        CAMERA + 'LightSource "point" "rgb I" [1 1 1] "point3 from" [0 0 -1]\n'
        'Translate 0 0 3\nShape "sphere" "float fuzz" 1\n'
    )
    result = raylume(
        "render", "ok.pbrt", "-o", "out.npy", "--set", "render.width=6", "--height", "4", "--stats", "s.json",
        cwd=tmp_path, env=THIS_RAYLUME,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert 'ok.pbrt:5: Shape "sphere": raylume does not use "float fuzz"' in result.stderr
    image = np.load(tmp_path / "out.npy")
    assert image.shape == (4, 6, 3) and image[1:3, 2:4].max() > 0  # the sphere, lit, in the middle


def test_a_named_material_may_be_defined_after_its_use(tmp_path):
    """pbrt-v4 creates named materials once the whole file is read."""
    (tmp_path / "late.pbrt").write_text(
        CAMERA + 'NamedMaterial "red"\nShape "sphere"\n'
        'MakeNamedMaterial "red" "string type" "diffuse" "rgb reflectance" [1 0 0]\n'
    )
    document, messages = pbrt_document(tmp_path / "late.pbrt")
    assert document["objects"][0]["material"] == "red" and messages == []
    assert document["materials"]["red"] == {"type": "diffuse", "color": [1.0, 0.0, 0.0]}


def test_a_warning_repeated_by_many_directives_is_issued_once_with_a_count(tmp_path):
    messages = warned(tmp_path, 'Shape "curve"\n' * 500 + 'Shape "curve" "float width" 1\n')
    curves = [m for m in messages if "shape 'curve' is not supported" in m]
    assert curves == [
        f"{tmp_path / 'w.pbrt'}:3: Shape \"curve\": shape 'curve' is not supported; it is left out "
        "(raylume reads sphere, disk, cylinder, trianglemesh, bilinearmesh, plymesh) (501 times, first here)"
    ]


TEMPLATES = [
    "Translate {} {} {}",
    "Scale {} {} {}",
    "Rotate {} {} {} {}",
    "LookAt {} {} {}  {} {} {}  {} {} {}",
    'Shape "sphere" "float radius" {} "float zmin" {} "float zmax" {} "float phimax" {}',
    'Shape "disk" "float radius" {} "float innerradius" {} "float phimax" {}',
    'Shape "cylinder" "float radius" {} "float zmin" {} "float zmax" {}',
    'Shape "trianglemesh" "point3 P" [{} {} {} {} {} {} {} {} {}] "point2 uv" [{} {} {} {} {} {}]',
    'Material "conductor" "float roughness" {} "rgb reflectance" [{} {} {}]',
    'LightSource "spot" "rgb I" [{} {} {}] "point3 to" [{} {} {}] "float coneangle" {} "float power" {}',
    'AreaLightSource "diffuse" "rgb L" [{} {} {}] "float scale" {}',
    'Camera "perspective" "float fov" {} "float lensradius" {} "float focaldistance" {}',
    'Texture "t" "spectrum" "checkerboard" "integer dimension" 3 "float uscale" {}',
    'Material "diffuse" "texture reflectance" "t"',
    "Transform [{} {} {} {} {} {} {} {} {} {} {} {} {} {} {} {}]",
    "AttributeBegin",
    "AttributeEnd",
    'ObjectBegin "o"',
    "ObjectEnd",
    'ObjectInstance "o"',
]
NUMBERS = st.sampled_from(["0", "1", "-1", "2.5", "1e30", "-1e-30", "360", "0.0001", "90", "180"])


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.sampled_from(TEMPLATES), st.lists(NUMBERS, min_size=16, max_size=16)), max_size=12))
def test_degenerate_numbers_read_or_are_refused(tmp_path, directives):
    """Zero scales, zero radii, huge or tiny values: a scene, or a SceneError, never a crash."""
    text = "\n".join(template.format(*numbers) for template, numbers in directives)
    (tmp_path / "d.pbrt").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            load_scene(tmp_path / "d.pbrt")
        except SceneError:
            pass
