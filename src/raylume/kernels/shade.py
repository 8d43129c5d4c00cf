"""Surface description at a hit and the seed's local lighting (ambient, diffuse, Phong).

The lean functions take the scene's views (Geometry G, Surfaces F, Lights L; see scene.py).
`surface_at`, `albedo_at` and `local_lighting` take the whole KernelScene, for callers outside
the hot ray loops."""

import math

from numba import njit

from .intersect import INF
from .layout import (
    HIT_PLANE,
    HIT_SPHERE,
    LIGHT_AMBIENT,
    LIGHT_POINT,
    MAT_ABSORPTION,
    MAT_CHECK_A,
    MAT_CHECK_B,
    MAT_CHECK_SCALE,
    MAT_COLOR,
    MAT_SPECULAR,
    MAT_TEXTURE,
    MAT_TRANSPARENCY,
    TEXTURE_CHECKER,
)
from .scene import geometry_of, lights_of, surfaces_of
from .traverse import any_hit, closest_hit
from .vec import FAST, KERNEL, add, cross, dot, length, madd, max_abs, mul, normalize, row3, sub


@njit(**KERNEL, inline="always")
def surface(G, F, kind, index, b1, b2, p):
    """(outward geometric normal, outward shading normal, material, object, prim) of a hit."""
    if kind == HIT_SPHERE:
        n = normalize(sub(p, row3(G.spheres, index, 0)))
        return n, n, F.sphere_material[index], F.sphere_object[index], 0
    if kind == HIT_PLANE:
        n = row3(G.planes, index, 3)
        return n, n, F.plane_material[index], F.plane_object[index], 0
    tri = G.triangles
    v0 = row3(tri, index, 0)
    ng = normalize(cross(sub(row3(tri, index, 3), v0), sub(row3(tri, index, 6), v0)))
    ns = ng
    if F.triangle_smooth[index]:
        b0 = 1.0 - b1 - b2
        nrm = F.triangle_normals
        s = add(add(mul(row3(nrm, index, 0), b0), mul(row3(nrm, index, 3), b1)), mul(row3(nrm, index, 6), b2))
        if dot(s, s) > 0.0:
            ns = normalize(s)
    return ng, ns, F.triangle_material[index], F.triangle_object[index], F.triangle_prim[index]


@njit(**KERNEL, inline="always")
def albedo(materials, m, p):
    """The material's colour at p: its plain colour or a world-space checkerboard."""
    if materials[m, MAT_TEXTURE] == TEXTURE_CHECKER:
        inv = 1.0 / materials[m, MAT_CHECK_SCALE]
        # A tiny bias keeps a plane through a cell boundary (y = 0) inside one cell.
        parity = (math.floor(p[0] * inv + 1e-9) + math.floor(p[1] * inv + 1e-9) + math.floor(p[2] * inv + 1e-9)) % 2
        if parity == 0:
            return row3(materials, m, MAT_CHECK_A)
        return row3(materials, m, MAT_CHECK_B)
    return row3(materials, m, MAT_COLOR)


@njit(**KERNEL)
def offset_epsilon(epsilon_floor, p):
    """Offset for rays leaving a surface: scaled to the hit's magnitude, so no acne at any scale."""
    return 1e-7 * max(max_abs(p), epsilon_floor)


