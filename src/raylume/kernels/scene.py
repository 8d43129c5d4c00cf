"""The compiled scene as the kernels see it: one NamedTuple of flat numpy arrays."""

from typing import NamedTuple

import numpy as np


class KernelScene(NamedTuple):
    materials: np.ndarray  # float64 (M, MAT_WIDTH)
    light_kind: np.ndarray  # int32 (L,)
    light_data: np.ndarray  # float64 (L, 6)
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
