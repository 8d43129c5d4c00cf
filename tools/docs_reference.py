"""The documentation's generated reference pages: the scene file keys, from the pydantic scene model
(src/raylume/scene/model.py, each field's docstring), and the command line, from the click command
that Typer builds of raylume.cli. `docs/gen_pages.py` writes them at `mkdocs build` time;
tests/test_docs.py checks that every model field is there and that the docs' command lines parse.

    python tools/docs_reference.py scene|cli     # print a page
"""

from __future__ import annotations

import ast
import functools
import inspect
import shlex
import sys
import tomllib
import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Union

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

import annotated_types  # noqa: E402
from pydantic import BaseModel  # noqa: E402
from pydantic_core import PydanticUndefined  # noqa: E402

from raylume.scene import model  # noqa: E402

# ---------------------------------------------------------------------------------------------
# The scene model, walked as the scene file nests it


@dataclass(frozen=True)
class Table:
    """A table of the scene file and the model that validates it."""

    heading: str  # as the file writes it: [render], [materials.NAME] type = "conductor", [[objects]] ...
    anchor: str
    path: str  # key prefix as --set writes it: render, materials.NAME, objects.N
    model: type[BaseModel]
    intro: str


def _kinds(union_of: dict[str, type[BaseModel]], heading: str, path: str, anchor: str, what: str) -> list[Table]:
    return [
        Table(f'{heading} type = "{name}"', f"{anchor}-{name}", path, cls, f"{what} of type `{name}`.")
        for name, cls in union_of.items()
    ]


def scene_tables() -> list[Table]:
    """Every table a scene file can hold, in the reference's order."""
    tables = [
        Table("[render]", "render", "render", model.RenderSettings, "How to render; command-line flags override it."),
        Table("[camera]", "camera", "camera", model.Camera, "The camera (left-handed: by default at the origin, +z)."),
        *_kinds(model.MATERIAL_TYPES, "[materials.NAME]", "materials.NAME", "materials", "A named material"),
        Table(
            'texture = { type = "checker" }',
            "texture-checker",
            "materials.NAME.texture",
            model.Checker,
            "A material's `texture`: a checkerboard.",
        ),
        Table(
            'texture = { type = "image" }',
            "texture-image",
            "materials.NAME.texture",
            model.ImageTexture,
            "A material's `texture`: an image.",
        ),
        Table(
            "normal_map = { ... }",
            "normal-map",
            "materials.NAME.normal_map",
            model.NormalMap,
            "A material's `normal_map`: a tangent-space normal map.",
        ),
        Table(
            "bump_map = { ... }",
            "bump-map",
            "materials.NAME.bump_map",
            model.BumpMap,
            "A material's `bump_map`: a height map.",
        ),
        Table(
            "alpha_map = { ... }",
            "alpha-map",
            "materials.NAME.alpha_map",
            model.AlphaMap,
            "A material's `alpha_map`: a cut-out mask.",
        ),
        *_kinds(model.LIGHT_TYPES, "[[lights]]", "lights.N", "lights", "A light"),
        *_kinds(model.OBJECT_TYPES, "[[objects]]", "objects.N", "objects", "An object"),
        Table(
            "transform = { ... }",
            "transform",
            "objects.N.transform",
            model.MeshTransform,
            "An object's `transform` (`fit` for meshes only; disks and cylinders take a uniform `scale` only); "
            "a mesh's `instances` list takes the same keys but `fit`.",
        ),
        Table("fit = { ... }", "fit", "objects.N.transform.fit", model.Fit, "A mesh's `transform.fit`."),
        Table("[environment]", "environment", "environment", model.Environment, "Light from every direction."),
        *_kinds(model.MEDIUM_TYPES, "[media.NAME]", "media.NAME", "media", "A named participating medium (path mode)"),
        Table("[animation]", "animation", "animation", model.Animation, "A camera flight."),
        Table(
            "[[animation.camera]]",
            "animation-camera",
            "animation.camera.N",
            model.CameraKey,
            "A camera keyframe of the animation.",
        ),
    ]
    return tables


def covered_fields() -> set[tuple[str, str]]:
    """(model class name, field) of every table in the reference, to compare with the model; a table of a
    subclass (MeshTransform) covers its base's fields (Transform) too."""
    return {
        (klass.__name__, name)
        for table in scene_tables()
        for klass in table.model.__mro__
        if isinstance(klass, type) and issubclass(klass, BaseModel)
        for name in table.model.model_fields
        if name in klass.model_fields
    }


