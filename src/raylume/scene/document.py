"""A scene document (the parsed TOML or JSON, a dict) validated into the scene model."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

from pydantic import ValidationError

from ..errors import SceneError
from .model import Scene
from .overrides import Overrides
from .validation_errors import format_validation_error


def parse_document(text: str, path: Path) -> dict:
    """The document of a scene file's text: TOML, or JSON for a .json path."""
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
        raise SceneError(format_validation_error(exc, source, Scene, overrides=overrides)) from None
