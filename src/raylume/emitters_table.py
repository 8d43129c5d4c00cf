"""The emitter table path mode samples (kernels/emitters.py), built from the scene's lights,
its emissive primitives and its environment, with a distribution proportional to power."""

from __future__ import annotations

import math

import numpy as np

from .environment_file import build_environment
from .kernels.geometry.shape_triangle import area as shape_triangle_area
from .kernels.geometry.shapes import EMISSION_SAMPLED, PRIM_KIND, PRIM_LIGHT, PRIM_MATERIAL, PRIM_ROW, surface_areas
from .kernels.shading import emitters as EM
from .kernels.shading import lights as LI
from .kernels.shading.environment import Environment, no_environment
from .kernels.shading.materials import MAT_EMISSION


def scene_environment(scene, source: str) -> Environment:
    """The kernels' Environment of the scene's [environment] table (not present without one)."""
    env = scene.environment
    if env is None:
        return no_environment()
    return build_environment(
        color=env.color,
        file=env.file,
        intensity=env.intensity,
        rotate=env.rotate,
        base_dir=scene.base_dir,
        source=source,
    )


def instance_weights(inverse: np.ndarray) -> np.ndarray:
    """Each instance's weight in its mesh's instance distribution (kernels/emitters.py's
    instance_weight): |det A|^(2/3) of the object-to-world matrix, from the float32 inverses
    (N, 12) the kernels use; exactly the instance's area scale when A is a similarity."""
    b = inverse.astype(np.float64).reshape(-1, 3, 4)[:, :, :3]
    return np.abs(np.linalg.det(b)) ** (-2.0 / 3.0)


def instanced_emitters(prims, triangles, materials, instances):
    """The INSTANCED rows of the emissive instanced meshes: (rows, powers, distributions); the
    meshes' primitive rows get PRIM_LIGHT set by the caller. Per mesh the distributions array
    holds its instances' cdf (by instance_weights) and rows, and its triangles' cdf (by
    object-space area): 16 bytes per instance and 8 per triangle, the triangles stored once."""
    emission = materials[:, MAT_EMISSION : MAT_EMISSION + 3]
    rows, power, dist, meshes = [], [], [], []
    offset = 0
    for first, count, root in instances.meshes:
        radiance = emission[prims[first, PRIM_MATERIAL]]
        if not (radiance > 0).any() or count == 0:
            continue
        which = np.flatnonzero(instances.index[:, 0] == root)
        w = instance_weights(instances.inverse[which])
        tri_rows = prims[first : first + count, PRIM_ROW].astype(np.int64)
        area = shape_triangle_area(triangles[tri_rows])
        inst_cdf = np.concatenate([[0.0], np.cumsum(w)])
        tri_cdf = np.concatenate([[0.0], np.cumsum(area)])
        row = np.zeros(EM.EMIT_WIDTH)
        row[LI.LIGHT_INTENSITY : LI.LIGHT_INTENSITY + 3] = radiance
        row[EM.INST_CDF] = offset
        row[EM.INST_COUNT] = len(which)
        row[EM.TRI_CDF] = offset + 2 * len(which) + 1
        row[EM.TRI_COUNT] = count
        row[EM.EMIT_PRIM] = first
        row[EM.EMIT_AREA] = tri_cdf[-1]
        dist.extend([inst_cdf, which.astype(np.float64), tri_cdf])
        offset += len(inst_cdf) + len(which) + len(tri_cdf)
        rows.append(row)
        # both sides of every instance's triangles (exact for similarities: |det A|^(2/3) is
        # the area scale; only the choice between emitters depends on it)
        power.append(2 * math.pi * tri_cdf[-1] * inst_cdf[-1] * float(radiance.mean()))
        meshes.append((first, count))
    return rows, power, dist, meshes


