"""The Mitsuba 3 XML reader against hand-written expectations: parameters (<default>, $name,
--define), ids and refs, includes, transforms in XML order, the camera's field of view and
handedness, serialized meshes, named materials, and every unsupported element named (a warning
or an error with the file and line). The images themselves are checked against Mitsuba in
tests/test_mitsuba_vs_reference.py.
"""

from __future__ import annotations

import math
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference.mitsuba_xml_scenes import box_mesh, serialized_bytes
from test_pbrt_analytic import assert_renders_as_the_sphere_written_with

import raylume
from raylume.errors import SceneError
from raylume.scene.checks import SceneWarning
from raylume.scene.mitsuba_named import CONDUCTORS, IORS

SENSOR = """
  <sensor type="perspective">
    <float name="fov" value="{fov}"/>
    <transform name="to_world">{mirror}<lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/></film>
  </sensor>
"""


def xml(body: str, *, fov=45, mirror="", width=16, height=16, extra="") -> str:
    sensor = SENSOR.format(fov=fov, mirror=mirror, width=width, height=height)
    return f'<scene version="3.0.0">{extra}{sensor}{body}\n</scene>\n'


OBJ_TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def load(tmp_path: Path, text: str, name="scene.xml", **kwargs):
    path = tmp_path / name
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)  # an unexpected warning fails the test
        return raylume.load(path, **kwargs)


def sphere(centre="0, 0, 0", radius="1", inner="") -> str:
    x, y, z = (c.strip() for c in centre.split(","))
    return (
        f'<shape type="sphere"><point name="center" x="{x}" y="{y}" z="{z}"/>'
        f'<float name="radius" value="{radius}"/>{inner}</shape>'
    )


# ---------------------------------------------------------------- parameters, ids, includes


def test_defaults_are_used_and_defines_win(tmp_path):
    text = xml(sphere(radius="$r"), extra='<default name="r" value="0.25"/>')
    assert load(tmp_path, text).objects[0].radius == 0.25
    assert load(tmp_path, text, defines={"r": "0.5"}).objects[0].radius == 0.5
    # numbers as Mitsuba's Python API takes them ("expected str instance" before)
    assert load(tmp_path, text, defines={"r": 0.5}).objects[0].radius == 0.5
    with pytest.raises(TypeError, match=r"defines\['r'\]: a string or a number is needed, got \[0.5\]"):
        load(tmp_path, text, defines={"r": [0.5]})


def test_a_define_the_scene_never_uses_is_refused(tmp_path):
    """As Mitsuba's -D ("Found unused parameters"): a misspelt name changed nothing, silently."""
    text = xml(sphere(radius="$r"), extra='<default name="r" value="0.25"/>')
    with pytest.raises(SceneError, match=r"--define rr: the scene has no parameter \$rr \(it has: \$r\)"):
        load(tmp_path, text, defines={"rr": "0.5"})
    assert load(tmp_path, text.replace("$r", "0.5"), defines={"r": "0.1"}).objects[0].radius == 0.5  # a <default>


def test_a_parameter_substitutes_inside_attribute_text(tmp_path):
    text = xml(sphere(centre="$x, 0, 1"), extra='<default name="x" value="2"/>')
    assert load(tmp_path, text).objects[0].center == (-2.0, 0.0, 1.0)  # x mirrored into raylume's frame


def test_an_undefined_parameter_names_file_line_and_how_to_define_it(tmp_path):
    text = xml(sphere(radius="$size"))
    with pytest.raises(SceneError, match=r"scene\.xml:\d+: <float>: \$size is not defined.*--define size="):
        load(tmp_path, text)


def test_refs_name_the_bsdf_and_an_unknown_id_is_an_error(tmp_path):
    bsdf = '<bsdf type="diffuse" id="paint"><rgb name="reflectance" value="0.1, 0.2, 0.3"/></bsdf>'
    scene = load(tmp_path, xml(bsdf + sphere(inner='<ref id="paint"/>')))
    assert scene.objects[0].material == "paint"
    assert scene.materials["paint"].color == (0.1, 0.2, 0.3)
    with pytest.raises(SceneError, match=r"scene\.xml:\d+: <ref>: no element with id 'varnish'"):
        load(tmp_path, xml(bsdf + sphere(inner='<ref id="varnish"/>')))


def test_an_alias_names_the_element_again(tmp_path):
    """<alias id="red" as="crimson"/>: a ref to crimson is a ref to red (Mitsuba 3 renders such a
    file's sphere red; the alias's id had been taken for a second element with that id)."""
    bsdf = (
        '<bsdf type="diffuse" id="red"><rgb name="reflectance" value="1, 0, 0"/></bsdf><alias id="red" as="crimson"/>'
    )
    scene = load(tmp_path, xml(bsdf + sphere(inner='<ref id="crimson"/>')))
    assert scene.materials[scene.objects[0].material].color == (1.0, 0.0, 0.0)
    with pytest.raises(SceneError, match="id 'red' is already used"):
        load(tmp_path, xml(bsdf + '<alias id="red" as="red"/>' + sphere(inner='<ref id="red"/>')))


@pytest.mark.parametrize(
    "inner",
    [
        '<ref id="paint" name="bsdf"/>',  # as Blender's exporter writes a shape's material
        '<bsdf type="diffuse" name="bsdf"><rgb name="reflectance" value="1, 0, 0"/></bsdf>',
    ],
)
def test_a_bsdf_given_as_the_property_bsdf_is_the_shape_s_material(tmp_path, inner):
    """A shape's BSDF by its property name, referenced or nested: its material, without a
    warning that the property is ignored (the ref had been dropped for the default grey)."""
    bsdf = '<bsdf type="diffuse" id="paint"><rgb name="reflectance" value="1, 0, 0"/></bsdf>'
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = load(tmp_path, xml(bsdf + sphere(inner=inner)))
    material = scene.objects[0].material
    assert (scene.materials[material] if isinstance(material, str) else material).color == (1.0, 0.0, 0.0)


