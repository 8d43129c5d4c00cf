"""raylume: ray casting, Whitted ray tracing and rasterization of declarative 3D scenes.

import raylume
image = raylume.render(raylume.builtin_scene("seed"), width=300, height=300)
image.rgb          # float32 (H, W, 3), linear RGB
image.aovs["depth"]
image.save("seed.png")

session = raylume.Session(raylume.builtin_scene("seed"))   # compile once ...
a = session.render(width=300, height=300)                   # ... render many times
b = session.render(camera={"position": [0, 1, -1]}, mode="cast")

url = raylume.view(raylume.builtin_scene("seed"))           # a live view in the browser
"""

from .errors import RaylumeError, SceneError
from .image import Image
from .kernels.film import Film
from .query import intersect
from .render import render
from .scene.builtin import builtin_names, builtin_scene
from .scene.checks import SceneWarning
from .scene.load import load_scene, scene_from_dict
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
    "intersect",
    "load_scene",
    "render",
    "scene_from_dict",
    "view",
]
__version__ = "0.1.0"
