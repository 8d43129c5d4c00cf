"""Normal maps read from pbrt-v4 and Mitsuba 3 files: each becomes the material's `normal_map`
(file, scale, strength 1), a shape under it gets the UVs an image texture would, and what
raylume draws otherwise is named in a warning. The images: tests/test_pbrt_equivalence.py
(pbrt against the same scene in TOML), below (Mitsuba against TOML) and
tests/test_mitsuba_vs_reference.py (the `normalmap` scene against Mitsuba 3 itself)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image as PILImage
from test_pbrt_equivalence import write_normal_map

import raylume
from raylume.scene.checks import SceneWarning
from raylume.scene.pbrt_scene import pbrt_document
from raylume.scene.pbrt_tokens import PbrtError

PBRT_HEAD = """
LookAt 0 3 0.001  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "rgb" "integer xresolution" 8 "integer yresolution" 8 "string filename" "x.exr"
WorldBegin
LightSource "distant" "point3 from" [0 1 0] "point3 to" [0 0 0]
"""


def messages(caught) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


def loaded_with_warnings(path):
    """The scene at `path` and the scene warnings its loading gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = raylume.load_scene(path)
    return scene, messages(caught)


def test_pbrt_normalmap_is_the_materials_normal_map_on_every_material(tmp_path):
    write_normal_map(tmp_path / "bumps.png")
    (tmp_path / "scene.pbrt").write_text(
        PBRT_HEAD
        + """
MakeNamedMaterial "coat" "string type" "coateddiffuse" "string normalmap" "bumps.png"
Material "conductor" "string normalmap" "bumps.png"
Shape "bilinearmesh" "point3 P" [-1 0 -1  1 0 -1  -1 0 1  1 0 1]
NamedMaterial "coat"
Shape "disk" "float radius" 0.3
Material "diffuse"
Shape "sphere" "float radius" 0.2
"""
    )
    scene, said = loaded_with_warnings(tmp_path / "scene.pbrt")
    assert said == []
    document, _ = pbrt_document(tmp_path / "scene.pbrt")
    assert document["materials"]["coat"]["normal_map"] == {"file": "bumps.png"}
    mapped = [m for m in (scene.materials[obj.material] for obj in scene.objects) if m.normal_map is not None]
    assert len(mapped) == 2
    for material in mapped:
        assert material.normal_map.file == "bumps.png"
        assert material.normal_map.strength == 1.0 and material.normal_map.scale == (1.0, 1.0)
    # a shape under a normal map gets pbrt's UVs, as under an image texture: the bilinear patch
    # its corners' (u, v), the disk tessellated with pbrt's (u, v); the plain sphere stays a sphere
    kinds = [(obj["type"], "uvs" in obj) for obj in document["objects"]]
    assert kinds == [("mesh", True), ("mesh", True), ("sphere", False)]


def test_pbrt_normalmap_missing_or_on_an_interface(tmp_path):
    write_normal_map(tmp_path / "bumps.png")
    (tmp_path / "a.pbrt").write_text(PBRT_HEAD + 'Material "diffuse" "string normalmap" "nowhere.png"\n')
    with pytest.raises(PbrtError, match=r"a\.pbrt:7: Material.*no such normal map file .*nowhere\.png"):
        pbrt_document(tmp_path / "a.pbrt")
    (tmp_path / "b.pbrt").write_text(
        PBRT_HEAD + 'Material "interface" "string normalmap" "bumps.png"\nShape "sphere"\n'
    )
    _, warned = pbrt_document(tmp_path / "b.pbrt")
    assert any("interface material has no surface for a normal map" in w for w in warned), warned


