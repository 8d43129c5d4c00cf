"""A scene as users name it (a Scene, a scene file, a glTF or mesh file, a built-in name) made a
Scene: one rule for the command line's SCENE argument and the Python API's `scene` arguments."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import SceneError
from .autoframe import MESH_SUFFIXES, is_mesh_file, mesh_scene
from .builtin import DEFAULT_SCENE, builtin_names, builtin_scene
from .gltf import is_gltf_file
from .gltf_scene import gltf_scene
from .load import DEFINE_SUFFIXES, DEFINES_REFUSED, FOREIGN_SUFFIXES, SCENE_SUFFIXES, load_scene
from .model import Scene

SceneLike = Scene | str | os.PathLike | None


def open_scene(
    scene: SceneLike,
    overrides: list[str] | None = None,
    *,
    width: int | None = None,
    height: int | None = None,
    camera: str | None = None,
    defines: dict[str, str] | None = None,
) -> tuple[Scene, str]:
    """(the Scene, its label for messages) for `scene`:

    * a Scene: itself (`overrides` do not apply to it);
    * None: the built-in `seed` scene;
    * a path or a name: a glTF file (its camera, or the one `camera` names), a mesh file
      (framed and lit for a width x height image), a scene file (.toml, .json, .pbrt, or a
      Mitsuba .xml, its $parameters set by `defines`), or else a built-in scene's name.

    `overrides` are `--set` style KEY=VALUE strings. A name that is none of these is a
    SceneError that lists the built-ins."""
    if isinstance(scene, Scene):
        if defines or camera is not None:  # (they were ignored)
            given = "defines" if defines else "camera"
            raise SceneError(f"{given}= applies to a file as it is read; this scene is a raylume.Scene already")
        return scene, "<scene>"
    if scene is not None and not isinstance(scene, str | os.PathLike):
        raise TypeError(
            f"scene: expected a raylume.Scene, a path to a scene, glTF or mesh file, or a built-in scene's name; "
            f"got {type(scene).__name__}"
        )
    name = DEFAULT_SCENE if scene is None else os.fspath(scene)
    if defines and Path(name).suffix.lower() not in DEFINE_SUFFIXES:
        raise SceneError(f"{name}: {DEFINES_REFUSED}")
    if is_gltf_file(name):
        return gltf_scene(name, overrides, camera=camera, width=width, height=height), name
    if is_mesh_file(name):
        return mesh_scene(name, overrides, width=width, height=height), name
    if Path(name).suffix.lower() in (*SCENE_SUFFIXES, *FOREIGN_SUFFIXES) or os.sep in name or Path(name).exists():
        return load_scene(name, overrides=overrides, defines=defines), name
    if name in builtin_names():
        return builtin_scene(name, overrides=overrides), f"built-in scene {name!r}"
    raise SceneError(
        f"{name}: not a scene file (.toml, .json, .pbrt or .xml), a mesh file ({', '.join(MESH_SUFFIXES)}) nor a "
        f"built-in scene; built-ins: {', '.join(builtin_names())}"
    )
