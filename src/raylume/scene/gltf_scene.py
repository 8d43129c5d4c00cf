"""A glTF file as a scene by itself (`raylume render model.glb`): the file's meshes as one
`gltf` object, its first perspective camera (or the one named by `--camera`), its
KHR_lights_punctual lights. A file without a camera is framed as a mesh file is
(scene/autoframe.py: from the model's front, glTF's +z, looking towards -z); a file without
lights is lit by a uniform environment of radiance 1 (an ambient light: path mode's uniform
environment, trace mode's ambient term).

The scene renders in path mode with 16 samples per pixel and sRGB encoding by default, as
glTF's materials and lights are physically based (in trace mode point lights do not fall off
with distance, so glTF's intensities would overexpose). Everything is a plain scene document,
so `--set` and the command line's flags edit it like a file.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SceneError
from .autoframe import frame, square_sides
from .document import scene_from_dict
from .gltf import GltfCamera, GltfError, GltfScene, read_gltf
from .model import Scene
from .overrides import Overrides, apply_overrides

RENDER = {"mode": "path", "spp": 16, "encoding": "srgb"}
SIDE = 600  # the image's width; its height follows the camera's aspect ratio when the file gives one
NO_LIGHTS = [{"type": "ambient", "intensity": 1.0}]


def choose_camera(imported: GltfScene, name: str | None) -> GltfCamera | None:
    """The camera named `name` (a camera's or its node's name), else the file's first."""
    if name is None:
        return imported.cameras[0] if imported.cameras else None
    for camera in imported.cameras:
        if camera.name == name:
            return camera
    for camera in imported.cameras:  # a node's name, where its camera has a name of its own
        if camera.node_name == name:
            return camera
    known = ", ".join(repr(c.name) for c in imported.cameras) or "it has none"
    raise SceneError(f"{imported.path}: --camera {name!r}: no perspective camera of that name ({known})")


def gltf_document(
    path: str | Path,
    imported: GltfScene,
    camera: GltfCamera | None,
    width: int | None = None,
    height: int | None = None,
) -> dict:
    """The scene document of a glTF file, before framing. With the camera's aspect ratio, a
    width or height given (flags) sets the other side; neither: SIDE pixels wide. Without one
    (or a camera), the image is square, as by default."""
    render = dict(RENDER)
    if camera is None or camera.aspect is None:
        render.update(square_sides(width, height))
    document: dict = {"render": render, "lights": [dict(light) for light in imported.lights] or list(NO_LIGHTS)}
    if camera is not None:
        document["camera"] = {
            "position": camera.position,
            "look_at": camera.look_at,
            "up": camera.up,
            "fov": camera.fov,
        }
        if camera.aspect is not None and not (width and height):
            if height:
                render.update(width=max(1, round(height * camera.aspect)), height=height)
            else:
                render.update(width=width or SIDE, height=max(1, round((width or SIDE) / camera.aspect)))
    document["objects"] = [{"type": "gltf", "file": Path(path).name}]
    return document


def gltf_scene(
    path: str | Path,
    overrides: Overrides | None = None,
    source: str | None = None,
    camera: str | None = None,
    width: int | None = None,
    height: int | None = None,
) -> Scene:
    """The scene of a glTF file. `camera` names the camera to use; `overrides` edit the
    document as `--set` does; `width`/`height` (flags applied later) are framed for."""
    path = Path(path)
    source = source or str(path)
    try:
        imported = read_gltf(path)
    except GltfError as exc:
        raise SceneError(str(exc)) from None
    chosen = choose_camera(imported, camera)
    document = apply_overrides(gltf_document(path, imported, chosen, width, height), overrides)
    scene = scene_from_dict(document, source=source, overrides=overrides).with_base_dir(path.resolve().parent)
    if chosen is not None:
        return scene
    table = document.get("camera", {})
    given = {key for key in ("position", "look_at") if isinstance(table, dict) and key in table}
    if given == {"position", "look_at"}:
        return scene
    lo, hi = imported.bounds()
    aspect = (width or scene.render.width) / (height or scene.render.height)
    return scene.with_camera(frame(lo, hi, scene.camera, aspect, given))