def test_pbrt_displacement_textures_raylume_cannot_bump_map_by(tmp_path):
    write_normal_map(tmp_path / "bumps.png")
    textures = (
        'Texture "h" "float" "imagemap" "string filename" "bumps.png" "float scale" 0.1\n'
        'Texture "n" "float" "fbm"\n'
        'Texture "c" "spectrum" "imagemap" "string filename" "bumps.png"\n'
    )
    cases = {
        'Material "diffuse" "texture displacement" "h"': None,
        'Material "diffuse" "texture displacement" "n"': "displacement texture 'n' is not an imagemap",
        'Material "diffuse" "texture displacement" "h" "string normalmap" "bumps.png"': "the normalmap is ignored",
    }
    for k, (material, message) in enumerate(cases.items()):
        (tmp_path / f"{k}.pbrt").write_text(PBRT_HEAD + textures + material + '\nShape "sphere"\n')
        document, warned = pbrt_document(tmp_path / f"{k}.pbrt")
        table = next(iter(document["materials"].values()))
        if message is None:
            assert warned == [] and table["bump_map"] == {
                "file": "bumps.png",
                "scale": [1.0, 1.0],
                "height": 0.1,
                "encoding": "srgb",
            }
        else:
            assert any(message in w for w in warned), warned
    (tmp_path / "spectrum.pbrt").write_text(PBRT_HEAD + textures + 'Material "diffuse" "texture displacement" "c"\n')
    with pytest.raises(PbrtError, match="'c' is a spectrum texture; displacement needs a float texture"):
        pbrt_document(tmp_path / "spectrum.pbrt")


MITSUBA = """<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="2"/></integrator>
  <sensor type="perspective"><float name="fov" value="30"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/></film>
    <sampler type="independent"><integer name="sample_count" value="2"/></sampler>
  </sensor>
  <emitter type="directional">
    <vector name="direction" x="-0.3" y="-1" z="-1"/><rgb name="irradiance" value="1"/>
  </emitter>
  {shape}
</scene>
"""
BOARD_OBJ = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"


def mitsuba_board(texture_extra="", raw=True, kind="obj", wrap=("", "")) -> str:
    where = '<string name="filename" value="board.obj"/>' if kind == "obj" else ""
    raw_tag = '<boolean name="raw" value="true"/>' if raw else ""
    return MITSUBA.format(
        shape=f"""<shape type="{kind}">{where}
    {wrap[0]}<bsdf type="normalmap">
      <texture name="normalmap" type="bitmap">
        <string name="filename" value="maps/bumps.png"/>{raw_tag}{texture_extra}
      </texture>
      <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>
    </bsdf>{wrap[1]}
  </shape>"""
    )


def write_mitsuba(tmp_path, text: str):
    (tmp_path / "maps").mkdir(exist_ok=True)
    write_normal_map(tmp_path / "maps" / "bumps.png")
    # a height map with slopes everywhere, rising along u and v (16 levels a texel, wrapping)
    heights = (np.add.outer(np.arange(8), np.arange(8)) * 16 % 256).astype(np.uint8)
    PILImage.fromarray(heights, mode="L").save(tmp_path / "maps" / "heights.png")
    (tmp_path / "board.obj").write_text(BOARD_OBJ)
    (tmp_path / "scene.xml").write_text(text)
    return loaded_with_warnings(tmp_path / "scene.xml")


@pytest.mark.parametrize("wrap", [("", ""), ('<bsdf type="twosided">', "</bsdf>")])
def test_mitsuba_normalmap_gives_the_inner_bsdf_a_normal_map(tmp_path, wrap):
    extra = '<transform name="to_uv"><scale x="2" y="3"/></transform>'
    scene, warned = write_mitsuba(tmp_path, mitsuba_board(extra, wrap=wrap))
    assert warned == []
    material = scene.objects[0].material
    assert material.type == "diffuse" and material.color == pytest.approx((0.6, 0.5, 0.4))
    assert material.normal_map.file == "maps/bumps.png"
    assert material.normal_map.scale == (2.0, 3.0) and material.normal_map.strength == 1.0


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (mitsuba_board(raw=False), "raw = false: Mitsuba decodes this normal map's texels from sRGB"),
        (mitsuba_board(kind="rectangle"), "turns a normal map's y on a rectangle towards increasing v"),
        (mitsuba_board(kind="disk"), "disk has texture coordinates of its own, not Mitsuba's: the normal map lies"),
        (mitsuba_board('<transform name="to_uv"><rotate z="1" angle="30"/></transform>'), "more than a scale"),
    ],
)
def test_mitsuba_normalmap_warnings(tmp_path, text, message):
    _, warned = write_mitsuba(tmp_path, text)
    assert any(message in w for w in warned), warned


@pytest.mark.parametrize(("value", "warns"), [("false", False), ("true", True)])
def test_mitsuba_normalmap_use_shadowing_function(tmp_path, value, warns):
    """raylume has no shadowing function: `false` renders as Mitsuba does, in silence (the Mitsuba
    comparison's normal-map scene sets it); `true` written out is named (Mitsuba's default, left
    unset, passes in silence as it always has)."""
    flag = f'<bsdf type="normalmap"><boolean name="use_shadowing_function" value="{value}"/>'
    scene, warned = write_mitsuba(tmp_path, mitsuba_board().replace('<bsdf type="normalmap">', flag))
    assert scene.objects[0].material.normal_map.file == "maps/bumps.png"
    assert [w for w in warned if "use_shadowing_function = true" in w] == ([warned[0]] if warns else [])
    assert len(warned) == (1 if warns else 0), warned


