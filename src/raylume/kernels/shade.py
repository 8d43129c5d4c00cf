"""Surface description at a hit, textures, and the seed's local lighting (ambient, diffuse,
Phong) from point, directional and area lights.

The lean functions take the scene's views (Geometry G, Surfaces F, Lights L; see scene.py).
`surface_at`, `albedo_at` and `local_lighting` take the whole KernelScene, for callers outside
the hot ray loops.

Area lights (quad, sphere) are the seed's point light spread over a shape: their contribution
is the average, over `samples` stratified points on the shape, of a point light of the same
intensity at that point (diffuse and Phong terms, shadow ray to the point). A small area light
therefore looks like the point light at its centre, and a large one casts soft shadows. A
sphere light is sampled on its disk facing the shading point (its silhouette as seen from
afar). Lights are not geometry: camera rays and reflections do not see them.
"""

import math

import numpy as np
from numba import njit

from .intersect import INF
from .layout import (
    HIT_PLANE,
    HIT_SPHERE,
    LIGHT_AMBIENT,
    LIGHT_DIRECTIONAL,
    LIGHT_POINT,
    LIGHT_QUAD,
    LIGHT_RADIUS,
    LIGHT_SAMPLES,
    LIGHT_U,
    LIGHT_V,
    MAT_ABSORPTION,
    MAT_CHECK_A,
    MAT_CHECK_B,
    MAT_CHECK_SCALE,
    MAT_COLOR,
    MAT_SPECULAR,
    MAT_TEX_HEIGHT,
    MAT_TEX_OFFSET,
    MAT_TEX_SCALE_U,
    MAT_TEX_SCALE_V,
    MAT_TEX_WIDTH,
    MAT_TEXTURE,
    MAT_TRANSPARENCY,
    TEXTURE_CHECKER,
    TEXTURE_IMAGE,
)
from .sampling import concentric_disk, event_key, stratified_key, sub_key
from .scene import geometry_of, lights_of, surfaces_of
from .traverse import any_hit, closest_hit
from .vec import KERNEL, add, cross, dot, length, madd, max_abs, mul, normalize, row3, sub

# Shadow rays towards a point on an area light stop this fraction short of it, so a light
# placed on a surface (a lamp on a ceiling) is not shadowed by that surface.
AREA_SHADOW_SHORTEN = 1e-6


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
    """The material's colour at p: its plain colour or a world-space checkerboard. (An image
    texture needs UVs, see `surface_albedo`; here it gives the texture's mean colour.)"""
    if materials[m, MAT_TEXTURE] == TEXTURE_CHECKER:
        inv = 1.0 / materials[m, MAT_CHECK_SCALE]
        # A tiny bias keeps a plane through a cell boundary (y = 0) inside one cell.
        parity = (math.floor(p[0] * inv + 1e-9) + math.floor(p[1] * inv + 1e-9) + math.floor(p[2] * inv + 1e-9)) % 2
        if parity == 0:
            return row3(materials, m, MAT_CHECK_A)
        return row3(materials, m, MAT_CHECK_B)
    if materials[m, MAT_TEXTURE] == TEXTURE_IMAGE:
        return row3(materials, m, MAT_CHECK_A)
    return row3(materials, m, MAT_COLOR)


@njit(**KERNEL, inline="always")
def surface_albedo(G, F, kind, index, b1, b2, p, m):
    """The material's colour at a hit, image textures included (they need the hit's UVs)."""
    mat = F.materials
    if mat[m, MAT_TEXTURE] == TEXTURE_IMAGE:
        # explicit int64: call sites after inlined traversal may type kind/index as literals,
        # which would compile surface_uv once per literal
        u, v = surface_uv(G, F, np.int64(kind), np.int64(index), b1, b2, p)
        return texture_lookup(F.textures, int(mat[m, MAT_TEX_OFFSET]), int(mat[m, MAT_TEX_WIDTH]),
                              int(mat[m, MAT_TEX_HEIGHT]), u * mat[m, MAT_TEX_SCALE_U], v * mat[m, MAT_TEX_SCALE_V])
    return albedo(mat, m, p)


