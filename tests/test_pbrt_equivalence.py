"""pbrt-v4 files against hand-written TOML scenes of the same geometry, camera, materials and
lights: both render to the same bits (path mode, small images, a few samples per pixel).

The cameras look along an axis and the rotations are exact matrices (Transform /
ConcatTransform), so that the TOML can state the same numbers exactly; Rotate and tilted
cameras are checked against hand-computed matrices and projections in test_pbrt_analytic.py.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image as PILImage

import raylume
from raylume.scene.checks import SceneWarning
from raylume.scene.pbrt_spectra import NAMED_RGB

HEADER = """
LookAt 0 1 -6  0 1 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 40 "integer yresolution" 30 "string filename" "ignored.exr"
Sampler "zsobol" "integer pixelsamples" 4
Integrator "path" "integer maxdepth" 3
WorldBegin
"""

TOML_HEADER = """
[render]
mode = "path"
width = 40
height = 30
spp = 4
max_depth = 4
encoding = "srgb"
filter = "gaussian"

[camera]
position = [0, 1, -6]
look_at = [0, 1, -5]
up = [0, 1, 0]
fov = 40

[materials.pbrt-default]
type = "diffuse"
color = [0.5, 0.5, 0.5]
"""

FLOOR_PBRT = 'Shape "bilinearmesh" "point3 P" [-4 0 -4  4 0 -4  -4 0 4  4 0 4]\n'
FLOOR_TOML = """
[[objects]]
type = "mesh"
vertices = [[-4, 0, -4], [4, 0, -4], [-4, 0, 4], [4, 0, 4]]
faces = [[0, 1, 3], [0, 3, 2]]
material = "{material}"
"""


def render_both(tmp_path, pbrt: str, toml: str, files: dict | None = None, expect_warnings: bool = False):
    for name, text in (files or {}).items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    (tmp_path / "scene.pbrt").write_text(pbrt)
    (tmp_path / "scene.toml").write_text(toml)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        from_pbrt = raylume.render(tmp_path / "scene.pbrt", aovs=False)
    if not expect_warnings:
        assert not [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    from_toml = raylume.render(tmp_path / "scene.toml", aovs=False)
    assert from_pbrt.rgb.shape == (30, 40, 3)
    assert from_toml.rgb.max() > 0.01, "the reference scene renders black: the test would prove nothing"
    np.testing.assert_array_equal(from_pbrt.rgb, from_toml.rgb)
    return from_pbrt


def test_shapes_and_transforms(tmp_path):
    pbrt = (
        HEADER
        + """
LightSource "point" "rgb I" [8 8 8] "point3 from" [0 4 -2]
AttributeBegin
  Translate 1 1 0
  Scale 0.5 0.5 0.5
  Shape "sphere" "float radius" 1
AttributeEnd
AttributeBegin
  Translate -1.5 0.25 0
  # a quarter turn about x, exactly: the disk's +z becomes +y
  ConcatTransform [1 0 0 0  0 0 -1 0  0 1 0 0  0 0 0 1]
  Shape "disk" "float radius" 0.75 "float height" 0
AttributeEnd
AttributeBegin
  Transform [1 0 0 0  0 0 -1 0  0 1 0 0  0 0 2 1]
  Shape "cylinder" "float radius" 0.25 "float zmin" 0 "float zmax" 1.5
AttributeEnd
AttributeBegin
  CoordinateSystem "here"
  Translate 100 100 100
  CoordSysTransform "here"
  Shape "trianglemesh" "point3 P" [-1 0 1  1 0 1  0 2 1.5] "integer indices" [0 1 2]
    "normal N" [0 0 -1  0 0 -1  0 0 -1]
AttributeEnd
"""
        + FLOOR_PBRT
    )
    toml = (
        TOML_HEADER
        + """
[[lights]]
type = "point"
position = [0, 4, -2]
intensity = [8, 8, 8]

[[objects]]
type = "sphere"
center = [1, 1, 0]
radius = 0.5
material = "pbrt-default"

[[objects]]
type = "disk"
center = [-1.5, 0.25, 0]
normal = [0, 1, 0]
radius = 0.75
material = "pbrt-default"

[[objects]]
type = "cylinder"
p0 = [0, 0, 2]
p1 = [0, 1.5, 2]
radius = 0.25
capped = false
material = "pbrt-default"