def test_a_duplicate_id_is_an_error(tmp_path):
    bsdf = '<bsdf type="diffuse" id="a"/>'
    with pytest.raises(SceneError, match="id 'a' is already used"):
        load(tmp_path, xml(bsdf + "\n" + bsdf))


def test_include_splices_the_other_files_elements_in(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "ball.xml").write_text(f'<scene version="3.0.0">{sphere(centre="1, 2, 3")}</scene>')
    scene = load(tmp_path, xml('<include filename="parts/ball.xml"/>'))
    assert scene.objects[0].center == (-1.0, 2.0, 3.0)


def test_files_named_in_an_included_file_are_found_from_the_scene_files_folder(tmp_path):
    """Mitsuba resolves the file names of an included file (meshes, images, further includes) by
    its file resolver, which holds the folder of the scene file it loads, not the included
    file's (xml.cpp): mitsuba-data's docs/scenes/include/matpreview.xml names
    "meshes/matpreview.serialized", which lies in docs/scenes/meshes."""
    (tmp_path / "include").mkdir()
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "box.obj").write_text(OBJ_TRIANGLE)
    (tmp_path / "include" / "parts.xml").write_text(
        '<scene version="3.0.0"><shape type="obj"><string name="filename" value="meshes/box.obj"/></shape>'
        '<include filename="include/more.xml"/></scene>'
    )
    (tmp_path / "include" / "more.xml").write_text(f'<scene version="3.0.0">{sphere()}</scene>')
    scene = load(tmp_path, xml('<include filename="include/parts.xml"/>'))
    assert [o.type for o in scene.objects] == ["mesh", "sphere"]
    assert (tmp_path / scene.objects[0].file).resolve() == (tmp_path / "meshes" / "box.obj").resolve()
    (tmp_path / "include" / "more.xml").write_text(
        '<scene version="3.0.0"><shape type="obj"><string name="filename" value="nowhere.obj"/></shape></scene>'
    )
    with pytest.raises(SceneError, match=r"more\.xml:1: .*no file 'nowhere\.obj' \(relative to .*include or to the "):
        load(tmp_path, xml('<include filename="include/parts.xml"/>'))


def test_a_file_that_includes_itself_is_refused(tmp_path):
    (tmp_path / "loop.xml").write_text('<scene version="3.0.0"><include filename="loop.xml"/></scene>')
    with pytest.raises(SceneError, match="includes nest deeper"):
        load(tmp_path, xml('<include filename="loop.xml"/>'))


def test_invalid_xml_names_the_file_and_line(tmp_path):
    text = xml(sphere()).replace("<float", "<float <", 1)
    line = next(k for k, row in enumerate(text.splitlines(), 1) if "<float <" in row)
    with pytest.raises(SceneError, match=rf"scene\.xml:{line}: invalid XML"):
        load(tmp_path, text)


# ---------------------------------------------------------------- transforms and the camera


def placed(tmp_path, ops: str):
    """The centre raylume gets for Mitsuba's unit sphere placed by `ops`, in Mitsuba's frame."""
    body = f'<shape type="sphere"><transform name="to_world">{ops}</transform></shape>'
    obj = load(tmp_path, xml(body)).objects[0]
    return np.array([-obj.center[0], obj.center[1], obj.center[2]]), obj.radius  # undo the x mirror


@pytest.mark.parametrize(
    ("ops", "centre", "radius"),
    [
        ('<scale value="2"/><translate x="1"/>', (1, 0, 0), 2),
        ('<translate x="1"/><scale value="2"/>', (2, 0, 0), 2),  # the translation is scaled too: XML order
        ('<translate x="1"/><rotate y="1" angle="90"/>', (0, 0, -1), 1),  # right-handed turn about +y
        ('<translate z="1"/><rotate x="1" angle="90"/>', (0, -1, 0), 1),
        ('<translate x="1"/><rotate value="0, 0, 1" angle="90"/>', (0, 1, 0), 1),
        ('<matrix value="2 0 0 3  0 2 0 4  0 0 2 5  0 0 0 1"/>', (3, 4, 5), 2),
        ('<lookat origin="1, 2, 3" target="1, 2, 4" up="0, 1, 0"/>', (1, 2, 3), 1),
    ],
)
def test_transforms_compose_in_xml_order(tmp_path, ops, centre, radius):
    got, r = placed(tmp_path, ops)
    np.testing.assert_allclose(got, centre, atol=1e-12)
    assert r == pytest.approx(radius)


def test_a_mesh_transform_round_trips_through_raylumes_transform_table(tmp_path):
    from raylume.scene.mesh import transform_matrix
    from raylume.scene.mitsuba_props import rotation

    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    ops = '<scale x="2" y="3" z="0.5"/><rotate value="1, 2, 3" angle="37"/><translate x="1" y="-2" z="0.5"/>'
    body = (
        f'<shape type="obj"><string name="filename" value="m.obj"/><transform name="to_world">{ops}</transform></shape>'
    )
    t = load(tmp_path, xml(body)).objects[0].transform
    expected = np.eye(4)
    expected[:3, 3] = (1, -2, 0.5)
    expected = expected @ rotation(np.array([1.0, 2.0, 3.0]), 37) @ np.diag([2, 3, 0.5, 1])
    mirror = np.diag([-1.0, 1, 1, 1])
    np.testing.assert_allclose(transform_matrix(t.translate, t.rotate, t.scale3), mirror @ expected, atol=1e-12)


def test_a_shearing_mesh_transform_is_kept_as_a_matrix(tmp_path):
    from raylume.scene.mitsuba_props import rotation

    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    ops = '<rotate z="1" angle="30"/><scale x="3"/>'
    body = (
        f'<shape type="obj"><string name="filename" value="m.obj"/><transform name="to_world">{ops}</transform></shape>'
    )
    t = load(tmp_path, xml(body)).objects[0].transform
    expected = np.diag([-1.0, 1, 1, 1]) @ np.diag([3.0, 1, 1, 1]) @ rotation(np.array([0.0, 0, 1]), 30)
    np.testing.assert_allclose(np.array(t.matrix), expected, atol=1e-12)


