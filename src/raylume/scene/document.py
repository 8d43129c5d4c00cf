"""A scene document (the parsed TOML or JSON, a dict) validated into the scene model."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

from pydantic import ValidationError

from ..errors import SceneError
from .model import Scene
from .nesting import too_deep
from .overrides import Overrides
from .validation_errors import format_validation_error, name_origins


def parse_document(text: str, path: Path) -> dict:
    """The document of a scene file's text: TOML, or JSON for a .json path."""
    kind = "TOML" if path.suffix.lower() == ".toml" else "JSON"
    try:
        document = tomllib.loads(text) if kind == "TOML" else json.loads(text, object_pairs_hook=_unique_keys)
    except _DuplicateKey as exc:
        raise SceneError(f"{path}: invalid JSON: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: invalid TOML: {exc}") from None
    except json.JSONDecodeError as exc:
        raise SceneError(f"{path}: invalid JSON: {exc.msg} (at line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:
        raise SceneError(f"{path}: invalid {kind}: tables or lists nested too deeply") from None
    except ValueError as exc:  # Python's limit on the digits of an integer it converts
        raise SceneError(f"{path}: invalid {kind}: {_number_problem(text, exc)}") from None
    if not isinstance(document, dict):
        raise SceneError(
            f"{path}: a JSON scene must be an object with render, camera, materials, lights and objects keys"
        )
    return document


class _DuplicateKey(ValueError):
    pass


def _unique_keys(pairs: list[tuple[str, object]]) -> dict:
    """A JSON object, refused where a key repeats (as TOML refuses it): json keeps the last one
    silently, so a material or key written twice lost the first without a word."""
    table = {}
    for key, value in pairs:
        if key in table:
            raise _DuplicateKey(f"the key {json.dumps(key)} appears twice in one object")
        table[key] = value
    return table


def _number_problem(text: str, exc: ValueError) -> str:
    """A number the parser refused, with its line where it can be found."""
    long = re.search(r"\d{4000,}", text)
    if long is None:
        return str(exc).split(";")[0]
    line = text.count("\n", 0, long.start()) + 1
    return f"line {line}: a number of {len(long.group())} digits"


def scene_from_dict(
    document: dict,
    source: str | Path = "<scene>",
    overrides: Overrides | None = None,
    origins: dict[str, str] | None = None,
) -> Scene:
    """Validate a scene document. `overrides` are only used to say which --set caused an error
    (apply them to the document with overrides.apply_overrides first, as load_scene does).
    `origins`: where another renderer's file made each table ({"objects[3]": 'scene.pbrt:12:
    Shape "plymesh"'}), named in the errors and kept by the scene for those found later."""
    try:
        try:
            scene = Scene.model_validate(document)
        except ValidationError as exc:
            message = format_validation_error(exc, source, Scene, overrides=overrides)
            raise SceneError(name_origins(message, origins) if origins else message) from None
    except RecursionError:
        raise too_deep(document, str(source)) from None
    return scene.with_origins(origins) if origins else scene