[[objects]]
type = "mesh"
vertices = [[-1, 0, 1], [1, 0, 1], [0, 2, 1.5]]
faces = [[0, 1, 2]]
normals = [[0, 0, -1], [0, 0, -1], [0, 0, -1]]
material = "pbrt-default"
"""
        + FLOOR_TOML.format(material="pbrt-default")
    )
    render_both(tmp_path, pbrt, toml)


def test_materials(tmp_path):
    au_eta, au_k = NAMED_RGB["metal-Au-eta"], NAMED_RGB["metal-Au-k"]
    pbrt = (
        HEADER
        + """
LightSource "point" "rgb I" [8 8 8] "point3 from" [0 4 -2]
MakeNamedMaterial "gold" "string type" "conductor"
    "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.04
MakeNamedMaterial "mirror" "string type" "conductor" "rgb reflectance" [0.25 0.5 0.75] "bool remaproughness" false
    "float roughness" 0.2
AttributeBegin
  NamedMaterial "gold"
  Translate -1.2 0.6 0
  Shape "sphere" "float radius" 0.6
AttributeEnd
AttributeBegin
  NamedMaterial "mirror"
  Translate 0 0.6 1
  Shape "sphere" "float radius" 0.6
AttributeEnd
AttributeBegin
  Material "dielectric" "float eta" 1.33 "float roughness" 0.01
  Translate 1.2 0.6 0
  Shape "sphere" "float radius" 0.6
AttributeEnd
AttributeBegin
  Material "coateddiffuse" "rgb reflectance" [0.1 0.6 0.2] "float roughness" 0.09 "float eta" 1.6
  Translate 0 1.8 0
  Shape "sphere" "float radius" 0.4
AttributeEnd
Material "diffuse" "rgb reflectance" [0.7 0.7 0.5]
"""
        + FLOOR_PBRT
    )
    k = [float(2 * np.sqrt(r) / np.sqrt(1 - r)) for r in (0.25, 0.5, 0.75)]
    toml = (
        TOML_HEADER
        + f"""
[materials.gold]
type = "conductor"
color = [1, 1, 1]
eta = {list(au_eta)}
k = {list(au_k)}
roughness = 0.2

[materials.mirror]
type = "conductor"
color = [1, 1, 1]
eta = [1, 1, 1]
k = {k}
roughness = 0.2

[materials.water]
type = "dielectric"
ior = 1.33
roughness = 0.1

[materials.green]
type = "plastic"
color = [0.1, 0.6, 0.2]
ior = 1.6
roughness = 0.3

[materials.floor]
type = "diffuse"
color = [0.7, 0.7, 0.5]

[[lights]]
type = "point"
position = [0, 4, -2]
intensity = 8

[[objects]]
type = "sphere"
center = [-1.2, 0.6, 0]
radius = 0.6
material = "gold"

[[objects]]
type = "sphere"
center = [0, 0.6, 1]
radius = 0.6
material = "mirror"

[[objects]]
type = "sphere"
center = [1.2, 0.6, 0]
radius = 0.6
material = "water"

[[objects]]
type = "sphere"
center = [0, 1.8, 0]
radius = 0.4
material = "green"
"""
        + FLOOR_TOML.format(material="floor")
    )
    render_both(tmp_path, pbrt, toml)


def test_lights(tmp_path):
    pbrt = (
        HEADER
        + """
LightSource "spot" "rgb I" [20 10 5] "point3 from" [0 4 0] "point3 to" [0 0 0]
    "float coneangle" 25 "float conedelta" 10
LightSource "distant" "blackbody L" 6500 "float scale" 0.5 "point3 from" [1 3 -2] "point3 to" [0 0 0]
LightSource "infinite" "rgb L" [0.05 0.1 0.2]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 3 2]
  Translate 1.5 1.5 1
  Shape "sphere" "float radius" 0.3
AttributeEnd
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [1 2 3] "float scale" 2 "bool twosided" true
  Material "diffuse" "rgb reflectance" [0.2 0.2 0.2]
  Shape "bilinearmesh" "point3 P" [-2 2 1  -1 2 1  -2 3 1  -1 3 1]