@njit(**KERNEL)
def surface_uv(G, F, kind, index, b1, b2, p):
    """Texture coordinates of a hit.

    Spheres: u = 0.5 + atan2(n.x, -n.z) / 2pi (0.5 faces -z, the default camera; the seam is
    at the back, +z), v = 0.5 + asin(n.y) / pi (0 at the south pole, 1 at the north).
    Planes: world units along two axes of the plane (right and up of a wall facing -z; x and
    z on a floor). Triangles: the mesh's UVs interpolated; a `triangle` object has (0, 0),
    (1, 0), (0, 1) at its vertices."""
    if kind == HIT_SPHERE:
        n = normalize(sub(p, row3(G.spheres, index, 0)))
        u = 0.5 + math.atan2(n[0], -n[2]) * (0.5 / math.pi)
        v = 0.5 + math.asin(min(1.0, max(-1.0, n[1]))) / math.pi
        return u, v
    if kind == HIT_PLANE:
        n = row3(G.planes, index, 3)
        hint = (0.0, 0.0, 1.0) if abs(n[1]) > 0.999 else (0.0, 1.0, 0.0)
        t1 = normalize(cross(n, hint))
        t2 = cross(t1, n)
        rel = sub(p, row3(G.planes, index, 0))
        return dot(rel, t1), dot(rel, t2)
    uv = F.triangle_uvs
    if uv.shape[0] <= index:
        return b1, b2
    b0 = 1.0 - b1 - b2
    return (b0 * uv[index, 0] + b1 * uv[index, 2] + b2 * uv[index, 4],
            b0 * uv[index, 1] + b1 * uv[index, 3] + b2 * uv[index, 5])


@njit(**KERNEL)
def texture_lookup(textures, offset, width, height, u, v):
    """Bilinear lookup of an image texture at (u, v), wrapping (repeating) in both directions.

    The image's top row is v = 1 and its left column u = 0 (OBJ/glTF convention); texel
    (x, y), y counted from the top, has its centre at ((x + 0.5) / width, 1 - (y + 0.5) / height)
    and there the lookup returns exactly that texel."""
    if not (u == u and v == v):  # NaN
        u = 0.0
        v = 0.0
    u -= math.floor(u)
    v -= math.floor(v)
    fx = u * width - 0.5
    fy = (1.0 - v) * height - 0.5
    x0f = math.floor(fx)
    y0f = math.floor(fy)
    tx = fx - x0f
    ty = fy - y0f
    x0 = int(x0f) % width
    y0 = int(y0f) % height
    x1 = (x0 + 1) % width
    y1 = (y0 + 1) % height
    top = offset + y0 * width
    bottom = offset + y1 * width
    w00 = (1.0 - tx) * (1.0 - ty)
    w10 = tx * (1.0 - ty)
    w01 = (1.0 - tx) * ty
    w11 = tx * ty
    t = textures
    return (
        t[top + x0, 0] * w00 + t[top + x1, 0] * w10 + t[bottom + x0, 0] * w01 + t[bottom + x1, 0] * w11,
        t[top + x0, 1] * w00 + t[top + x1, 1] * w10 + t[bottom + x0, 1] * w01 + t[bottom + x1, 1] * w11,
        t[top + x0, 2] * w00 + t[top + x1, 2] * w10 + t[bottom + x0, 2] * w01 + t[bottom + x1, 2] * w11,
    )


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
    return _transparent_shadow(G, F, o, d, tmax, node_stack, t_stack)


# A call, not inlined: a walk through transparent surfaces costs several traversals anyway, and
# one more inlined copy of the traversal costs seconds of compile time in every trace kernel.
@njit(**KERNEL)
def _transparent_shadow(G, F, o, d, tmax, node_stack, t_stack):
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
def _phong(n, l, view, specular):
    """The seed's diffuse + specular factor for the unit direction l towards a light (n and
    view unit too)."""
    n_dot_l = dot(n, l)
    scale = max(n_dot_l, 0.0)
    if specular > 0.0:
        # the seed adds the highlight whatever the sign of N.L (R and V decide)
        r = sub(mul(n, 2.0 * n_dot_l), l)
        cos_rv = dot(r, view)  # the seed divides by |R| |V|: both are 1 here
        if cos_rv > 0.0:
            # Below 1 - 50/s the highlight is under e^-50 (about 2e-22): skip the power, whose
            # result would otherwise often be a slow subnormal number.
            if cos_rv > 1.0 - 50.0 / specular:
                scale += cos_rv ** specular
    return scale