@pytest.mark.parametrize(
    ("axis", "width", "height", "tan_vertical"),
    [
        ("x", 64, 32, math.tan(math.radians(30)) / 2),
        ("y", 64, 32, math.tan(math.radians(30))),
        ("diagonal", 64, 32, math.tan(math.radians(30)) / math.sqrt(5)),
        ("smaller", 64, 32, math.tan(math.radians(30))),  # the smaller side is the height
        ("larger", 32, 64, math.tan(math.radians(30))),  # the larger side is the height
        ("smaller", 32, 64, math.tan(math.radians(30)) * 2),  # the width, half the height
    ],
)
def test_fov_axis_becomes_raylumes_vertical_fov(tmp_path, axis, width, height, tan_vertical):
    text = xml("", fov=60, width=width, height=height).replace(
        '<float name="fov"', f'<string name="fov_axis" value="{axis}"/><float name="fov"'
    )
    scene = load(tmp_path, text)
    assert math.tan(math.radians(scene.camera.fov) / 2) == pytest.approx(tan_vertical)
    assert (scene.render.width, scene.render.height) == (width, height)


def rendered_side(scene) -> str:
    """Where the scene's one object is in a cast render: 'left' or 'right'."""
    objects = raylume.render(scene.replace(render={"mode": "cast", "spp": 1, "max_depth": 1})).aovs["object"]
    columns = np.nonzero((objects >= 0).any(axis=0))[0]
    return "left" if columns.mean() < objects.shape[1] / 2 else "right"


def test_the_image_is_mitsubas_not_its_mirror_image(tmp_path):
    # Mitsuba is right-handed: looking down -z with y up, +x is on the right of the image
    assert rendered_side(load(tmp_path, xml(sphere(centre="2, 0, 0")))) == "right"


def test_a_mirrored_sensor_shows_mitsubas_mirror_image(tmp_path):
    # Blender's exports put <scale x="-1"/> in the sensor's to_world: Mitsuba shows +x on the left
    scene = load(tmp_path, xml(sphere(centre="2, 0, 0"), mirror='<scale x="-1"/>'))
    assert rendered_side(scene) == "left"


def test_a_thinlens_aperture_radius_is_half_raylumes_aperture(tmp_path):
    text = xml("").replace('type="perspective">', 'type="thinlens"><float name="aperture_radius" value="0.1"/>')
    text = text.replace("<film", '<float name="focus_distance" value="4"/><film')
    camera = load(tmp_path, text).camera
    assert (camera.aperture, camera.focus_distance) == (pytest.approx(0.2), 4.0)


def test_film_sampler_filter_and_integrator_become_render_settings(tmp_path):
    text = xml(
        '<integrator type="volpath"><integer name="max_depth" value="7"/></integrator>',
    ).replace(
        "</film>",
        '<rfilter type="box"/></film><sampler type="stratified"><integer name="sample_count" value="9"/></sampler>',
    )
    render = load(tmp_path, text).render
    assert (render.mode, render.spp, render.max_depth, render.filter) == ("path", 9, 7, "box")
    assert load(tmp_path, xml("")).render.filter == "gaussian"  # hdrfilm's default rfilter


# ---------------------------------------------------------------- materials


def test_named_conductors_and_iors_come_from_mitsubas_table(tmp_path):
    body = (
        '<bsdf type="conductor" id="gold"><string name="material" value="Au"/></bsdf>'
        '<bsdf type="dielectric" id="water"><string name="int_ior" value="water"/>'
        '<string name="ext_ior" value="air"/></bsdf>'
        '<bsdf type="roughplastic" id="p"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/>'
        "</bsdf>"
    )
    materials = load(tmp_path, xml(body)).materials
    assert (materials["gold"].eta, materials["gold"].k) == CONDUCTORS["Au"]
    assert materials["gold"].roughness == 0  # a smooth conductor
    assert materials["water"].ior == pytest.approx(IORS["water"] / IORS["air"])
    assert (materials["p"].type, materials["p"].roughness, materials["p"].ior) == (
        "plastic",
        0.3,
        pytest.approx(1.49 / IORS["air"]),
    )
    # the table is Mitsuba's RGB: gold reflects red more than blue
    assert CONDUCTORS["Au"][1][0] > CONDUCTORS["Au"][1][2]
    assert IORS["bk7"] == pytest.approx(1.5046, abs=1e-4)


def test_an_unknown_named_material_is_an_error_listing_the_names(tmp_path):
    body = '<bsdf type="conductor" id="m"><string name="material" value="Unobtainium"/></bsdf>'
    with pytest.raises(SceneError, match=r"scene\.xml:\d+: <bsdf type=\"conductor\">: material 'Unobtainium'.*Au"):
        load(tmp_path, xml(body))


def test_an_area_emitter_makes_the_shape_emit_and_without_a_bsdf_it_is_black(tmp_path):
    body = sphere(inner='<emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>')
    material = load(tmp_path, xml(body)).objects[0].material
    assert (material.type, material.color, material.emission) == ("diffuse", (0.0, 0.0, 0.0), (1.0, 2.0, 3.0))
    assert load(tmp_path, xml(sphere())).objects[0].material.color == (0.5, 0.5, 0.5)  # Mitsuba's default


