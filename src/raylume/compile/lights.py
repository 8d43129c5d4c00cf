"""The light table both modes read (kernels/shading/lights/table.py), built from the scene's
lights, its emissive primitives and instanced meshes and its environment, each row packed by
its kind's module, with path mode's distribution proportional to power (each kind's `power`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..kernels.geometry.shape_triangle import area as shape_triangle_area
from ..kernels.geometry.shapes import EMISSION_SAMPLED, PRIM_KIND, PRIM_LIGHT, PRIM_MATERIAL, PRIM_ROW, surface_areas
from ..kernels.shading import lights as LI
from ..kernels.shading.environment import Environment, no_environment
from ..kernels.shading.lights import ambient, environment, instanced, surface
from ..kernels.shading.materials import MAT_EMISSION
from .environment import build_environment


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
        matrix=env.matrix,
        mapping=env.mapping,
        base_dir=scene.base_dir,
        source=source,
    )


def instance_weights(inverse: np.ndarray) -> np.ndarray:
    """Each instance's weight in its mesh's instance distribution (lights/instanced.py's
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
        row = np.zeros(LI.LIGHT_ROW_WIDTH)
        row[LI.LIGHT_INTENSITY : LI.LIGHT_INTENSITY + 3] = radiance
        row[LI.INST_CDF] = offset
        row[LI.INST_COUNT] = len(which)
        row[LI.TRI_CDF] = offset + 2 * len(which) + 1
        row[LI.TRI_COUNT] = count
        row[LI.EMIT_PRIM] = first
        row[LI.EMIT_AREA] = tri_cdf[-1]
        dist.extend([inst_cdf, which.astype(np.float64), tri_cdf])
        offset += len(inst_cdf) + len(which) + len(tri_cdf)
        rows.append(row)
        power.append(instanced.power(tri_cdf[-1], inst_cdf[-1], radiance))
        meshes.append((first, count))
    return rows, power, dist, meshes


class LightTable(NamedTuple):
    """The light table's arrays (KernelScene's light_* fields) and its landmarks."""

    kind: np.ndarray  # int32 (E,)
    data: np.ndarray  # float64 (E, LIGHT_ROW_WIDTH)
    order: np.ndarray  # int32 (L,): the rows of the scene's lights, in its order
    cdf: np.ndarray  # float64 (C + 1,): path mode's distribution over rows 0..C-1
    dist: np.ndarray  # float64 (D,): instanced meshes' instance and triangle cdfs
    n_area: int
    environment_row: int
    ambient_row: int


def build_light_table(
    scene,
    prims,
    shapes,
    triangles,
    materials,
    env: Environment,
    radius: float,
    candidates=None,
    instances=None,
) -> LightTable:
    """The light table (kernels/shading/lights/table.py has the order of its rows); sets
    prims[:, PRIM_LIGHT] for the emissive primitives (among `candidates`, a bool per row, when
    given: instanced meshes' rows are not) and for the emissive instanced meshes' rows
    (`instances`, the instances.InstanceArrays: one row per mesh, instanced_emitters).
    Ambient lights are one row for path mode (a uniform environment of their summed radiance)
    and a row each, after the distribution's rows, for trace mode."""
    rows: list[np.ndarray] = []
    kinds: list[int] = []
    power: list[float] = []
    radius = max(radius, 1e-9)  # the scene's bounding radius: an infinite light's reach (geometry._radius)
    lights = [(i, light) for i, light in enumerate(scene.lights) if light.type != ambient.NAME]
    # area lights (the kinds rays see) first: the ray test loops over them; then the rest
    lights.sort(key=lambda item: not LI.BY_NAME[item[1].type].VISIBLE)
    n_area = sum(LI.BY_NAME[light.type].VISIBLE for _, light in lights)
    order = np.full(len(scene.lights), -1, dtype=np.int32)
    for i, light in lights:
        kind, row = LI.pack_light(light)
        order[i] = len(rows)
        rows.append(row)
        kinds.append(kind)
        power.append(LI.BY_NAME[light.type].power(row, radius))

    emission = materials[:, MAT_EMISSION : MAT_EMISSION + 3]
    # the emissive materials first (a few rows), then their primitives: the emission gathered
    # for every primitive had cost 0.2 s at 4M triangles in scenes with no emitter at all
    emissive = np.flatnonzero((emission > 0).any(axis=1))
    glowing = np.zeros(0, dtype=np.int64)
    if len(emissive):
        glowing = np.isin(prims[:, PRIM_MATERIAL], emissive) & np.isin(prims[:, PRIM_KIND], EMISSION_SAMPLED)
        glowing = np.flatnonzero(glowing if candidates is None else glowing & candidates)
    first_prim = len(rows)
    if len(glowing):
        area = surface_areas(prims, glowing, shapes, triangles)
        radiance = emission[prims[glowing, PRIM_MATERIAL]]
        block = np.zeros((len(glowing), LI.LIGHT_ROW_WIDTH))
        block[:, LI.LIGHT_INTENSITY : LI.LIGHT_INTENSITY + 3] = radiance
        block[:, LI.EMIT_PRIM] = glowing
        block[:, LI.EMIT_AREA] = area
        rows.extend(block)
        kinds.extend([surface.KIND] * len(glowing))
        power.extend(surface.power(area, radiance))
        prims[glowing, PRIM_LIGHT] = first_prim + np.arange(len(glowing), dtype=np.int32)

    dist = [np.zeros(1)]  # never empty: the kernels' array stays typed alike
    if instances is not None and len(instances.meshes):
        i_rows, i_power, i_dist, i_meshes = instanced_emitters(prims, triangles, materials, instances)
        base = sum(len(d) for d in dist)
        for row, (first, count) in zip(i_rows, i_meshes):
            row[LI.INST_CDF] += base
            row[LI.TRI_CDF] += base
            prims[first : first + count, PRIM_LIGHT] = len(rows)
            rows.append(row)
            kinds.append(instanced.KIND)
        power.extend(i_power)
        dist.extend(i_dist)

    ambients = [(i, light) for i, light in enumerate(scene.lights) if light.type == ambient.NAME]
    summed = sum((np.asarray(light.intensity) for _, light in ambients), np.zeros(3))
    ambient_row = -1
    if summed.any():
        ambient_row = len(rows)
        row = np.zeros(LI.LIGHT_ROW_WIDTH)
        row[LI.LIGHT_INTENSITY : LI.LIGHT_INTENSITY + 3] = summed
        rows.append(row)
        kinds.append(ambient.KIND)
        power.append(ambient.power(row, radius))

    env_row = -1
    if env.present:
        env_row = len(rows)
        rows.append(np.zeros(LI.LIGHT_ROW_WIDTH))
        kinds.append(environment.KIND)
        power.append(environment.power(env.image, radius))

    if rows:
        weights = np.maximum(np.asarray(power, dtype=np.float64), 0.0)
        cdf = np.zeros(len(weights) + 1)
        cdf[1:] = np.cumsum(weights)
    else:
        cdf = np.zeros(2)  # nothing to sample (path mode tests the total first)
    for i, light in ambients:  # trace mode's ambient lights, each in its turn
        order[i] = len(rows)
        rows.append(ambient.pack(light))
        kinds.append(ambient.KIND)
    if not rows:
        rows, kinds = [np.zeros(LI.LIGHT_ROW_WIDTH)], [ambient.KIND]  # typed alike, never read
    return LightTable(
        np.asarray(kinds, np.int32),
        np.ascontiguousarray(np.stack(rows)),
        order,
        cdf,
        np.ascontiguousarray(np.concatenate(dist)),
        n_area,
        env_row,
        ambient_row,
    )