@njit(**KERNEL, inline="always")
def lighting(G, F, L, p, n, view, m, shadows, node_stack, t_stack):
    """The seed's ComputeLighting (see `sampled_lighting`), with area lights sampled by a fixed
    pattern: for callers without a per-sample random key."""
    return sampled_lighting(G, F, L, p, n, view, m, shadows, node_stack, t_stack, np.uint64(0), 0)


@njit(**KERNEL, inline="always")
def sampled_lighting(G, F, L, p, n, view, m, shadows, node_stack, t_stack, key, event):
    """The seed's ComputeLighting: ambient + diffuse + specular from each light, RGB.

    n faces the viewer; p is already offset off the surface. Area lights take their light's
    `samples` stratified points, jittered by hashes of the camera sample's `key` and `event`
    (a counter along its path, e.g. the rays traced so far). Returns (intensity, rays)."""
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
        # Point and directional lights take one sample, area lights `samples`, all through one
        # shadow-ray call site (each inlined copy of the traversal costs seconds of JIT time).
        # The area lights' state lives in `area_light_point` and is recomputed per sample, so
        # that the point-light path keeps its registers (live values across the shadow ray
        # slow the traversal) and gives the seed's results bit for bit.
        remaining = 1 if kind == LIGHT_POINT or kind == LIGHT_DIRECTIONAL else int(L.data[k, LIGHT_SAMPLES])
        while remaining > 0:
            remaining -= 1
            if kind == LIGHT_POINT:
                to_light = sub(row3(L.data, k, 0), p)
                tmax = length(to_light)
            elif kind == LIGHT_DIRECTIONAL:
                to_light = row3(L.data, k, 0)
                tmax = INF
            else:
                to_light, tmax = area_light_point(L, k, p, key, event, remaining)
            l = normalize(to_light)
            scale = _phong(n, l, view, specular)
            if scale <= 0.0:
                continue  # nothing to add: skip the shadow ray
            if shadows:
                tr, used = shadow_transmittance(G, F, p, l, tmax, node_stack, t_stack)
                rays += used
            else:
                tr = (1.0, 1.0, 1.0)
            if kind == LIGHT_POINT or kind == LIGHT_DIRECTIONAL:
                ir += intensity[0] * scale * tr[0]
                ig += intensity[1] * scale * tr[1]
                ib += intensity[2] * scale * tr[2]
            else:
                weight = scale / L.data[k, LIGHT_SAMPLES]
                ir += intensity[0] * weight * tr[0]
                ig += intensity[1] * weight * tr[1]
                ib += intensity[2] * weight * tr[2]
    return (ir, ig, ib), rays


@njit(**KERNEL)
def area_light_point(L, k, p, key, event, s):
    """Sample s of area light k (of its `samples`) for the shading event `event` of the camera
    sample `key`, as seen from p: (vector from p to the point, shadow ray length). Quads are
    sampled uniformly over their area, spheres over their disk facing p, at stratified points
    jittered by hashes of (key, event, k, s)."""
    count = int(L.data[k, LIGHT_SAMPLES])
    u1, u2 = stratified_key(sub_key(event_key(key, event), k), s, count)
    centre = row3(L.data, k, 0)
    if L.kind[k] == LIGHT_QUAD:
        q = madd(madd(centre, row3(L.data, k, LIGHT_U), u1 - 0.5), row3(L.data, k, LIGHT_V), u2 - 0.5)
    else:
        e1, e2 = _basis(normalize(sub(centre, p)))
        a, b = concentric_disk(u1, u2)
        r = L.data[k, LIGHT_RADIUS]
        q = madd(madd(centre, e1, a * r), e2, b * r)
    to_light = sub(q, p)
    return to_light, length(to_light) * (1.0 - AREA_SHADOW_SHORTEN)


@njit(**KERNEL)
def _basis(w):
    """Two unit vectors completing the unit w to an orthonormal basis (Duff et al. 2017)."""
    sign = 1.0 if w[2] >= 0.0 else -1.0
    a = -1.0 / (sign + w[2])
    b = w[0] * w[1] * a
    return (1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]), (b, sign + w[1] * w[1] * a, -w[1])


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
