"""Small Mitsuba 3 XML scenes (with their meshes and images) that tests/test_mitsuba_vs_reference.py
renders with raylume and tools/mitsuba_xml_references.py with Mitsuba 3, one per feature the
XML reader maps: each BSDF family, an environment map, instances, a serialized mesh, a mirrored
sensor. Every scene is lopsided (something red on the left) so that a mirror image fails.

This module imports neither raylume nor Mitsuba: it writes the files with numpy, zlib and
OpenEXR, by the formats' specifications, so both renderers read the same bytes.
"""

from __future__ import annotations

import hashlib
import struct
import zlib
from pathlib import Path

import numpy as np

SIZE = 32  # pixels, width and height
MAX_DEPTH = 6

HEAD = f"""<scene version="3.0.0">
  <integrator type="path"><integer name="max_depth" value="{MAX_DEPTH}"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world">{{sensor}}</transform>
    <film type="hdrfilm">
      <integer name="width" value="{SIZE}"/><integer name="height" value="{SIZE}"/>
      <rfilter type="box"/>
    </film>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
  </sensor>
"""
LOOK = '<lookat origin="0, 2, 6" target="0, 0.6, 0" up="0, 1, 0"/>'
# A floor, a red sphere on the image's left, a light above (its back faces empty space)
STAGE = """
  <bsdf type="diffuse" id="floor"><rgb name="reflectance" value="0.6, 0.6, 0.55"/></bsdf>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="4"/></transform>
    <ref id="floor"/>
  </shape>
  <shape type="sphere">
    <point name="center" x="-1.4" y="0.5" z="0.3"/><float name="radius" value="0.5"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world">
      <scale x="0.8" y="0.5"/><rotate x="1" angle="90"/><translate y="3.5" x="0.5"/>
    </transform>
    <emitter type="area"><rgb name="radiance" value="9, 8, 7"/></emitter>
  </shape>
  <emitter type="constant"><rgb name="radiance" value="0.15, 0.2, 0.3"/></emitter>
"""
TAIL = "</scene>\n"


def _scene(body: str, sensor: str = LOOK, stage: str = STAGE) -> str:
    return HEAD.format(sensor=sensor) + stage + body + TAIL


def _sphere(x: float, bsdf: str, radius: float = 0.6) -> str:
    return f"""
  <shape type="sphere">
    <transform name="to_world"><scale value="{radius}"/><translate x="{x}" y="{radius}"/></transform>
    {bsdf}
  </shape>"""


def write_obj(path: Path) -> None:
    """A unit octahedron, outward-wound."""
    v = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    f = [(0, 2, 4), (4, 2, 1), (1, 2, 5), (5, 2, 0), (4, 3, 0), (1, 3, 4), (5, 3, 1), (0, 3, 5)]
    lines = [f"v {x} {y} {z}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")


def serialized_bytes(meshes: list[tuple[np.ndarray, np.ndarray]]) -> bytes:
    """Mitsuba's serialized format (version 4), written from its documentation: per mesh the
    header (0x041C, 4) and a zlib stream of flags, name, counts, float32 positions, uint32 indices;
    then each mesh's offset (uint64) and the mesh count (uint32)."""
    out, offsets = bytearray(), []
    for k, (vertices, faces) in enumerate(meshes):
        offsets.append(len(out))
        body = struct.pack("<I", 0x1000) + f"mesh{k}".encode() + b"\0"
        body += struct.pack("<QQ", len(vertices), len(faces))
        body += np.asarray(vertices, "<f4").tobytes() + np.asarray(faces, "<u4").tobytes()
        out += struct.pack("<HH", 0x041C, 4) + zlib.compress(body)
    out += b"".join(struct.pack("<Q", o) for o in offsets) + struct.pack("<I", len(meshes))
    return bytes(out)


