"""raylume.save_scene: a Scene written as a raylume scene file (the text: scene/export.py),
atomically, as every output."""

from __future__ import annotations

from pathlib import Path

from .image import write_atomic
from .scene.export import scene_text
from .scene.model import Scene


def save_scene(scene: Scene | str | Path, path: str | Path) -> Path:
    """Write `scene` as a .toml (or .json) scene file at `path`; returns the path. Meshes,
    textures and images stay where they are, named relative to the new file's folder; loading
    the file gives a scene that renders bit for bit the same image. `scene` may be named as
    `raylume.render` takes it (a file, a built-in scene's name)."""
    if not isinstance(scene, Scene):
        from .scene.open import open_scene

        scene, _ = open_scene(scene)
    path = Path(path)
    data = scene_text(scene, path).encode()
    write_atomic(path, lambda fh: fh.write(data))
    return path
