"""raylume: ray casting, Whitted ray tracing and rasterization of declarative 3D scenes.

    import raylume
    image = raylume.render(raylume.builtin_scene("seed"), width=300, height=300)
    image.rgb          # float32 (H, W, 3), linear RGB
    image.aovs["depth"]
    image.save("seed.png")
"""

from .errors import RaylumeError, SceneError
from .image import Image
from .query import intersect
from .render import render
from .scene.builtin import builtin_names, builtin_scene
from .scene.load import load_scene, scene_from_dict
from .scene.model import Scene

__all__ = [
    "Image",
    "RaylumeError",
    "Scene",
    "SceneError",
    "builtin_names",
    "builtin_scene",
    "intersect",
    "load_scene",
    "render",
    "scene_from_dict",
]
__version__ = "0.1.0"
