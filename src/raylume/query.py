"""raylume as a ray-intersection library: closest hits for arrays of rays against a scene."""

from __future__ import annotations

import numba
import numpy as np

from .compile import CompiledScene, compile_scene
from .kernels.query import intersect_rays
from .kernels.shapes import geometry_features
from .scene.model import Scene


def intersect(scene: Scene | CompiledScene, origins: np.ndarray, directions: np.ndarray, *, instances: bool = False):
    """Closest hit of each ray: (t float64, object int32, prim int32), each of the rays' leading
    shape (origins and directions of shape (..., 3)); with `instances`, a fourth array: the
    instance AOV (int32: the instance's index within its object, 0 for objects without
    instances, -1 for misses).

    Directions are normalised here, so t is a distance. Misses give t = inf and -1 indices.
    Pass a CompiledScene (raylume.compile.compile_scene) to reuse its BVH across calls."""
    compiled = scene if isinstance(scene, CompiledScene) else compile_scene(scene)
    origins = np.asarray(origins, dtype=np.float64)
    directions = np.asarray(directions, dtype=np.float64)
    if origins.shape != directions.shape or origins.shape[-1:] != (3,):
        raise ValueError(f"origins {origins.shape} and directions {directions.shape} must have one shape (..., 3)")
    shape = origins.shape[:-1]
    origins = np.ascontiguousarray(origins.reshape(-1, 3))
    directions = np.ascontiguousarray(directions.reshape(-1, 3))
    n = len(origins)
    t = np.empty(n)
    obj = np.empty(n, dtype=np.int32)
    prim = np.empty(n, dtype=np.int32)
    inst = np.empty(n, dtype=np.int32)
    # the ray offset floor of a camera at the origin: the scene's own extent
    S = compiled.for_camera((0.0, 0.0, 0.0))
    # the kernel makes the directions unit vectors as it goes and counts the rays it cannot
    # trace (numpy's passes over the arrays for it had cost ~80% of the kernel's time)
    lanes = numba.get_num_threads()
    if intersect_rays(S, geometry_features(S), origins, directions, t, obj, prim, inst, lanes, unit=True):
        raise ValueError("directions must be finite and non-zero, origins finite")
    if instances:
        return t.reshape(shape), obj.reshape(shape), prim.reshape(shape), inst.reshape(shape)
    return t.reshape(shape), obj.reshape(shape), prim.reshape(shape)
