"""Read a scene file into the validated model: TOML or JSON (scene/document.py), a pbrt-v4 file
(scene/pbrt_scene.py), or a glTF or mesh file as a scene by itself (scene/gltf_scene.py,
scene/autoframe.py)."""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError
from .autoframe import mesh_scene
from .document import parse_document, scene_from_dict
from .gltf_scene import gltf_scene
from .mesh import SUPPORTED_EXTENSIONS
from .model import Scene
from .overrides import Overrides, apply_overrides
from .pbrt_scene import pbrt_scene

__all__ = ["SCENE_SUFFIXES", "load_scene", "parse_document", "scene_from_dict"]

SCENE_SUFFIXES = (".toml", ".json", ".pbrt")


def load_scene(path: str | Path, overrides: Overrides | None = None, source: str | None = None) -> Scene:
    """Load and validate a scene file; relative paths inside it are resolved against its folder.
    A pbrt-v4 file (.pbrt) is read as pbrt would render it (scene/pbrt_scene.py).
    A glTF file (.gltf, .glb) is a scene by itself, with its camera and lights
    (scene/gltf_scene.py); so is a mesh file (.obj, .ply, .stl, .off): the mesh framed by the
    camera, lit by a default rig (scene/autoframe.py). `overrides` ("KEY=VALUE" texts as
    --set takes them, or a {dotted key: value} mapping) edit the parsed document before
    validation (see scene/overrides.py). `source` names the scene in validation errors
    (default: the path)."""
    path = Path(path)
    if path.suffix.lower() in (".gltf", ".glb"):
        return gltf_scene(path, overrides, source=source)
    if path.suffix.lower() in SUPPORTED_EXTENSIONS:
        return mesh_scene(path, overrides, source=source)
    if path.suffix.lower() == ".pbrt":
        return pbrt_scene(path, overrides, source=source)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise SceneError(
            f"{path}: scene files end in .toml, .json or .pbrt, mesh files in {', '.join(SUPPORTED_EXTENSIONS)} "
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