def box_mesh(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """An axis-aligned box, outward-wound triangles."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([(x, y, z) for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], dtype=np.float64)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(f, dtype=np.int64)


def envmap_pixels(width: int = 512, height: int = 256) -> np.ndarray:
    """A smooth, lopsided sky: a warm lobe at azimuth 60 degrees, 30 degrees up, over a blue gradient."""
    v, u = np.meshgrid((np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij")
    theta, phi = v * np.pi, (u - 0.5) * 2 * np.pi
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], axis=-1)
    c = np.radians(60)
    lobe_dir = np.array(
        [np.cos(np.radians(30)) * np.sin(c), np.sin(np.radians(30)), np.cos(np.radians(30)) * np.cos(c)]
    )
    lobe = np.maximum(d @ lobe_dir, 0) ** 8
    sky = 0.2 + 0.5 * np.clip(np.cos(theta), 0, 1)
    rgb = np.stack([0.3 * sky + 6 * lobe, 0.4 * sky + 4 * lobe, sky + 1 * lobe], axis=-1)
    return rgb.astype(np.float32)


def write_exr(path: Path, rgb: np.ndarray) -> None:
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {name: np.ascontiguousarray(rgb[:, :, k]) for k, name in enumerate("RGB")}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))


def diffuse(folder: Path) -> str:
    return _scene(_sphere(0.3, '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf>'))


def conductor(folder: Path) -> str:
    return _scene(
        _sphere(-0.1, '<bsdf type="conductor"><string name="material" value="Cu"/></bsdf>', 0.5)
        + _sphere(
            1.3,
            '<bsdf type="roughconductor"><string name="material" value="Au"/>'
            '<string name="distribution" value="ggx"/><float name="alpha" value="0.25"/></bsdf>',
            0.5,
        )
    )


def dielectric(folder: Path) -> str:
    return _scene(
        _sphere(-0.1, '<bsdf type="dielectric"><string name="int_ior" value="bk7"/></bsdf>', 0.5)
        + _sphere(
            1.3,
            '<bsdf type="roughdielectric"><float name="int_ior" value="1.33"/>'
            '<string name="distribution" value="ggx"/><float name="alpha" value="0.2"/></bsdf>',
            0.5,
        )
    )


def plastic(folder: Path) -> str:
    return _scene(
        _sphere(-0.1, '<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.1, 0.6, 0.2"/></bsdf>', 0.5)
        + _sphere(
            1.3,
            '<bsdf type="twosided"><bsdf type="roughplastic"><rgb name="diffuse_reflectance" value="0.7, 0.6, 0.1"/>'
            '<string name="distribution" value="ggx"/><float name="alpha" value="0.3"/></bsdf></bsdf>',
            0.5,
        )
    )


def envmap(folder: Path, sensor_prefix: str = "") -> str:
    write_exr(folder / "sky.exr", envmap_pixels())
    # the sky replaces the constant emitter; a wider floor and a camera looking down hide the sky itself
    stage = STAGE.split('  <emitter type="constant">')[0].replace('<scale value="4"/>', '<scale value="20"/>')
    sky = """
  <emitter type="envmap">
    <string name="filename" value="sky.exr"/><float name="scale" value="1.5"/>
    <transform name="to_world"><rotate y="1" angle="40"/></transform>
  </emitter>"""
    sensor = sensor_prefix + '<lookat origin="0, 4, 4.5" target="0, 0.3, 0" up="0, 1, 0"/>'
    return _scene(_sphere(0.6, '<bsdf type="conductor"/>', 0.6) + sky, sensor=sensor, stage=stage)


def envmap_mirrored_sensor(folder: Path) -> str:
    """The environment map seen through a Blender-style mirrored sensor: Mitsuba shows the sky mirrored too."""
    return envmap(folder, sensor_prefix='<scale x="-1"/>')


def instances(folder: Path) -> str:
    write_obj(folder / "octahedron.obj")
    return _scene("""
  <shape type="shapegroup" id="group">
    <shape type="obj">
      <string name="filename" value="octahedron.obj"/>
      <boolean name="face_normals" value="true"/>
      <transform name="to_world"><scale x="0.3" y="0.5" z="0.3"/><translate y="0.5"/></transform>
      <bsdf type="diffuse"><rgb name="reflectance" value="0.9, 0.8, 0.2"/></bsdf>
    </shape>
  </shape>
  <shape type="instance"><ref id="group"/><transform name="to_world"><translate x="-0.2"/></transform></shape>
  <shape type="instance"><ref id="group"/>
    <transform name="to_world"><rotate y="1" angle="30"/><translate x="0.8" z="-0.5"/></transform></shape>
  <shape type="instance"><ref id="group"/>
    <transform name="to_world"><rotate z="1" angle="20"/><scale value="1.3"/><translate x="1.8" z="0.4"/></transform>
  </shape>""")


def serialized(folder: Path) -> str:
    meshes = [box_mesh((-9, -9, -9), (-8, -8, -8)), box_mesh((-0.4, 0, -0.3), (0.4, 1.2, 0.3))]
    (folder / "boxes.serialized").write_bytes(serialized_bytes(meshes))
    return _scene("""
  <shape type="serialized">
    <string name="filename" value="boxes.serialized"/><integer name="shape_index" value="1"/>
    <boolean name="face_normals" value="true"/>
    <transform name="to_world"><rotate y="1" angle="25"/><translate x="0.6"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.8, 0.4"/></bsdf>
  </shape>""")


def mirrored_sensor(folder: Path) -> str:
    """A Blender-style sensor: <scale x="-1"/> before the lookat (Mitsuba shows this mirrored)."""
    body = _sphere(0.6, '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.3, 0.9"/></bsdf>', 0.5)
    return _scene(body, sensor='<scale x="-1"/>' + LOOK)


def lights(folder: Path) -> str:
    """Point, spot (a hard-edged cone: raylume's falloff differs inside a soft one) and directional
    lights, no area light and no sky: their units against Mitsuba's."""
    stage = STAGE.split('  <shape type="rectangle">\n    <transform name="to_world">\n      <scale x="0.8"')[0]
    return _scene(
        """
  <emitter type="point"><point name="position" x="1.5" y="2" z="1"/><rgb name="intensity" value="3, 2.5, 2"/></emitter>
  <emitter type="spot">
    <transform name="to_world"><lookat origin="-0.5, 3, 1.5" target="0.3, 0, 0" up="0, 1, 0"/></transform>
    <float name="cutoff_angle" value="25"/><float name="beam_width" value="25"/>
    <rgb name="intensity" value="4, 6, 9"/>
  </emitter>
  <emitter type="directional">
    <vector name="direction" x="1" y="-2" z="-0.5"/><rgb name="irradiance" value="0.3, 0.25, 0.2"/>
  </emitter>"""
        + _sphere(0.6, '<bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.7, 0.7"/></bsdf>', 0.5),
        stage=stage,
    )


def texture_pixels() -> np.ndarray:
    """A 16 x 16 sRGB image: a red top-left quadrant, a blue bottom-right one, grey stripes."""
    img = np.full((16, 16, 3), 150, dtype=np.uint8)
    img[:8, :8] = (220, 30, 30)
    img[8:, 8:] = (30, 40, 200)
    img[:, ::4] = (240, 240, 240)
    return img


def textures(folder: Path) -> str:
    from PIL import Image

    Image.fromarray(texture_pixels()).save(folder / "marks.png")
    board = """
  <shape type="rectangle">
    <transform name="to_world">
      <scale x="1.2" y="0.9"/><rotate y="1" angle="15"/><translate x="0.5" y="1" z="-0.5"/>
    </transform>
    <bsdf type="diffuse">
      <texture type="bitmap" name="reflectance"><string name="filename" value="marks.png"/></texture>
    </bsdf>
  </shape>"""
    return _scene(board)


def normal_map_pixels(size: int = 32) -> np.ndarray:
    """A tangent-space normal map (8-bit, stored as is): x along u, y up the image (increasing
    v), z out. Every texel leans up the image (y 0.2) and waves along u and v, at most 20 degrees
    from flat, so that a map read with y the other way lights the board differently."""
    y, x = np.mgrid[0:size, 0:size]
    u, v = (x + 0.5) / size, 1.0 - (y + 0.5) / size
    n = np.stack(
        [0.2 * np.sin(2 * np.pi * u), 0.2 + 0.1 * np.cos(2 * np.pi * 2 * v), np.ones_like(u)],
        axis=-1,
    )
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n + 1.0) / 2.0 * 255.0).astype(np.uint8)


