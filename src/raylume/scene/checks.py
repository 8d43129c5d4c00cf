"""Scenes that are valid but will not render what their author expects: warnings, not errors.

`warn_about(scene, mode)` issues each as a `SceneWarning` (a UserWarning): Python code sees
them through the warnings module, and the command line prints each as one line on stderr.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from .model import Scene

_PACKAGE = str(Path(__file__).resolve().parents[1])  # the raylume package's folder

LIT_MODES = ("trace", "raster")  # the modes that shade with the scene's lights


class SceneWarning(UserWarning):
    """A scene that renders, but probably not as intended (no lights, no objects)."""


def scene_warnings(scene: Scene, mode: str) -> list[str]:
    """What looks wrong with rendering `scene` in `mode`, one sentence each."""
    found = []
    if not scene.objects:
        seen = "the environment" if scene.environment is not None else "the background"
        found.append(f"the scene has no objects: nothing to render, the image is {seen}")
    elif mode in LIT_MODES and not scene.lights:
        found.append(
            f"the scene has no lights, so {mode} mode renders every object black; add [[lights]] "
            '(e.g. type = "ambient") or use --mode cast to see the objects\' colours'
        )
    if mode == "raster" and any(getattr(scene.material_of(obj), "alpha_map", None) for obj in scene.objects):
        found.append(
            "raster mode draws alpha-mapped surfaces whole (their holes are cut in cast, trace and path modes only)"
        )
    if mode != "path" and (scene.media or scene.render.medium is not None):
        found.append(
            f"participating media render in path mode only: {mode} mode shows the media's boundaries "
            "(their materials) and nothing between them; use --mode path"
        )
    return found


def warn_about(scene: Scene, mode: str) -> None:
    """Issue scene_warnings as SceneWarnings, attributed to the first caller outside raylume
    (the user's render call, whether through raylume.render or a Session)."""
    for message in scene_warnings(scene, mode):
        warn(message)


def warn(message: str) -> None:
    """One SceneWarning (also those found while compiling, which need the geometry), attributed
    to the first caller outside raylume."""
    warnings.warn(message, SceneWarning, stacklevel=_outside_level())


def _outside_level() -> int:
    """The warnings.warn stacklevel, as seen from warn, of the nearest frame outside the package."""
    frame, level = sys._getframe(2), 2  # level 1 is warn, 2 its caller
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    return level
