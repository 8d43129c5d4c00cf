"""Mitsuba shapes as raylume objects, placed in raylume's (mirrored) world.

| Mitsuba | raylume |
| --- | --- |
| obj, ply, serialized | mesh (file by path; serialized: shape_index), transform from to_world (a matrix if it shears) |
| rectangle | quad |
| cube | six quads (one closed mesh where it holds a medium) |
| sphere | sphere (with an image texture or normal map: turned by its transform to Mitsuba's (u, v)) |
| disk | disk |
| cylinder | cylinder, capped = false (Mitsuba's is an open tube) |
| shapegroup + instance | a mesh's instances (analytic shapes: one object per instance) |

`face_normals = true` is `smooth = false`; otherwise a mesh is smooth: the file's normals, or
vertex normals raylume computes (weighted by area, where Mitsuba weights by angle: documented).
`flip_normals` warns: raylume's surfaces are two-sided.
"""

from __future__ import annotations

import numpy as np

from .affine import Z_POLE_SPHERE, decompose, is_identity, turned
from .mitsuba_bsdf import GREY, bsdf_table
from .mitsuba_context import Context, uniform_scale
from .mitsuba_emitters import area_radiance
from .mitsuba_media import Media
from .mitsuba_xml import Node

BEHIND = 1e-3  # how far (in the emitter's size) the black twin of a one-sided emitter sits behind it
MESH_TYPES = {"obj": (".obj",), "ply": (".ply",), "serialized": (".serialized",)}
# Mitsuba's cube: the faces of [-1, 1]^3, each (centre, u, v) with u x v pointing out
CUBE_FACES = [
    ((1, 0, 0), (0, 2, 0), (0, 0, 2)),
    ((-1, 0, 0), (0, 0, 2), (0, 2, 0)),
    ((0, 1, 0), (0, 0, 2), (2, 0, 0)),
    ((0, -1, 0), (2, 0, 0), (0, 0, 2)),
    ((0, 0, 1), (2, 0, 0), (0, 2, 0)),
    ((0, 0, -1), (0, 2, 0), (2, 0, 0)),
]


