"""raylume: ray casting, Whitted ray tracing, path tracing and rasterization of declarative 3D scenes.

import raylume
image = raylume.render(raylume.builtin_scene("seed"), width=300, height=300)
image.rgb          # float32 (H, W, 3), linear RGB
image.aovs["depth"]
image.save("render.png")

session = raylume.Session(raylume.builtin_scene("seed"))   # compile once ...
a = session.render(width=300, height=300)                   # ... render many times
b = session.render(camera={"position": [0, 1, -1]}, mode="cast")

url = raylume.view(raylume.builtin_scene("seed"))           # a live view in the browser

scene = raylume.load("scene.xml", defines={"spp": "64"})     # a Mitsuba 3 scene, its $spp set
raylume.save_scene(scene, "scene.toml")                     # ... as raylume's own TOML
"""

# The public names are imported on first use (PEP 562), so that `import raylume` and the
# command line's --help do not load Numba, pydantic and the kernels (1.5 s) before they are needed.
import importlib
from typing import TYPE_CHECKING

from ._version import __version__ as __version__
from .errors import RaylumeError, SceneError
from .render import render  # at once: the function shadows its module (render.py stays light)

_HOMES = {
    "Camera": ".scene.model",
    "Film": ".kernels.film.film",
    "Image": ".image",
    "Scene": ".scene.model",
    "SceneWarning": ".scene.checks",
    "Session": ".session",
    "builtin_names": ".scene.builtin",
    "builtin_scene": ".scene.builtin",
    "camera_rays": ".query",
    "intersect": ".query",
    "load": ".scene.load",
    "load_scene": ".scene.load",
    "occluded": ".query",
    "save_scene": ".save",
    "scene_from_dict": ".scene.document",
    "view": ".viewer",
}


# Hidden from type checkers, which then read the names from the TYPE_CHECKING imports below and
# refuse a misspelt one (raylume.rendr) instead of typing it as whatever __getattr__ returns.
if not TYPE_CHECKING:

    def __getattr__(name: str):
        home = _HOMES.get(name)
        if home is not None:
            value = getattr(importlib.import_module(home, __name__), name)
        else:
            try:  # a submodule (raylume.compile, raylume.cluster, ...) not imported yet
                value = importlib.import_module(f".{name}", __name__)
            except ModuleNotFoundError as error:
                if error.name != f"{__name__}.{name}":
                    raise
                raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
        globals()[name] = value
        return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})


if TYPE_CHECKING:
    from .image import Image
    from .kernels.film.film import Film
    from .query import camera_rays, intersect, occluded
    from .save import save_scene
    from .scene.builtin import builtin_names, builtin_scene
    from .scene.checks import SceneWarning
    from .scene.document import scene_from_dict
    from .scene.load import load, load_scene
    from .scene.model import Camera, Scene
    from .session import Session
    from .viewer import view

__all__ = [
    "Camera",
    "Film",
    "Image",
    "RaylumeError",
    "Scene",
    "SceneError",
    "SceneWarning",
    "Session",
    "builtin_names",
    "builtin_scene",
    "camera_rays",
    "intersect",
    "load",
    "load_scene",
    "occluded",
    "render",
    "save_scene",
    "scene_from_dict",
    "view",
]