@njit(**KERNEL, inline="always")
def shadow_transmittance(G, F, o, d, tmax, node_stack, t_stack):
    """Fraction (RGB) of light reaching o from distance tmax along d, and the rays used.

    Opaque scenes use the any-hit query. With transparent materials the ray walks from hit to
    hit: each transparent surface lets `transparency` through, and the path inside a medium
    (between entering and leaving it) is attenuated by exp(-absorption * length)."""
    if not F.has_transparency:
        if any_hit(G, o, d, 0.0, tmax, node_stack):
            return (0.0, 0.0, 0.0), 1
        return (1.0, 1.0, 1.0), 1
    tr = (1.0, 1.0, 1.0)
    origin = o
    remaining = tmax
    rays = 0
    for _ in range(32):
        t, kind, index, b1, b2 = closest_hit(G, origin, d, 0.0, remaining, node_stack, t_stack)
        rays += 1
        if t == INF or t >= remaining:
            return tr, rays
        p = madd(origin, d, t)
        ng, ns, m, obj, prim = surface(G, F, kind, index, b1, b2, p)
        transparency = F.materials[m, MAT_TRANSPARENCY]
        if transparency <= 0.0:
            return (0.0, 0.0, 0.0), rays
        tr = mul(tr, transparency)
        leaving = dot(ng, d) > 0.0
        if leaving:  # the segment just travelled lay inside this medium
            tr = (
                tr[0] * math.exp(-F.materials[m, MAT_ABSORPTION] * t),
                tr[1] * math.exp(-F.materials[m, MAT_ABSORPTION + 1] * t),
                tr[2] * math.exp(-F.materials[m, MAT_ABSORPTION + 2] * t),
            )
        if max(tr[0], tr[1], tr[2]) < 1e-4:
            return (0.0, 0.0, 0.0), rays
        eps = offset_epsilon(F.epsilon_floor, p)
        origin = madd(p, ng, eps if leaving else -eps)
        remaining -= t
    return (0.0, 0.0, 0.0), rays


@njit(**KERNEL, inline="always")
def lighting(G, F, L, p, n, view, m, shadows, node_stack, t_stack):
    """The seed's ComputeLighting: ambient + diffuse + specular from each light, RGB.

    n faces the viewer; p is already offset off the surface. Returns (intensity, rays)."""
    specular = F.materials[m, MAT_SPECULAR]
    ir = 0.0
    ig = 0.0
    ib = 0.0
    rays = 0
    for k in range(L.kind.shape[0]):
        kind = L.kind[k]
        intensity = row3(L.data, k, 3)
        if kind == LIGHT_AMBIENT:
            ir += intensity[0]
            ig += intensity[1]
            ib += intensity[2]
            continue
        if kind == LIGHT_POINT:
            to_light = sub(row3(L.data, k, 0), p)
            tmax = length(to_light)
        else:
            to_light = row3(L.data, k, 0)
            tmax = INF
        l = normalize(to_light)
        n_dot_l = dot(n, l)
        scale = max(n_dot_l, 0.0)
        if specular > 0.0:
            # the seed adds the highlight whatever the sign of N.L (R and V decide)
            r = sub(mul(n, 2.0 * n_dot_l), l)
            r_dot_v = dot(r, view)
            if r_dot_v > 0.0:
                scale += (r_dot_v / (length(r) * length(view))) ** specular
        if scale <= 0.0:
            continue  # nothing to add: skip the shadow ray
        if shadows:
            tr, used = shadow_transmittance(G, F, p, l, tmax, node_stack, t_stack)
            rays += used
        else:
            tr = (1.0, 1.0, 1.0)
        ir += intensity[0] * scale * tr[0]
        ig += intensity[1] * scale * tr[1]
        ib += intensity[2] * scale * tr[2]
    return (ir, ig, ib), rays


# --- whole-scene conveniences (not for per-ray use) -----------------------------------------


@njit(**KERNEL)
def surface_at(S, kind, index, b1, b2, p):
    return surface(geometry_of(S), surfaces_of(S), kind, index, b1, b2, p)


@njit(**KERNEL)
def albedo_at(S, m, p):
    return albedo(S.materials, m, p)


@njit(**KERNEL)
def local_lighting(S, p, n, view, m, shadows, node_stack, t_stack):
    return lighting(geometry_of(S), surfaces_of(S), lights_of(S), p, n, view, m, shadows, node_stack, t_stack)


@njit(**KERNEL)
def ray_epsilon(S, p):
    return offset_epsilon(S.epsilon_floor, p)
