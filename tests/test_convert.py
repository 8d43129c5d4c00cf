"""`raylume convert IN -o OUT.toml` and raylume.save_scene: the written file renders bit for bit
the image IN renders (a Mitsuba scene with meshes, a serialized mesh, a texture and an
environment map; a TOML scene), with its files referenced where they are; and the command line
of Mitsuba scenes (--define, errors with file and line, nothing written on bad input)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage
from reference.mitsuba_xml_scenes import box_mesh, envmap_pixels, serialized_bytes, write_exr, write_obj
from test_cli import raylume as cli

import raylume
from raylume.scene.export import scene_document

REPO = Path(__file__).resolve().parents[1]

SCENE = """<scene version="3.0.0">
  <default name="spp" value="4"/>
  <sensor type="perspective">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0.3, 1.5, 5" target="0, 0.4, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="20"/><integer name="height" value="14"/></film>
    <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
  </sensor>
  <integrator type="path"><integer name="max_depth" value="5"/></integrator>
  <bsdf type="diffuse" id="tex">
    <texture type="bitmap" name="reflectance"><string name="filename" value="textures/grid.png"/></texture>
  </bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="3"/></transform><ref id="tex"/>
  </shape>
  <shape type="obj">
    <string name="filename" value="meshes/octahedron.obj"/>
    <transform name="to_world"><scale value="0.5"/><rotate y="1" angle="20"/><translate x="-1" y="0.5"/></transform>
    <bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.7, 0.2, 0.2"/></bsdf>
  </shape>
  <shape type="serialized">
    <string name="filename" value="meshes/box.serialized"/>
    <transform name="to_world"><translate x="1"/></transform>
    <bsdf type="roughconductor"><string name="material" value="Cu"/><string name="distribution" value="ggx"/></bsdf>
  </shape>
  <shape type="sphere"><point name="center" x="0" y="0.4" z="0.8"/><float name="radius" value="0.4"/>
    <bsdf type="dielectric"/></shape>
  <emitter type="point"><point name="position" x="1" y="3" z="2"/><rgb name="intensity" value="8"/></emitter>
  <emitter type="envmap"><string name="filename" value="sky.exr"/>
    <transform name="to_world"><rotate y="1" angle="70"/></transform></emitter>
</scene>
"""


def write_mitsuba_scene(folder: Path) -> Path:
    (folder / "meshes").mkdir(parents=True)
    (folder / "textures").mkdir()
    write_obj(folder / "meshes" / "octahedron.obj")
    (folder / "meshes" / "box.serialized").write_bytes(serialized_bytes([box_mesh((-0.3, 0, -0.3), (0.3, 0.8, 0.3))]))
    grid = (np.indices((16, 16)).sum(axis=0) % 2 * 200 + 30).astype(np.uint8)
    PILImage.fromarray(np.stack([grid, grid // 2, 255 - grid], axis=-1)).save(folder / "textures" / "grid.png")
    write_exr(folder / "sky.exr", envmap_pixels(64, 32))
    path = folder / "scene.xml"
    path.write_text(SCENE)
    return path


def renders(scene, modes=("path", "trace"), **kwargs) -> list[np.ndarray]:
    return [raylume.render(scene, mode=mode, seed=3, aovs=False, **kwargs).rgb for mode in modes]


def test_convert_writes_toml_that_renders_bit_for_bit_the_same(tmp_path):
    source = write_mitsuba_scene(tmp_path / "mitsuba")
    out = tmp_path / "elsewhere" / "converted.toml"
    out.parent.mkdir()
    result = cli("convert", source, "-o", out, "--define", "spp=3", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stderr == f"{out}: written from {source}\n"  # one line, as render's
    quiet = cli("convert", "seed", "-o", tmp_path / "seed.toml", "--quiet", cwd=tmp_path)
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr
    original, converted = raylume.load(source, defines={"spp": "3"}), raylume.load(out)
    assert scene_document(converted, tmp_path) == scene_document(original, tmp_path)
    assert converted.render.spp == 3
    text = out.read_text()
    assert '"../mitsuba/meshes/octahedron.obj"' in text  # referenced where it is, not copied
    assert '"../mitsuba/sky.exr"' in text and list(out.parent.iterdir()) == [out]
    for a, b in zip(renders(original), renders(converted)):
        np.testing.assert_array_equal(a, b)


def test_save_scene_takes_a_scene_named_as_render_takes_it(tmp_path):
    """A built-in scene's name or a file, as raylume.render takes them (an AttributeError before)."""
    out = raylume.save_scene("seed", tmp_path / "seed.toml")
    assert raylume.load(out) == raylume.builtin_scene("seed").with_base_dir(tmp_path)


def test_save_scene_round_trips_a_toml_scene_into_another_folder(tmp_path):
    scene = raylume.load(REPO / "examples" / "cornell.toml")
    out = raylume.save_scene(scene, tmp_path / "cornell.json")
    again = raylume.load(out)
    assert scene_document(again, tmp_path) == scene_document(scene, tmp_path)
    size = {"width": 16, "height": 16, "spp": 2, "modes": ("path",)}
    for a, b in zip(renders(scene, **size), renders(again, **size)):
        np.testing.assert_array_equal(a, b)


def assert_refused(result, *words):
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    for word in words:
        assert word in result.stderr, result.stderr


def test_convert_refuses_bad_input_and_writes_nothing(tmp_path):
    source = write_mitsuba_scene(tmp_path)
    assert_refused(cli("convert", source, "-o", "out.png", cwd=tmp_path), "out.png", ".toml or .json")
    bad = tmp_path / "bad.xml"
    bad.write_text(SCENE.replace('value="$spp"', 'value="$count"'))
    assert_refused(cli("convert", bad, "-o", "out.toml", cwd=tmp_path), "bad.xml:7:", "$count is not defined")
    assert_refused(
        cli("convert", REPO / "examples" / "cornell.toml", "-o", "out.toml", "-D", "a=1", cwd=tmp_path),
        "sets parameters of a Mitsuba scene",
    )
    assert_refused(  # as render says it (this said "cannot write the file (No such file ...)")
        cli("convert", source, "-o", "missing/out.toml", cwd=tmp_path), "the folder missing does not exist"
    )
    assert not (tmp_path / "out.toml").exists() and not (tmp_path / "out.png").exists()


def test_render_takes_a_mitsuba_scene_with_defines_and_flags(tmp_path):
    source = write_mitsuba_scene(tmp_path)
    out = tmp_path / "out.npy"
    result = cli("render", source, "-D", "spp=2", "--set", "camera.fov=30", "--width", "8", "-o", out, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert np.load(out).shape == (14, 8, 3)  # the file's height, the flag's width


def test_render_of_broken_xml_names_file_and_line_and_writes_nothing(tmp_path):
    bad = tmp_path / "broken.xml"
    bad.write_text(SCENE.replace('<shape type="sphere">', '<shape type="sphere"', 1))
    result = cli("render", bad, "-o", "out.png", cwd=tmp_path)
    line = next(k for k, row in enumerate(SCENE.splitlines(), 1) if '<shape type="sphere">' in row)
    assert_refused(result, f"broken.xml:{line}: invalid XML")
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_save_scene_refuses_other_suffixes_only(tmp_path, suffix):
    scene = raylume.builtin_scene("seed")
    assert raylume.save_scene(scene, tmp_path / f"s{suffix}").exists()
    with pytest.raises(raylume.RaylumeError, match="ends in .toml or .json"):
        raylume.save_scene(scene, tmp_path / "s.yaml")
