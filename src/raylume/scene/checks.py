"""Scenes that are valid but will not render what their author expects: warnings, not errors.

`warn_about(scene, mode)` issues each as a `SceneWarning` (a UserWarning): Python code sees
them through the warnings module, and the command line prints each as one line on stderr.
"""

from __future__ import annotations

import warnings

from .model import Scene

LIT_MODES = ("trace", "raster")  # the modes that shade with the scene's lights


class SceneWarning(UserWarning):
    """A scene that renders, but probably not as intended (no lights, no objects)."""


def scene_warnings(scene: Scene, mode: str) -> list[str]:
    """What looks wrong with rendering `scene` in `mode`, one sentence each."""
    found = []
    if not scene.objects:
        found.append("the scene has no objects: nothing to render, the image is the background")
    elif mode in LIT_MODES and not scene.lights:
        found.append(
            f"the scene has no lights, so {mode} mode renders every object black; add [[lights]] "
            '(e.g. type = "ambient") or use --mode cast to see the objects\' colours'
        )
    return found


def warn_about(scene: Scene, mode: str, stacklevel: int = 3) -> None:
    """Issue scene_warnings as SceneWarnings (by default pointing at the caller's caller)."""
    for message in scene_warnings(scene, mode):
        warnings.warn(message, SceneWarning, stacklevel=stacklevel)
