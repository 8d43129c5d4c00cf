"""Built-in scenes, shipped as TOML files inside the package (raylume/scenes/*.toml)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import SceneError
from .load import load_scene
from .model import Scene

DEFAULT_SCENE = "seed"


def builtin_names() -> list[str]:
    folder = resources.files("raylume") / "scenes"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_path(name: str) -> Path:
    if name not in builtin_names():
        raise SceneError(f"no built-in scene named {name!r}; built-ins: {', '.join(builtin_names())}")
    return Path(str(resources.files("raylume") / "scenes" / f"{name}.toml"))


def builtin_scene(name: str = DEFAULT_SCENE) -> Scene:
    return load_scene(builtin_path(name))


def builtin_description(name: str) -> str:
    """The first comment line of the scene file."""
    for line in builtin_path(name).read_text().splitlines():
        if line.startswith("#"):
            return line.lstrip("# ").strip()
    return ""
