"""A mesh file as a whole scene (`raylume render model.obj`): framed, facing the camera, lit by a
default rig of key, fill and ambient light, in a neutral grey.

Convention: a mesh file is taken as right-handed, +y up, its front towards +z (glTF's convention
and that of most OBJ files). raylume's frame is left-handed, so the mesh is mirrored across x
(`handedness = "right"`) and turned 180 degrees about y: its front then faces -z, towards a
camera that looks along +z as raylume's default camera does. The image is what a glTF viewer
shows from the front: +y up, the model's +x on the right, its front towards the viewer. (In
world coordinates the model's z is negated: `--set` keys such as camera.position use them.)

The camera looks at the centre of the mesh's bounding box from -z, far enough for the bounding
sphere to fit the vertical field of view (the horizontal one for portrait images) with a margin.
Everything is a plain scene document, so `--set` edits it like a file: a camera position or
look_at that is set is kept (the other one follows), and the fov and size set are framed for.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .document import scene_from_dict
from .mesh import SUPPORTED_EXTENSIONS, MeshError
from .model import Mesh, Scene, beyond_float32
from .overrides import Overrides, apply_overrides
from .placement import bounds, load_mesh_object

MESH_SUFFIXES = tuple(SUPPORTED_EXTENSIONS)
MARGIN = 1.1  # the bounding sphere's radius, relative to the half-height the view leaves it
VIEW = (0.0, 0.0, 1.0)  # the camera's viewing direction
BACKGROUND = [0.2, 0.2, 0.2]  # a neutral dark grey, as model viewers use
GREY = {"color": [0.8, 0.8, 0.8], "specular": 30}

# Directions towards the lights, in the camera's frame (x right, y up, z away from the viewer):
# the key from the upper left in front, a weaker fill from the right, and ambient light so that
# no side is black. The sum stays under 1 where the key and fill both reach: no clipping.
RIG = [
    {"type": "ambient", "intensity": 0.15},
    {"type": "directional", "direction": [-0.6, 0.8, -1.0], "intensity": 0.6},
    {"type": "directional", "direction": [1.0, 0.2, -0.6], "intensity": 0.25},
]


def is_mesh_file(path: str | Path) -> bool:
    return Path(path).suffix.lower() in MESH_SUFFIXES


def square_sides(width: int | None, height: int | None) -> dict:
    """The image size of a scene whose default is square (a mesh file's, a glTF camera's without
    an aspect ratio) where a flag gives one side: the other side the same. Nothing otherwise."""
    side = width or height
    return {"width": side, "height": side} if side and not (width and height) else {}


def mesh_document(path: str | Path, width: int | None = None, height: int | None = None) -> dict:
    """The scene document of a mesh file, before framing: the camera's position and look_at are
    left out for `frame` to fill in. `width`/`height`: the flags' sides (see square_sides)."""
    return {
        "render": {"background": BACKGROUND, **square_sides(width, height)},
        "materials": {"grey": GREY},
        "lights": [dict(light) for light in RIG],
        "objects": [
            {
                "type": "mesh",
                "file": Path(path).name,
                "material": "grey",
                "handedness": "right",
                "transform": {"rotate": [0, 180, 0]},
            }
        ],
    }


def mesh_scene(
    path: str | Path,
    overrides: Overrides | None = None,
    source: str | None = None,
    width: int | None = None,
    height: int | None = None,
) -> Scene:
    """The scene of a mesh file, framed. `overrides` edit the document as `--set` does;
    `width`/`height` (command-line flags applied later) are framed for too."""
    path = Path(path)
    source = source or str(path)
    document = apply_overrides(mesh_document(path, width, height), overrides)
    scene = scene_from_dict(document, source=source, overrides=overrides).with_base_dir(path.resolve().parent)
    camera = document.get("camera", {})
    given = {key for key in ("position", "look_at") if isinstance(camera, dict) and key in camera}
    if given == {"position", "look_at"} or not scene.objects or not isinstance(scene.objects[0], Mesh):
        return scene
    try:
        # kept for the compiler, which then reads the file no second time
        lo, hi = bounds(load_mesh_object(scene.objects[0], scene.base_dir, keep=True))
    except MeshError as exc:
        raise SceneError(str(exc)) from None
    # (the camera framing it would be refused, for a key the file does not have)
    if (problem := beyond_float32(float(max(np.abs(lo).max(), np.abs(hi).max())))) is not None:
        raise SceneError(f"{source}: {problem}")
    W = width or scene.render.width
    H = height or scene.render.height
    return scene.with_camera(frame(lo, hi, scene.camera, W / H, given))


def frame(lo, hi, camera, aspect: float, given: set[str] = frozenset()) -> dict:
    """Camera position and look_at showing the box lo..hi whole: looking at its centre along
    VIEW from the distance at which its bounding sphere fits the field of view. A key in
    `given` keeps the camera's value, and the other one follows from it."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
    half = math.radians(camera.fov) / 2
    if aspect < 1:  # portrait: the horizontal field of view is the narrower one
        half = math.atan(math.tan(half) * aspect)
    distance = MARGIN * radius / math.sin(half)
    if "position" in given:
        return {"look_at": centre.tolist()}
    look_at = np.asarray(camera.look_at) if "look_at" in given else centre
    return {"position": (look_at - distance * np.asarray(VIEW)).tolist(), "look_at": look_at.tolist()}
