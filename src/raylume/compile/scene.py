"""compile_scene: the scene model -> the flat arrays the kernels read (kernels/scene.py), in
stages: objects (objects.py), geometry and BVH (geometry.py), materials and textures
(materials.py), lights and emitters (lights.py, with the environment, environment.py).

The compiled scene holds no camera and no file paths: geometry, materials, textures, lights
and the BVH only, so one compilation renders through any camera (Session) and can be pickled
and shipped (a cluster's workers never read the scene's files).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..accel.wide import wide_nbytes
from ..errors import SceneError
from ..kernels.frame_stack import roomy_frame_stack
from ..kernels.geometry.shape_triangle import triangle_tables
from ..kernels.geometry.shapes import PRIM_KIND, Shape
from ..kernels.geometry.sweep import sweep_table
from ..kernels.jit_clock import JitClock
from ..kernels.scene import KernelScene
from ..kernels.shading.materials import MAT_ALPHA_MAP, MAT_TRANSPARENCY
from ..scene.model import Scene
from ..scene.validation_errors import name_origins
from .geometry import build_geometry
from .lights import build_light_table, scene_environment
from .materials import material_table
from .media import build_media
from .objects import gather_objects


class CompiledScene(NamedTuple):
    kernel: KernelScene  # epsilon_floor left at the geometry's own; see with_camera
    extent: float  # largest coordinate magnitude of the geometry (for ray offsets)
    stats: dict  # primitives, triangles, bvh_nodes, bvh_bytes, build_seconds, compile_seconds, ...

    def for_camera(self, position) -> KernelScene:
        """The kernel scene with the ray-offset floor for a camera at `position`: a tiny
        fraction of the extent of the scene and the camera together."""
        extent = max(self.extent, float(np.abs(np.asarray(position, dtype=np.float64)).max()))
        return self.kernel._replace(epsilon_floor=float(max(1e-3 * extent, 1e-30)))


@roomy_frame_stack  # the BVH builder's kernels compile on first use (kernels/frame_stack.py)
def compile_scene(
    scene: Scene, source="<scene>", accelerate: bool = True, status: Callable[[str], None] | None = None
) -> CompiledScene:
    """Flatten the scene into arrays. `accelerate=False` skips the BVH (the rasterizer needs
    none: at 4M triangles that saves about 9 s). The first build on a machine compiles the BVH
    builder's kernels: that time is the stats' `compile_seconds`, not `build_seconds`, and
    `status` (if given) hears "compiling the BVH builder" when it starts and "building" after."""
    start = time.perf_counter()
    on_compile = None if status is None else (lambda: status(COMPILING_BVH))
    try:
        with JitClock(on_compile) as jit:
            compiled = _compile_scene(scene, source, accelerate)
    except SceneError as exc:  # 'objects[3].file: ...' of a pbrt or Mitsuba file: name its line too
        if scene.origins:
            exc.args = (name_origins(str(exc), scene.origins), *exc.args[1:])
        raise
    if jit.compiled and status is not None:
        status("building")
    compiled.stats["build_seconds"] = max(time.perf_counter() - start - jit.seconds, 0.0)
    compiled.stats["compile_seconds"] = jit.seconds
    return compiled


COMPILING_BVH = "compiling the BVH builder"


def _compile_scene(scene: Scene, source: str, accelerate: bool) -> CompiledScene:
    gathered = gather_objects(scene, source)
    g = build_geometry(gathered.geometry, accelerate, source)
    mat_rows, textures = material_table(
        gathered.materials, gathered.material_where, scene.base_dir, source, gathered.images
    )
    masked = bool((mat_rows[:, MAT_ALPHA_MAP] > 0).any())  # alpha maps: rays pass their holes
    environment = scene_environment(scene, source)
    media = build_media(
        scene, gathered.geometry, {k: scene.material_of(obj).type for k, obj in enumerate(scene.objects)}, source
    )
    # instanced meshes' triangles (stored in object space) are sampled per mesh, through its
    # instances (lights.instanced_emitters), not one row per triangle
    world = np.ones(len(g.prims), dtype=bool)
    world[g.n_world : g.n_bounded] = False
    lights = build_light_table(
        scene, g.prims, g.shapes, g.triangles, mat_rows, environment, g.radius, candidates=world, instances=g.instances
    )
    inst = g.instances
    kernel = KernelScene(
        prims=g.prims,
        n_bounded=g.n_bounded,
        shapes=g.shapes,
        triangles=g.triangles,
        **triangle_tables(g.triangles),
        triangle_normals=g.triangle_normals,
        triangle_smooth=g.triangle_smooth,
        triangle_uvs=g.triangle_uvs,
        sweep=sweep_table(
            g.triangles, g.prims, g.shapes, g.n_bounded, instanced=len(inst.prims) > 0 or len(inst.inverse) > 0
        ),
        node_bounds=g.bvh.node_bounds,
        node_index=g.bvh.node_index,
        materials=mat_rows,
        textures=textures.table(),
        texels=textures.texels(),
        light_kind=lights.kind,
        light_data=lights.data,
        light_order=lights.order,
        light_cdf=lights.cdf,
        light_dist=lights.dist,
        n_area_lights=lights.n_area,
        environment_row=lights.environment_row,
        ambient_row=lights.ambient_row,
        env_image=environment.image,
        env_alias=environment.alias,
        env_row_z=environment.row_z,
        env_rotation=environment.rotation,
        env_present=environment.present,
        # shadow rays walk from surface to surface where some let light through: transparent
        # materials (trace mode) and the holes of alpha maps
        has_transparency=bool((mat_rows[:, MAT_TRANSPARENCY] > 0).any()) or masked,
        basic_shapes=bool(np.isin(g.prims[:, PRIM_KIND], (Shape.SPHERE, Shape.TRIANGLE)).all()),
        inst_node_bounds=inst.node_bounds,
        inst_node_index=inst.node_index,
        instance_inverse=inst.inverse,
        instance_index=inst.index,
        medium_data=media.data,
        medium_density=media.density,
        medium_majorants=media.majorants,
        medium_interface=media.interface,
        camera_medium=media.camera,
        media_present=media.present,
        pass_through=media.pass_through or masked,
        epsilon_floor=1e-30,
    )
    stats = {
        "primitives": len(g.prims),
        "triangles": len(g.triangles),  # stored: an instanced mesh's once (instanced_triangles: as drawn)
        "degenerate_triangles": gathered.geometry.soup.degenerate,
        # without acceleration (the rasterizer's scenes) there is no BVH to report, only the
        # placeholder leaf that keeps the kernels' arrays typed alike
        "bvh_nodes": int(len(g.bvh.node_index)) if accelerate else 0,  # BVH_WIDTH-wide nodes
        "bvh_depth": int(g.depth) if accelerate else 0,
        # nodes, and the two columns of the primitive table that traversal reads (kind, row)
        "bvh_bytes": int(wide_nbytes(g.bvh) + 8 * len(g.prims) + inst.node_bytes) if accelerate else 0,
        "mesh_load_seconds": gathered.mesh_seconds,
        **inst.stats,
    }
    return CompiledScene(kernel, g.extent, stats)
