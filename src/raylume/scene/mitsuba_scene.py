"""A Mitsuba 3 XML scene as a raylume scene document (DESIGN.md section 7): the file's sensor,
film, sampler and integrator as [camera] and [render] (path mode, sRGB), its BSDFs, shapes and
emitters as materials, objects, lights and [environment] (scene/mitsuba_bsdf.py,
scene/mitsuba_shapes.py, scene/mitsuba_emitters.py). The document is validated as a TOML
file's is, so `--set` and every flag apply to it afterwards.

What raylume lacks is named: a SceneWarning naming the file, line, element and what replaced
it, or a SceneError (exit 2) where nothing honest can replace it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .mitsuba_bsdf import bsdf_table
from .mitsuba_context import MIRROR, Context
from .mitsuba_emitters import light_or_environment
from .mitsuba_media import Media
from .mitsuba_shapes import Shapes, clean_transform
from .mitsuba_xml import Node, read_document
from .model import MAX_DEPTH, MAX_SPP

FILTERS = {"box": "box", "gaussian": "gaussian", "mitchell": "mitchell"}
FILM_SIZE = (768, 576)  # hdrfilm's default width and height
FULL_FRAME_DIAGONAL = math.hypot(36.0, 24.0)  # mm: focal_length is a 35 mm camera's


def _collect_ids(node: Node, ids: dict[str, Node]) -> None:
    for child in node.children:
        if child.tag == "alias":  # its id names the element it aliases: not an id of its own
            target, alias = child.attrs.get("id"), child.attrs.get("as")
            if target not in ids or alias is None:
                raise child.error("needs id (an element defined before it) and as")
            if alias in ids:
                raise child.error(f"id {alias!r} is already used at {ids[alias].where}")
            ids[alias] = ids[target]
            continue
        key = child.attrs.get("id")
        if key is not None and child.tag != "ref":
            if key in ids:
                raise child.error(f"id {key!r} is already used at {ids[key].where}")
            ids[key] = child
        _collect_ids(child, ids)


def vertical_fov(node: Node, fov: float, axis: str, width: int, height: int) -> float:
    """raylume's vertical fov (degrees) for Mitsuba's `fov` measured along `fov_axis`."""
    aspect = width / height
    if axis == "smaller":
        axis = "y" if aspect >= 1 else "x"
    elif axis == "larger":
        axis = "x" if aspect >= 1 else "y"
    t = math.tan(math.radians(fov) / 2)
    if axis == "x":
        t /= aspect
    elif axis == "diagonal":
        t /= math.hypot(1.0, aspect)
    elif axis != "y":
        raise node.error(f"fov_axis {axis!r}: Mitsuba's are x, y, diagonal, smaller, larger")
    return math.degrees(2 * math.atan(t))


class Reader:
    def __init__(self, path: Path, defines: dict[str, str] | None):
        self.path = path
        self.document = read_document(path, defines)
        self.ctx = Context(folder=path.resolve().parent, search_paths=self.document.search_paths)
        _collect_ids(self.document.root, self.ctx.ids)
        # max_depth unset is path mode's -1 (Mitsuba's default), and leaves other modes (--mode trace) their own
        self.render: dict = {"mode": "path", "encoding": "srgb", "filter": "gaussian"}
        self.camera: dict = {}
        self.materials: dict[str, dict] = {}
        self.lights: list[dict] = []
        self.environment: dict | None = None
        self.origins: dict[str, Node] = {}  # a key path ("objects[3]") -> the element it came from

    def scene_document(self) -> dict:
        root = self.document.root
        sensors = [c for c in root.children if c.tag == "sensor"]
        if not sensors:
            raise root.error("has no <sensor>: raylume renders through the file's camera, and there is none")
        for extra in sensors[1:]:
            self.ctx.warn(extra, "a second sensor: raylume renders through the first one only")
        integrator = next((c for c in root.children if c.tag == "integrator"), None)
        volumes = integrator is not None and integrator.attrs.get("type") in ("volpath", "volpathmis")
        self.media = Media(self.ctx, rendered=volumes)
        self.sensor(sensors[0])
        self.origins.update(camera=sensors[0], render=sensors[0])
        shapes = Shapes(self.ctx, self.materials, self.media)
        integrators = 0
        for child in root.children:
            if child.tag == "integrator":
                integrators += 1
                if integrators == 1:
                    self.integrator(child)
                else:
                    self.ctx.warn(child, "a second integrator: raylume uses the first")
            elif child.tag == "bsdf":
                key = child.attrs.get("id")
                if key is None:
                    self.ctx.warn(child, "a BSDF without an id at the top level is never used")
                else:
                    self.materials[key] = bsdf_table(self.ctx, child)
                    self.origins[f"materials.{key}"] = child
            elif child.tag == "shape":
                shapes.add(child)
            elif child.tag == "emitter":
                self.emitter(child)
            elif child.tag in ("texture", "sensor", "alias", "film", "sampler", "rfilter"):
                continue  # read where they are used (by <ref>); the sensor above
            elif child.tag in ("medium", "phase", "volume"):
                continue  # read where a shape or the sensor refers to it
            else:
                raise child.error("is not an element of a Mitsuba scene raylume knows")
        document: dict = {"render": self.render, "camera": self.camera, "materials": self.materials}
        document["lights"] = self.lights
        document["objects"] = [clean_transform(obj) for obj in shapes.objects]
        self.origins.update({f"objects[{k}]": node for k, node in enumerate(shapes.origins)})
        if self.environment is not None:
            document["environment"] = self.environment
        if self.media.tables:
            document["media"] = self.media.tables
        return document

    def emitter(self, node: Node) -> None:
        light, environment = light_or_environment(self.ctx, node)
        if light is not None:
            self.origins[f"lights[{len(self.lights)}]"] = node
            self.lights.append(light)
        if environment is not None:
            if self.environment is not None:
                raise node.error("a second environment emitter (constant or envmap): raylume's scene has one")
            self.environment = environment
            self.origins["environment"] = node

    def sensor(self, node: Node) -> None:
        ctx = self.ctx
        kind = node.attrs.get("type")
        if kind not in ("perspective", "thinlens"):
            raise node.error("raylume's cameras are perspective (pinhole or thin lens); this sensor has no equivalent")
        props = ctx.props(node)
        m = props.transform()
        a = m[:3, :3]
        if abs(np.linalg.det(a)) < 1e-12:
            raise node.error("its to_world is singular")
        # A to_world that mirrors already shows Mitsuba's image mirrored: then the world stays as it is
        ctx.world = np.eye(4) if np.linalg.det(a) < 0 else MIRROR.copy()
        film = self.film(node, props)
        outside = props.plugin("medium") or next((p for p in props.plugins if p.tag == "medium"), None)
        if outside is not None:
            self.media.outside = outside
            name = self.media.name(outside, node, "medium")
            if name is not None:
                self.render["medium"] = name
        width, height = film
        fov, focal = props.float("fov"), props.string("focal_length")
        if fov is not None and focal is not None:
            raise node.error("give fov or focal_length, not both")
        if fov is None:
            text = (focal or "50mm").strip().lower().removesuffix("mm")
            try:
                f_mm = float(text)
            except ValueError:
                raise node.error(f"focal_length {focal!r}: expected millimetres, e.g. 50mm") from None
            fov, axis = math.degrees(2 * math.atan(FULL_FRAME_DIAGONAL / (2 * f_mm))), "diagonal"
        else:
            axis = props.string("fov_axis", "x")
        if not 0 < fov < 180:
            raise node.error(f"fov {fov:g}: a perspective camera's field of view lies between 0 and 180 degrees")
        origin = ctx.point(m)
        forward = ctx.vector(m, (0.0, 0.0, 1.0))
        up = ctx.vector(m, (0.0, 1.0, 0.0))
        self.camera = {
            "position": origin,
            "look_at": [p + d / np.linalg.norm(forward) for p, d in zip(origin, forward)],
            "up": up,
            "fov": vertical_fov(node, fov, axis, width, height),
        }
        if kind == "thinlens":
            radius, focus = props.float("aperture_radius"), props.float("focus_distance")
            if radius is None or focus is None:
                raise node.error("a thinlens sensor needs aperture_radius and focus_distance")
            self.camera.update(aperture=2 * radius, focus_distance=focus)
        for name, default in (("near_clip", 1e-2), ("far_clip", 1e4)):
            value = props.float(name, default)
            if value != default:
                ctx.warn(node, f"{name} = {value:g}: raylume's camera does not clip; it is ignored")
        for name in ("principal_point_offset_x", "principal_point_offset_y"):
            if props.float(name, 0.0) != 0.0:
                ctx.warn(node, f"{name}: raylume's camera looks through the image's centre; it is ignored")
        for name in ("shutter_open", "shutter_close", "srf"):
            props.take(name)  # motion blur, spectral response: nothing an RGB still shows
        if kind == "perspective":
            props.take("focus_distance")  # Mitsuba's perspective camera takes it and ignores it
        ctx.done(node, props)

    def film(self, sensor: Node, props) -> tuple[int, int]:
        ctx = self.ctx
        width, height = FILM_SIZE
        spp = 4  # the independent sampler's default
        for plugin in props.plugins:
            p = ctx.props(plugin)
            if "name" in plugin.attrs:  # read here (Blender's exporter names them "film", "sampler")
                props.take(plugin.attrs["name"])
            if plugin.tag == "film":
                if plugin.attrs.get("type") not in ("hdrfilm", "specfilm"):
                    ctx.warn(plugin, "raylume treats this film as an hdrfilm")
                width, height = p.integer("width", width), p.integer("height", height)
                if width < 1 or height < 1:
                    raise plugin.error(f"width and height must be at least 1, got {width} x {height}")
                for name in ("pixel_format", "component_format", "file_format", "sample_border", "banner"):
                    p.take(name)  # how Mitsuba writes its file: raylume's output follows -o
                for name in ("crop_offset_x", "crop_offset_y", "crop_width", "crop_height"):
                    if p.take(name) is not None:
                        ctx.warn(plugin, f"{name}: use raylume's --crop; the whole film is rendered")
                filters = [f for f in p.plugins if f.tag == "rfilter"]
                if filters:
                    self.rfilter(filters[0])
                ctx.done(plugin, p)
            elif plugin.tag == "medium":
                continue  # the sensor's medium: Reader.sensor
            elif plugin.tag == "sampler":
                spp = p.integer("sample_count", spp)
                seed = p.integer("seed", None)
                if seed is not None:
                    self.render["seed"] = seed
                ctx.done(plugin, p)
            else:
                raise plugin.error(f"a sensor cannot hold a <{plugin.tag}>")
        if spp > MAX_SPP:
            ctx.warn(sensor, f"sample_count {spp} is more than raylume renders ({MAX_SPP}); {MAX_SPP} it is")
            spp = MAX_SPP
        self.render.update(width=width, height=height, spp=spp)
        return width, height

    def rfilter(self, node: Node) -> None:
        kind = node.attrs.get("type")
        props = self.ctx.props(node)
        if kind == "gaussian":
            stddev = props.float("stddev", 0.5)
            if stddev != 0.5:
                self.ctx.warn(node, f"stddev {stddev:g}: raylume's gaussian filter has sigma 0.5 px")
        elif kind == "mitchell":
            for name, default in (("B", 1 / 3), ("C", 1 / 3)):
                if abs(props.float(name, default) - default) > 1e-6:
                    self.ctx.warn(node, f"{name}: raylume's mitchell filter has B = C = 1/3")
        props.take("radius")
        if kind in FILTERS:
            self.render["filter"] = FILTERS[kind]
        else:
            self.ctx.warn(node, "raylume has no such pixel filter: its gaussian replaces it")
        self.ctx.done(node, props)

    def integrator(self, node: Node) -> None:
        kind = node.attrs.get("type")
        props = self.ctx.props(node)
        if kind not in ("path", "volpath", "volpathmis"):
            if kind == "direct":
                self.ctx.warn(node, "raylume's path integrator with max_depth 2 (direct lighting) replaces it")
                self.render["max_depth"] = 2
            else:
                self.ctx.warn(node, "raylume has no such integrator: its path tracer replaces it")
            return
        depth = props.integer("max_depth", -1)
        if depth > MAX_DEPTH:
            self.ctx.warn(node, f"max_depth {depth} is more than raylume traces ({MAX_DEPTH}); {MAX_DEPTH} it is")
            depth = MAX_DEPTH
        if depth < -1:
            raise node.error(f"max_depth {depth}: -1 (unlimited) or a depth >= 0")
        if depth >= 0:
            self.render["max_depth"] = depth
        if props.integer("rr_depth", 5) != 5:
            self.ctx.warn(node, "rr_depth: raylume's Russian roulette starts at depth 5")
        if props.boolean("hide_emitters", False):
            self.ctx.warn(node, "hide_emitters: raylume shows emitters seen directly")
        self.ctx.done(node, props)


def mitsuba_document(path: str | Path, defines: dict[str, str] | None = None) -> tuple[dict, dict[str, str]]:
    """The raylume scene document of a Mitsuba XML file (`defines` set its $parameters), and
    where its tables came from: {"objects[3]": 'scene.xml:12 <shape type="sphere">', ...}."""
    reader = Reader(Path(path), defines)
    document = reader.scene_document()
    return document, {key: f"{node.where} {node.describe()}" for key, node in reader.origins.items()}
