"""Every shape behind one switch per question: intersection, the surface at a hit (normals,
UVs), bounds and rasterizer tessellation.

The compiled scene lists its primitives in one table, `prims` int32 (P, PRIM_WIDTH), in BVH
leaf order: bounded primitives first (the BVH's leaves index them), then the unbounded ones
(planes), which traversal tests before descending. Each row names the shape kind, the row in
that kind's storage (triangles: the float32 triangle table; every other shape: the float64
`shapes` table of SHAPE_WIDTH columns), the material, the scene object, the face inside that
object (the `prim` AOV; 0 for analytic shapes) and the light the primitive emits for (-1 for
none; path tracing's emitters will find their light here).

To add a shape: write `shape_NAME.py` (pack, bounds, intersect, normal, uv, tessellate, and
TESSELLATION_IS_EXACT where its tessellation is exactly the shape; see shape_disk.py), add its
kind below and a line in each switch, and register its model class in scene/model.py and
compile/objects.py. docs/architecture.md lists the places.
"""

import math
from enum import IntEnum

import numpy as np
from numba.extending import overload

from ..scene import is_instances
from ..vec import INLINE_OVERLOAD, inline_function, kernel_function, max_abs, normalize
from . import shape_cylinder, shape_disk, shape_plane, shape_quad, shape_sphere, shape_triangle


class Shape(IntEnum):
    """Shape kinds (the prims table's PRIM_KIND column)."""

    SPHERE = 0
    TRIANGLE = 1
    PLANE = 2
    DISK = 3
    QUAD = 4
    CYLINDER = 5


# The same values as plain ints, for the kernels.
SPHERE = int(Shape.SPHERE)
TRIANGLE = int(Shape.TRIANGLE)
PLANE = int(Shape.PLANE)
DISK = int(Shape.DISK)
QUAD = int(Shape.QUAD)
CYLINDER = int(Shape.CYLINDER)

# Analytic shapes' modules (triangles are stored apart: float32, with normals and UVs).
ANALYTIC = {
    Shape.SPHERE: shape_sphere,
    Shape.PLANE: shape_plane,
    Shape.DISK: shape_disk,
    Shape.QUAD: shape_quad,
    Shape.CYLINDER: shape_cylinder,
}
SHAPE_WIDTH = 16  # columns of the analytic shape table, enough for every shape's row

# Columns of the primitive table.
PRIM_KIND = 0
PRIM_ROW = 1
PRIM_MATERIAL = 2
PRIM_OBJECT = 3
PRIM_FACE = 4
PRIM_LIGHT = 5
PRIM_WIDTH = 6
PRIM_LAST = PRIM_WIDTH - 1  # a literal for prefetch_cells: a whole row

NO_HIT = -1  # the primitive index of a ray that hit nothing
INF = math.inf

# --- hits on instances ---------------------------------------------------------------------
# A hit on an instance is reported as one int64, `(instance + 1) << INSTANCE_SHIFT | primitive`
# (traverse_instances.py): primitive is the instanced mesh's row of the primitive table, and
# instance the row of X.inverse. Hits on everything else are the primitive alone. Functions
# that index the primitive table with a hit split it first (split_hit); without Instances X
# that is the identity and compiles to nothing.
INSTANCE_SHIFT = 32
_PRIM_MASK = (1 << INSTANCE_SHIFT) - 1


def split_hit(X, hit):
    raise NotImplementedError("a Numba overload")


def world_normals(X, inst, ng, ns):
    raise NotImplementedError("a Numba overload")


def object_vector(X, inst, a):
    raise NotImplementedError("a Numba overload")


def instance_id(X, hit):
    raise NotImplementedError("a Numba overload")


@overload(split_hit, jit_options=INLINE_OVERLOAD)
def _split_hit_impl(X, hit):
    """(primitive row, instance row or -1) of a hit."""
    if is_instances(X):
        return lambda X, hit: (hit & _PRIM_MASK, (hit >> INSTANCE_SHIFT) - 1)
    return lambda X, hit: (hit, -1)


