"""raylume as a ray-intersection library: closest hits and occlusion for arrays of rays against a
scene."""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Literal, overload

import numba
import numpy as np

from .compile import CompiledScene, compile_scene
from .kernels.film.camera import CAM_FORWARD, CAM_POSITION, CAM_RIGHT, CAM_UP, camera_of
from .kernels.geometry.query import grid_width
from .kernels.variants import geometry_features
from .query_lanes import intersect_rays, occluded_rays, ray_spans
from .scene.model import Camera, Scene

if TYPE_CHECKING:
    from .session import Session

_REFUSED = "directions must be finite and non-zero, origins finite"


def camera_rays(
    view: Scene | Camera, width: int | None = None, height: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The rays through the centres of the pixels of a width x height image, as a render at one
    sample a pixel traces them (raylume's camera; equal to the render's to the last bit or
    two: its kernels may fuse multiplies and adds): (origins, directions), float64 arrays of
    shape (height, width, 3), the ray of pixel (i, j) (column i from the left, row j from the
    top) at [j, i], directions unit vectors. `view`: a Camera, or a Scene for its camera, whose
    [render] width and height are then the defaults. A thin lens's rays start at its centre.

    Shaped as their image, they go to intersect as they are, which traces them in 4 x 2 pixel
    packets: faster on large meshes than the same rays reshaped to (N, 3)."""
    camera = view
    if isinstance(view, Scene):
        camera = view.camera
        width = view.render.width if width is None else width
        height = view.render.height if height is None else height
    if not isinstance(camera, Camera):
        raise TypeError(f"camera_rays takes a raylume.Camera or raylume.Scene, not {type(view).__name__}")
    if width is None or height is None:
        raise TypeError("camera_rays: width and height are needed with a Camera")
    for name, n in (("width", width), ("height", height)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"camera_rays: {name} must be a whole number of pixels >= 1, not {n!r}")
    cam = camera_of(camera, width, height)
    a = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    b = 1.0 - (np.arange(height) + 0.5) / height * 2.0
    f, r, u = (cam[k : k + 3] for k in (CAM_FORWARD, CAM_RIGHT, CAM_UP))
    directions = f + a[None, :, None] * r + b[:, None, None] * u
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    origins = np.empty_like(directions)
    origins[...] = cam[CAM_POSITION : CAM_POSITION + 3]
    return origins, directions


def _compiled(scene) -> CompiledScene:
    """The compiled scene of what a query takes: a CompiledScene, a Session (its compiled
    scene, with its BVH), a Scene, or what a Session takes by name (a scene, glTF or mesh file,
    a built-in scene); anything else is a TypeError naming these."""
    from .session import Session

    if isinstance(scene, CompiledScene):
        return scene
    if isinstance(scene, Session):
        if not scene._accelerated:  # a rasterizing session has no BVH yet
            scene._compile(True)
        return scene.compiled
    if isinstance(scene, Scene):
        return compile_scene(scene)
    if isinstance(scene, (str, os.PathLike)):
        return Session(scene).compiled
    raise TypeError(
        "raylume.intersect and raylume.occluded take a raylume.Session, a Scene, a CompiledScene "
        f"(raylume.compile.compile_scene) or a scene's file or built-in name, not {type(scene).__name__}"
    )


def _query(scene, origins, directions, tmin, tmax):
    """What both queries hand their kernel: (S, X, origins, directions, tmin, tmax, the rays'
    leading shape). The scene compiled unless it is already (its kernel scene for a camera at the
    origin: the ray offset floor is then the scene's own extent); the rays as C-contiguous
    float64 (N, 3) arrays (copied only where they are not); tmin and tmax as the kernels read
    them (ray_spans)."""
    S = _compiled(scene).for_camera((0.0, 0.0, 0.0))
    origins = np.asarray(origins, dtype=np.float64)
    directions = np.asarray(directions, dtype=np.float64)
    if origins.shape != directions.shape or origins.shape[-1:] != (3,):
        raise ValueError(f"origins {origins.shape} and directions {directions.shape} must have one shape (..., 3)")
    shape = origins.shape[:-1]
    origins = np.ascontiguousarray(origins.reshape(-1, 3))
    directions = np.ascontiguousarray(directions.reshape(-1, 3))
    return (S, geometry_features(S), origins, directions, *ray_spans(tmin, tmax, shape), shape)


# Overloads, so that a type checker knows `t, obj, prim = intersect(...)` from the four arrays
# that `instances=True` gives.
@overload
def intersect(
    scene: Session | Scene | CompiledScene | str | os.PathLike,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    instances: Literal[False] = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


@overload
def intersect(
    scene: Session | Scene | CompiledScene | str | os.PathLike,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    instances: Literal[True],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...


@overload
def intersect(
    scene: Session | Scene | CompiledScene | str | os.PathLike,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    instances: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]: ...


def intersect(
    scene: Session | Scene | CompiledScene | str | os.PathLike,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    instances: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Closest hit of each ray strictly between the distances tmin (at least 0) and tmax (numbers or
    arrays that broadcast to the rays' leading shape): (t float64, object int32, prim int32), each of
    the rays' leading shape (origins and directions of shape (..., 3)); with `instances`, a
    fourth array: the instance AOV (int32: the instance's index within its object, 0 for objects
    without instances, -1 for misses).

    Directions need not be unit vectors: t is a distance (each is divided by its length, as
    numpy's d / norm(d) would). Misses give t = inf and -1 indices. A direction that is zero or
    not finite, or an origin that is not finite, is a ValueError. Pass a Session (or a
    CompiledScene, raylume.compile.compile_scene) to reuse its BVH across calls. Rays shaped like an image,
    (..., H, W, 3) with W >= 8, are traced in packets of 4 x 2 neighbours (with one tmin and one
    tmax for all), faster on large meshes than rows of eight; the answers are the same."""
    S, X, origins, directions, tmin, tmax, shape = _query(scene, origins, directions, tmin, tmax)
    n = len(origins)
    t = np.empty(n)
    obj = np.empty(n, dtype=np.int32)
    prim = np.empty(n, dtype=np.int32)
    inst = np.empty(n, dtype=np.int32)
    # the kernel makes the directions unit vectors as it goes and counts the rays it cannot
    # trace (numpy's passes over the arrays for it had cost ~80% of the kernel's time)
    lanes = numba.get_num_threads()
    width = grid_width(shape)  # an image's rays go in 4 x 2 packets
    if intersect_rays(S, X, origins, directions, t, obj, prim, inst, lanes, True, tmin, tmax, width):
        raise ValueError(_REFUSED)
    if instances:
        return t.reshape(shape), obj.reshape(shape), prim.reshape(shape), inst.reshape(shape)
    return t.reshape(shape), obj.reshape(shape), prim.reshape(shape)


def occluded(
    scene: Session | Scene | CompiledScene | str | os.PathLike,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
) -> np.ndarray:
    """Whether anything lies along each ray strictly between the distances tmin and tmax (bool,
    of the rays' leading shape): shadow rays (towards a point light, tmax its distance) and
    visibility queries. Each ray stops at the first thing it finds, so this is cheaper than
    intersect. tmin (at least 0) and tmax are numbers or arrays that broadcast to the rays' leading shape;
    directions and errors as intersect says."""
    S, X, origins, directions, tmin, tmax, shape = _query(scene, origins, directions, tmin, tmax)
    out = np.empty(len(origins), dtype=np.bool_)
    if occluded_rays(S, X, origins, directions, tmin, tmax, out, numba.get_num_threads(), unit=True):
        raise ValueError(_REFUSED)
    return out.reshape(shape)