def test_lights_and_environment(tmp_path):
    body = (
        '<emitter type="point"><point name="position" x="1" y="2" z="3"/><rgb name="intensity" value="5"/></emitter>'
        '<emitter type="directional"><vector name="direction" x="0" y="-1" z="0"/>'
        '<rgb name="irradiance" value="2"/></emitter>'
        '<emitter type="spot"><float name="cutoff_angle" value="30"/><float name="beam_width" value="30"/>'
        '<transform name="to_world"><lookat origin="1, 4, 0" target="1, 0, 0" up="0, 0, 1"/></transform></emitter>'
        '<emitter type="constant"><rgb name="radiance" value="0.1, 0.2, 0.3"/></emitter>'
    )
    scene = load(tmp_path, xml(body))
    point, directional, spot = scene.lights
    assert (point.position, point.intensity) == ((-1.0, 2.0, 3.0), (5.0, 5.0, 5.0))
    assert directional.direction == (0.0, 1.0, 0.0)  # raylume's points towards the light
    np.testing.assert_allclose(spot.position, (-1, 4, 0), atol=1e-12)
    np.testing.assert_allclose(spot.direction, (0, -1, 0), atol=1e-12)
    assert (spot.angle, spot.inner) == (30, 30)
    assert scene.environment.color == (0.1, 0.2, 0.3)


# ---------------------------------------------------------------- serialized meshes


def test_serialized_meshes_are_read_by_index(tmp_path):
    from raylume.scene.serialized import read_serialized

    meshes = [box_mesh((0, 0, 0), (1, 1, 1)), box_mesh((-2, -3, -4), (5, 6, 7))]
    path = tmp_path / "two.serialized"
    path.write_bytes(serialized_bytes(meshes))
    for k, (v, f) in enumerate(meshes):
        vertices, faces, normals, uvs = read_serialized(path, k)
        np.testing.assert_array_equal(vertices, v)
        np.testing.assert_array_equal(faces, f)
        assert normals is None and uvs is None
    with pytest.raises(ValueError, match="shape_index 2 is out of range: the file holds 2"):
        read_serialized(path, 2)


def test_a_version_3_serialized_mesh_with_double_precision_and_normals(tmp_path):
    from raylume.scene.serialized import read_serialized

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f8")
    n = np.array([[0, 0, 1]] * 3, dtype="<f8")
    body = struct.pack("<I", 0x2000 | 0x0001) + struct.pack("<QQ", 3, 1) + v.tobytes() + n.tobytes()
    body += np.array([0, 1, 2], dtype="<u4").tobytes()
    data = struct.pack("<HH", 0x041C, 3) + zlib.compress(body) + struct.pack("<I", 0) + struct.pack("<I", 1)
    (tmp_path / "old.serialized").write_bytes(data)
    vertices, faces, normals, _ = read_serialized(tmp_path / "old.serialized")
    np.testing.assert_array_equal(vertices, v)
    np.testing.assert_array_equal(normals, n)
    np.testing.assert_array_equal(faces, [[0, 1, 2]])


def test_a_damaged_serialized_file_is_a_scene_error_when_rendered(tmp_path):
    (tmp_path / "bad.serialized").write_bytes(struct.pack("<HH", 0x041C, 4) + b"not zlib" + struct.pack("<QI", 0, 1))
    body = '<shape type="serialized"><string name="filename" value="bad.serialized"/></shape>'
    scene = load(tmp_path, xml(body))
    with pytest.raises(raylume.RaylumeError, match="bad.serialized.*serialized mesh"):
        raylume.render(scene, mode="cast", width=4, height=4)


# ---------------------------------------------------------------- unsupported elements are named


@pytest.mark.parametrize("shape", ['<shape type="ply"><string name="filename" value="t.ply"/>', '<shape type="disk">'])
def test_a_checkerboard_is_not_said_to_lie_otherwise_on_a_shape(tmp_path, shape):
    """raylume's checker is a 3D pattern in world space: it needs no texture coordinates, so a
    PLY mesh's v axis or a disk's own (u, v) changes nothing of it; only the checker's warning is
    given."""
    (tmp_path / "t.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    )
    body = f'{shape}<bsdf type="diffuse"><texture type="checkerboard" name="reflectance"/></bsdf></shape>'
    (tmp_path / "scene.xml").write_text(xml(body))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        raylume.load(tmp_path / "scene.xml")
    messages = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert len(messages) == 1 and "checker is a 3D pattern in world space" in messages[0], messages


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ('<bsdf type="hair" id="h"/>', r'<bsdf type="hair">: raylume has no such BSDF: a grey diffuse'),
        ('<bsdf type="principled" id="p"/>', r"no principled BSDF: a plastic material .* replaces it"),
        ('<bsdf type="thindielectric" id="t"/>', r"no thin dielectric: a null surface .* 0\.0\d\d, is lost"),
        ('<bsdf type="roughconductor" id="r"/>', r"distribution 'beckmann': .* GGX of alpha 0\.1 replaces it"),
        ('<bsdf type="diffuse" id="d"><float name="sheen" value="1"/></bsdf>', r"property 'sheen' is not supported"),
        ('<bsdf type="bumpmap" id="b"><bsdf type="diffuse"/></bsdf>', r"a bumpmap without a nested <texture>"),
        (sphere(inner='<boolean name="flip_normals" value="true"/>'), "flip_normals: raylume's surfaces are two-sided"),
        (
            '<emitter type="spot"><float name="cutoff_angle" value="30"/></emitter>',
            "smooth step in the cosine",
        ),
        ('<integrator type="aov"/>', "no such integrator: its path tracer replaces it"),
        (
            '<shape type="disk"><bsdf type="diffuse"><texture type="bitmap" name="reflectance">'
            '<string name="filename" value="t.png"/></texture></bsdf></shape>',
            "disk has texture coordinates of its own, not Mitsuba's",
        ),
        (
            '<bsdf type="diffuse" id="c"><texture type="checkerboard" name="reflectance"/></bsdf>',
            "checker is a 3D pattern in world space",
        ),
    ],
)
def test_what_raylume_replaces_is_named_in_a_warning(tmp_path, body, message):
    (tmp_path / "t.png").write_bytes(b"")  # named, never read while loading
    path = tmp_path / "scene.xml"
    path.write_text(xml(body))
    with pytest.warns(SceneWarning, match=r"scene\.xml:\d+: .*" + message):
        raylume.load(path)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ('<shape type="bsplinecurve"/>', r'<shape type="bsplinecurve">: raylume has no such shape'),
        ('<emitter type="projector"/>', r'<emitter type="projector">: raylume has no such emitter'),
        (
            '<integrator type="volpath"/><medium type="heterogeneous" id="m"/>'
            + sphere(inner='<ref name="interior" id="m"/>'),
            "homogeneous media",
        ),
        (
            '<bsdf type="diffuse" id="s"><spectrum name="reflectance" value="400:0.1, 700:0.9"/></bsdf>',
            "wavelength:value pairs",
        ),
        ('<shape type="sphere"><transform name="to_world"><scale x="2"/></transform></shape>', "ellipsoid"),
        ('<emitter type="area"/>', "an area emitter belongs inside a <shape>"),
    ],
)
def test_what_raylume_cannot_replace_is_an_error_naming_file_line_and_element(tmp_path, body, message):
    with pytest.raises(SceneError, match=r"scene\.xml:\d+: .*" + message):
        load(tmp_path, xml(body))