@inline_function
def _to_world_normal(inv, inst, n):
    """n (object space) by the inverse transpose of the instance's matrix, normalised: normals
    stay perpendicular to the surface under non-uniform scale, and outward under mirroring."""
    return normalize(
        (
            inv[inst, 0] * n[0] + inv[inst, 4] * n[1] + inv[inst, 8] * n[2],
            inv[inst, 1] * n[0] + inv[inst, 5] * n[1] + inv[inst, 9] * n[2],
            inv[inst, 2] * n[0] + inv[inst, 6] * n[1] + inv[inst, 10] * n[2],
        )
    )


@overload(world_normals, jit_options=INLINE_OVERLOAD)
def _world_normals_impl(X, inst, ng, ns):
    """(geometric, shading) normals of a hit in world space (those of an instance's mesh are
    computed in its object space)."""
    if is_instances(X):

        def impl(X, inst, ng, ns):
            if inst < 0:
                return ng, ns
            return _to_world_normal(X.inverse, inst, ng), _to_world_normal(X.inverse, inst, ns)

        return impl
    return lambda X, inst, ng, ns: (ng, ns)


@overload(object_vector, jit_options=INLINE_OVERLOAD)
def _object_vector_impl(X, inst, a):
    """A world-space vector in the instance's object space (unchanged off instances)."""
    if is_instances(X):

        def impl(X, inst, a):
            if inst < 0:
                return a
            m = X.inverse
            return (
                m[inst, 0] * a[0] + m[inst, 1] * a[1] + m[inst, 2] * a[2],
                m[inst, 4] * a[0] + m[inst, 5] * a[1] + m[inst, 6] * a[2],
                m[inst, 8] * a[0] + m[inst, 9] * a[1] + m[inst, 10] * a[2],
            )

        return impl
    return lambda X, inst, a: a


@overload(instance_id, jit_options=INLINE_OVERLOAD)
def _instance_id_impl(X, hit):
    """The `instance` AOV of a hit: the instance's index within its object, 0 off instances."""
    if is_instances(X):

        def impl(X, hit):
            inst = (hit >> INSTANCE_SHIFT) - 1
            return np.int64(X.index[inst, 1]) if inst >= 0 else np.int64(0)

        return impl
    return lambda X, hit: np.int64(0)


@inline_function
def intersect(G, X, k, o, d, shear, tmin, tmax):
    """Ray against primitive k: (t, b1, b2), t = +inf for no hit in (tmin, tmax). b1, b2 are a
    triangle's barycentric weights of v1 and v2; shapes that need to remember which part they
    hit keep it in b1 (the cylinder)."""
    kind = G.prims[k, PRIM_KIND]
    row = np.int64(G.prims[k, PRIM_ROW])
    if kind == SPHERE:
        return shape_sphere.intersect(G.shapes, row, o, d, tmin, tmax), 0.0, 0.0
    if kind == TRIANGLE:
        return shape_triangle.intersect_triangle(o, shear, G.triangles, row, tmin, tmax)
    # other shapes: no code at all in the basic variant (X is None); planes, tested once per
    # ray before traversal, inline (as a call, the glass example's cast frame took 20% longer,
    # its trace frame 9%); the rest by a call, so that they cost the leaf loop no code size
    if X is not None:
        if kind == PLANE:
            return shape_plane.intersect(G.shapes, row, o, d, tmin, tmax), 0.0, 0.0
        return _intersect_other(G.shapes, kind, row, o, d, tmin, tmax)
    return INF, 0.0, 0.0


@kernel_function
def _intersect_other(shapes, kind, row, o, d, tmin, tmax):
    """Disks, quads and cylinders (intersect tests planes inline)."""
    if kind == DISK:
        return shape_disk.intersect(shapes, row, o, d, tmin, tmax), 0.0, 0.0
    if kind == QUAD:
        return shape_quad.intersect(shapes, row, o, d, tmin, tmax), 0.0, 0.0
    if kind == CYLINDER:
        t, part = shape_cylinder.intersect(shapes, row, o, d, tmin, tmax)
        return t, part, 0.0
    return INF, 0.0, 0.0  # a kind no module defines (never: compile/objects.py packs registered shapes)


