"""The compiled scene as the kernels see it: one NamedTuple of flat numpy arrays."""

from typing import NamedTuple

import numpy as np
from numba import njit


class KernelScene(NamedTuple):
    materials: np.ndarray  # float64 (M, MAT_WIDTH)
    light_kind: np.ndarray  # int32 (L,)
    light_data: np.ndarray  # float64 (L, LIGHT_WIDTH), see layout.py
    spheres: np.ndarray  # float64 (S, 4): centre, radius
    sphere_material: np.ndarray  # int32 (S,)
    sphere_object: np.ndarray  # int32 (S,)
    planes: np.ndarray  # float64 (P, 6): point, unit normal
    plane_material: np.ndarray  # int32 (P,)
    plane_object: np.ndarray  # int32 (P,)
    triangles: np.ndarray  # float32 (T, 9): v0, v1, v2, in BVH leaf order
    triangle_normals: np.ndarray  # float32 (T, 9) vertex normals, or (1, 9) when no mesh is smooth
    triangle_smooth: np.ndarray  # bool (T,)
    triangle_material: np.ndarray  # int32 (T,)
    triangle_object: np.ndarray  # int32 (T,)
    triangle_prim: np.ndarray  # int32 (T,): index of the face inside its object
    node_bounds: np.ndarray  # float32 (N, 6)
    node_index: np.ndarray  # int32 (N, 2): right child / first prim, 0 / prim count
    prim_type: np.ndarray  # int8 (P,): PRIM_SPHERE or PRIM_TRIANGLE, in leaf order
    prim_id: np.ndarray  # int32 (P,): row in spheres or triangles
    has_transparency: bool
    epsilon_floor: float  # smallest ray offset: a tiny fraction of the scene's extent
    triangle_uvs: np.ndarray  # float32 (T, 6): uv0, uv1, uv2, or (1, 6) when no triangle needs UVs
    textures: np.ndarray  # float32 (N, 3): every image texture's linear texels, row by row


# Hot kernels take small views of the scene instead of the whole KernelScene: Numba passes a
# tuple argument by value, and copying 21 array descriptors on every call cost more than the
# traversal itself (measured: 250 ns vs 120 ns per ray on the bunny).


class Geometry(NamedTuple):
    """What traversal needs."""

    planes: np.ndarray
    spheres: np.ndarray
    triangles: np.ndarray
    node_bounds: np.ndarray
    node_index: np.ndarray
    prim_type: np.ndarray
    prim_id: np.ndarray


class Surfaces(NamedTuple):
    """What shading a hit needs, beside the geometry."""

    materials: np.ndarray
    sphere_material: np.ndarray
    sphere_object: np.ndarray
    plane_material: np.ndarray
    plane_object: np.ndarray
    triangle_normals: np.ndarray
    triangle_smooth: np.ndarray
    triangle_material: np.ndarray
    triangle_object: np.ndarray
    triangle_prim: np.ndarray
    has_transparency: bool
    epsilon_floor: float
    triangle_uvs: np.ndarray
    textures: np.ndarray


class Lights(NamedTuple):
    kind: np.ndarray
    data: np.ndarray


@njit
def geometry_of(S):
    return Geometry(S.planes, S.spheres, S.triangles, S.node_bounds, S.node_index, S.prim_type, S.prim_id)


@njit
def surfaces_of(S):
    return Surfaces(S.materials, S.sphere_material, S.sphere_object, S.plane_material, S.plane_object,
                    S.triangle_normals, S.triangle_smooth, S.triangle_material, S.triangle_object,
                    S.triangle_prim, S.has_transparency, S.epsilon_floor, S.triangle_uvs, S.textures)


@njit
def lights_of(S):
    return Lights(S.light_kind, S.light_data)
