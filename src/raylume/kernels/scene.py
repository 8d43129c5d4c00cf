"""The compiled scene as the kernels see it: one NamedTuple of flat numpy arrays, and the small
views of it that hot kernels take."""

from typing import NamedTuple

import numpy as np

from .geometry.layout import on_a_line
from .geometry.shape_triangle import TRIANGLE_TABLES, triangle_tables
from .shading.environment import Environment
from .vec import kernel_function


class KernelScene(NamedTuple):
    prims: np.ndarray  # int32 (P, PRIM_WIDTH): the primitive table in BVH leaf order (shapes.py)
    n_bounded: int  # prims[:n_bounded] are in the BVH; the rest (planes) are tested before it
    shapes: np.ndarray  # float64 (A, SHAPE_WIDTH): analytic shapes' rows (shape_*.py)
    triangles: np.ndarray  # float32 (T, 9): v0, v1, v2, in BVH leaf order
    # the same by columns, float32 (9, T + 4), for the block test of scenes of at most 4096
    # triangles; (9, 4) otherwise (shape_triangle.triangle_columns)
    triangle_columns: np.ndarray
    # their unit face normals, float64 (T, 3), in the same scenes; (0, 3) otherwise
    triangle_face_normals: np.ndarray
    triangle_normals: np.ndarray  # float32 (T, 9) vertex normals, or (1, 9) when no mesh is smooth
    triangle_smooth: np.ndarray  # bool (T,)
    triangle_uvs: np.ndarray  # float32 (T, 6): uv0, uv1, uv2, or (1, 6) when no triangle needs UVs
    # small scenes' triangles for the sweep instead of the BVH walk: float32 (SWEEP_ROWS, 32), or
    # (SWEEP_ROWS, 0) for the walk (geometry/sweep.py)
    sweep: np.ndarray
    # W-wide BVH nodes (accel/wide.py): float32 (N, NODE_ROWS, W) records, the child boxes SoA,
    # then each lane's reference (layout.py); node_index is the same records as int32
    node_bounds: np.ndarray
    node_index: np.ndarray
    materials: np.ndarray  # float64 (M, MAT_WIDTH), shading/materials/table.py
    textures: np.ndarray  # float64 (X, TEX_WIDTH), textures.py
    texels: np.ndarray  # float32 (N, 3): every image texture's linear texels, row by row
    # the light table of both modes (shading/lights/table.py): kinds, rows, the rows of the
    # scene's lights in its order (trace mode), path mode's power cdf over the first rows, the
    # instanced emitters' instance and triangle cdfs, how many area lights lead the table, the
    # environment's and the summed ambient lights' rows (-1: none)
    light_kind: np.ndarray  # int32 (E,)
    light_data: np.ndarray  # float64 (E, LIGHT_ROW_WIDTH)
    light_order: np.ndarray  # int32 (L,)
    light_cdf: np.ndarray  # float64 (C + 1,), C <= E
    light_dist: np.ndarray  # float64 (D,)
    n_area_lights: int
    environment_row: int
    ambient_row: int
    # the environment (environment.py's Environment, flattened: parallel kernels take no
    # nested tuples)
    env_image: np.ndarray
    env_alias: np.ndarray
    env_row_z: np.ndarray
    env_rotation: np.ndarray
    env_present: bool
    has_transparency: bool
    # every primitive a sphere or a triangle (variants.features): found once here, since a scan
    # of the primitive table cost 12 ms at 4 M triangles on every query
    basic_shapes: bool
    # Instances (traverse_instances.py): the top-level BVH (node 0, over the instances' world
    # boxes) followed by every instanced mesh's own BVH, in one node array; per instance its
    # inverse matrix (world to object, 3 x 4 row-major) and (BLAS root node, index within its
    # object), in top-level leaf order. Instanced meshes' triangles and primitive rows lie in
    # the shared tables (prims[n_world:n_bounded]). Zero instances: no top-level BVH.
    inst_node_bounds: np.ndarray  # float32 (M, NODE_ROWS, W) node records
    inst_node_index: np.ndarray  # the same records as int32
    instance_inverse: np.ndarray  # float32 (N, 12)
    instance_index: np.ndarray  # int32 (N, 2)
    # Participating media (shading/media/): the medium table, every grid's densities and
    # majorant cells, each object's (inside, outside) medium, the camera's medium (-1: none),
    # whether there are media, and whether shadow rays must pass null boundaries and media
    medium_data: np.ndarray  # float64 (K, MED_WIDTH)
    medium_density: np.ndarray  # float32 (D,)
    medium_majorants: np.ndarray  # float64 (C,)
    medium_interface: np.ndarray  # int32 (objects, 2)
    camera_medium: int
    media_present: bool
    pass_through: bool
    # Smallest ray offset: a tiny fraction of the scene's extent, camera included (set per
    # render by the Session, since the camera may move).
    epsilon_floor: float

    def __reduce__(self):
        # node_index is node_bounds' memory seen as int32: pickled as they are, each would be
        # copied, doubling the nodes' memory where the scene is unpickled (cluster workers) and
        # splitting each node record in two; the tables made from the triangles are made again there
        made_again = dict.fromkeys(TRIANGLE_TABLES)
        return _unpickle_scene, (tuple(self._replace(node_index=None, inst_node_index=None, **made_again)),)