def write_board_obj(path: Path) -> None:
    """A square in z = 0 facing +z, [-1, 1]^2, with UVs (v up +y) and normals."""
    path.write_text(
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
    )


def normalmap(folder: Path) -> str:
    """A normal map (a raw bitmap) on an OBJ board tipped back towards the light, its up the image
    towards the light, where the map read with y the other way changes the board's light by
    about a quarter. Mitsuba's shadowing function for normal maps is switched off
    (`use_shadowing_function`), which raylume does not have: on, it darkened the sky's grazing
    light enough to be measured (see tests/test_mitsuba_vs_reference.py). The board's back faces
    the floor: a black rectangle just behind it makes that back black in both renderers (it is in
    Mitsuba's one-sided BSDF; raylume's surfaces are two-sided, and its floor took 0.6% more
    light off the back without it)."""
    from PIL import Image

    Image.fromarray(normal_map_pixels()).save(folder / "bumps.png")
    write_board_obj(folder / "board.obj")
    board = (
        '<scale x="1.2" y="0.9"/><rotate x="1" angle="-50"/><rotate y="1" angle="15"/>'
        '<translate x="0.3" y="0.8" z="-0.5"/>'
    )
    body = f"""
  <shape type="rectangle">
    <transform name="to_world"><translate z="-0.002"/>{board}</transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0, 0, 0"/></bsdf>
  </shape>
  <shape type="obj">
    <string name="filename" value="board.obj"/>
    <transform name="to_world">{board}</transform>
    <bsdf type="normalmap">
      <boolean name="use_shadowing_function" value="false"/>
      <texture name="normalmap" type="bitmap">
        <string name="filename" value="bumps.png"/><boolean name="raw" value="true"/>
      </texture>
      <bsdf type="diffuse"><rgb name="reflectance" value="0.75, 0.75, 0.7"/></bsdf>
    </bsdf>
  </shape>"""
    return _scene(body)