# The Mitsuba board scene's twin in raylume's world (Mitsuba's mirrored, x -> -x: the camera looks
# down -z from z = 5 with +x on the left), its objects given by each test
BOARD_TOML = """
[render]
mode = "path"
width = 12
height = 12
spp = 2
max_depth = 2
filter = "gaussian"

[camera]
position = [0, 0, 5]
look_at = [0, 0, 0]
up = [0, 1, 0]
fov = 30

[[lights]]
type = "directional"
direction = [-0.3, 1, 1]
intensity = 1
"""
BOARD_COLOUR = {"type": "diffuse", "color": [0.6, 0.5, 0.4]}


def assert_renders_as_the_toml_board(tmp_path, scene, maps: dict, others=()) -> None:
    """The imported `scene` renders as the OBJ board written in TOML, its material the board's
    colour with `maps` (normal_map, bump_map, alpha_map), beside `others` (objects in raylume's
    world): the same image to 1e-6; and the maps change it, so the comparison proves something."""
    (tmp_path / "scene.toml").write_text(BOARD_TOML)
    base = raylume.load_scene(tmp_path / "scene.toml")

    def rendered(material) -> np.ndarray:
        board = {"type": "mesh", "file": "board.obj", "transform": {"scale": [-1, 1, 1]}, "material": material}
        return raylume.render(base.replace(objects=[board, *others]), seed=3, aovs=False).rgb

    a = raylume.render(scene, seed=3, aovs=False).rgb
    assert a.max() > 0.05
    np.testing.assert_allclose(a, rendered({**BOARD_COLOUR, **maps}), rtol=1e-6, atol=1e-7)
    assert np.abs(a - rendered(BOARD_COLOUR)).max() > 0.02, "the map changes nothing: the test would prove nothing"


def test_mitsuba_normalmap_renders_as_the_toml_normal_map(tmp_path):
    """The OBJ board (Mitsuba flips its v on loading, which puts the image's top at v = 1 as
    raylume has it) renders as the same board written in TOML with the normal_map."""
    scene, warned = write_mitsuba(tmp_path, mitsuba_board())
    assert warned == []
    assert_renders_as_the_toml_board(tmp_path, scene, {"normal_map": {"file": "maps/bumps.png"}})


def mitsuba_bump_board(raw=True, scale="0.05") -> str:
    raw_tag = '<boolean name="raw" value="true"/>' if raw else ""
    return MITSUBA.format(
        shape=f"""<shape type="obj"><string name="filename" value="board.obj"/>
    <bsdf type="bumpmap">
      <texture type="bitmap" name="heights">
        <string name="filename" value="maps/heights.png"/>{raw_tag}
        <transform name="to_uv"><scale x="2" y="2"/></transform>
      </texture>
      <float name="scale" value="{scale}"/>
      <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>
    </bsdf>
  </shape>"""
    )


@pytest.mark.parametrize("raw", [True, False])
def test_mitsuba_bumpmap_gives_the_inner_bsdf_a_bump_map(tmp_path, raw):
    # Mitsuba's bumpmap scales its texture's gradient by `scale`: the height of a texel of 1;
    # its bitmap is sRGB-decoded unless raw
    scene, warned = write_mitsuba(tmp_path, mitsuba_bump_board(raw=raw))
    assert warned == []
    material = scene.objects[0].material
    assert material.type == "diffuse" and material.normal_map is None
    assert material.bump_map.file == "maps/heights.png" and material.bump_map.scale == (2.0, 2.0)
    assert material.bump_map.height == 0.05
    assert material.bump_map.encoding == ("linear" if raw else "srgb")


def test_mitsuba_bumpmap_renders_as_the_toml_bump_map(tmp_path):
    scene, _ = write_mitsuba(tmp_path, mitsuba_bump_board(scale="0.2"))
    bump = {"bump_map": {"file": "maps/heights.png", "scale": 2, "height": 0.2}}
    assert_renders_as_the_toml_board(tmp_path, scene, bump)
