"""Write room.glb, the glTF example: a small room with an asymmetric letter F, a gold sphere, a
glass sphere and two instances of one box, lit by an emissive ceiling panel, a point light and
a spot light, seen through the file's camera.

    python examples/gltf/make_room.py            # writes examples/gltf/room.glb
    raylume render examples/gltf/room.glb -o room.png

Only numpy and Pillow: the file is written by hand (JSON chunk + one binary buffer), with the
right-handed, +y up, +z towards the viewer axes of glTF. A glTF viewer and raylume show the F
reading the right way round, on the left.
"""

from __future__ import annotations

import io
import json
import math
import struct
from pathlib import Path

import numpy as np
from PIL import Image

FLOAT, UINT = 5126, 5125


class Writer:
    def __init__(self):
        self.doc: dict = {
            "asset": {"version": "2.0", "generator": "raylume examples/gltf/make_room.py"},
            "scene": 0,
            "scenes": [{"nodes": []}],
            "nodes": [],
            "meshes": [],
            "materials": [],
            "accessors": [],
            "bufferViews": [],
            "extensionsUsed": [
                "KHR_lights_punctual",
                "KHR_materials_emissive_strength",
                "KHR_materials_transmission",
                "KHR_materials_ior",
            ],
            "extensions": {"KHR_lights_punctual": {"lights": []}},
        }
        self.blob = bytearray()

    def view(self, data: bytes) -> int:
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)})
        self.blob += data
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, values: np.ndarray, ctype: int = FLOAT) -> int:
        values = np.ascontiguousarray(values, dtype=np.float32 if ctype == FLOAT else np.uint32)
        kind = {1: "SCALAR", 2: "VEC2", 3: "VEC3"}[1 if values.ndim == 1 else values.shape[1]]
        acc = {"bufferView": self.view(values.tobytes()), "componentType": ctype, "count": len(values), "type": kind}
        if kind == "VEC3":  # POSITION accessors need their bounds
            acc.update(min=values.min(axis=0).tolist(), max=values.max(axis=0).tolist())
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def mesh(self, name: str, positions, normals, uvs, indices, material: int) -> int:
        attributes = {"POSITION": self.accessor(positions), "NORMAL": self.accessor(normals)}
        if uvs is not None:
            attributes["TEXCOORD_0"] = self.accessor(uvs)
        prim = {"attributes": attributes, "indices": self.accessor(np.ravel(indices), UINT), "material": material}
        self.doc["meshes"].append({"name": name, "primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def material(self, name: str, color, metallic=0.0, roughness=1.0, **extra) -> int:
        pbr = {"baseColorFactor": [*color, 1.0], "metallicFactor": metallic, "roughnessFactor": roughness}
        pbr.update(extra.pop("pbr", {}))
        self.doc["materials"].append({"name": name, "pbrMetallicRoughness": pbr, **extra})
        return len(self.doc["materials"]) - 1

    def texture(self, pixels: np.ndarray) -> int:
        png = io.BytesIO()
        Image.fromarray(pixels).save(png, format="PNG")
        self.doc.setdefault("images", []).append({"bufferView": self.view(png.getvalue()), "mimeType": "image/png"})
        self.doc.setdefault("samplers", []).append({"magFilter": 9728, "minFilter": 9987})
        self.doc.setdefault("textures", []).append({"source": len(self.doc["images"]) - 1, "sampler": 0})
        return len(self.doc["textures"]) - 1

    def node(self, name: str, **table) -> int:
        self.doc["nodes"].append({"name": name, **table})
        self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)
        return len(self.doc["nodes"]) - 1

    def light(self, name: str, light: dict, **node) -> int:
        lights = self.doc["extensions"]["KHR_lights_punctual"]["lights"]
        lights.append({"name": name, **light})
        return self.node(name, extensions={"KHR_lights_punctual": {"light": len(lights) - 1}}, **node)

    def save(self, path: Path) -> None:
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc["buffers"] = [{"byteLength": len(self.blob)}]
        text = json.dumps(self.doc, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
        chunks += struct.pack("<II", len(self.blob), 0x004E4942) + bytes(self.blob)
        path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)


def box(size=(1.0, 1.0, 1.0)):
    """A box centred on the origin: 24 vertices (flat normals), 12 triangles facing out."""
    h = np.asarray(size) / 2
    positions, normals, uvs, faces = [], [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.roll([1.0, 0.0, 0.0], axis + 1)  # any unit vector across n
            v = np.cross(n, u)  # cross(u, v) = n: the corners below wind counter-clockwise about n
            base = len(positions)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                positions.append((n + a * u + b * v) * h)
                normals.append(n)
                uvs.append(((a + 1) / 2, (1 - b) / 2))
            faces += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return np.array(positions), np.array(normals), np.array(uvs), np.array(faces)


def sphere(radius=1.0, rings=24, segments=48):
    theta = np.linspace(0, math.pi, rings + 1)
    phi = np.linspace(0, 2 * math.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    n = np.stack([np.sin(t) * np.sin(p), np.cos(t), np.sin(t) * np.cos(p)], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(rings):
        for j in range(segments):
            a, b = i * (segments + 1) + j, (i + 1) * (segments + 1) + j
            faces += [[a, b, a + 1], [a + 1, b, b + 1]]
    faces = np.array(faces)
    area = np.linalg.norm(np.cross(n[faces[:, 1]] - n[faces[:, 0]], n[faces[:, 2]] - n[faces[:, 0]]), axis=1)
    return n * radius, n, None, faces[area > 1e-9]


def quad(width, depth):
    """A floor-like rectangle in the xz plane facing +y, UVs 0..1 (v down the image)."""
    w, d = width / 2, depth / 2
    positions = np.array([[-w, 0, d], [w, 0, d], [w, 0, -d], [-w, 0, -d]])
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]]) * [width, depth]
    return positions, np.tile([0.0, 1.0, 0.0], (4, 1)), uvs, np.array([[0, 1, 2], [0, 2, 3]])


def rotation(axis: str, degrees: float) -> list:
    """A unit quaternion (x, y, z, w) turning `degrees` about a coordinate axis."""
    half = math.radians(degrees) / 2
    q = [0.0, 0.0, 0.0, math.cos(half)]
    q["xyz".index(axis)] = math.sin(half)
    return q


def aim(position, target) -> list:
    """The quaternion (x, y, z, w) turning -z (where glTF cameras and lights point) towards target."""
    a = np.array([0.0, 0.0, -1.0])
    b = np.asarray(target, float) - np.asarray(position, float)
    b /= np.linalg.norm(b)
    q = np.append(np.cross(a, b), 1.0 + a @ b)
    return (q / np.linalg.norm(q)).tolist()


def build() -> Writer:
    g = Writer()
    checker = np.kron((np.indices((8, 8)).sum(axis=0) % 2)[..., None], np.ones((16, 16, 1)))
    pixels = (np.where(checker > 0, [200, 196, 186], [90, 84, 78])).astype(np.uint8)
    floor_mat = g.material("floor", (1, 1, 1), pbr={"baseColorTexture": {"index": g.texture(pixels)}})
    wall = g.material("wall", (0.75, 0.73, 0.7))
    red = g.material("red wall", (0.7, 0.12, 0.1))
    teal = g.material("teal wall", (0.1, 0.45, 0.45))
    letter = g.material("blue plastic", (0.1, 0.2, 0.8), roughness=0.35)
    gold = g.material("gold", (1.0, 0.78, 0.34), metallic=1.0, roughness=0.3)
    glass = g.material(
        "glass",
        (1, 1, 1),
        roughness=0.0,
        extensions={"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.5}},
    )
    orange = g.material("orange plastic", (0.9, 0.4, 0.1), roughness=0.5)
    panel = g.material(
        "ceiling lamp",
        (1, 1, 1),
        emissiveFactor=[1.0, 0.9, 0.75],
        extensions={"KHR_materials_emissive_strength": {"emissiveStrength": 12.0}},
    )
    g.doc["extensionsUsed"].sort()

    floor = g.mesh("floor", *quad(6, 6), floor_mat)
    plane = g.mesh("wall", *quad(6, 6), wall)
    g.node("floor", mesh=floor)
    g.node("ceiling", mesh=plane, translation=[0, 4, 0], rotation=rotation("x", 180))
    g.node("back wall", mesh=plane, translation=[0, 2, -3], rotation=rotation("x", 90))
    g.node("left wall", mesh=g.mesh("left wall", *quad(6, 6), red), translation=[-3, 2, 0], rotation=rotation("z", -90))
    g.node(
        "right wall", mesh=g.mesh("right wall", *quad(6, 6), teal), translation=[3, 2, 0], rotation=rotation("z", 90)
    )
    g.node("lamp", mesh=g.mesh("lamp", *quad(1.6, 1.6), panel), translation=[0, 3.99, 0], rotation=rotation("x", 180))

    # The letter F from one shared bar mesh (three nodes: instances of one mesh), on the left
    bar = g.mesh("bar", *box((1.0, 1.0, 1.0)), letter)
    g.node("F stem", mesh=bar, translation=[-1.8, 1.2, -1.2], scale=[0.35, 2.4, 0.35])
    g.node("F top", mesh=bar, translation=[-1.25, 2.225, -1.2], scale=[1.1, 0.35, 0.35])
    g.node("F middle", mesh=bar, translation=[-1.35, 1.35, -1.2], scale=[0.9, 0.35, 0.35])

    ball = sphere(0.6)
    g.node("gold sphere", mesh=g.mesh("gold sphere", *ball, gold), translation=[1.5, 0.6, -1.4])
    g.node("glass sphere", mesh=g.mesh("glass sphere", *ball, glass), translation=[-0.1, 0.6, 0.5])
    crate = g.mesh("crate", *box((0.6, 0.6, 0.6)), orange)
    g.node("crate", mesh=crate, translation=[1.9, 0.3, 1.1], rotation=rotation("y", 30))
    g.node("crate on crate", mesh=crate, translation=[1.9, 0.9, 1.1], rotation=rotation("y", 55))

    g.light("warm point", {"type": "point", "color": [1.0, 0.85, 0.7], "intensity": 3.0}, translation=[1.5, 3.0, 1.5])
    g.light(
        "spot on the F",
        {"type": "spot", "intensity": 12.0, "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.4}},
        translation=[0.5, 3.6, 1.0],
        rotation=aim([0.5, 3.6, 1.0], [-1.4, 1.6, -1.2]),
    )
    g.doc["cameras"] = [
        {"name": "front", "type": "perspective", "perspective": {"yfov": 0.82, "aspectRatio": 4 / 3, "znear": 0.05}}
    ]
    g.node("front camera", camera=0, translation=[0, 1.9, 6.2], rotation=rotation("x", -7))
    return g


if __name__ == "__main__":
    out = Path(__file__).with_name("room.glb")
    build().save(out)
    print(f"wrote {out} ({out.stat().st_size} bytes)")
