"""Read TOML or JSON scene files into the validated model, with errors that name file and key."""

from __future__ import annotations

import difflib
import json
import tomllib
from pathlib import Path

from pydantic import BaseModel, ValidationError

from ..errors import SceneError
from . import model as m
from .model import Scene

SCENE_SUFFIXES = (".toml", ".json")


def load_scene(path: str | Path) -> Scene:
    """Load and validate a scene file; relative paths inside it are resolved against its folder."""
    path = Path(path)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise SceneError(f"{path}: scene files must end in .toml or .json (got {path.suffix or 'no extension'!r})")
    if path.is_dir():
        raise SceneError(f"{path}: is a folder, not a scene file")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc})") from None
    document = parse_document(text, path)
    return scene_from_dict(document, source=path).with_base_dir(path.resolve().parent)


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
        raise SceneError(f"{path}: a JSON scene must be an object with render, camera, materials, lights and objects keys")
    return document


def scene_from_dict(document: dict, source: str | Path = "<scene>") -> Scene:
    try:
        return Scene.model_validate(document)
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, source)) from None


def _known_keys() -> list[str]:
    keys: set[str] = set()
    for obj in vars(m).values():
        if isinstance(obj, type) and issubclass(obj, BaseModel):
            keys.update(obj.model_fields)
    return sorted(keys)


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


def _describe(error: dict) -> str:
    kind, msg = error["type"], error["msg"]
    if kind == "extra_forbidden":
        bad = str(error["loc"][-1])
        close = difflib.get_close_matches(bad, _known_keys(), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"unknown key {bad!r}{hint}"
    if kind == "missing":
        return "this key is required"
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    value = error.get("input")
    if kind not in ("unknown_type", "material_ref") and not isinstance(value, (dict, list)):
        return f"{msg} (got {value!r})"
    if kind == "unknown_type" and isinstance(value, dict):
        return f"{msg} (got {value.get('type')!r})"
    return msg


def format_validation_error(exc: ValidationError, source) -> str:
    errors = exc.errors()
    lines = []
    for error in errors[:5]:
        path = key_path(error["loc"])
        if error["type"] == "unknown_type":
            path = f"{path}.type" if path else "type"
        where = f"{path}: " if path else ""
        lines.append(f"{where}{_describe(error)}")
    more = f" (and {len(errors) - 5} more problems)" if len(errors) > 5 else ""
    return f"{source}: " + "; ".join(lines) + more
