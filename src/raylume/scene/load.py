"""Read a scene file into the validated model: TOML or JSON (scene/document.py), a pbrt-v4 file
(scene/pbrt_scene.py), a Mitsuba 3 XML scene (scene/mitsuba_scene.py), or a glTF or mesh file as
a scene by itself (scene/gltf_scene.py, scene/autoframe.py). Other renderers' scenes become a
scene document first, so validation and `--set` overrides are the same for every kind of file."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import SceneError
from .autoframe import mesh_scene
from .document import parse_document, scene_from_dict
from .files import read_scene_text
from .gltf_scene import gltf_scene
from .mesh import SUPPORTED_EXTENSIONS
from .model import Scene
from .overrides import Overrides, apply_overrides
from .pbrt_scene import pbrt_scene

__all__ = [
    "DEFINE_SUFFIXES",
    "FOREIGN_SUFFIXES",
    "SCENE_SUFFIXES",
    "load",
    "load_scene",
    "parse_document",
    "scene_from_dict",
]

SCENE_SUFFIXES = (".toml", ".json", ".pbrt")
# Other renderers' scene files read into a scene document by foreign_document (.pbrt: pbrt_scene)
FOREIGN_SUFFIXES = (".xml",)
DEFINE_SUFFIXES = (".xml",)  # the files whose $parameters --define sets (Mitsuba's)
DEFINES_REFUSED = "--define (defines= in Python) sets parameters of a Mitsuba scene (.xml), and this is not one"


def foreign_document(path: Path, defines: dict[str, str] | None) -> tuple[dict, dict[str, str]]:
    """The scene document of another renderer's scene file, and where its tables came from
    ({key path: "file:line element"}, for messages about values the model refuses)."""
    suffix = path.suffix.lower()
    if suffix == ".xml":
        from .mitsuba_scene import mitsuba_document

        return mitsuba_document(path, defines)
    raise SceneError(f"{path}: not a scene file of another renderer ({', '.join(FOREIGN_SUFFIXES)})")


def _define_texts(defines: dict) -> dict[str, str]:
    """Mitsuba's $parameters as the texts -D gives; numbers as Mitsuba's Python API takes them
    (defines={"spp": 4}: a join of the values had failed with "expected str instance")."""
    texts = {}
    for name, value in defines.items():
        if isinstance(value, bool) or not isinstance(value, (str, int, float)):
            raise TypeError(f"defines[{name!r}]: a string or a number is needed, got {value!r}")
        texts[str(name)] = value if isinstance(value, str) else repr(value)
    return texts


def load_scene(
    path: str | os.PathLike,
    overrides: Overrides | None = None,
    source: str | None = None,
    defines: dict[str, str] | None = None,
    camera: str | None = None,
) -> Scene:
    """Load and validate a scene file; relative paths inside it are resolved against its folder.
    A pbrt-v4 file (.pbrt) is read as pbrt would render it (scene/pbrt_scene.py).
    A glTF file (.gltf, .glb) is a scene by itself, with its camera and lights
    (scene/gltf_scene.py); so is a mesh file (.obj, .ply, .stl, .off): the mesh framed by the
    camera, lit by a default rig (scene/autoframe.py). `overrides` ("KEY=VALUE" texts as
    --set takes them, or a {dotted key: value} mapping) edit the parsed document before
    validation (see scene/overrides.py). `source` names the scene in validation errors
    (default: the path). A Mitsuba scene (.xml) takes `defines`, {NAME: VALUE} for its $NAME
    parameters (Mitsuba's -D); other files refuse them. `camera` names a glTF file's camera (as
    the command line's --camera; the first one by default); other files refuse it."""
    path = Path(path)
    if defines and path.suffix.lower() not in DEFINE_SUFFIXES:
        raise SceneError(f"{path}: {DEFINES_REFUSED}")
    if camera is not None and path.suffix.lower() not in (".gltf", ".glb"):
        raise SceneError(f"{path}: a camera is chosen by name (--camera, camera=) in glTF files alone")
    if defines:
        defines = _define_texts(defines)
    if path.suffix.lower() in FOREIGN_SUFFIXES:
        document, origins = foreign_document(path, defines)
        document = apply_overrides(document, overrides, path)
        scene = scene_from_dict(document, source=source or path, overrides=overrides, origins=origins)
        return scene.with_base_dir(path.resolve().parent)
    if path.suffix.lower() in (".gltf", ".glb"):
        return gltf_scene(path, overrides, source=source, camera=camera)
    if path.suffix.lower() in SUPPORTED_EXTENSIONS:
        return mesh_scene(path, overrides, source=source)
    if path.suffix.lower() == ".pbrt":
        return pbrt_scene(path, overrides, source=source)
    if path.suffix.lower() not in SCENE_SUFFIXES:
        raise SceneError(
            f"{path}: scene files end in .toml, .json or .pbrt (or .xml: Mitsuba 3), mesh files in "
            f"{', '.join(SUPPORTED_EXTENSIONS)} (got {path.suffix or 'no extension'!r})"
        )
    document = apply_overrides(parse_document(read_scene_text(path), path), overrides, path)
    scene = scene_from_dict(document, source=source or path, overrides=overrides)
    return scene.with_base_dir(path.resolve().parent)


load = load_scene  # raylume.load(path), as DESIGN.md section 7 names it