@inline_function
def normals(G, X, k, b1, b2, p):
    """(outward geometric normal, outward shading normal) of primitive k at the hit point p."""
    kind = G.prims[k, PRIM_KIND]
    row = np.int64(G.prims[k, PRIM_ROW])
    if kind == SPHERE:
        n = shape_sphere.normal(G.shapes, row, p)
        return n, n
    if kind == TRIANGLE:
        return shape_triangle.normals(G, row, b1, b2)
    n = (0.0, 0.0, 1.0)
    if X is not None:
        n = _normal_other(G.shapes, kind, row, b1, p)
    return n, n


@kernel_function
def _normal_other(shapes, kind, row, b1, p):
    if kind == PLANE:
        return shape_plane.normal(shapes, row, p)
    if kind == DISK:
        return shape_disk.normal(shapes, row, p)
    if kind == QUAD:
        return shape_quad.normal(shapes, row, p)
    if kind == CYLINDER:
        return shape_cylinder.normal(shapes, row, p, b1)
    return (0.0, 0.0, 1.0)  # a kind no module defines


@kernel_function
def uv(G, X, hit, b1, b2, p):
    """Texture coordinates of a hit on primitive k (each shape's module documents its own)."""
    k, _ = split_hit(X, hit)
    kind = np.int64(G.prims[k, PRIM_KIND])
    row = np.int64(G.prims[k, PRIM_ROW])
    if kind == TRIANGLE:
        return shape_triangle.uv(G, row, b1, b2)
    if kind == SPHERE:
        return shape_sphere.uv(G.shapes, row, p)
    if X is None:
        return 0.0, 0.0
    return _uv_other(G.shapes, kind, row, b1, p)


@kernel_function
def uv_differentials(G, X, hit, b1, b2, p, u, v, a1, a2):
    """Changes (du1, dv1, du2, dv2) of the UVs (u, v) at p from p to p + a1 and to p + a2,
    two vectors in the surface's tangent plane (texture filtering). Triangles answer exactly;
    other shapes by finite differences of their UVs, wrapped across seams (a sphere's u)."""
    k, inst = split_hit(X, hit)
    if G.prims[k, PRIM_KIND] == TRIANGLE:
        row = np.int64(G.prims[k, PRIM_ROW])
        a1 = object_vector(X, inst, a1)  # an instance's triangles are stored in object space
        a2 = object_vector(X, inst, a2)
        du1, dv1 = shape_triangle.uv_change(G, row, a1)
        du2, dv2 = shape_triangle.uv_change(G, row, a2)
        return du1, dv1, du2, dv2
    u1, v1 = uv(G, X, hit, b1, b2, (p[0] + a1[0], p[1] + a1[1], p[2] + a1[2]))
    u2, v2 = uv(G, X, hit, b1, b2, (p[0] + a2[0], p[1] + a2[1], p[2] + a2[2]))
    return _wrapped(u1 - u), _wrapped(v1 - v), _wrapped(u2 - u), _wrapped(v2 - v)


@inline_function
def _wrapped(x):
    return x - math.floor(x + 0.5)


@kernel_function
def _uv_other(shapes, kind, row, b1, p):
    if kind == PLANE:
        return shape_plane.uv(shapes, row, p)
    if kind == DISK:
        return shape_disk.uv(shapes, row, p)
    if kind == QUAD:
        return shape_quad.uv(shapes, row, p)
    if kind == CYLINDER:
        return shape_cylinder.uv(shapes, row, p, b1)
    return 0.0, 0.0  # a kind no module defines


# --- Python side -----------------------------------------------------------------------------


