"""raylume as a ray-intersection library: closest hits and occlusion for arrays of rays against a
scene."""

from __future__ import annotations

import numba
import numpy as np

from .compile import CompiledScene, compile_scene
from .kernels.query import intersect_rays, occluded_rays
from .kernels.shapes import geometry_features
from .scene.model import Scene

_REFUSED = "directions must be finite and non-zero, origins finite"


def _rays(origins, directions) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """The rays as C-contiguous float64 (N, 3) arrays (copied only where they are not), and their
    leading shape."""
    origins = np.asarray(origins, dtype=np.float64)
    directions = np.asarray(directions, dtype=np.float64)
    if origins.shape != directions.shape or origins.shape[-1:] != (3,):
        raise ValueError(f"origins {origins.shape} and directions {directions.shape} must have one shape (..., 3)")
    shape = origins.shape[:-1]
    return np.ascontiguousarray(origins.reshape(-1, 3)), np.ascontiguousarray(directions.reshape(-1, 3)), shape


def _spans(tmin, tmax, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """tmin and tmax as numbers (arrays of one) or, where either varies, one per ray in the rays'
    order (broadcast to their leading shape)."""
    tmin, tmax = np.asarray(tmin, dtype=np.float64), np.asarray(tmax, dtype=np.float64)
    if tmin.size == 1 and tmax.size == 1:
        return tmin.reshape(1), tmax.reshape(1)
    try:
        return tuple(np.broadcast_to(v, shape).reshape(-1) for v in (tmin, tmax))
    except ValueError:
        raise ValueError(f"tmin and tmax must broadcast to the rays' shape {shape}") from None


def _kernel_scene(scene):
    compiled = scene if isinstance(scene, CompiledScene) else compile_scene(scene)
    # the ray offset floor of a camera at the origin: the scene's own extent
    S = compiled.for_camera((0.0, 0.0, 0.0))
    return S, geometry_features(S)


def intersect(
    scene: Scene | CompiledScene,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    instances: bool = False,
):
    """Closest hit of each ray strictly between the distances tmin and tmax (numbers or arrays
    that broadcast to the rays' leading shape): (t float64, object int32, prim int32), each of
    the rays' leading shape (origins and directions of shape (..., 3)); with `instances`, a
    fourth array: the instance AOV (int32: the instance's index within its object, 0 for objects
    without instances, -1 for misses).

    Directions need not be unit vectors: t is a distance (each is divided by its length, as
    numpy's d / norm(d) would). Misses give t = inf and -1 indices. A direction that is zero or
    not finite, or an origin that is not finite, is a ValueError. Pass a CompiledScene
    (raylume.compile.compile_scene) to reuse its BVH across calls."""
    S, X = _kernel_scene(scene)
    origins, directions, shape = _rays(origins, directions)
    spans = _spans(tmin, tmax, shape)
    n = len(origins)
    t = np.empty(n)
    obj = np.empty(n, dtype=np.int32)
    prim = np.empty(n, dtype=np.int32)
    inst = np.empty(n, dtype=np.int32)
    # the kernel makes the directions unit vectors as it goes and counts the rays it cannot
    # trace (numpy's passes over the arrays for it had cost ~80% of the kernel's time)
    lanes = numba.get_num_threads()
    if intersect_rays(S, X, origins, directions, t, obj, prim, inst, lanes, unit=True, tmin=spans[0], tmax=spans[1]):
        raise ValueError(_REFUSED)
    if instances:
        return t.reshape(shape), obj.reshape(shape), prim.reshape(shape), inst.reshape(shape)
    return t.reshape(shape), obj.reshape(shape), prim.reshape(shape)


def occluded(
    scene: Scene | CompiledScene,
    origins: np.ndarray,
    directions: np.ndarray,
    *,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
) -> np.ndarray:
    """Whether anything lies along each ray strictly between the distances tmin and tmax (bool,
    of the rays' leading shape): shadow rays (towards a point light, tmax its distance) and
    visibility queries. Each ray stops at the first thing it finds, so this is cheaper than
    intersect. tmin and tmax are numbers or arrays that broadcast to the rays' leading shape;
    directions and errors as intersect says."""
    S, X = _kernel_scene(scene)
    origins, directions, shape = _rays(origins, directions)
    spans = _spans(tmin, tmax, shape)
    out = np.empty(len(origins), dtype=np.bool_)
    if occluded_rays(S, X, origins, directions, *spans, out, numba.get_num_threads(), unit=True):
        raise ValueError(_REFUSED)
    return out.reshape(shape)