def _unpickle_scene(fields: tuple) -> KernelScene:
    s = KernelScene(*fields)
    node_bounds, inst_node_bounds = on_a_line(s.node_bounds), on_a_line(s.inst_node_bounds)
    return s._replace(
        node_bounds=node_bounds,
        node_index=node_bounds.view(np.int32),
        inst_node_bounds=inst_node_bounds,
        inst_node_index=inst_node_bounds.view(np.int32),
        **triangle_tables(s.triangles),
    )


# Hot kernels take small views of the scene instead of the whole KernelScene: Numba passes a
# tuple argument by value, and copying every array descriptor on every call cost more than the
# traversal itself (measured: 250 ns vs 120 ns per ray on the bunny).


class Geometry(NamedTuple):
    """What traversal and the surface at a hit need."""

    prims: np.ndarray
    n_bounded: int
    shapes: np.ndarray
    triangles: np.ndarray
    triangle_columns: np.ndarray
    triangle_face_normals: np.ndarray
    triangle_normals: np.ndarray
    triangle_smooth: np.ndarray
    triangle_uvs: np.ndarray
    sweep: np.ndarray
    node_bounds: np.ndarray
    node_index: np.ndarray


class Surfaces(NamedTuple):
    """What shading a hit needs, beside the geometry: materials and their textures."""

    materials: np.ndarray
    textures: np.ndarray
    texels: np.ndarray
    has_transparency: bool
    epsilon_floor: float


class Lights(NamedTuple):
    """Trace mode's view of the light table: the scene's lights, in its order."""

    kind: np.ndarray
    data: np.ndarray
    order: np.ndarray


class Instances(NamedTuple):
    """The kernels' feature argument X for scenes with instances (variants.features), holding
    what the two-level traversal needs beside the Geometry view. Its type selects the kernels'
    variant with instance code; scenes without instances compile none of it."""

    node_bounds: np.ndarray
    node_index: np.ndarray
    inverse: np.ndarray
    index: np.ndarray


def is_instances(X) -> bool:
    """Typing-time test (in @overload implementations): is the Numba type X an Instances?"""
    from numba import types

    return isinstance(X, types.BaseNamedTuple) and getattr(X, "instance_class", None) is Instances


def instances_of(S) -> Instances:
    return Instances(S.inst_node_bounds, S.inst_node_index, S.instance_inverse, S.instance_index)


class Emitters(NamedTuple):
    """Path mode's view of the light table: the rows its power distribution covers."""

    kind: np.ndarray
    data: np.ndarray
    cdf: np.ndarray
    dist: np.ndarray
    n_area: int
    environment_row: int
    ambient_row: int


class Media(NamedTuple):
    """Path mode's view of the participating media (shading/media/)."""

    data: np.ndarray
    density: np.ndarray
    majorants: np.ndarray
    interface: np.ndarray
    camera: int
    present: bool
    pass_through: bool


@kernel_function()
def media_of(S):
    return Media(
        S.medium_data,
        S.medium_density,
        S.medium_majorants,
        S.medium_interface,
        S.camera_medium,
        S.media_present,
        S.pass_through,
    )


@kernel_function()
def emitters_of(S):
    return Emitters(
        S.light_kind,
        S.light_data,
        S.light_cdf,
        S.light_dist,
        S.n_area_lights,
        S.environment_row,
        S.ambient_row,
    )


@kernel_function()
def environment_of(S):
    return Environment(
        S.env_image,
        S.env_alias,
        S.env_row_z,
        S.env_rotation,
        S.env_present,
    )


@kernel_function()
def geometry_of(S):
    return Geometry(
        S.prims,
        S.n_bounded,
        S.shapes,
        S.triangles,
        S.triangle_columns,
        S.triangle_face_normals,
        S.triangle_normals,
        S.triangle_smooth,
        S.triangle_uvs,
        S.sweep,
        S.node_bounds,
        S.node_index,
    )


@kernel_function()
def surfaces_of(S):
    return Surfaces(S.materials, S.textures, S.texels, S.has_transparency, S.epsilon_floor)


@kernel_function()
def lights_of(S):
    return Lights(S.light_kind, S.light_data, S.light_order)


def trace_views(S: KernelScene, B=0) -> tuple:
    """The views trace mode's lanes take (frame.trace_lane), made on the host by the kernels'
    own accessors: (Geometry, Surfaces, Lights, Environment). For the seed's variant (B None,
    variants.trace_features) only what its wavefront reads: SphereLeafGeometry,
    SphereLeafSurfaces, the Lights and no environment, so that the kernel's CPython wrapper
    unboxes 6 arrays of the scene instead of 20."""
    if B is None:
        return (
            SphereLeafGeometry(S.prims, S.node_index),
            SphereLeafSurfaces(S.materials, S.epsilon_floor),
            lights_of.py_func(S),
            None,
        )
    return geometry_of.py_func(S), surfaces_of.py_func(S), lights_of.py_func(S), environment_of.py_func(S)


class SphereLeafGeometry(NamedTuple):
    """The Geometry fields that trace mode's seed variant reads: the root leaf of spheres."""

    prims: np.ndarray
    node_index: np.ndarray


class SphereLeafSurfaces(NamedTuple):
    """The Surfaces fields that trace mode's seed variant reads (no textures)."""

    materials: np.ndarray
    epsilon_floor: float