AREA = '<emitter type="area"><rgb name="radiance" value="1"/></emitter>'


@pytest.mark.parametrize(
    ("shape", "scale", "message"),
    [
        ("sphere", '<scale value="0"/>', r'<shape type="sphere">: its to_world is singular \(it scales by 0\)'),
        ("sphere", '<scale x="0"/>', r"singular \(it scales by 0\), which would collapse the sphere"),
        ("disk", '<scale value="0"/>', r'<shape type="disk">: its to_world is singular'),
        ("cylinder", '<scale y="0"/>', r'<shape type="cylinder">: its to_world is singular'),
        ("rectangle", '<scale value="0"/>', r'objects\[0\] \(.*scene\.xml:\d+ <shape type="rectangle">\): u and v'),
        ("envmap", '<scale value="0"/>', r'<emitter type="envmap">: its to_world is singular'),
    ],
)
def test_a_to_world_that_scales_by_0_is_an_error_without_a_numpy_warning(tmp_path, shape, scale, message):
    (tmp_path / "sky.exr").write_bytes(b"")  # named, not read while loading
    transform = f'<transform name="to_world">{scale}</transform>'
    if shape == "envmap":
        body = f'<emitter type="envmap"><string name="filename" value="sky.exr"/>{transform}</emitter>'
    else:  # emitting, so that a rectangle's black twin is made too
        body = f'<shape type="{shape}">{transform}{AREA}</shape>'
    path = tmp_path / "scene.xml"
    path.write_text(xml(body))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's RuntimeWarning on a division by 0 included
        with pytest.raises(SceneError, match=r"scene\.xml:?\d*: .*" + message):
            raylume.load(path)


def test_other_sensors_and_files_without_a_sensor_are_refused(tmp_path):
    ortho = xml("").replace('type="perspective"', 'type="orthographic"')
    with pytest.raises(SceneError, match="perspective"):
        load(tmp_path, ortho)
    with pytest.raises(SceneError, match="has no <sensor>"):
        load(tmp_path, '<scene version="3.0.0"><shape type="sphere"/></scene>')


