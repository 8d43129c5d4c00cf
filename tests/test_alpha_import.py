"""Cut-out alpha read from pbrt-v4 and Mitsuba 3 files (glTF's alphaMode: tests/test_gltf.py):
each becomes a material's `alpha_map` (pbrt-v4's per shape, so a variant of the shape's
material), and what raylume cuts otherwise is named in a warning. The images:
tests/test_pbrt_equivalence.py (pbrt against the same scene in TOML) and below (Mitsuba
against TOML)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image as PILImage
from test_normal_map_import import (
    BOARD_OBJ,
    MITSUBA,
    PBRT_HEAD,
    assert_renders_as_the_toml_board,
    loaded_with_warnings,
)

import raylume
from raylume.scene.pbrt_scene import pbrt_document
from raylume.scene.pbrt_tokens import PbrtError


def write_mask(path, mode="L") -> None:
    """An 8 x 8 mask, 0 on its left half, 1 on its right: grey (L), or in the alpha channel of an
    opaque white image (RGBA, LA); "RGBA-opaque": a grey mask saved with an alpha of 1 throughout."""
    grey = np.zeros((8, 8), dtype=np.uint8)
    grey[:, 4:] = 255
    if mode == "L":
        PILImage.fromarray(grey, mode="L").save(path)
    elif mode == "RGBA-opaque":
        PILImage.fromarray(np.dstack([grey, grey, grey, np.full_like(grey, 255)]), mode="RGBA").save(path)
    else:
        white = np.full_like(grey, 255)
        bands = [white, grey] if mode == "LA" else [white, white, white, grey]
        PILImage.fromarray(np.dstack(bands), mode=mode).save(path)


def pbrt_file(tmp_path, body: str, mask_mode="L") -> tuple[dict, list[str]]:
    write_mask(tmp_path / "mask.png", mask_mode)
    (tmp_path / "scene.pbrt").write_text(PBRT_HEAD + body)
    return pbrt_document(tmp_path / "scene.pbrt")


def test_pbrt_alpha_texture_gives_the_shapes_material_a_variant_with_the_alpha_map(tmp_path):
    document, warned = pbrt_file(
        tmp_path,
        """