AttributeEnd
"""
        + FLOOR_PBRT
    )
    # pbrt-v4 scales a blackbody to unit luminance: its RGB follows from the band means
    from raylume.scene.pbrt_spectra import blackbody_rgb

    sun = [0.5 * c for c in blackbody_rgb(6500)]
    toml = (
        TOML_HEADER
        + f"""
[environment]
color = [0.05, 0.1, 0.2]

[[lights]]
type = "spot"
position = [0, 4, 0]
direction = [0, -4, 0]
angle = 25
inner_angle = 15
intensity = [20, 10, 5]

[[lights]]
type = "directional"
direction = [1, 3, -2]
intensity = {sun}

[[objects]]
type = "sphere"
center = [1.5, 1.5, 1]
radius = 0.3
material = {{ type = "diffuse", color = [0.5, 0.5, 0.5], emission = [4, 3, 2] }}

[[objects]]
type = "mesh"
vertices = [[-2, 2, 1], [-1, 2, 1], [-2, 3, 1], [-1, 3, 1]]
faces = [[0, 1, 3], [0, 3, 2]]
material = {{ type = "diffuse", color = [0.2, 0.2, 0.2], emission = [2, 4, 6] }}
"""
        + FLOOR_TOML.format(material="pbrt-default")
    )
    render_both(tmp_path, pbrt, toml)


def test_instances(tmp_path):
    pbrt = (
        HEADER
        + """
LightSource "point" "rgb I" [8 8 8] "point3 from" [0 4 -2]
ObjectBegin "thing"
  Material "diffuse" "rgb reflectance" [0.8 0.3 0.1]
  Translate 0 0.5 0
  Shape "trianglemesh" "point3 P" [-0.5 0 0  0.5 0 0  0 1 0] "integer indices" [0 1 2]
  Shape "sphere" "float radius" 0.25
ObjectEnd
AttributeBegin
  Translate -1 0 0
  ObjectInstance "thing"
AttributeEnd
AttributeBegin
  Translate 1 0 1
  Scale 2 2 2
  ObjectInstance "thing"
AttributeEnd
"""
        + FLOOR_PBRT
    )
    toml = (
        TOML_HEADER
        + """
[materials.orange]
type = "diffuse"
color = [0.8, 0.3, 0.1]

[[lights]]
type = "point"
position = [0, 4, -2]
intensity = 8
"""
        + FLOOR_TOML.format(material="pbrt-default")
        + """
[[objects]]
type = "mesh"
vertices = [[-0.5, 0, 0], [0.5, 0, 0], [0, 1, 0]]
faces = [[0, 1, 2]]
material = "orange"
transform = { translate = [0, 0.5, 0] }
instances = [{ translate = [-1, 0, 0] }, { translate = [1, 0, 1], scale = 2 }]

[[objects]]
type = "sphere"
center = [-1, 0.5, 0]
radius = 0.25
material = "orange"

[[objects]]
type = "sphere"
center = [1, 1, 1]
radius = 0.5
material = "orange"
"""
    )
    render_both(tmp_path, pbrt, toml)


def test_textures(tmp_path):
    pixels = np.zeros((4, 8, 3), dtype=np.uint8)
    pixels[:2, :, 0] = 255  # top half red, bottom half blue
    pixels[2:, :, 2] = 255
    PILImage.fromarray(pixels).save(tmp_path / "stripes.png")
    pbrt = (
        HEADER
        + """
LightSource "point" "rgb I" [8 8 8] "point3 from" [0 4 -2]
Texture "stripes" "spectrum" "imagemap" "string filename" "stripes.png" "float uscale" 2 "float vscale" 3
Texture "checks" "spectrum" "checkerboard" "integer dimension" 3 "rgb tex1" [0.9 0.9 0.2] "rgb tex2" [0.1 0.2 0.3]
AttributeBegin
  Material "diffuse" "texture reflectance" "stripes"
  Shape "bilinearmesh" "point3 P" [-2 0.5 1  0 0.5 1  -2 2.5 1  0 2.5 1] "point2 uv" [0 0  1 0  0 1  1 1]
AttributeEnd
AttributeBegin
  Scale 0.5 0.5 0.5
  Texture "small" "spectrum" "checkerboard" "integer dimension" 3
AttributeEnd
Material "diffuse" "texture reflectance" "checks"
AttributeBegin
  Translate 1 1 0
  Shape "sphere" "float radius" 0.6