def bounds(kind: Shape, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float64 (N, 3) lower and upper corners of analytic shapes' boxes (+-inf: unbounded)."""
    return ANALYTIC[kind].bounds(rows)


def is_bounded(kind: Shape) -> bool:
    return kind == Shape.TRIANGLE or ANALYTIC[kind].BOUNDED


def tessellate(kind: Shape, row: np.ndarray, view) -> tuple[np.ndarray, np.ndarray]:
    """Triangles (float64 (N, 9)) drawing an analytic shape for the rasterizer, as seen from
    view.eye at view.px_per_rad pixels per radian, and the b1 value (part) of each."""
    result = ANALYTIC[kind].tessellate(row, view)
    tris, part = result if isinstance(result, tuple) else (result, None)
    return tris, (np.zeros(len(tris)) if part is None else part)


def exact_triangles(kind: Shape, row: np.ndarray) -> np.ndarray | None:
    """float64 (N, 9) triangles that are exactly the analytic shape (a flat polygon's:
    TESSELLATION_IS_EXACT in its module), or None: small scenes sweep such shapes with their
    triangles (sweep.py) and test only the candidates by the shape's own test."""
    module = ANALYTIC[kind]
    return module.tessellate(row, None) if getattr(module, "TESSELLATION_IS_EXACT", False) else None


@inline_function
def surface(G, X, hit, b1, b2, p):
    """The surface at a hit (a primitive, or an instance's primitive: split_hit) at p: (outward
    geometric normal, outward shading normal, material, object, face), in world space."""
    k, inst = split_hit(X, hit)
    ng, ns = normals(G, X, k, b1, b2, p)
    ng, ns = world_normals(X, inst, ng, ns)
    return (
        ng,
        ns,
        np.int64(G.prims[k, PRIM_MATERIAL]),
        np.int64(G.prims[k, PRIM_OBJECT]),
        np.int64(G.prims[k, PRIM_FACE]),
    )


# Rays leave a surface this fraction of the point's distance from the origin off it: above
# float32's rounding of the triangles there (6e-8), so no acne at any scale
RAY_OFFSET = 1e-7


@kernel_function
def offset_epsilon(epsilon_floor, p):
    """Offset for rays leaving a surface at p: scaled to the hit's magnitude, so no acne at any
    scale (epsilon_floor: a tiny fraction of the scene's extent)."""
    return RAY_OFFSET * max(max_abs(p), epsilon_floor)


# --- emission: path mode samples points on emissive primitives (lights/surface.py) ---------

# Shapes whose surface next-event estimation samples (a sphere by the cone it subtends, the rest
# uniformly by area); other emissive shapes are found by BSDF sampling alone.
EMISSION_SAMPLED = (TRIANGLE, SPHERE, QUAD, DISK)


@inline_function
def sample_surface(G, k, u1, u2):
    """A uniform point on primitive k (a triangle, quad or disk) and its normal there."""
    kind = G.prims[k, PRIM_KIND]
    row = np.int64(G.prims[k, PRIM_ROW])
    if kind == QUAD:
        return shape_quad.sample(G.shapes, row, u1, u2)
    if kind == DISK:
        return shape_disk.sample(G.shapes, row, u1, u2)
    if kind == TRIANGLE:
        return shape_triangle.sample(G, row, u1, u2)
    return (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)  # never asked (spheres: by their cone, shading/lights/)


def surface_areas(prims: np.ndarray, rows: np.ndarray, shapes: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """One side's area of each primitive in rows (0 for the shapes emission does not sample)."""
    kinds = prims[rows, PRIM_KIND]
    where = prims[rows, PRIM_ROW].astype(np.int64)
    out = np.zeros(len(rows))
    tri = kinds == TRIANGLE
    if tri.any():
        out[tri] = shape_triangle.area(triangles[where[tri]])
    for kind in (SPHERE, QUAD, DISK):
        sel = kinds == kind
        if sel.any():
            out[sel] = ANALYTIC[Shape(kind)].area(shapes[where[sel]])
    return out
