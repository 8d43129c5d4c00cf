"""A pbrt-v4 scene file as a raylume scene (`raylume render scene.pbrt`).

The file's directives (scene/pbrt_parse.py) run against pbrt-v4's graphics state: the current
transformation matrix (CTM), the attribute stack (AttributeBegin/End: CTM, material, area light,
ReverseOrientation), named coordinate systems, named materials and textures, object
definitions (ObjectBegin/End) and their instances. Out comes a plain scene document, validated
by scene_from_dict like a TOML file's, so `--set` and the command line's flags apply to it.

Anything raylume cannot render the way pbrt does is named in a SceneWarning saying what replaced
it, or refused with a PbrtError naming the file, line and directive.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .checks import SceneWarning
from .document import scene_from_dict
from .model import Scene
from .overrides import Overrides, apply_overrides
from .pbrt_lights import area_emission, light_tables
from .pbrt_materials import Materials
from .pbrt_options import Options
from .pbrt_params import Params
from .pbrt_parse import Directive, parse_file
from .pbrt_shapes import SUPPORTED, Piece, no_surface, place, shape_piece
from .pbrt_tokens import PbrtError
from .pbrt_transform import from_pbrt_numbers, look_at, rotate, scale, translate

DEFAULT_MATERIAL = "pbrt-default"  # pbrt-v4's default: diffuse, reflectance 0.5
# Directives that only tune how pbrt computes; they change nothing raylume draws.
NO_EFFECT = ("Accelerator",)
# Shapes that enclose a volume: a one-sided area light on them emits only outwards, as raylume's.
CLOSED = ("sphere",)


@dataclass
class State:
    ctm: np.ndarray
    material: str = DEFAULT_MATERIAL  # a name in the document's materials
    emission: tuple[list[float], bool] | None = None  # (radiance, twosided) of AreaLightSource
    reverse: bool = False


@dataclass
class Placed:
    """A shape waiting to be placed: its piece, the CTM it was defined under, its material."""

    piece: Piece
    ctm: np.ndarray
    material: str
    emission: tuple[list[float], bool] | None
    reverse: bool
    directive: Directive
    alpha: dict | None = None  # the shape's alpha_map table (pbrt's alpha is a shape's, raylume's a material's)


@dataclass
class Definition:
    """An ObjectBegin/End block: its shapes, and the matrices it is instanced with."""

    shapes: list[Placed] = field(default_factory=list)
    instances: list[np.ndarray] = field(default_factory=list)


class Builder:
    def __init__(self):
        self.state = State(np.eye(4))
        self.stack: list[tuple[str, State, Directive]] = []
        self.coordinate_systems: dict[str, np.ndarray] = {}
        self.options = Options()
        self.materials_doc: dict[str, dict] = {DEFAULT_MATERIAL: {"type": "diffuse", "color": [0.5, 0.5, 0.5]}}
        self.materials = Materials(self.warn)
        self.named_materials: set[str] = set()
        self.named_uses: dict[str, Directive] = {}  # name -> its first NamedMaterial
        self.anonymous = 0
        self.shapes: list[Placed] = []
        self.definitions: dict[str, Definition] = {}
        self.current: tuple[str, Definition] | None = None
        self.lights: list[tuple[list[dict], Directive]] = []
        self.environment: tuple[dict, Directive] | None = None
        self.warnings: dict[str, list] = {}  # what -> [where it first happened, how often]
        self.active = "all"
        self.camera_directive: Directive | None = None
        self.integrator_directive: Directive | None = None
        self.last: Directive | None = None
        self.material_directives: dict[str, Directive] = {}  # a document material -> the directive that made it
        self.alpha_materials: dict[tuple, str] = {}  # (material, its alpha_map) -> the variant's name
        self.origins: dict[str, str] = {}  # a key path ("objects[3]") -> its directive, set by finish()
        self.world: Directive | None = None  # the WorldBegin: options before it, the scene after

    def warn(self, d: Directive, message: str) -> None:
        """Note a warning; the same one from many directives (10,000 curves) is issued once, with its
        first place and its count."""
        kind = f' "{d.args[0]}"' if d.args and isinstance(d.args[0], str) else ""
        seen = self.warnings.setdefault(f"{d.name}{kind}: {message}", [d.where, 0])
        seen[1] += 1

    @property
    def messages(self) -> list[str]:
        return [
            f"{where}: {what}" + (f" ({count} times, first here)" if count > 1 else "")
            for what, (where, count) in self.warnings.items()
        ]

    # -- the directives ---------------------------------------------------------------------
    def run(self, d: Directive) -> None:
        self.last = d
        p = Params(d)
        handler = getattr(self, f"_{d.name}", None)
        if handler is None:
            self.warn(d, "is not supported; ignored")
            for q in d.params:
                q.used = True
        else:
            handler(d, p)
        unused = p.unused()
        if unused:
            names = ", ".join(q.label for q in unused)
            self.warn(d, f"raylume does not use {names}; ignored")

    def _concat(self, d: Directive, m: np.ndarray) -> None:
        if self.active == "end":
            self.warn(d, "transforms for the end of the shutter interval (motion blur) are not supported; ignored")
            return
        self.state.ctm = self.state.ctm @ m

    def _Identity(self, d, p):
        if self.active != "end":
            self.state.ctm = np.eye(4)

    def _Translate(self, d, p):
        self._concat(d, translate(*d.args))

    def _Scale(self, d, p):
        self._concat(d, scale(*d.args))

    def _Rotate(self, d, p):
        angle, *axis = d.args
        if not any(axis):
            raise d.fail("the rotation axis must not be (0, 0, 0)")
        self._concat(d, rotate(angle, axis))

    def _LookAt(self, d, p):
        try:
            self._concat(d, look_at(d.args[0:3], d.args[3:6], d.args[6:9]))
        except ValueError as exc:
            raise d.fail(str(exc)) from None

    def _Transform(self, d, p):
        if self.active != "end":
            self.state.ctm = from_pbrt_numbers(d.args[0])

    def _ConcatTransform(self, d, p):
        self._concat(d, from_pbrt_numbers(d.args[0]))

    def _CoordinateSystem(self, d, p):
        self.coordinate_systems[d.args[0]] = self.state.ctm.copy()

    def _CoordSysTransform(self, d, p):
        name = d.args[0]
        if name not in self.coordinate_systems:
            known = ", ".join(sorted(self.coordinate_systems)) or "none yet"
            raise d.fail(f"no coordinate system named {name!r} ({known})")
        self.state.ctm = self.coordinate_systems[name].copy()

    def _ActiveTransform(self, d, p):
        word = str(d.args[0])
        if word not in ("StartTime", "EndTime", "All"):
            raise d.fail(f"expected StartTime, EndTime or All, got {word!r}")
        self.active = {"StartTime": "start", "EndTime": "end", "All": "all"}[word]

    def _TransformTimes(self, d, p):
        pass  # without motion (EndTime transforms are ignored), the times change nothing

    def _ReverseOrientation(self, d, p):
        self.state.reverse = not self.state.reverse

    def _push(self, kind: str, d: Directive) -> None:
        self.stack.append((kind, replace(self.state, ctm=self.state.ctm.copy()), d))

    def _pop(self, kind: str, d: Directive) -> State:
        if not self.stack:
            raise d.fail(f"has no matching {kind}Begin")
        opened, state, start = self.stack.pop()
        if opened != kind:
            raise d.fail(f"closes the {opened}Begin of {start.where}; expected {opened}End")
        return state

    def _AttributeBegin(self, d, p):
        self._push("Attribute", d)

    def _AttributeEnd(self, d, p):
        self.state = self._pop("Attribute", d)

    def _TransformBegin(self, d, p):
        self._push("Transform", d)

    def _TransformEnd(self, d, p):
        self.state.ctm = self._pop("Transform", d).ctm

    def _WorldBegin(self, d, p):
        if self.world is not None:
            raise d.fail(f"a second WorldBegin (the first is at {self.world.where}); a file has one world block")
        self.world = d
        self.state.ctm = np.eye(4)
        self.coordinate_systems["world"] = np.eye(4)

    def _before_world(self, d) -> None:
        """pbrt refuses a scene-wide option inside the world block ("Options cannot be set inside
        world block"): a second Camera there had silently replaced the first."""
        if self.world is not None:
            raise d.fail(f"options are set before WorldBegin ({self.world.where}), not inside the world block")

    def _WorldEnd(self, d, p):
        pass  # pbrt-v3's end of the world block: nothing follows it

    def _Camera(self, d, p):
        self._before_world(d)
        self.options.camera(d, p, self.state.ctm, self.warn)
        self.camera_directive = d
        self.coordinate_systems["camera"] = np.linalg.inv(self.state.ctm)

    def _Film(self, d, p):
        self._before_world(d)
        self.options.film(d, p, self.warn)

    def _Sampler(self, d, p):
        self._before_world(d)
        self.options.sampler(d, p)

    def _Integrator(self, d, p):
        self._before_world(d)
        self.options.integrator_directive(d, p, self.warn)
        self.integrator_directive = d

    def _PixelFilter(self, d, p):
        self._before_world(d)
        self.options.pixel_filter(d, p, self.warn)

    def _Accelerator(self, d, p):
        self._before_world(d)
        for q in d.params:
            q.used = True  # how pbrt builds its BVH: nothing raylume draws

    def _ColorSpace(self, d, p):
        if str(d.args[0]).lower() != "srgb":
            self.warn(d, "raylume renders linear sRGB (Rec. 709) colours; RGB values are taken as sRGB")

    def _Option(self, d, p):
        self._before_world(d)
        if p.has("seed"):
            self.options.seed = p.int("seed")
        for q in d.params:
            if not q.used:
                q.used = True
                self.warn(d, f"option {q.label} is not supported; ignored")

    def _MakeNamedMedium(self, d, p):
        self.warn(d, "participating media are not read from pbrt files; this medium is ignored")
        for q in d.params:
            q.used = True

    def _MediumInterface(self, d, p):
        if any(d.args):
            self.warn(d, "participating media are not read from pbrt files; surfaces are drawn without media")

    def _Attribute(self, d, p):
        self.warn(d, "default parameters for later directives (Attribute) are not supported; ignored")
        for q in d.params:
            q.used = True

    def _Texture(self, d, p):
        self.materials.define_texture(d, p, self.state.ctm)

    def _Material(self, d, p):
        kind = d.args[0]
        table = self.materials.material(d, p, kind, self._named)
        self.anonymous += 1
        name = f"pbrt-material-{self.anonymous}"
        self.materials_doc[name] = table
        self.material_directives[name] = d
        self.state.material = name

    def _MakeNamedMaterial(self, d, p):
        name = d.args[0]
        kind = p.string("type")
        if kind is None:
            raise d.fail('needs "string type", e.g. "diffuse"')
        self.materials_doc[name] = self.materials.material(d, p, kind, self._named)
        self.material_directives[name] = d
        self.named_materials.add(name)

    def _named(self, name: str) -> dict | None:
        return self.materials_doc.get(name) if name in self.named_materials else None

    def _NamedMaterial(self, d, p):
        # pbrt-v4 creates named materials after reading the whole file, so one may be defined
        # after its first use; finish() checks that it was defined at all
        name = d.args[0]
        self.named_uses.setdefault(name, d)
        self.state.material = name

    def _AreaLightSource(self, d, p):
        self.state.emission = area_emission(d, p, self.warn)

    def _LightSource(self, d, p):
        if self.current is not None:
            self.warn(d, "a light inside ObjectBegin/End is not instanced (pbrt-v4 does not allow it); left out")
            for q in d.params:
                q.used = True
            return
        lights, environment = light_tables(d, p, self.state.ctm, self.warn)
        if lights:
            self.lights.append((lights, d))
        if environment is not None:
            if self.environment is not None:
                first, where = self.environment
                if "color" in first and "color" in environment:
                    first["color"] = [a + b for a, b in zip(first["color"], environment["color"])]
                    return
                raise d.fail(f"a second infinite light (the first is at {where.where}); raylume has one environment")
            self.environment = (environment, d)

    def _Shape(self, d, p):
        kind = d.args[0]
        if kind not in SUPPORTED:
            self.warn(d, f"shape {kind!r} is not supported; it is left out (raylume reads {', '.join(SUPPORTED)})")
            for q in d.params:
                q.used = True
            return
        alpha = self.materials.alpha(d, p)
        if alpha is False:
            for q in d.params:
                q.used = True
            return
        for key in ("displacement", "edgelength", "emissionfilename"):
            if p.has(key):
                p.by_name[key].used = True
                self.warn(d, f'"{key}" is not supported; ignored')
        piece = shape_piece(d, p)
        empty = no_surface(piece)
        if empty is not None:
            self.warn(d, f"{empty}: the shape has no surface; it is left out (pbrt draws nothing of it)")
            return
        placed = Placed(
            piece, self.state.ctm.copy(), self.state.material, self.state.emission, self.state.reverse, d, alpha
        )
        if self.current is not None:
            if placed.emission is not None:
                self.warn(d, "area lights on instanced shapes are not supported (nor by pbrt-v4); drawn unlit")
                placed.emission = None
            self.current[1].shapes.append(placed)
        else:
            self.shapes.append(placed)

    def _ObjectBegin(self, d, p):
        if self.current is not None:
            raise d.fail(f"inside the definition of {self.current[0]!r}; object definitions cannot nest")
        name = d.args[0]
        if name in self.definitions:
            self.warn(d, f"object {name!r} is defined again; the new definition replaces the first")
        self._push("Object", d)
        self.current = (name, Definition())
        self.definitions[name] = self.current[1]

    def _ObjectEnd(self, d, p):
        if self.current is None:
            raise d.fail("has no matching ObjectBegin")
        self.state = self._pop("Object", d)
        self.current = None

    def _ObjectInstance(self, d, p):
        name = d.args[0]
        if self.current is not None:
            raise d.fail("inside an object definition; instances cannot nest")
        if name not in self.definitions:
            raise d.fail(f"no object named {name!r} (define it with ObjectBegin/ObjectEnd first)")
        self.definitions[name].instances.append(self.state.ctm.copy())

    # -- the document -----------------------------------------------------------------------
    def finish(self) -> dict:
        if self.stack:
            kind, _, start = self.stack[-1]
            raise start.fail(f"is never closed (no {kind}End before the end of the file)")
        for name, d in self.named_uses.items():
            if name not in self.named_materials:
                known = ", ".join(sorted(self.named_materials)) or "none are defined"
                raise d.fail(f"no material named {name!r} in the file ({known})")
        for s in self.shapes + [s for definition in self.definitions.values() for s in definition.shapes]:
            self._alpha_material(s)
        flip = self.options.flip()
        camera_where = self.camera_directive or self.last
        checkers = any((t.get("texture") or {}).get("type") == "checker" for t in self.materials_doc.values())
        if checkers and not np.array_equal(flip, np.eye(4)):
            self.warn(
                camera_where,
                "the camera mirrors, so raylume mirrors the world instead; 3D checkerboards "
                "(raylume's are in world space) are drawn in the mirrored world",
            )
        camera = self.options.camera_table(lambda m: self.warn(camera_where, m))
        render = self.options.render_table(lambda m: self.warn(self.integrator_directive or self.last, m))
        placed = [(self._object(s, flip @ s.ctm), s.directive) for s in self.shapes]
        for definition in self.definitions.values():
            placed += self._instanced(definition, flip)
        objects = [obj for obj, _ in placed]
        lights = [self._flipped_light(light, flip) for group, _ in self.lights for light in group]
        document = {"render": render, "camera": camera, "materials": self._used_materials(objects)}
        self._note_origins(placed)
        if lights:
            document["lights"] = lights
        document["objects"] = objects
        if self.environment is not None:
            document["environment"] = self._placed_environment(*self.environment, flip)
        return document

    def _note_origins(self, placed: list[tuple[dict, Directive]]) -> None:
        """Where the document's tables came from, so that a value the scene model refuses later
        (a singular transform, an unreadable PLY file) names its file, line and directive."""
        origins = {f"objects[{k}]": d for k, (_, d) in enumerate(placed)}
        origins.update({f"lights[{k}]": d for k, d in enumerate(d for group, d in self.lights for _ in group)})
        origins.update({f"materials.{name}": d for name, d in self.material_directives.items()})
        if self.environment is not None:
            origins["environment"] = self.environment[1]
        if self.camera_directive is not None:
            origins["camera"] = self.camera_directive
        self.origins = {key: d.label for key, d in origins.items()}

    def _placed_environment(self, table: dict, d: Directive, flip: np.ndarray) -> dict:
        table = dict(table)
        ctm = table.pop("_ctm", None)
        turn = table.pop("_turn", np.eye(3))  # the map's own frame in the light's (pbrt-v3's lat-long)
        if ctm is None:
            return table
        a = (flip @ ctm)[:3, :3] @ turn
        lengths = np.linalg.norm(a, axis=0)
        if not np.allclose(a.T @ a, np.diag(lengths**2), atol=1e-9 * max(lengths) ** 2):
            self.warn(d, "the light's transform shears the sky; only its rotation is used")
        q, r = np.linalg.qr(a)
        a = q * np.sign(np.diag(r))  # a's orthonormal frame: exact for a rotation (or mirror) times a uniform scale
        if not np.allclose(a, np.eye(3), atol=1e-12):
            table["matrix"] = a.tolist()
        return table

    def _material_ref(self, s: Placed):
        if s.emission is None:
            return s.material
        radiance, twosided = s.emission
        if not twosided and s.piece.kind in CLOSED and s.reverse:
            self.warn(
                s.directive,
                "raylume's emitters emit from both sides; this one-sided area light turned inwards "
                "(ReverseOrientation) also shines outwards",
            )
        elif not twosided and s.piece.kind not in CLOSED:
            self.warn(
                s.directive,
                "raylume's emitters emit from both sides; this one-sided area light also lights what is behind it",
            )
        table = dict(self.materials_doc[s.material])
        if table.get("type") == "null":
            table = {"type": "diffuse", "color": [0.0, 0.0, 0.0]}
        return {**table, "emission": radiance}

    def _alpha_material(self, s: Placed) -> None:
        """Give a shape with an alpha texture a variant of its material with that alpha_map (one
        per material and mask), as raylume's alpha is a material's."""
        if s.alpha is None:
            return
        table = self.materials_doc[s.material]
        if table.get("type") == "null":
            return  # an interface has no surface to cut
        if s.emission is not None:
            self.warn(
                s.directive,
                "an area light with an alpha texture: raylume's emitters take no alpha map (its holes would be "
                "sampled as light), so it is drawn and lit whole",
            )
            return
        key = (s.material, tuple(sorted((k, str(v)) for k, v in s.alpha.items())))
        if key not in self.alpha_materials:
            name = f"{s.material}+alpha-{len(self.alpha_materials) + 1}"
            self.alpha_materials[key] = name
            self.materials_doc[name] = {**table, "alpha_map": s.alpha}
            self.material_directives[name] = self.material_directives.get(s.material, s.directive)
        s.material = self.alpha_materials[key]

    def _needs_uvs(self, s: Placed) -> bool:
        """Whether the shape's material reads pbrt's (u, v): an image texture, a normal, bump or alpha map."""
        table = self.materials_doc[s.material]
        texture = table.get("texture")
        image = texture is not None and texture.get("type") == "image"
        return image or "normal_map" in table or "bump_map" in table or "alpha_map" in table

    def _object(self, s: Placed, m: np.ndarray) -> dict:
        obj, note = place(s.piece, m, self._material_ref(s), self._needs_uvs(s), s.reverse)
        if note:
            self.warn(s.directive, f"{note} is tessellated into triangles")
        if s.reverse and s.piece.kind != "mesh" and obj["type"] != "mesh":
            self.warn(s.directive, "ReverseOrientation on an analytic shape is ignored (its surface is two-sided)")
        return obj

    def _instanced(self, definition: Definition, flip: np.ndarray) -> list[tuple[dict, Directive]]:
        """An object's shapes, each with its Shape directive: meshes as one raylume mesh with
        instances each, analytic shapes placed once per instance."""
        out = []
        if not definition.instances:
            return out
        for s in definition.shapes:
            if s.piece.kind == "mesh":
                obj, _ = place(s.piece, s.ctm, s.material, self._needs_uvs(s), s.reverse)
                obj["instances"] = [{"matrix": (flip @ m).tolist()} for m in definition.instances]
                out.append((obj, s.directive))
            else:
                out += [(self._object(s, flip @ m @ s.ctm), s.directive) for m in definition.instances]
        return out

    @staticmethod
    def _flipped_light(light: dict, flip: np.ndarray) -> dict:
        if np.array_equal(flip, np.eye(4)):
            return light
        out = dict(light)
        a, t = flip[:3, :3], flip[:3, 3]
        if "position" in out:
            out["position"] = (a @ np.array(out["position"]) + t).tolist()
        if "direction" in out:
            out["direction"] = (a @ np.array(out["direction"])).tolist()
        return out

    def _used_materials(self, objects: list[dict]) -> dict:
        used = {obj["material"] for obj in objects if isinstance(obj.get("material"), str)}
        return {name: table for name, table in self.materials_doc.items() if name in used}


def _read(path: Path) -> tuple[dict, Builder]:
    builder = Builder()
    for directive in parse_file(path):
        builder.run(directive)
    return builder.finish(), builder


def pbrt_document(path: str | Path) -> tuple[dict, list[str]]:
    """(the scene document of a pbrt-v4 file, its warnings). Raises PbrtError."""
    document, builder = _read(Path(path))
    return document, builder.messages


def pbrt_scene(path: str | Path, overrides: Overrides | None = None, source: str | None = None) -> Scene:
    """The scene of a pbrt-v4 file, `overrides` applied as --set does. Its warnings are issued as
    SceneWarnings once the scene is valid."""
    path = Path(path)
    if path.is_dir():
        raise SceneError(f"{path}: is a folder, not a pbrt file")
    document, builder = _read(path)
    document = apply_overrides(document, overrides)
    # a value the model refuses is named by the directive it came from
    scene = scene_from_dict(document, source=source or path, overrides=overrides, origins=builder.origins)
    for message in builder.messages:
        warnings.warn(message, SceneWarning, stacklevel=2)
    return scene.with_base_dir(path.resolve().parent)


__all__ = ["PbrtError", "pbrt_document", "pbrt_scene"]
