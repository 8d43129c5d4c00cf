"""Surface description at a hit and the seed's local lighting (ambient, diffuse, Phong)."""

import math

from numba import njit

from .layout import (
    HIT_PLANE,
    HIT_SPHERE,
    LIGHT_AMBIENT,
    LIGHT_POINT,
    MAT_CHECK_A,
    MAT_CHECK_B,
    MAT_CHECK_SCALE,
    MAT_COLOR,
    MAT_SPECULAR,
    MAT_TEXTURE,
    MAT_TRANSPARENCY,
    MAT_ABSORPTION,
    TEXTURE_CHECKER,
)
from .traverse import any_hit, closest_hit
from .vec import FAST, add, cross, dot, length, madd, max_abs, mul, normalize, row3, sub
from .intersect import INF


@njit(fastmath=FAST)
def surface_at(S, kind, index, b1, b2, p):
    """(outward geometric normal, outward shading normal, material, object, prim) of a hit."""
    if kind == HIT_SPHERE:
        n = normalize(sub(p, row3(S.spheres, index, 0)))
        return n, n, S.sphere_material[index], S.sphere_object[index], 0
    if kind == HIT_PLANE:
        n = row3(S.planes, index, 3)
        return n, n, S.plane_material[index], S.plane_object[index], 0
    tri = S.triangles
    v0 = row3(tri, index, 0)
    ng = normalize(cross(sub(row3(tri, index, 3), v0), sub(row3(tri, index, 6), v0)))
    ns = ng
    if S.triangle_smooth[index]:
        b0 = 1.0 - b1 - b2
        nrm = S.triangle_normals
        s = add(add(mul(row3(nrm, index, 0), b0), mul(row3(nrm, index, 3), b1)), mul(row3(nrm, index, 6), b2))
        if dot(s, s) > 0.0:
            ns = normalize(s)
    return ng, ns, S.triangle_material[index], S.triangle_object[index], S.triangle_prim[index]


@njit(fastmath=FAST)
def albedo_at(S, m, p):
    """The material's colour at p: its plain colour or a world-space checkerboard."""
    mat = S.materials
    if mat[m, MAT_TEXTURE] == TEXTURE_CHECKER:
        inv = 1.0 / mat[m, MAT_CHECK_SCALE]
        # A tiny bias keeps a plane through a cell boundary (y = 0) inside one cell.
        parity = (math.floor(p[0] * inv + 1e-9) + math.floor(p[1] * inv + 1e-9) + math.floor(p[2] * inv + 1e-9)) % 2
        if parity == 0:
            return row3(mat, m, MAT_CHECK_A)
        return row3(mat, m, MAT_CHECK_B)
    return row3(mat, m, MAT_COLOR)


@njit(fastmath=FAST)
def ray_epsilon(S, p):
    """Offset for rays leaving a surface: scaled to the hit's magnitude, so no acne at any scale."""
    return 1e-7 * max(max_abs(p), S.epsilon_floor)


@njit(fastmath=FAST)
def shadow_transmittance(S, o, d, tmax, node_stack, t_stack):
    """Fraction (RGB) of light reaching o from distance tmax along d.

    Opaque scenes use the any-hit query. With transparent materials the ray walks from hit to
    hit: each transparent surface lets `transparency` through, and the path inside a medium
    (between entering and leaving it) is attenuated by exp(-absorption * length)."""
    if not S.has_transparency:
        if any_hit(S, o, d, 0.0, tmax, node_stack):
            return (0.0, 0.0, 0.0), 1
        return (1.0, 1.0, 1.0), 1
    tr = (1.0, 1.0, 1.0)
    origin = o
    remaining = tmax
    rays = 0
    for _ in range(32):
        t, kind, index, b1, b2 = closest_hit(S, origin, d, 0.0, remaining, node_stack, t_stack)
        rays += 1
        if t == INF or t >= remaining:
            return tr, rays
        p = madd(origin, d, t)
        ng, ns, m, obj, prim = surface_at(S, kind, index, b1, b2, p)
        transparency = S.materials[m, MAT_TRANSPARENCY]
        if transparency <= 0.0:
            return (0.0, 0.0, 0.0), rays
        tr = mul(tr, transparency)
        if dot(ng, d) > 0.0:  # leaving the medium: absorb along the segment inside it
            tr = (
                tr[0] * math.exp(-S.materials[m, MAT_ABSORPTION] * t),
                tr[1] * math.exp(-S.materials[m, MAT_ABSORPTION + 1] * t),
                tr[2] * math.exp(-S.materials[m, MAT_ABSORPTION + 2] * t),
            )
        if max(tr[0], tr[1], tr[2]) < 1e-4:
            return (0.0, 0.0, 0.0), rays
        eps = ray_epsilon(S, p)
        side = eps if dot(ng, d) > 0.0 else -eps
        origin = madd(p, ng, side)
        remaining -= t
    return (0.0, 0.0, 0.0), rays


@njit(fastmath=FAST)
def local_lighting(S, p, n, view, m, shadows, node_stack, t_stack):
    """The seed's ComputeLighting: ambient + diffuse + specular from each light, RGB.

    n faces the viewer; p is already offset off the surface. Returns (intensity, rays)."""
    specular = S.materials[m, MAT_SPECULAR]
    ir = 0.0
    ig = 0.0
    ib = 0.0
    rays = 0
    for k in range(S.light_kind.shape[0]):
        kind = S.light_kind[k]
        intensity = row3(S.light_data, k, 3)
        if kind == LIGHT_AMBIENT:
            ir += intensity[0]
            ig += intensity[1]
            ib += intensity[2]
            continue
        if kind == LIGHT_POINT:
            to_light = sub(row3(S.light_data, k, 0), p)
            tmax = length(to_light)
        else:
            to_light = row3(S.light_data, k, 0)
            tmax = INF
        l = normalize(to_light)
        n_dot_l = dot(n, l)
        if n_dot_l <= 0.0 and specular <= 0.0:
            continue  # faces away and has no highlight: the seed adds nothing, skip the ray
        scale = 0.0
        if n_dot_l > 0.0:
            scale = n_dot_l
        if specular > 0.0:
            r = sub(mul(n, 2.0 * n_dot_l), l)
            r_dot_v = dot(r, view)
            if r_dot_v > 0.0:
                scale += (r_dot_v / (length(r) * length(view))) ** specular
        if scale <= 0.0:
            continue
        if shadows:
            tr, used = shadow_transmittance(S, p, l, tmax, node_stack, t_stack)
            rays += used
        else:
            tr = (1.0, 1.0, 1.0)
        ir += intensity[0] * scale * tr[0]
        ig += intensity[1] * scale * tr[1]
        ib += intensity[2] * scale * tr[2]
    return (ir, ig, ib), rays