Texture "leaf" "float" "imagemap" "string filename" "mask.png" "float uscale" 2
Texture "lin" "float" "imagemap" "string filename" "mask.png" "string encoding" "linear" "float scale" 2
NamedMaterial "late"
Shape "sphere" "float radius" 0.2 "texture alpha" "leaf"
Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 0 1] "integer indices" [0 1 2] "texture alpha" "leaf"
Shape "sphere" "float radius" 0.3
Shape "disk" "texture alpha" "lin"
MakeNamedMaterial "late" "string type" "conductor"
""",
    )
    assert warned == []
    materials, objects = document["materials"], document["objects"]
    # one variant per material and mask, defined after its first use (pbrt-v4 allows that)
    assert [obj["material"] for obj in objects] == ["late+alpha-1", "late+alpha-1", "late", "late+alpha-2"]
    assert materials["late+alpha-1"] == {
        **materials["late"],
        "alpha_map": {"file": "mask.png", "scale": [2.0, 1.0], "cutoff": 0.5, "encoding": "srgb"},
    }
    assert materials["late+alpha-2"]["alpha_map"] == {"file": "mask.png", "scale": [1.0, 1.0], "cutoff": 0.25}
    assert "alpha_map" not in materials["late"]
    # shapes under a mask get pbrt's UVs, as under an image texture: the sphere turned so that its
    # (u, v) is pbrt's, the triangle its corners' (0, 0), (1, 0), (1, 1), the disk tessellated;
    # the plain sphere stays as it is
    assert [(obj["type"], "uvs" in obj, "transform" in obj) for obj in objects] == [
        ("sphere", False, True),
        ("mesh", True, False),
        ("sphere", False, False),
        ("mesh", True, False),
    ]
    raylume.load_scene(tmp_path / "scene.pbrt")  # the document is a valid scene


@pytest.mark.parametrize(
    ("alpha", "kept", "message"),
    [
        ('"float alpha" 1', True, None),
        ('"float alpha" 0', False, '"float alpha" 0: pbrt-v4 cuts the whole shape away; it is left out'),
        (
            '"float alpha" 0.3',
            False,
            "keeps that fraction of the rays that hit the shape; raylume cuts masks at 0.5, so the shape is left out",
        ),
        ('"float alpha" 0.7', True, "so the shape is drawn solid"),
        ('"texture alpha" "faint"', False, "alpha texture 'faint' has scale 0.25, so its alpha stays below 0.5"),
        (
            '"texture alpha" "noise"',
            True,
            "alpha texture 'noise' is not an imagemap; raylume cuts masks by images only",
        ),
    ],
)
def test_pbrt_constant_alpha_and_what_raylume_cannot_cut_by(tmp_path, alpha, kept, message):
    document, warned = pbrt_file(
        tmp_path,
        'Texture "faint" "float" "imagemap" "string filename" "mask.png" "float scale" 0.25\n'
        'Texture "noise" "float" "fbm"\n'
        f'Shape "sphere" {alpha}\nShape "disk"\n',
    )
    assert len(document["objects"]) == (2 if kept else 1)
    assert all("alpha_map" not in table for table in document["materials"].values())
    if message is None:
        assert warned == []
    else:
        assert any(message in w for w in warned), warned


@pytest.mark.parametrize(
    ("mode", "message"),
    [
        ("RGBA", None),
        ("LA", "pbrt-v4 reads this image's grey (or colour), dropping its alpha; raylume's alpha map reads the alpha"),
        ("RGBA-opaque", "its alpha is 1 everywhere, so pbrt-v4 reads the mean of r, g and b"),
    ],
)
def test_pbrt_alpha_images_pbrt_reads_otherwise(tmp_path, mode, message):
    _, warned = pbrt_file(
        tmp_path,
        'Texture "leaf" "float" "imagemap" "string filename" "mask.png"\nShape "disk" "texture alpha" "leaf"\n',
        mode,
    )
    if message is None:
        assert warned == []
    else:
        assert any(message in w for w in warned), warned


def test_pbrt_alpha_on_an_area_light_or_naming_no_float_texture(tmp_path):
    document, warned = pbrt_file(
        tmp_path,
        'Texture "leaf" "float" "imagemap" "string filename" "mask.png"\n'
        'AreaLightSource "diffuse" "rgb L" [1 1 1]\nShape "disk" "texture alpha" "leaf"\n',
    )
    assert any("an area light with an alpha texture: raylume's emitters take no alpha map" in w for w in warned)
    assert "alpha_map" not in document["objects"][0]["material"]
    (tmp_path / "c.pbrt").write_text(
        PBRT_HEAD + 'Texture "c" "spectrum" "imagemap" "string filename" "mask.png"\nShape "disk" "texture alpha" "c"\n'
    )
    with pytest.raises(PbrtError, match="'c' is a spectrum texture; alpha needs a float texture"):
        pbrt_document(tmp_path / "c.pbrt")
    (tmp_path / "d.pbrt").write_text(PBRT_HEAD + 'Shape "disk" "texture alpha" "nowhere"\n')
    with pytest.raises(PbrtError, match="no texture named 'nowhere'"):
        pbrt_document(tmp_path / "d.pbrt")


def test_pbrt_a_mirrored_float_image_is_refused_where_a_map_uses_it_naming_its_texture(tmp_path):
    # pbrt mirrors an image by a negative uscale; raylume's maps do not: the error names the
    # Texture directive's file and line (not a material made of it), and only where a map uses it
    texture = 'Texture "m" "float" "imagemap" "string filename" "mask.png" "float uscale" -1\n'
    document, _ = pbrt_file(tmp_path, texture + 'Shape "disk"\n')  # defined, never used: no error
    assert len(document["objects"]) == 1
    for use in ('Shape "disk" "texture alpha" "m"\n', 'Material "diffuse" "texture displacement" "m"\n'):
        with pytest.raises(PbrtError, match=r"scene\.pbrt:7: Texture \"m\": uscale -1 and vscale 1: .*scales > 0"):
            pbrt_file(tmp_path, texture + use)


def test_pbrt_an_unreadable_alpha_image_names_the_material_directive(tmp_path):
    """An error found when the scene is compiled names the directive of the material the alpha
    variant was made from, as a normal map's does (the variant's name, with its "+", went
    unnamed)."""
    pbrt_file(tmp_path, "")
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"not an image")
    body = """
Texture "holes" "float" "imagemap" "string filename" "broken.png"
Material "diffuse"
Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 0 1] "integer indices" [0 1 2] "point2 uv" [0 0 1 0 0 1]
  "texture alpha" "holes"
