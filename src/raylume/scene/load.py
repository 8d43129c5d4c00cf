"""Read TOML or JSON scene files into the validated model, with errors that name file and key."""

from __future__ import annotations

import difflib
import json
import tomllib
import types
import typing
from pathlib import Path

from pydantic import BaseModel, ValidationError

from ..errors import SceneError
from . import model as m
from .mesh import SUPPORTED_EXTENSIONS
from .model import Scene
from .overrides import Overrides, apply_overrides, assignments, touches

SCENE_SUFFIXES = (".toml", ".json")
# How alike an unknown key must be to a known one to be suggested (difflib's ratio): close
# enough for typos (radus, colour, focus_distanse), far from unrelated words.
SUGGESTION_CUTOFF = 0.8


def load_scene(path: str | Path, overrides: Overrides | None = None, source: str | None = None) -> Scene:
    """Load and validate a scene file; relative paths inside it are resolved against its folder.
    A glTF file (.gltf, .glb) is a scene by itself, with its camera and lights
    (scene/gltf_scene.py); so is a mesh file (.obj, .ply, .stl, .off): the mesh framed by the
    camera, lit by a default rig (scene/autoframe.py). `overrides` ("KEY=VALUE" texts as
    --set takes them, or a {dotted key: value} mapping) edit the parsed document before
    validation (see scene/overrides.py). `source` names the scene in validation errors
    (default: the path)."""
    path = Path(path)
    if path.suffix.lower() in (".gltf", ".glb"):
        from .gltf_scene import gltf_scene

        return gltf_scene(path, overrides, source=source)
    if path.suffix.lower() in SUPPORTED_EXTENSIONS:
        from .autoframe import mesh_scene

        return mesh_scene(path, overrides, source=source)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise SceneError(
            f"{path}: scene files end in .toml or .json, mesh files in {', '.join(SUPPORTED_EXTENSIONS)} "
            f"(got {path.suffix or 'no extension'!r})"
        )
    if path.is_dir():
        raise SceneError(f"{path}: is a folder, not a scene file")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc})") from None
    document = apply_overrides(parse_document(text, path), overrides)
    scene = scene_from_dict(document, source=source or path, overrides=overrides)
    return scene.with_base_dir(path.resolve().parent)


def parse_document(text: str, path: Path) -> dict:
    if path.suffix.lower() == ".toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SceneError(f"{path}: invalid TOML: {exc}") from None
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SceneError(f"{path}: invalid JSON: {exc.msg} (at line {exc.lineno}, column {exc.colno})") from None
    if not isinstance(document, dict):
        raise SceneError(
            f"{path}: a JSON scene must be an object with render, camera, materials, lights and objects keys"
        )
    return document


def scene_from_dict(document: dict, source: str | Path = "<scene>", overrides: Overrides | None = None) -> Scene:
    """Validate a scene document. `overrides` are only used to say which --set caused an error
    (apply them to the document with overrides.apply_overrides first, as load_scene does)."""
    try:
        return Scene.model_validate(document)
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, source, overrides)) from None


def _known_keys() -> list[str]:
    keys: set[str] = set()
    for obj in vars(m).values():
        if isinstance(obj, type) and issubclass(obj, BaseModel):
            keys.update(obj.model_fields)
    return sorted(keys)


def keys_at(loc: tuple) -> list[str] | None:
    """The keys the model allows in the table that holds the last step of `loc` (an error
    location such as ('objects', 0, '<sphere>', 'radus')), or None when the model cannot be
    followed there. Union tags ('<sphere>') choose the member of a tagged union."""
    node = Scene
    for part in loc[:-1]:
        node = _step(node, part)
        if node is None:
            return None
    node = _unwrap(node, None)
    if isinstance(node, type) and issubclass(node, BaseModel):
        return sorted(node.model_fields)
    return None


