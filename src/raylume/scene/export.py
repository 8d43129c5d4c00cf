"""A Scene as the text of a raylume scene file (`raylume convert`; raylume/save.py writes it):
the validated model dumped as TOML (or JSON), every number as the float it is (TOML and JSON
writers print the shortest repr that reads back exactly), file paths rewritten relative to the
new file's folder so meshes, textures and environment images stay where they are. Loading the
file gives an equal Scene, which renders the same image bit for bit.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from ..errors import OutputError
from .model import Scene

SUFFIXES = (".toml", ".json")
# tomli_w writes every array one item a line; vectors and colours read better on one
_NUMBER_ARRAY = re.compile(r"\[\n((?:[ \t]+[-+0-9.eE]+,\n)+)[ \t]*\]")


def _inline_number_arrays(text: str) -> str:
    return _NUMBER_ARRAY.sub(lambda m: "[" + ", ".join(v.strip(" \t,") for v in m.group(1).splitlines()) + "]", text)


def scene_document(scene: Scene, folder: str | Path) -> dict:
    """The scene as a document for a file in `folder`: what differs from the defaults, paths
    relative to `folder`."""
    document = scene.model_dump(mode="json", exclude_defaults=True, exclude_none=True)
    folder = Path(folder).resolve()

    def moved(name: str) -> str:
        path = Path(name)
        if path.is_absolute():
            return name
        return Path(os.path.relpath((scene.base_dir / path).resolve(), folder)).as_posix()

    def textures(material) -> None:
        for key in ("texture", "normal_map", "bump_map", "alpha_map"):
            if isinstance(material, dict) and isinstance(material.get(key), dict):
                texture = material[key]
                if "file" in texture:
                    texture["file"] = moved(texture["file"])

    for material in document.get("materials", {}).values():
        textures(material)
    for obj in document.get("objects", []):
        if "file" in obj:
            obj["file"] = moved(obj["file"])
        if isinstance(obj.get("instances"), str):
            obj["instances"] = moved(obj["instances"])
        textures(obj.get("material"))
    for medium in document.get("media", {}).values():
        if isinstance(medium.get("density"), str):
            medium["density"] = moved(medium["density"])
    environment = document.get("environment")
    if isinstance(environment, dict) and "file" in environment:
        environment["file"] = moved(environment["file"])
    return _type_first(document)


def _type_first(value):
    """Tables with their `type` key first, as people write them."""
    if isinstance(value, dict):
        items = sorted(value.items(), key=lambda item: item[0] != "type")
        return {key: _type_first(item) for key, item in items}
    if isinstance(value, list):
        return [_type_first(item) for item in value]
    return value


def scene_text(scene: Scene, path: str | Path) -> str:
    """The text of a .toml (or .json) scene file at `path` holding `scene`."""
    import tomli_w

    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise OutputError(f"{path}: a scene file ends in .toml or .json")
    document = scene_document(scene, path.parent if str(path.parent) else ".")
    if path.suffix.lower() == ".toml":
        return _inline_number_arrays(tomli_w.dumps(document))
    return json.dumps(document, indent=2) + "\n"