def model_fields_reachable() -> set[tuple[str, str]]:
    """(class name, field) of every model reachable from Scene through its fields' annotations."""
    seen: set[type[BaseModel]] = set()
    stack: list[type[BaseModel]] = [model.Scene]
    while stack:
        cls = stack.pop()
        if cls in seen:
            continue
        seen.add(cls)
        for info in cls.model_fields.values():
            stack.extend(_models_in(info.annotation))
    return {(cls.__name__, name) for cls in seen for name in cls.model_fields if cls is not model.Scene}


def _models_in(annotation: Any) -> Iterator[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield annotation
        return
    for arg in typing.get_args(annotation):
        yield from _models_in(arg)


# Each field's description is the docstring under it in the model's source (read here, not by pydantic at import).
def _attribute_docstrings() -> dict[tuple[str, str], str]:
    return dict(_parsed_docstrings())  # a copy: callers may change theirs


@functools.cache
def _parsed_docstrings() -> dict[tuple[str, str], str]:
    tree = ast.parse(Path(inspect.getsourcefile(model)).read_text())
    docs: dict[tuple[str, str], str] = {}
    for node in tree.body:
        if not isinstance(node, ast.ClassDef):
            continue
        for stmt, after in zip(node.body, node.body[1:]):
            if (
                isinstance(stmt, ast.AnnAssign)
                and isinstance(stmt.target, ast.Name)
                and isinstance(after, ast.Expr)
                and isinstance(after.value, ast.Constant)
                and isinstance(after.value.value, str)
            ):
                docs[(node.name, stmt.target.id)] = inspect.cleandoc(after.value.value).replace("\n", " ")
    return docs


def field_description(cls: type[BaseModel], name: str, docs: dict[tuple[str, str], str] | None = None) -> str:
    """The docstring of the field as the class or its nearest base declares it; '' if none."""
    docs = _attribute_docstrings() if docs is None else docs
    for klass in cls.__mro__:
        if (klass.__name__, name) in docs:
            return docs[(klass.__name__, name)]
    return ""


def _strip_optional(annotation: Any) -> tuple[Any, bool]:
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return (rest[0] if len(rest) == 1 else Union[tuple(rest)]), True  # noqa: UP007 (a tuple of members)
    return annotation, False


def _is_color(cls: type[BaseModel], name: str) -> bool:
    """Colour fields take '#rrggbb' too: their validators run _colour (or _intensity) before pydantic."""
    for decorator in cls.__pydantic_decorators__.field_validators.values():
        if name in decorator.info.fields and decorator.info.mode == "before":
            return True
    return False


def _unwrap(annotation: Any) -> Any:
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    return annotation


def type_text(cls: type[BaseModel], name: str) -> str:
    annotation, _ = _strip_optional(cls.model_fields[name].annotation)
    if name == "intensity" and issubclass(cls, model._LightBase):
        return "number or `[r, g, b]`"
    if name == "material":
        return "string (a material's name) or inline table"
    if name == "texture":
        return "inline table"
    if name == "instances":
        return "string (`.npy` file) or array of transform tables"
    if name == "scale" and cls is model.ImageTexture:
        return "number or `[u, v]`"
    if _is_color(cls, name):
        return "`[r, g, b]` pair" if name == "colors" else '`[r, g, b]` or `"#rrggbb"`'
    return _annotation_text(annotation)


def _annotation_text(annotation: Any) -> str:
    annotation = _unwrap(annotation)
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if annotation is bool:
        return "boolean"
    if annotation is int:
        return "integer"
    if annotation is float:
        return "number"
    if annotation is str:
        return "string"
    if origin is Literal:
        return "string"
    if origin is tuple:
        inner = [_unwrap(a) for a in args]
        if len(args) == 3 and all(a is float for a in inner):
            return "`[x, y, z]`"
        if all(a is float for a in inner):
            return f"{len(args)} numbers"
        if all(a is int for a in inner):
            return f"{len(args)} integers"
        return f"{len(args)} x " + _annotation_text(args[0])
    if origin is list:
        inner = _unwrap(args[0])
        if isinstance(inner, type) and issubclass(inner, BaseModel):
            return "array of tables"
        return "array of " + _annotation_text(inner)
    if origin is dict:
        return "tables by name"
    if origin in (Union, types.UnionType):
        return " or ".join(_annotation_text(a) for a in args)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "table"
    return str(annotation)


def range_text(cls: type[BaseModel], name: str) -> str:
    info = cls.model_fields[name]
    annotation, _ = _strip_optional(info.annotation)
    annotation = _unwrap(annotation)
    if typing.get_origin(annotation) is Literal:
        return ", ".join(f'`"{v}"`' for v in typing.get_args(annotation))
    bounds = []
    for meta in info.metadata:
        for attr, symbol in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
            value = getattr(meta, attr, None)
            if isinstance(meta, (annotated_types.Ge, annotated_types.Gt, annotated_types.Le, annotated_types.Lt)) and (
                value is not None
            ):
                bounds.append(f"{symbol} {value:g}" if isinstance(value, float) else f"{symbol} {value}")
    if name == "scale" and cls is model.ImageTexture:
        return "> 0"
    if _is_color(cls, name):
        upper = name in ("color", "colors") and cls is not model.Environment
        return "components 0..1" if upper else "components >= 0"
    return ", ".join(bounds)


def default_text(cls: type[BaseModel], name: str) -> str:
    info = cls.model_fields[name]
    if info.default is PydanticUndefined:
        return "required"
    value = info.default
    if value is None:
        return "unset"
    if isinstance(value, BaseModel):
        return "see below" if value.model_fields_set else "identity" if "Transform" in type(value).__name__ else "{}"
    return f"`{toml_value(value)}`"


def toml_value(value: Any) -> str:
    """A value as TOML writes it inline."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}" if value != int(value) or abs(value) >= 1e16 else str(int(value))
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, BaseModel):
        return toml_value(value.model_dump(exclude_defaults=True))
    raise TypeError(f"no TOML for {value!r}")


# Examples: the value a shipped scene file gives the key, found by walking the example scenes.
EXAMPLE_FILES = sorted((REPO / "examples").glob("**/*.toml")) + sorted((REPO / "src/raylume/scenes").glob("*.toml"))


def _walk_examples() -> dict[tuple[str, str], tuple[Any, str]]:
    found: dict[tuple[str, str], tuple[Any, str]] = {}

    def visit(cls: type[BaseModel], table: dict, source: str) -> None:
        for key, value in table.items():
            if key not in cls.model_fields:
                continue
            found.setdefault((cls.__name__, key), (value, source))
            for sub in _models_in(_strip_optional(cls.model_fields[key].annotation)[0]):
                if isinstance(value, dict) and sub in _candidates(cls, key, value):
                    visit(sub, value, source)
                elif isinstance(value, list):
                    for item in value:
                        if isinstance(item, dict) and sub in _candidates(cls, key, item):
                            visit(sub, item, source)

    for path in EXAMPLE_FILES:
        document = tomllib.loads(path.read_text())
        source = str(path.relative_to(REPO))
        tables = ("materials", "lights", "objects", "media")
        visit(model.Scene, {k: v for k, v in document.items() if k not in tables}, source)
        for table in document.get("media", {}).values():
            if table.get("type") in model.MEDIUM_TYPES:
                visit(model.MEDIUM_TYPES[table["type"]], table, source)
        for table in document.get("materials", {}).values():
            visit(model.MATERIAL_TYPES.get(table.get("type", "phong"), model.PhongMaterial), table, source)
            if isinstance(table.get("texture"), dict):
                texture = table["texture"]
                visit(model.Checker if texture.get("type") == "checker" else model.ImageTexture, texture, source)
        for key, kinds in (("lights", model.LIGHT_TYPES), ("objects", model.OBJECT_TYPES)):
            for table in document.get(key, []):
                if table.get("type") in kinds:
                    cls = kinds[table["type"]]
                    visit(cls, table, source)
                    if isinstance(table.get("transform"), dict):
                        visit(model.MeshTransform, table["transform"], source)
                        if isinstance(table["transform"].get("fit"), dict):
                            visit(model.Fit, table["transform"]["fit"], source)
    return found


def _candidates(cls: type[BaseModel], key: str, value: dict) -> tuple[type[BaseModel], ...]:
    if key == "transform":
        return (model.Transform, model.MeshTransform)
    if key == "camera" and cls is model.Animation:
        return (model.CameraKey,)
    models = tuple(_models_in(cls.model_fields[key].annotation))
    if "type" in value:  # a tagged union's member: only the model of that type
        return tuple(m for m in models if _literal_type(m) == value["type"])
    return models


def _literal_type(cls: type[BaseModel]) -> str | None:
    info = cls.model_fields.get("type")
    args = typing.get_args(_unwrap(info.annotation)) if info else ()
    return args[0] if args else None


# Examples for keys no shipped scene uses, by (class, key) or by key.
_SYNTHETIC: dict[str | tuple[str, str], str] = {
    ("Gltf", "file"): '"gltf/room.glb"',
    "file": '"model.obj"',
    "u": "[1, 0, 0]",
    "v": "[0, 0, 1]",
    "p0": "[0, -1, 3]",
    "p1": "[0, 1, 3]",
    "size": "2",
    "frame": "0",
    "frames": "72",
    "radius": "0.5",
    "position": "[2, 1, 0]",
    "center": "[0, -1, 3]",
    "direction": "[1, 4, 4]",
    "instances": '"trees.npy"',
    "texture": '{ type = "checker", scale = 0.5 }',
    "normal_map": '{ file = "textures/bricks_normal.png" }',
    "bump_map": '{ file = "textures/bumps.png", height = 0.01 }',
    "alpha_map": '{ file = "textures/leaf.png" }',
    "material": '"glass"',
    "eta": "[0.143, 0.374, 1.442]",
    "k": "[3.983, 2.385, 1.603]",
    "color": "[0.8, 0.8, 0.8]",
    "look_at": "[0, 0, 3]",
    "up": "[0, 1, 0]",
    "fov": "45",
    "fit": "{ center = [0, 0, 3], size = 2 }",
    "inner_angle": "20",
    "focus_distance": "3",
    "specular": "500",
    "smooth": "true",
    "transform": "{ translate = [0, 0, 3], rotate = [90, 0, 0], scale = 0.5 }",
    "translate": "[0, -1, 3]",
    "rotate": "[0, 180, 0]",
    "scale": "0.5",
    "camera": "[{ frame = 0, position = [0, 0, 0] }, { frame = 71, position = [4, 1, 0] }]",
    "environment": "{ color = [0.2, 0.2, 0.3] }",
    "animation": "{ frames = 72 }",
    "interior": '"smoke"',
    "medium": '"fog"',
    ("Transform", "matrix"): "[[1, 0, 0, 0], [0, 1, 0, -1], [0, 0, 1, 3], [0, 0, 0, 1]]",
    ("MeshTransform", "matrix"): "[[1, 0, 0, 0], [0, 1, 0, -1], [0, 0, 1, 3], [0, 0, 0, 1]]",
    ("Environment", "matrix"): "[[-1, 0, 0], [0, 1, 0], [0, 0, 1]]",
    "vertices": "[[0, 0, 3], [1, 0, 3], [0, 1, 3], [1, 1, 3]]",
    ("Triangle", "vertices"): "[[0, 0, 3], [1, 0, 3], [0, 1, 3]]",
    "faces": "[[0, 1, 2], [2, 1, 3]]",
    "normals": "[[0, 0, -1], [0, 0, -1], [0, 0, -1], [0, 0, -1]]",
    "uvs": "[[0, 0], [1, 0], [0, 1], [1, 1]]",
    "density": '"smoke/density.npy"',
    "bounds_min": "[-1, 0, 2]",
    "bounds_max": "[1, 2, 4]",
    "sigma_a": "[0.05, 0.05, 0.05]",
    "sigma_s": "[0.5, 0.5, 0.5]",
    "g": "0.3",
    "noise_threshold": "0.02",
    "min_spp": "64",
    "time_limit": "60",
}


def example_text(cls: type[BaseModel], name: str, examples: dict[tuple[str, str], tuple[Any, str]]) -> str:
    if field_description(cls, name, _parsed_docstrings()).startswith("Refused"):
        return "(none: refused)"
    if (cls.__name__, name) in examples:
        value, source = examples[(cls.__name__, name)]
        if isinstance(value, list) and len(toml_value(value)) > 100:  # a long list: its first item shows the form
            return f"`{name} = [{toml_value(value[0])}, ...]` ({source})"
        return f"`{name} = {toml_value(value)}` ({source})"
    for klass in cls.__mro__[1:]:
        if (getattr(klass, "__name__", ""), name) in examples:
            value, source = examples[(klass.__name__, name)]
            return f"`{name} = {toml_value(value)}` ({source})"
    annotation = _unwrap(cls.model_fields[name].annotation)
    if name == "type" and typing.get_origin(annotation) is Literal:
        return f"`type = {toml_value(typing.get_args(annotation)[0])}`"
    if (cls.__name__, name) in _SYNTHETIC:
        return f"`{name} = {_SYNTHETIC[(cls.__name__, name)]}`"
    if name in _SYNTHETIC:
        return f"`{name} = {_SYNTHETIC[name]}`"
    default = cls.model_fields[name].default
    if default is not PydanticUndefined and default is not None and not isinstance(default, BaseModel):
        return f"`{name} = {toml_value(default)}`"
    raise ValueError(f"{cls.__name__}.{name}: no example; add one to tools/docs_reference.py's _SYNTHETIC")


def scene_reference_markdown() -> str:
    docs = _attribute_docstrings()
    examples = _walk_examples()
    missing = sorted(f"{c}.{f}" for c, f in model_fields_reachable() - covered_fields())
    undocumented = sorted(
        f"{t.model.__name__}.{name}"
        for t in scene_tables()
        for name in t.model.model_fields
        if not field_description(t.model, name, docs)
    )
    if missing or undocumented:
        raise ValueError(
            "scene reference: "
            + (f"fields in no table: {', '.join(missing)}; " if missing else "")
            + (f"fields without a docstring in scene/model.py: {', '.join(undocumented)}" if undocumented else "")
        )
    lines = [
        "# Scene file reference",
        "",
        "Generated from the scene model (`src/raylume/scene/model.py`) when the site is built: every key a scene file "
        "takes, its type, default, allowed range and an example (from a shipped scene file where one uses it). "
        "TOML, or the same structure as JSON; every table is optional and unknown keys are errors. "
        "`--set KEY=VALUE` on the command line takes the same keys as dotted paths (`--set render.width=64`, "
        "`--set objects.0.radius=0.5`, `--set materials.glass.ior=1.33`).",
        "",
        'Colours are linear RGB floats or `"#rrggbb"`; angles are in degrees; the coordinate system is '
        "left-handed (x right, y up, z into the picture). See the [scene files guide](../guide/scenes.md) for a "
        "whole file.",
        "",
    ]
    for table in scene_tables():
        lines += [f"## `{table.heading}` {{#{table.anchor}}}", "", table.intro, ""]
        if table.model.__doc__ and table.model.__doc__ is not model.Strict.__doc__:
            lines += [inspect.cleandoc(table.model.__doc__).replace("\n", " "), ""]
        lines += ["| key | type | default | allowed | description | example |", "| --- | --- | --- | --- | --- | --- |"]
        for name in table.model.model_fields:
            cells = [
                f"`{name}`",
                type_text(table.model, name),
                default_text(table.model, name),
                range_text(table.model, name),
                field_description(table.model, name, docs),
                example_text(table.model, name, examples),
            ]
            lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
        lines.append("")
    return "\n".join(lines)


# --set KEY paths, checked against the model as the overrides are (used by tests/test_docs.py)
def scene_key_exists(path: str) -> bool:
    """Whether a dotted --set key names a key of some scene (objects.2.radius, materials.glass.ior, ...)."""
    parts = path.split(".")
    return _key_in(model.Scene, parts)


def _key_in(cls: type[BaseModel], parts: list[str]) -> bool:
    if not parts:
        return True
    name, rest = parts[0], parts[1:]
    if name not in cls.model_fields:
        return False
    annotation, _ = _strip_optional(cls.model_fields[name].annotation)
    annotation = _unwrap(annotation)
    origin = typing.get_origin(annotation)
    if not rest:
        return True
    if origin is dict:  # materials.NAME...
        return any(_key_in(m, rest[1:]) for m in _models_in(annotation))
    if origin is list or (origin in (Union, types.UnionType) and name == "instances"):
        if not rest[0].isdigit():
            return False
        return any(_key_in(m, rest[1:]) for m in _models_in(annotation))
    if origin is tuple:  # camera.position.1: one component
        return len(rest) == 1 and rest[0].isdigit()
    models = list(_models_in(annotation))
    return any(_key_in(m, rest) for m in models)


# ---------------------------------------------------------------------------------------------
# The command line


# Typer builds its commands on click, or (typer >= 0.28) on a copy of click it carries: the classes are
# told apart by their kind, not by isinstance against one click.
def _is_option(param) -> bool:
    return param.param_type_name == "option"


def _is_argument(param) -> bool:
    return param.param_type_name == "argument"


class CommandLineError(ValueError):
    """A command line the command would refuse (click's usage error, whichever click Typer uses)."""


def cli_group():
    """The `raylume` command as the click group Typer builds of raylume.cli.app."""
    import typer.main

    from raylume.cli import app

    return typer.main.get_command(app)


def _option_row(param) -> str:
    flags = ", ".join(f"`{o}`" for o in [*param.opts, *param.secondary_opts])
    metavar = param.metavar or ""
    if _is_option(param) and not param.is_flag and not metavar:
        metavar = param.type.name.upper()
    default = ""
    if _is_option(param) and param.default not in (None, False, ()) and not param.is_flag:
        default = f"`{param.default}`"
    help_text = (getattr(param, "help", None) or "").replace("\n", " ").replace("|", "\\|")
    if getattr(param, "multiple", False):
        help_text += " (repeatable)" if "repeatable" not in help_text else ""
    value = f"`{metavar}`" if metavar else ""  # a | inside a code span does not split the table's cell
    return f"| {flags} | {value} | {default} | {help_text} |"


def cli_reference_markdown() -> str:
    group = cli_group()
    lines = [
        "# Command-line reference",
        "",
        "Generated from the `raylume` command itself (its click/Typer definition) when the site is built; "
        "`raylume COMMAND --help` prints the same.",
        "",
        f"`raylume [--version] COMMAND ...`: {group.help}",
        "",
        "| option | value | default | description |",
        "| --- | --- | --- | --- |",
        *(_option_row(p) for p in group.params if _is_option(p)),
        "",
    ]
    for name, command in group.commands.items():
        with command.make_context(f"raylume {name}", [], resilient_parsing=True) as ctx:
            usage = " ".join(command.collect_usage_pieces(ctx))
        lines += [f"## raylume {name}", "", f"```text\nraylume {name} {usage}\n```", "", command.help or "", ""]
        arguments = [p for p in command.params if _is_argument(p)]
        for argument in arguments:
            lines += [f"`{argument.metavar or argument.name.upper()}`: {getattr(argument, 'help', '') or ''}", ""]
        options = [p for p in command.params if _is_option(p)]
        if options:
            lines += ["| option | value | default | description |", "| --- | --- | --- | --- |"]
            lines += [_option_row(p) for p in options]
            lines.append("")
    return "\n".join(lines)


def parse_command_line(args: list[str]) -> None:
    """Parse `raylume ARGS` as the command would, without running it: a CommandLineError if the command
    would refuse it (an unknown command or flag, a value of the wrong type)."""
    group = cli_group()
    try:
        ctx = group.make_context("raylume", list(args))
        rest = [*getattr(ctx, "_protected_args", []), *getattr(ctx, "protected_args", []), *ctx.args]
        if rest:
            name, command, sub_args = group.resolve_command(ctx, rest)
            command.make_context(name, sub_args, parent=ctx)
    except Exception as error:  # click's exceptions, whichever click: told apart by name
        names = {klass.__name__ for klass in type(error).__mro__}
        if "Exit" in names:  # --version, --help; the CLI's own usage errors print a line and exit 2
            if getattr(error, "exit_code", 0) in (0, None):
                return
            raise CommandLineError(f"raylume {shlex.join(args)}: refused (exit status {error.exit_code})") from None
        if "UsageError" in names or "BadParameter" in names:
            raise CommandLineError(f"raylume {shlex.join(args)}: {error.format_message()}") from None
        raise


if __name__ == "__main__":
    page = sys.argv[1] if len(sys.argv) > 1 else "scene"
    print(scene_reference_markdown() if page == "scene" else cli_reference_markdown())
