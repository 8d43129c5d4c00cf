"""Built-in scenes, shipped as TOML files inside the package (raylume/scenes/*.toml)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import SceneError
from .load import load_scene
from .model import Scene
from .overrides import Overrides

DEFAULT_SCENE = "seed"


def builtin_names() -> list[str]:
    """The names of the built-in scenes (`raylume.builtin_scene(name)`, `raylume render NAME`)."""
    folder = resources.files("raylume") / "scenes"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_path(name: str) -> Path:
    if name not in builtin_names():
        raise SceneError(f"no built-in scene named {name!r}; built-ins: {', '.join(builtin_names())}")
    return Path(str(resources.files("raylume") / "scenes" / f"{name}.toml"))


def builtin_scene(name: str = DEFAULT_SCENE, overrides: Overrides | None = None) -> Scene:
    """A built-in scene; `overrides` edit it before validation, as `--set` does."""
    return load_scene(builtin_path(name), overrides=overrides, source=f"built-in scene {name!r}")


def builtin_description(name: str) -> str:
    """The scene file's first block of comment lines, joined into one paragraph."""
    lines = []
    for line in builtin_path(name).read_text().splitlines():
        if line.startswith("#"):
            lines.append(line.lstrip("#").strip())
        elif lines:
            break
    return " ".join(" ".join(lines).split())