def build_emitters(
    scene,
    prims,
    shapes,
    triangles,
    materials,
    environment: Environment,
    extent: float,
    candidates=None,
    instances=None,
):
    """(kinds int32 (E,), data float64 (E, EMIT_WIDTH), cdf float64 (E + 1,), distributions
    float64 (D,), n_area, environment row or -1, ambient row or -1); sets prims[:, PRIM_LIGHT]
    for the emissive primitives (among `candidates`, a bool per row, when given: instanced
    meshes' rows are not) and for the emissive instanced meshes' rows (`instances`, the
    compile_instances.InstanceArrays: one row per mesh, instanced_emitters). Ambient lights
    become one row: a uniform environment of their summed radiance."""
    rows: list[np.ndarray] = []
    kinds: list[int] = []
    power: list[float] = []
    radius = max(extent, 1e-9)  # the scene's bounding radius, roughly: a directional light's reach
    lights = [light for light in scene.lights if light.type != "ambient"]
    # area lights first (the ray test loops over them), then the rest
    lights.sort(key=lambda light: light.type not in ("quad", "sphere"))
    n_area = sum(light.type in ("quad", "sphere") for light in lights)
    for light in lights:
        kind, light_row = LI.pack_light(light)
        row = np.zeros(EM.EMIT_WIDTH)
        row[: LI.LIGHT_WIDTH] = light_row
        intensity = float(np.mean(light.intensity))
        if kind == LI.POINT:
            phi = 4 * math.pi * intensity
        elif kind == LI.SPOT:
            phi = 2 * math.pi * intensity * (1 - 0.5 * (row[LI.LIGHT_COS_INNER] + row[LI.LIGHT_COS_OUTER]))
        elif kind == LI.DIRECTIONAL:
            phi = math.pi * radius**2 * intensity
        elif kind == LI.QUAD:
            phi = 2 * math.pi * float(np.linalg.norm(np.cross(light.u, light.v))) * intensity
        else:  # sphere
            phi = math.pi * 4 * math.pi * light.radius**2 * intensity
        rows.append(row)
        kinds.append(kind)
        power.append(phi)

    emission = materials[:, MAT_EMISSION : MAT_EMISSION + 3]
    glowing = (emission[prims[:, PRIM_MATERIAL]] > 0).any(axis=1) & np.isin(prims[:, PRIM_KIND], EMISSION_SAMPLED)
    glowing = np.flatnonzero(glowing if candidates is None else glowing & candidates)
    first_prim = len(rows)
    if len(glowing):
        area = surface_areas(prims, glowing, shapes, triangles)
        radiance = emission[prims[glowing, PRIM_MATERIAL]]
        block = np.zeros((len(glowing), EM.EMIT_WIDTH))
        block[:, LI.LIGHT_INTENSITY : LI.LIGHT_INTENSITY + 3] = radiance
        block[:, EM.EMIT_PRIM] = glowing
        block[:, EM.EMIT_AREA] = area
        rows.extend(block)
        kinds.extend([EM.PRIMITIVE] * len(glowing))
        power.extend(2 * math.pi * area * radiance.mean(axis=1))  # both sides
        prims[glowing, PRIM_LIGHT] = first_prim + np.arange(len(glowing), dtype=np.int32)

    dist = [np.zeros(1)]  # never empty: the kernels' array stays typed alike
    if instances is not None and len(instances.meshes):
        i_rows, i_power, i_dist, i_meshes = instanced_emitters(prims, triangles, materials, instances)
        base = sum(len(d) for d in dist)
        for row, (first, count) in zip(i_rows, i_meshes):
            row[EM.INST_CDF] += base
            row[EM.TRI_CDF] += base
            prims[first : first + count, PRIM_LIGHT] = len(rows)
            rows.append(row)
            kinds.append(EM.INSTANCED)
        power.extend(i_power)
        dist.extend(i_dist)

    ambient = sum((np.asarray(light.intensity) for light in scene.lights if light.type == "ambient"), np.zeros(3))
    ambient_row = -1
    if ambient.any():
        ambient_row = len(rows)
        row = np.zeros(EM.EMIT_WIDTH)
        row[LI.LIGHT_INTENSITY : LI.LIGHT_INTENSITY + 3] = ambient
        rows.append(row)
        kinds.append(LI.AMBIENT)
        power.append(4 * math.pi * math.pi * radius**2 * float(ambient.mean()))

    env_row = -1
    if environment.present:
        env_row = len(rows)
        rows.append(np.zeros(EM.EMIT_WIDTH))
        kinds.append(EM.ENVIRONMENT)
        power.append(4 * math.pi * math.pi * radius**2 * float(environment.image.mean()))

    dist = np.ascontiguousarray(np.concatenate(dist))
    if not rows:
        return np.zeros(1, np.int32), np.zeros((1, EM.EMIT_WIDTH)), np.zeros(2), dist, 0, -1, -1
    weights = np.maximum(np.asarray(power, dtype=np.float64), 0.0)
    cdf = np.zeros(len(weights) + 1)
    cdf[1:] = np.cumsum(weights)
    return np.asarray(kinds, np.int32), np.ascontiguousarray(np.stack(rows)), cdf, dist, n_area, env_row, ambient_row