def _step(node, part):
    node = _unwrap(node, part if isinstance(part, str) and part.startswith("<") else None)
    if isinstance(part, str) and part.startswith("<"):
        return node
    origin = typing.get_origin(node)
    if isinstance(part, int) and origin in (list, tuple):
        return typing.get_args(node)[0]
    if origin is dict:
        return typing.get_args(node)[1]
    if isinstance(node, type) and issubclass(node, BaseModel) and part in node.model_fields:
        return node.model_fields[part].annotation
    return None


def _unwrap(node, tag: str | None):
    """Strip Annotated and Optional; in a tagged union, pick the member with `tag`."""
    while True:
        origin = typing.get_origin(node)
        if origin is typing.Annotated:
            node = typing.get_args(node)[0]
        elif origin in (typing.Union, types.UnionType):
            members = [a for a in typing.get_args(node) if a is not type(None)]
            chosen = [a for a in members if tag is not None and _tag_of(a) == tag]
            if chosen:
                node = chosen[0]
            elif len(members) == 1:
                node = members[0]
            else:
                models = [
                    a for a in members if isinstance(_unwrap(a, None), type) and issubclass(_unwrap(a, None), BaseModel)
                ]
                return models[0] if len(models) == 1 else node
        else:
            return node


def _tag_of(annotated) -> str | None:
    for meta in getattr(annotated, "__metadata__", ()):
        tag = getattr(meta, "tag", None)
        if isinstance(tag, str):
            return tag
    return None


def suggest(bad: str, loc: tuple) -> str | None:
    """A close match for an unknown key, from the keys valid where it was found."""
    candidates = keys_at(loc)
    close = difflib.get_close_matches(
        bad, candidates if candidates is not None else _known_keys(), n=1, cutoff=SUGGESTION_CUTOFF
    )
    return close[0] if close else None


def key_path(loc: tuple) -> str:
    """('objects', 2, '<sphere>', 'radius') -> 'objects[2].radius' (union tags dropped)."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif isinstance(part, str) and part.startswith("<") and part.endswith(">"):
            continue
        else:
            out += f".{part}" if out else str(part)
    return out


def describe_error(error: dict) -> str:
    """One pydantic error in words, with the offending value unless the message names it."""
    kind, msg = error["type"], error["msg"]
    if kind == "extra_forbidden":
        bad = str(error["loc"][-1])
        close = suggest(bad, tuple(error["loc"]))
        hint = f" (did you mean {close!r}?)" if close else ""
        return f"unknown key {bad!r}{hint}"
    if kind == "missing":
        return "this key is required"
    msg = msg.removeprefix("Value error, ")
    value = error.get("input")
    if kind == "unknown_type" and isinstance(value, dict):
        value = value.get("type")
    elif kind in ("unknown_type", "material_ref") or isinstance(value, (dict, list)):
        return msg
    return msg if _names_value(msg, value) else f"{msg} (got {value!r})"


def _names_value(msg: str, value) -> bool:
    """Whether a validator's message already shows the value ("..., got -1", "'#12345' must ...")."""
    return " got " in f" {msg}" or (isinstance(value, str) and repr(value) in msg)


def format_validation_error(exc: ValidationError, source, overrides: Overrides | None = None) -> str:
    errors = exc.errors()
    set_by = assignments(overrides)
    lines = []
    for error in errors[:5]:
        path = key_path(error["loc"])
        if error["type"] == "unknown_type":
            path = f"{path}.type" if path else "type"
        where = f"{path}: " if path else ""
        loc = [str(p) for p in error["loc"] if not (isinstance(p, str) and p.startswith("<"))]
        culprits = [text for keys, _, text in set_by if touches(keys, loc)]
        cause = f" (set by --set {culprits[-1]})" if culprits else ""
        lines.append(f"{where}{describe_error(error)}{cause}")
    more = f" (and {len(errors) - 5} more problems)" if len(errors) > 5 else ""
    return f"{source}: " + "; ".join(lines) + more