class Shapes:
    """Converts <shape> elements; `materials` are the document's named materials (by id)."""

    def __init__(self, ctx: Context, materials: dict[str, dict], media: Media):
        self.ctx = ctx
        self.materials = materials
        self.media = media
        self.objects: list[dict] = []
        self.origins: list[Node] = []  # the element each object came from, for error messages
        self.groups: dict[str, list[dict]] = {}  # shapegroup id -> its mesh objects, made at the first instance

    def material(self, node: Node, props) -> dict | str:
        """The shape's material: a name (a referenced BSDF) or an inline table, with emission if an
        area emitter is inside."""
        material: dict | str | None = None
        emitter = None
        props.take("bsdf")  # a BSDF given as the property "bsdf" (nested or a ref) is among the plugins
        for plugin in props.plugins:
            if plugin.tag == "bsdf":
                key = plugin.attrs.get("id")
                material = key if key in self.materials else bsdf_table(self.ctx, plugin)
            elif plugin.tag == "emitter":
                if plugin.attrs.get("type") != "area":
                    raise plugin.error("the only emitter a shape can hold is an area emitter")
                emitter = plugin
            elif plugin.tag == "medium":
                continue  # interior and exterior: Shapes.shape
            else:
                raise plugin.error(f"a {node.describe()} cannot hold a <{plugin.tag}>")
        if material is None:  # Mitsuba's default BSDF: diffuse 0.5, black on an emitter's shape
            material = {"type": "diffuse", "color": [0.0] * 3 if emitter is not None else list(GREY)}
        if emitter is not None:
            table = dict(self.materials[material]) if isinstance(material, str) else dict(material)
            if table.get("type") == "null":
                table = {"type": "diffuse", "color": [0.0, 0.0, 0.0]}  # raylume's null surface cannot emit
            if "alpha_map" in table:
                del table["alpha_map"]
                self.ctx.warn(
                    node,
                    "an area emitter on a masked BSDF: raylume's emitters take no alpha map (its holes would be "
                    "sampled as light), so the shape is drawn and lit whole",
                )
            table["emission"] = area_radiance(self.ctx, emitter)
            material = table
        return material

    def shape(self, node: Node, placement: np.ndarray | None = None) -> list[dict]:
        """The objects of one <shape>; `placement` is an instance's to_world (shapes in a group)."""
        ctx = self.ctx
        kind = node.attrs.get("type")
        props = ctx.props(node)
        m = props.transform()
        if placement is not None:
            m = placement @ m
        material = self.material(node, props)
        if props.boolean("flip_normals", False):
            ctx.warn(node, "flip_normals: raylume's surfaces are two-sided, so it is ignored")
        objects: list[dict]
        if kind in MESH_TYPES:
            name = props.string("filename")
            if name is None:
                raise node.error("needs a filename")
            obj = {"type": "mesh", "file": ctx.file(node, name, MESH_TYPES[kind]), "material": material}
            obj["transform"] = self.transform(node, m)
            obj["smooth"] = not props.boolean("face_normals", False)
            if kind == "serialized":
                obj["shape_index"] = props.integer("shape_index", 0)
            # Mitsuba looks texture row v from the image's top, raylume row 1 - v; its OBJ reader flips v
            # by default (flip_tex_coords), which makes the two agree; a PLY or serialized file's v is not
            flipped = kind == "obj" and props.boolean("flip_tex_coords", True)
            if not flipped and self.reads_uvs(material):
                ctx.warn(
                    node,
                    f"its {self.uv_images(material)}'s v axis runs the other way in raylume: "
                    "the image appears upside down",
                )
            objects = [obj]
        elif kind == "rectangle":
            # uv (0, 0) at local (-1, -1) in Mitsuba, its row v from the image's top: raylume's v runs down -y
            objects = [self.quad(m, (0, 0, 0), (2, 0, 0), (0, -2, 0), material, outward=False)]
            if self.normal_mapped(material):
                # Mitsuba's normal map frame takes y = n x dp/du: on a rectangle that is +v, down the image
                ctx.warn(
                    node,
                    "Mitsuba turns a normal map's y on a rectangle towards increasing v, down the image; raylume's "
                    "runs up the image, so the map's slopes along v are drawn mirrored (lit from the other side)",
                )
        elif kind == "cube":
            if props.plugin("interior") is not None:  # a medium fills closed shapes: not six open quads
                objects = [self.closed_cube(m, material)]
            else:
                objects = [self.quad(m, c, u, v, material) for c, u, v in CUBE_FACES]
        elif kind == "sphere":
            centre = props.point("center", np.zeros(3))
            radius = props.float("radius", 1.0)
            scale = uniform_scale(node, m, "sphere")
            sphere = {"type": "sphere", "center": ctx.point(m, centre), "radius": radius * scale, "material": material}
            if self.reads_uvs(material):
                sphere["transform"] = self.sphere_turn(m, scale, sphere["center"])
                sphere["center"] = [0.0, 0.0, 0.0]
            objects = [sphere]
        elif kind == "disk":
            scale = uniform_scale(node, m, "disk")
            objects = [
                {
                    "type": "disk",
                    "center": ctx.point(m),
                    "normal": ctx.vector(m, (0.0, 0.0, 1.0)),
                    "radius": scale,
                    "material": material,
                }
            ]
        elif kind == "cylinder":
            p0, p1 = props.point("p0", np.zeros(3)), props.point("p1", np.array([0.0, 0.0, 1.0]))
            radius = props.float("radius", 1.0)
            scale = uniform_scale(node, m, "cylinder")
            objects = [
                {
                    "type": "cylinder",
                    "p0": ctx.point(m, p0),
                    "p1": ctx.point(m, p1),
                    "radius": radius * scale,
                    "capped": False,
                    "material": material,
                }
            ]
        else:
            raise node.error("raylume has no such shape, and no shape that could honestly replace it")
        interior, exterior = props.plugin("interior"), props.plugin("exterior")
        if interior is not None:
            name = self.media.name(interior, node)
            if name is not None:
                for obj in objects:
                    obj["interior"] = name
        if self.media.rendered and exterior is not self.media.outside:
            # Mitsuba's rays take a shape's exterior on leaving it; raylume's outside is one medium
            ctx.warn(
                node,
                "its exterior differs from the sensor's medium: raylume fills the space outside every object with "
                "the sensor's medium (or none), so light leaving this shape travels through that",
            )
        if isinstance(material, dict) and any(material.get("emission", ())):
            objects += self.one_sided(node, kind, objects, np.linalg.det((ctx.world @ m)[:3, :3]))
        if kind in ("cube", "disk", "cylinder") and self.reads_uvs(material):
            ctx.warn(
                node,
                f"raylume's {kind} has texture coordinates of its own, not Mitsuba's: the "
                f"{self.uv_images(material)} lies otherwise",
            )
        ctx.done(node, props)
        return objects

    def one_sided(self, node: Node, kind: str, objects: list[dict], det: float) -> list[dict]:
        """Mitsuba's area emitters emit from their front alone, raylume's surfaces from both sides.
        A flat emitter gets a black twin just behind it, which takes in whatever reaches its back
        (as Mitsuba's emitter, black from behind, does) and hides the back's emission. Closed
        shapes need none (their inside is never seen); open meshes and tubes are named."""
        if kind in ("sphere", "cube"):
            return []
        if kind not in ("rectangle", "disk"):
            self.ctx.warn(
                node,
                "area emitter: raylume's emitting surfaces emit from both sides, Mitsuba's from the front alone; "
                "light leaving this shape's back adds to the image",
            )
            return []
        twins = []
        for obj in objects:
            if kind == "rectangle":
                # the front is local +z as a normal, W^-T z; with u = W x and v = -W y (see quad), that is
                # -sign(det W) u x v
                normal = -np.sign(det) * np.cross(obj["u"], obj["v"])
                size = max(np.linalg.norm(obj["u"]), np.linalg.norm(obj["v"]))
                centre = "position"
            else:  # a similarity's W z is its W^-T z, up to length
                normal, size, centre = np.asarray(obj["normal"]), 2 * obj["radius"], "center"
            length = np.linalg.norm(normal)
            if not length > 0:  # a rectangle collapsed by its to_world, which the scene's check refuses
                continue
            back = -normal / length * BEHIND * size
            twin = {**obj, centre: [float(c + b) for c, b in zip(obj[centre], back)]}
            twin["material"] = {"type": "diffuse", "color": [0.0, 0.0, 0.0]}
            twins.append(twin)
        return twins

    def table(self, material: dict | str) -> dict:
        return self.materials.get(material, {}) if isinstance(material, str) else material

    def image_textured(self, material: dict | str) -> bool:
        """Whether the material looks up an image by (u, v) (raylume's checker is in world space)."""
        return (self.table(material).get("texture") or {}).get("type") == "image"

    def normal_mapped(self, material: dict | str) -> bool:
        return "normal_map" in self.table(material)

    def bump_mapped(self, material: dict | str) -> bool:
        return "bump_map" in self.table(material)

    def alpha_mapped(self, material: dict | str) -> bool:
        return "alpha_map" in self.table(material)

    def reads_uvs(self, material: dict | str) -> bool:
        """Whether the material reads the surface's (u, v): an image texture, a normal, bump or alpha map."""
        maps = self.normal_mapped(material) or self.bump_mapped(material) or self.alpha_mapped(material)
        return self.image_textured(material) or maps

    def uv_images(self, material: dict | str) -> str:
        """What reads the (u, v), for warnings: "texture", "normal map", "bump map", "alpha map", or
        some of them."""
        found = (
            ("texture", self.image_textured(material)),
            ("normal map", self.normal_mapped(material)),
            ("bump map", self.bump_mapped(material)),
            ("alpha map", self.alpha_mapped(material)),
        )
        return " and ".join(what for what, has in found if has)

    def sphere_turn(self, m: np.ndarray, scale: float, centre: list[float]) -> dict:
        """The transform that turns raylume's sphere so that its (u, v) is Mitsuba's: Mitsuba finds
        a point's (u, v) in the frame of its to_world's rotation (the rotation of -to_world where
        that mirrors), and reads the image from its top, where raylume's v runs up."""
        frame = m[:3, :3] / scale
        if np.linalg.det(frame) < 0:
            frame = -frame
        return turned(self.ctx.world[:3, :3] @ frame @ Z_POLE_SPHERE, centre)

    def closed_cube(self, m: np.ndarray, material) -> dict:
        """Mitsuba's cube as one closed mesh of 12 triangles, its faces' corners shared, facing out
        (a mirroring to_world turns the winding back): a closed shape a medium can fill."""
        corners: dict[tuple, int] = {}
        faces = []
        for centre, u, v in CUBE_FACES:
            c, u, v = (np.asarray(x, dtype=np.float64) for x in (centre, u, v))
            quad = [c - u / 2 - v / 2, c + u / 2 - v / 2, c + u / 2 + v / 2, c - u / 2 + v / 2]  # u x v outward
            ids = [corners.setdefault(tuple(q.tolist()), len(corners)) for q in quad]
            faces += [[ids[0], ids[1], ids[2]], [ids[0], ids[2], ids[3]]]
        if np.linalg.det((self.ctx.world @ m)[:3, :3]) < 0:
            faces = [[a, c, b] for a, b, c in faces]
        vertices = [self.ctx.point(m, corner) for corner in corners]
        return {"type": "mesh", "vertices": vertices, "faces": faces, "material": material}

    def quad(self, m: np.ndarray, centre, u, v, material, outward: bool = True) -> dict:
        u, v = self.ctx.vector(m, u), self.ctx.vector(m, v)
        if outward and np.linalg.det((self.ctx.world @ m)[:3, :3]) < 0:
            u, v = v, u  # keep u x v facing out of a mirrored closed shape (a cube's faces)
        return {"type": "quad", "position": self.ctx.point(m, centre), "u": u, "v": v, "material": material}

    def transform(self, node: Node, m: np.ndarray) -> dict:
        return transform_table(node, self.ctx.world @ m)

    def add(self, node: Node) -> None:
        """A top-level <shape>: appended to `objects` (a shapegroup waits for its instances)."""
        kind = node.attrs.get("type")
        if kind == "shapegroup":
            if "id" not in node.attrs:
                raise node.error("a shapegroup needs an id for instances to refer to")
            return
        if kind == "instance":
            self.instance(node)
            return
        self.extend(node, self.shape(node))

    def extend(self, node: Node, objects: list[dict]) -> None:
        self.objects.extend(objects)
        self.origins.extend([node] * len(objects))

    def instance(self, node: Node) -> None:
        ctx = self.ctx
        props = ctx.props(node)
        groups = [p for p in props.plugins if p.tag == "shape" and p.attrs.get("type") == "shapegroup"]
        if len(groups) != 1:
            raise node.error("needs one <ref id=...> to a shapegroup")
        group = groups[0]
        m = props.transform()
        ctx.done(node, props)
        key = group.attrs["id"]
        if key not in self.groups:  # the group's meshes: one object each, its instances added below
            members = []
            for child in ctx.props(group).plugins:
                if child.tag != "shape":
                    raise child.error("a shapegroup holds shapes only")
                if child.attrs.get("type") in MESH_TYPES:
                    obj = self.shape(child)[0]
                    obj["instances"] = []
                    self.extend(child, [obj])
                    members.append(obj)
            self.groups[key] = members
        # raylume's instance matrix maps the object after its transform: Mitsuba's to_world, conjugated by the mirror
        placement = transform_table(node, ctx.world @ m @ np.linalg.inv(ctx.world))
        for obj in self.groups[key]:
            obj["instances"].append(placement)
        for child in ctx.props(group).plugins:  # analytic shapes: an object per instance
            if child.attrs.get("type") not in MESH_TYPES:
                self.extend(child, self.shape(child, placement=m))


def transform_table(node: Node, m: np.ndarray) -> dict:
    """A matrix as raylume's transform table: scale, rotate, translate where it is one (readable,
    editable with --set), else the whole matrix (a shear)."""
    try:
        return decompose(m)
    except ValueError:
        if abs(np.linalg.det(m[:3, :3])) < 1e-12 or not np.allclose(m[3], (0, 0, 0, 1)):
            raise node.error("its to_world is singular or not affine") from None
        return {"matrix": [[float(c) + 0.0 for c in row] for row in m]}


def clean_transform(obj: dict) -> dict:
    """Leave out an identity transform, so the document says no more than it must."""
    if "transform" in obj and "matrix" not in obj["transform"] and is_identity(obj["transform"]):
        del obj["transform"]
    return obj