def test_session_and_render_take_a_mitsuba_file_with_defines(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(xml(sphere(centre="$x, 0, 0"), extra='<default name="x" value="-2"/>'))
    assert raylume.Session(path, defines={"x": "2"}).scene.objects[0].center == (-2.0, 0.0, 0.0)
    image = raylume.render(path, defines={"x": "2"}, mode="cast", max_depth=1)
    columns = np.nonzero((image.aovs["object"] >= 0).any(axis=0))[0]
    assert columns.mean() > image.aovs["object"].shape[1] / 2  # Mitsuba's +x: the image's right
    with pytest.raises(SceneError, match="sets parameters of a Mitsuba scene"):
        raylume.render("seed", defines={"x": "1"})


@pytest.mark.parametrize(
    ("params", "kind"),
    [
        ("", "plastic"),
        ('<float name="metallic" value="0.8"/>', "conductor"),
        ('<float name="spec_trans" value="1"/>', "dielectric"),
    ],
)
def test_principled_becomes_the_type_of_its_dominant_lobe(tmp_path, params, kind):
    body = (
        f'<bsdf type="principled" id="p"><rgb name="base_color" value="0.2, 0.4, 0.6"/>'
        f'<float name="roughness" value="0.5"/><float name="sheen" value="0.3"/>{params}</bsdf>'
    )
    path = tmp_path / "scene.xml"
    path.write_text(xml(body))
    with pytest.warns(SceneWarning, match=f"a {kind} material .* sheen ignored"):
        material = raylume.load(path).materials["p"]
    assert (material.type, material.color, material.roughness) == (kind, (0.2, 0.4, 0.6), 0.25)


def test_a_film_and_sampler_defined_at_the_top_and_referenced_by_the_sensor(tmp_path):
    text = (
        '<scene version="2.0.0"><film type="hdrfilm" id="film"><integer name="width" value="40"/>'
        '<integer name="height" value="30"/></film><sampler type="independent" id="sampler">'
        '<integer name="sample_count" value="12"/></sampler>'
        '<sensor type="perspective"><float name="focus_distance" value="1000"/><ref id="sampler"/><ref id="film"/>'
        "</sensor></scene>"
    )
    render = load(tmp_path, text).render
    assert (render.width, render.height, render.spp) == (40, 30, 12)


# ---------------------------------------------------------------- properties


@settings(max_examples=60, deadline=None)
@given(
    translate=st.lists(st.floats(-100, 100), min_size=3, max_size=3),
    rotate=st.lists(st.floats(-360, 360), min_size=3, max_size=3),
    scale=st.lists(st.floats(0.01, 100).flatmap(lambda s: st.sampled_from([s, -s])), min_size=3, max_size=3),
)
def test_an_affine_matrix_and_its_transform_table_agree(translate, rotate, scale):
    from raylume.scene.affine import decompose
    from raylume.scene.mesh import transform_matrix

    m = transform_matrix(translate, rotate, scale)
    t = decompose(m)
    np.testing.assert_allclose(transform_matrix(**t), m, atol=1e-9 * max(1.0, np.abs(m).max()))


@settings(max_examples=80, deadline=None)
@given(
    text=st.text(alphabet=st.sampled_from(list('<>/="$ abcdefgnrstuvxyz0123456789.,-')), max_size=200),
    where=st.sampled_from(["body", "value"]),
)
def test_any_text_is_a_scene_or_a_scene_error_never_a_crash(tmp_path_factory, text, where):
    folder = tmp_path_factory.mktemp("fuzz")
    body = text if where == "body" else sphere(radius=text.replace('"', ""))
    path = folder / "scene.xml"
    path.write_text(xml(body))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        try:
            scene = raylume.load(path)
        except SceneError as exc:
            assert str(exc).startswith(str(path))
        else:
            assert all(math.isfinite(c) for obj in scene.objects for c in getattr(obj, "center", (0, 0, 0)))


TAGS = ["shape", "bsdf", "emitter", "texture", "float", "integer", "rgb", "spectrum", "point", "vector", "string"]
TAGS += ["boolean", "transform", "translate", "rotate", "scale", "matrix", "lookat", "ref", "include", "default"]
TYPES = ["sphere", "rectangle", "cube", "disk", "cylinder", "obj", "serialized", "shapegroup", "instance", "diffuse"]
TYPES += ["conductor", "roughconductor", "dielectric", "thindielectric", "plastic", "twosided", "null", "principled"]
TYPES += ["area", "point", "spot", "directional", "constant", "envmap", "bitmap", "checkerboard"]
NAMES = ["to_world", "radius", "center", "reflectance", "material", "alpha", "int_ior", "radiance", "intensity"]
NAMES += ["filename", "position", "cutoff_angle", "p0", "base_color", "distribution", "angle", "value", "x"]
VALUES = ["1", "-1", "0", "0.5, 0.2, 0.1", "1e400", "nan", "Au", "ggx", "abc", "$p", "2 3", "", "1, 2, 3, 4"]


def elements(depth: int = 2):
    attrs = st.dictionaries(
        st.sampled_from(["type", "name", "value", "id", "x", "y", "angle", "origin", "target"]),
        st.one_of(st.sampled_from(TYPES), st.sampled_from(NAMES), st.sampled_from(VALUES)),
        max_size=4,
    )
    children = st.lists(elements(depth - 1), max_size=3) if depth > 0 else st.just([])
    return st.builds(
        lambda tag, a, kids: f"<{tag} " + " ".join(f'{k}="{v}"' for k, v in a.items()) + f">{''.join(kids)}</{tag}>",
        st.sampled_from(TAGS),
        attrs,
        children,
    )


@settings(max_examples=60, deadline=None)
@given(body=st.lists(elements(), max_size=4))
def test_any_arrangement_of_elements_is_a_scene_or_a_scene_error(tmp_path_factory, body):
    path = tmp_path_factory.mktemp("fuzz") / "scene.xml"
    path.write_text(xml("".join(body)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SceneWarning)
        try:
            raylume.load(path)
        except SceneError as exc:
            assert str(exc).startswith(str(path)), exc


def test_a_value_raylume_refuses_names_the_element_it_came_from(tmp_path):
    body = sphere(centre="0, 0, 0", radius="-1") + "\n" + sphere(radius="2")
    body += '<emitter type="point"><rgb name="intensity" value="-1"/></emitter>'
    line = xml(body).splitlines().index(next(r for r in xml(body).splitlines() if 'value="-1"' in r)) + 1
    with pytest.raises(SceneError) as caught:
        load(tmp_path, xml(body))
    message = str(caught.value)
    assert f'objects[0].radius (scene.xml:{line} <shape type="sphere">): ' in message.replace(str(tmp_path) + "/", "")
    assert "lights[0].intensity (" in message and '<emitter type="point">): ' in message
    with pytest.raises(SceneError, match=r'scene\.xml:\d+: <film type="hdrfilm">: width and height must be at least 1'):
        load(tmp_path, xml("", width=0))


def test_a_flat_emitter_gets_a_black_twin_behind_its_back_and_emits_from_its_front_alone(tmp_path):
    # a rectangle facing down (local +z turned to -y), 4 x 2 wide, at y = 3
    body = (
        '<shape type="rectangle"><transform name="to_world"><scale x="2"/><rotate x="1" angle="90"/>'
        '<translate y="3"/></transform><emitter type="area"><rgb name="radiance" value="5"/></emitter></shape>'
    )
    light, twin = load(tmp_path, xml(body)).objects
    assert light.material.emission == (5.0, 5.0, 5.0)
    assert twin.material.emission == (0.0, 0.0, 0.0) and twin.material.color == (0.0, 0.0, 0.0)
    assert (twin.u, twin.v) == (light.u, light.v)
    np.testing.assert_allclose(np.subtract(twin.position, light.position), (0, 4e-3, 0), atol=1e-12)  # above it
    # seen from below it shines; from above, the twin hides it
    for y, lit in ((0.0, True), (6.0, False)):
        scene = load(tmp_path, xml(body)).replace(
            camera={"position": [0, y, 0.01], "look_at": [0, 3, 0], "up": [0, 0, 1]}, render={"mode": "cast"}
        )
        image = raylume.render(scene, width=4, height=4, max_depth=1)
        assert (image.aovs["object"][1:3, 1:3] == (0 if lit else 1)).all()


def test_an_emitting_open_mesh_is_named(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    body = '<shape type="obj"><string name="filename" value="m.obj"/><emitter type="area"/></shape>'
    path = tmp_path / "scene.xml"
    path.write_text(xml(body))
    with pytest.warns(SceneWarning, match="emit from both sides, Mitsuba's from the front alone"):
        raylume.load(path)


def test_the_example_mitsuba_scene_loads_without_warnings():
    example = Path(__file__).resolve().parents[1] / "examples" / "mitsuba" / "box.xml"
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        scene = raylume.load(example, defines={"res": "32"})
    assert (scene.render.width, scene.render.spp, scene.render.max_depth) == (32, 64, 8)
    assert scene.materials["red"].color == (0.65, 0.06, 0.05)


def test_an_environment_map_turns_with_the_mirror(tmp_path):
    (tmp_path / "sky.exr").write_bytes(b"")  # named, not read while loading
    env = (
        '<emitter type="envmap"><string name="filename" value="sky.exr"/>'
        '<transform name="to_world"><rotate y="1" angle="30"/></transform></emitter>'
    )
    plain = load(tmp_path, xml(env)).environment
    assert plain.rotate == pytest.approx((0, -30, 0))  # the mirror turns a rotation the other way
    mirrored = load(tmp_path, xml(env, mirror='<scale x="-1"/>')).environment
    assert np.linalg.det(np.array(mirrored.matrix)) == pytest.approx(-1)  # a mirrored sensor: a mirrored sky


def test_an_interior_that_is_no_medium_is_named_at_its_shape(tmp_path):
    """A <ref name="interior"> to a BSDF had been reported at the BSDF, as a heterogeneous medium."""
    text = xml(
        '<bsdf type="diffuse" id="m"/>' + sphere(inner='<ref id="m" name="interior"/>'),
        extra='<integrator type="volpath"/>',
    )
    with pytest.raises(
        SceneError,
        match=r"scene.xml:\d+: <shape type=\"sphere\">: interior: expected a <medium>, got a <bsdf> \(id 'm'\)$",
    ):
        load(tmp_path, text)


def test_homogeneous_media_with_volpath(tmp_path):
    medium = (
        '<medium type="homogeneous" id="{name}"><rgb name="albedo" value="0.5, 0.25, 1"/>'
        '<float name="sigma_t" value="2"/><float name="scale" value="{scale}"/>'
        '<phase type="hg"><float name="g" value="0.3"/></phase></medium>'
    )
    body = medium.format(name="milk", scale=1) + medium.format(name="fog", scale=0.01)
    body += sphere(inner='<bsdf type="null"/><ref name="interior" id="milk"/><ref name="exterior" id="fog"/>')
    text = xml(body, extra='<integrator type="volpath"/>').replace("<film", '<ref id="fog"/><film')
    scene = load(tmp_path, text)
    milk, fog = scene.media["milk"], scene.media["fog"]
    assert milk.sigma_s == (1.0, 0.5, 2.0) and milk.sigma_a == (1.0, 1.5, 0.0) and milk.g == 0.3
    assert fog.sigma_s == pytest.approx((0.01, 0.005, 0.02))
    assert scene.objects[0].interior == "milk" and scene.render.medium == "fog"
    # Mitsuba's path integrator ignores media: so does the scene read with it, saying so
    path = tmp_path / "path.xml"
    path.write_text(text.replace('<integrator type="volpath"/>', '<integrator type="path"/>'))
    with pytest.warns(SceneWarning, match="path integrator ignores media"):
        scene = raylume.load(path)
    assert not scene.media and scene.objects[0].interior is None and scene.render.medium is None


def test_a_sensors_film_and_sampler_named_as_blenders_exporter_names_them(tmp_path):
    """mitsuba-blender writes <film name="film"> and <sampler name="sampler">: read, and no
    warning that the properties 'film' and 'sampler' were ignored (load fails on a warning)."""
    sampler = '<sampler type="independent" name="sampler"><integer name="sample_count" value="8"/></sampler>'
    text = xml(sphere()).replace('<film type="hdrfilm">', sampler + '<film type="hdrfilm" name="film">')
    scene = load(tmp_path, text)
    assert (scene.render.width, scene.render.height, scene.render.spp) == (16, 16, 8)


def test_a_constant_spectrum_on_an_emitter_is_equal_energy_light(tmp_path):
    """Mitsuba 3.9.1's scalar_rgb evaluates a constant emitter of <spectrum value="0.6"/> to
    (0.7229, 0.5690, 0.5453), 0.6 times equal-energy light's sRGB, where an <rgb> or a <float> of
    0.6 gives grey (as does a reflectance's spectrum); raylume had drawn every one grey."""
    equal_energy = np.array([1.20479, 0.948291, 0.908916])
    for tag, expected in (("spectrum", 0.6 * equal_energy), ("rgb", [0.6] * 3), ("float", [0.6] * 3)):
        sky = f'<emitter type="constant"><{tag} name="radiance" value="0.6"/></emitter>'
        point = f'<emitter type="point"><{tag} name="intensity" value="0.6"/></emitter>'
        lamp = f'<emitter type="area"><{tag} name="radiance" value="0.6"/></emitter>'
        scene = load(tmp_path, xml(sky + point + sphere(inner=lamp)))
        np.testing.assert_allclose(scene.environment.color, expected, rtol=1e-5)
        np.testing.assert_allclose(scene.lights[0].intensity, expected, rtol=1e-5)
        np.testing.assert_allclose(scene.objects[0].material.emission, expected, rtol=1e-5)


def test_a_lookat_without_up_takes_mitsubas_up(tmp_path):
    """Mitsuba's up where <lookat> gives none is the first axis of its coordinate_system about
    the direction, not +y: for this view Mitsuba 3.9.1's sensor has up (0.9672, -0.0575, -0.2476)
    (its to_world read back), and raylume's image was rolled by about 90 degrees against it."""
    scene = (
        '<scene version="3.0.0"><sensor type="perspective"><transform name="to_world">'
        '<lookat origin="2, 4, 7" target="0, 0.5, 0"{up}/></transform></sensor>' + sphere() + "</scene>"
    )
    a = load(tmp_path, scene.format(up=""), name="a.xml").camera
    b = load(tmp_path, scene.format(up=' up="0.96720, -0.05748, -0.24758"'), name="b.xml").camera
    np.testing.assert_allclose(a.position, b.position)
    np.testing.assert_allclose(a.look_at, b.look_at)
    np.testing.assert_allclose(a.up, b.up, atol=1e-4)
    assert abs(a.up[1]) < 0.1  # not +y's roll


def test_a_cube_holding_a_medium_is_one_closed_mesh(tmp_path):
    """Six quads, as a cube is otherwise, have no inside to fill: the scene was refused. The mesh
    is the box [-1, 1]^3 placed by its to_world, closed (trimesh's check), its faces outward, a
    mirroring to_world included; it holds the medium as trimesh's own box does (path mode)."""
    import trimesh

    medium = '<medium type="homogeneous" name="interior"><float name="sigma_t" value="1.5"/></medium>'
    for scale in ("2, 1, 0.5", "-2, 1, 0.5"):
        cube = f'<shape type="cube"><transform name="to_world"><scale value="{scale}"/></transform>'
        text = xml(
            cube + f'<bsdf type="null"/>{medium}</shape><emitter type="constant"/>',
            extra='<integrator type="volpath"/>',
        )
        scene = load(tmp_path, text)
        (obj,) = scene.objects
        mesh = trimesh.Trimesh(np.array(obj.vertices), np.array(obj.faces), process=False)
        assert obj.type == "mesh" and obj.interior is not None and len(obj.faces) == 12
        assert mesh.is_watertight and mesh.volume == pytest.approx(8.0)  # positive: facing out
        np.testing.assert_allclose(mesh.bounds, [[-2, -1, -0.5], [2, 1, 0.5]])
    box = trimesh.creation.box(extents=[4, 2, 1])
    twin = scene.replace(
        objects=[obj.model_copy(update={"vertices": box.vertices.tolist(), "faces": box.faces.tolist()})]
    )
    size = {"width": 16, "height": 16, "spp": 64, "mode": "path"}
    a, b = raylume.render(scene, **size, aovs=False).rgb, raylume.render(twin, seed=1, **size, aovs=False).rgb
    assert 0.2 < a.mean() < 0.9  # the sky seen through the medium, dimmed
    diff = (a.astype(np.float64) - b).mean(axis=2)
    assert abs(diff.mean()) < 4 * diff.std(ddof=1) / math.sqrt(diff.size) + 1e-7


# ---------------------------------------------------------------- a textured sphere's (u, v)


def textured_ball(to_world: str) -> str:
    return xml(
        '<shape type="sphere"><float name="radius" value="0.5"/>'
        f'<transform name="to_world">{to_world}</transform>'
        '<bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="uv.png"/>'
        "</texture></bsdf></shape>",
        extra='<emitter type="constant"/>',
        fov=15,
        width=24,
        height=24,
    )


def uv_image(folder: Path) -> None:
    from raylume.image import save_array

    gradient = np.stack([*np.meshgrid(np.linspace(0, 1, 16), np.linspace(0, 1, 8)), np.full((8, 16), 0.5)], -1)
    save_array(folder / "uv.png", gradient.astype(np.float32))


def rotation(axis, degrees) -> np.ndarray:
    """A right-handed rotation (Mitsuba's Transform4f::rotate), by Rodrigues' formula."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t = math.radians(degrees)
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * k @ k


@pytest.mark.parametrize("sx", [1.5, -1.5])
def test_a_turned_textured_sphere_has_mitsubas_uv(tmp_path, sx):
    """Mitsuba 3's sphere (sphere.cpp): to_world is split into scale, rotation Q and translation
    (transform_decompose: Q negated where it mirrors, so that it is a rotation); a point's local
    = Q^T (p - centre) / r, u = atan2(local.y, local.x) / 2pi in [0, 1), v = acos(local.z) / pi,
    and a bitmap's v runs from the image's top. raylume's v runs up: at each point, raylume's
    (u, v) is Mitsuba's (u, 1 - v), the point mirrored into raylume's world (x -> -x)."""
    from raylume.compile import compile_scene
    from raylume.kernels.geometry.shape_sphere import uv as sphere_uv

    uv_image(tmp_path)
    to_world = f'<scale x="{sx}" y="1.5" z="1.5"/><rotate x="1" y="2" z="3" angle="40"/><translate x="0.3" y="-0.2"/>'
    scene = load(tmp_path, textured_ball(to_world))  # no warning
    rows = compile_scene(scene).kernel.shapes
    q = rotation((1, 2, 3), 40) @ np.diag([np.sign(sx), 1, 1])
    q = -q if np.linalg.det(q) < 0 else q
    centre, radius = np.array([0.3, -0.2, 0.0]), 0.75
    for local in np.random.default_rng(3).normal(size=(100, 3)):
        local /= np.linalg.norm(local)
        u = (math.atan2(local[1], local[0]) % (2 * math.pi)) / (2 * math.pi)
        v = math.acos(local[2]) / math.pi
        p = centre + radius * q @ local
        got_u, got_v = sphere_uv(rows, 0, (-p[0], p[1], p[2]))
        assert (got_u - u + 0.5) % 1.0 - 0.5 == pytest.approx(0.0, abs=1e-9)
        assert got_v == pytest.approx(1.0 - v, abs=1e-9)


def test_a_turned_textured_sphere_renders_as_the_sphere_written_with_its_transform(tmp_path):
    """The Mitsuba sphere's picture is that of raylume's sphere given the mirrored to_world and
    Mitsuba's z-up frame (raylume's object x, y, z = Mitsuba's -y, z, x) as its transform matrix."""
    uv_image(tmp_path)
    scene = load(tmp_path, textured_ball('<rotate x="1" y="2" z="3" angle="40"/><translate x="0.3" y="-0.2"/>'))
    matrix = np.eye(4)
    matrix[:3, :3] = np.diag([-1.0, 1, 1]) @ rotation((1, 2, 3), 40) @ [[0, 0, 1], [-1, 0, 0], [0, 1, 0]]
    matrix[:3, 3] = (-0.3, -0.2, 0.0)
    assert_renders_as_the_sphere_written_with(scene, matrix)