"""
    (tmp_path / "scene.pbrt").write_text(PBRT_HEAD + body)
    with pytest.raises(
        raylume.SceneError, match=r"\+alpha-1.alpha_map.file \(\S*scene.pbrt:\d+: Material \"diffuse\"\): "
    ):
        raylume.render(tmp_path / "scene.pbrt", width=8, height=8, mode="cast")


def mitsuba_mask(
    opacity: str, inner='<bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>', emitter=""
) -> str:
    wall = """<shape type="obj"><string name="filename" value="wall.obj"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.3, 0.7"/></bsdf>
  </shape>"""
    return MITSUBA.format(
        shape=f"""<shape type="obj"><string name="filename" value="board.obj"/>{emitter}
    <bsdf type="mask">
      {opacity}
      {inner}
    </bsdf>
  </shape>
  {wall}"""
    )


def bitmap(extra="") -> str:
    return f"""<texture name="opacity" type="bitmap">
        <string name="filename" value="maps/mask.png"/>{extra}
      </texture>"""


WALL_OBJ = "v -3 -3 -1\nv 3 -3 -1\nv 3 3 -1\nv -3 3 -1\nf 1 2 3\nf 1 3 4\n"
WALL_COLOUR = {"type": "diffuse", "color": [0.2, 0.3, 0.7]}


def write_mitsuba(tmp_path, text: str, mask_mode="L"):
    (tmp_path / "maps").mkdir(exist_ok=True)
    write_mask(tmp_path / "maps" / "mask.png", mask_mode)
    (tmp_path / "board.obj").write_text(BOARD_OBJ)
    (tmp_path / "wall.obj").write_text(WALL_OBJ)
    (tmp_path / "scene.xml").write_text(text)
    return loaded_with_warnings(tmp_path / "scene.xml")


@pytest.mark.parametrize("raw", [False, True])
@pytest.mark.parametrize("twosided", [False, True])
def test_mitsuba_mask_gives_the_inner_bsdf_an_alpha_map(tmp_path, raw, twosided):
    # Mitsuba's bitmap is sRGB-decoded unless raw; its to_uv's scale is the map's
    extra = '<transform name="to_uv"><scale x="2" y="3"/></transform>'
    if raw:
        extra += '<boolean name="raw" value="true"/>'
    inner = '<bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.5, 0.4"/></bsdf>'
    if twosided:
        inner = f'<bsdf type="twosided">{inner}</bsdf>'
    scene, warned = write_mitsuba(tmp_path, mitsuba_mask(bitmap(extra), inner))
    assert warned == []
    material = scene.objects[0].material
    assert material.type == "diffuse" and material.color == pytest.approx((0.6, 0.5, 0.4))
    assert material.alpha_map.file == "maps/mask.png" and material.alpha_map.scale == (2.0, 3.0)
    assert material.alpha_map.cutoff == 0.5
    assert material.alpha_map.encoding == ("linear" if raw else "srgb")


@pytest.mark.parametrize(
    ("opacity", "kind", "message"),
    [
        ('<float name="opacity" value="0"/>', "null", None),
        ('<float name="opacity" value="1"/>', "diffuse", None),
        ('<float name="opacity" value="0.3"/>', "null", "opacity 0.3: Mitsuba keeps that fraction of the rays"),
        ("", "diffuse", "raylume cuts masks at 0.5, so it is drawn solid"),  # Mitsuba's default opacity, 0.5
        ('<rgb name="opacity" value="0.2, 0.2, 0.2"/>', "null", "so it is invisible (null)"),
    ],
)
def test_mitsuba_constant_opacity(tmp_path, opacity, kind, message):
    scene, warned = write_mitsuba(tmp_path, mitsuba_mask(opacity))
    material = scene.objects[0].material
    assert material.type == kind and material.alpha_map is None
    if message is None:
        assert warned == []
    else:
        assert any(message in w for w in warned), warned


def test_mitsuba_mask_warnings(tmp_path):
    _, warned = write_mitsuba(tmp_path, mitsuba_mask(bitmap()), mask_mode="RGBA")
    assert any("Mitsuba drops this bitmap's alpha channel and reads its grey" in w for w in warned), warned
    checks = '<texture name="opacity" type="checkerboard"/>'
    scene, warned = write_mitsuba(tmp_path, mitsuba_mask(checks))
    assert any(
        "raylume's opacity masks are images (a bitmap): the BSDF inside is drawn without one" in w for w in warned
    )
    assert scene.objects[0].material.alpha_map is None
    emitter = '<emitter type="area"><rgb name="radiance" value="1"/></emitter>'
    scene, warned = write_mitsuba(tmp_path, mitsuba_mask(bitmap(), emitter=emitter))
    assert any("an area emitter on a masked BSDF: raylume's emitters take no alpha map" in w for w in warned)
    material = scene.objects[0].material
    assert material.alpha_map is None and max(material.emission) > 0


def test_mitsuba_mask_renders_as_the_toml_alpha_map(tmp_path):
    """The OBJ board, its left half cut away, in front of a wall: the same image as the board
    written in TOML with the alpha_map, in raylume's world (Mitsuba's mirrored, x -> -x)."""
    scene, warned = write_mitsuba(tmp_path, mitsuba_mask(bitmap()))
    assert warned == []
    wall = {"type": "mesh", "file": "wall.obj", "transform": {"scale": [-1, 1, 1]}, "material": WALL_COLOUR}
    alpha = {"alpha_map": {"file": "maps/mask.png", "encoding": "srgb"}}
    assert_renders_as_the_toml_board(tmp_path, scene, alpha, others=[wall])