AttributeEnd
Material "diffuse" "texture reflectance" "small"
"""
        + FLOOR_PBRT
    )
    toml = (
        TOML_HEADER
        + """
[materials.checks]
type = "diffuse"
texture = { type = "checker", colors = [[0.9, 0.9, 0.2], [0.1, 0.2, 0.3]], scale = 1 }

[materials.small]
type = "diffuse"
texture = { type = "checker", colors = [[1, 1, 1], [0, 0, 0]], scale = 0.5 }

[[lights]]
type = "point"
position = [0, 4, -2]
intensity = 8

[[objects]]
type = "mesh"
vertices = [[-2, 0.5, 1], [0, 0.5, 1], [-2, 2.5, 1], [0, 2.5, 1]]
faces = [[0, 1, 3], [0, 3, 2]]
uvs = [[0, 0], [1, 0], [0, 1], [1, 1]]
material = { type = "diffuse", texture = { type = "image", file = "stripes.png", scale = [2, 3] } }

[[objects]]
type = "sphere"
center = [1, 1, 0]
radius = 0.6
material = "checks"
"""
        + FLOOR_TOML.format(material="small")
    )
    render_both(tmp_path, pbrt, toml)


@pytest.mark.parametrize("directive", ["Include", "Import"])
def test_includes(tmp_path, directive):
    """Included files share the graphics state; names in them resolve against the folder of the
    file given to raylume (pbrt-v4's search directory), not the including file's."""
    files = {
        "parts/lights.pbrt": f'LightSource "point" "rgb I" [8 8 8] "point3 from" [0 4 -2]\n'
        f'{directive} "parts/ball.pbrt"\n',
        "parts/ball.pbrt": 'Translate 1 1 0\nShape "sphere" "float radius" 0.5\n',
    }
    pbrt = HEADER + f'AttributeBegin\n{directive} "parts/lights.pbrt"\nAttributeEnd\n' + FLOOR_PBRT
    toml = (
        TOML_HEADER
        + """
[[lights]]
type = "point"
position = [0, 4, -2]
intensity = 8

[[objects]]
type = "sphere"
center = [1, 1, 0]
radius = 0.5
material = "pbrt-default"
"""
        + FLOOR_TOML.format(material="pbrt-default")
    )
    render_both(tmp_path, pbrt, toml, files)


def test_plymesh(tmp_path):
    """A PLY file stays a file; its placement is the CTM as a matrix."""
    (tmp_path / "tri.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "-1 0 0\n1 0 0\n0 1.5 0\n3 0 1 2\n"
    )
    pbrt = (
        HEADER
        + """
LightSource "point" "rgb I" [8 8 8] "point3 from" [0 4 -2]
AttributeBegin
  Translate 0 0.5 0.5
  Scale 1 0.5 1
  Shape "plymesh" "string filename" "tri.ply"
AttributeEnd
"""
        + FLOOR_PBRT
    )
    toml = (
        TOML_HEADER
        + """
[[lights]]
type = "point"
position = [0, 4, -2]
intensity = 8

[[objects]]
type = "mesh"
file = "tri.ply"
transform = { translate = [0, 0.5, 0.5], scale = [1, 0.5, 1] }
material = "pbrt-default"
"""
        + FLOOR_TOML.format(material="pbrt-default")
    )
    render_both(tmp_path, pbrt, toml)


def write_normal_map(path) -> None:
    """A map that leans its normals up the image (y) and along u (x), differently in each half."""
    pixels = np.zeros((4, 8, 3), dtype=np.uint8)
    pixels[:, :4] = (128, 200, 220)
    pixels[:, 4:] = (200, 100, 220)
    PILImage.fromarray(pixels).save(path)


def board_scenes(texture: str = "", material: str = "", shape: str = "", toml_map: str = "", wall=False):
    """(pbrt, toml): a diffuse board with pbrt's UVs under a point light, over the floor, and a
    wall behind it where `wall`; in pbrt, `texture` (a Texture line) before it, `material` and
    `shape` appended to its Material's and Shape's parameters; in TOML, `toml_map` (a map key)
    in its material."""
    pbrt = (
        HEADER
        + 'LightSource "point" "rgb I" [8 8 8] "point3 from" [1 4 -2]\n'
        + texture
        + f"""
AttributeBegin
  Material "diffuse" "rgb reflectance" [0.7 0.6 0.5]{material}
  Shape "bilinearmesh" "point3 P" [-2 0.5 1  0 0.5 1  -2 2.5 1  0 2.5 1] "point2 uv" [0 0  1 0  0 1  1 1]{shape}
AttributeEnd
"""
        + ('Shape "bilinearmesh" "point3 P" [-4 0 3  4 0 3  -4 4 3  4 4 3]\n' if wall else "")
        + FLOOR_PBRT
    )
    toml = (
        TOML_HEADER
        + """
[[lights]]
type = "point"
position = [1, 4, -2]
intensity = 8

[[objects]]
type = "mesh"
vertices = [[-2, 0.5, 1], [0, 0.5, 1], [-2, 2.5, 1], [0, 2.5, 1]]
faces = [[0, 1, 3], [0, 3, 2]]
uvs = [[0, 0], [1, 0], [0, 1], [1, 1]]
"""
        + f'material = {{ type = "diffuse", color = [0.7, 0.6, 0.5]{", " + toml_map if toml_map else ""} }}\n'
        + (
            """
[[objects]]
type = "mesh"
vertices = [[-4, 0, 3], [4, 0, 3], [-4, 4, 3], [4, 4, 3]]
faces = [[0, 1, 3], [0, 3, 2]]
material = "pbrt-default"
"""
            if wall
            else ""
        )
        + FLOOR_TOML.format(material="pbrt-default")
    )
    return pbrt, toml


def test_normal_maps(tmp_path):
    """A material's "string normalmap" is its normal_map (pbrt-v4 reads it as stored, at (u, v)
    with v = 1 the image's top, as raylume does): the same bits as the TOML's normal_map."""
    write_normal_map(tmp_path / "bumps.png")
    flat = render_both(tmp_path, *board_scenes())
    mapped = render_both(
        tmp_path,
        *board_scenes(material=' "string normalmap" "bumps.png"', toml_map='normal_map = { file = "bumps.png" }'),
    )
    assert np.abs(mapped.rgb - flat.rgb).max() > 0.05, "the map changes nothing: the test would prove nothing"


def test_bump_maps(tmp_path):
    """A material's "texture displacement" naming a float imagemap is its bump_map (pbrt-v4's
    BumpMap: the texture's value, times its `scale`, displaces the surface; a PNG's texels
    sRGB-decoded by default): the same bits as the TOML's bump_map."""
    heights = (np.add.outer(np.arange(8), np.arange(8)) * 16 % 256).astype(np.uint8)
    PILImage.fromarray(heights, mode="L").save(tmp_path / "heights.png")
    texture = 'Texture "bumps" "float" "imagemap" "string filename" "heights.png" "float scale" 1.5 "float uscale" 2\n'
    flat = render_both(tmp_path, *board_scenes(texture))
    mapped = render_both(
        tmp_path,
        *board_scenes(
            texture,
            material=' "texture displacement" "bumps"',
            toml_map='bump_map = { file = "heights.png", scale = [2, 1], height = 1.5, encoding = "srgb" }',
        ),
    )
    assert np.abs(mapped.rgb - flat.rgb).max() > 0.05, "the map changes nothing: the test would prove nothing"


def test_alpha_maps(tmp_path):
    """A shape's "texture alpha" naming a float imagemap gives its material an alpha_map (pbrt-v4
    cuts where alpha is 0 and keeps a fraction alpha elsewhere; raylume cuts below 0.5, a PNG's
    texels sRGB-decoded as pbrt-v4 reads them): the same bits as the TOML's alpha_map, a wall
    seen and lit through the holes."""
    mask = np.zeros((8, 8), dtype=np.uint8)
    mask[:, 4:] = 255
    mask[:2] = 255
    PILImage.fromarray(mask, mode="L").save(tmp_path / "mask.png")
    texture = 'Texture "leaf" "float" "imagemap" "string filename" "mask.png"\n'
    whole = render_both(tmp_path, *board_scenes(texture, wall=True))
    cut = render_both(
        tmp_path,
        *board_scenes(
            texture,
            shape='\n    "texture alpha" "leaf"',
            toml_map='alpha_map = { file = "mask.png", cutoff = 0.5, encoding = "srgb" }',
            wall=True,
        ),
    )
    assert np.abs(cut.rgb - whole.rgb).max() > 0.05, "the mask changes nothing: the test would prove nothing"