def medium(folder: Path) -> str:
    """A ball of scattering medium behind a null boundary, rendered by volpath."""
    body = """
  <medium type="homogeneous" id="milk">
    <rgb name="albedo" value="0.9, 0.7, 0.5"/><float name="sigma_t" value="3"/>
    <phase type="hg"><float name="g" value="0.4"/></phase>
  </medium>
  <shape type="sphere">
    <point name="center" x="0.4" y="0.7" z="0"/><float name="radius" value="0.7"/>
    <bsdf type="null"/><ref name="interior" id="milk"/>
  </shape>"""
    text = _scene(body).replace('<integrator type="path">', '<integrator type="volpath">')
    return text


SCENES = {
    "diffuse": diffuse,
    "conductor": conductor,
    "dielectric": dielectric,
    "plastic": plastic,
    "envmap": envmap,
    "envmap_mirrored_sensor": envmap_mirrored_sensor,
    "instances": instances,
    "serialized": serialized,
    "mirrored_sensor": mirrored_sensor,
    "lights": lights,
    "textures": textures,
    "medium": medium,
    "normalmap": normalmap,
}


def write_scene(name: str, folder: Path) -> tuple[Path, str]:
    """Write scene `name` (and its files) into `folder`: (the XML's path, a digest of every file)."""
    folder.mkdir(parents=True, exist_ok=True)
    text = SCENES[name](folder)
    path = folder / f"{name}.xml"
    path.write_text(text)
    digest = hashlib.sha256(text.encode())
    for extra in sorted(folder.iterdir()):
        if extra.suffix in (".obj", ".serialized"):
            digest.update(extra.read_bytes())
    if name.startswith("envmap"):
        digest.update(envmap_pixels().tobytes())  # the EXR's pixels (its bytes may vary with the library)
    if name == "textures":
        digest.update(texture_pixels().tobytes())
    if name == "normalmap":
        digest.update(normal_map_pixels().tobytes())
    return path, digest.hexdigest()
