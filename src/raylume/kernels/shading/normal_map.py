"""Normal and bump maps: a material's texture turning the shading normal at a hit.

Both need the surface's UV directions dp/du and dp/dv at the hit. They come from the UVs'
changes along two tangent vectors (shapes.uv_differentials: exact on triangles, finite
differences elsewhere), so every shape that has UVs takes a map. A surface without UVs (a mesh
without them), where the UVs do not change, keeps its normal.

Normal map: the texel (r, g, b), read as stored (compile/materials.py does not sRGB-decode
it), is the normal (2r - 1, 2g - 1, 2b - 1) in the frame (T, B, N): N the shading normal, T the
direction of increasing u in the plane of N, and B = N x T, turned to the side of increasing v
(so that a mirrored UV layout keeps its bumps, as MikkTSpace's bitangent sign does). With the
UVs' usual orientation this is pbrt-v4's and Mitsuba 3's frame (x along dp/du, y = n x x), and
glTF's. The map's x and y are multiplied by the material's strength before the normal is
normalised; a texel whose normal would point into the surface leaves it as it is.

Bump map (pbrt-v4's BumpMap, Mitsuba 3's bumpmap): the surface displaced along N by h(u, v)
times the material's height, h the texel's value (the mean of r, g and b, as stored). The
displaced surface's dp/du is dp/du + dh/du height N (the change of N itself left out, as small
against it), likewise for v, with dh/du and dh/dv by forward differences of one texel; its
normal, cross(dp/du', dp/dv') turned to N's side, is the shading normal.

Both look up their map bilinearly at full size, as pbrt-v4 reads them.
"""

import math

import numpy as np

from ..geometry.shapes import offset_epsilon, uv, uv_differentials
from ..vec import cross, dot, inline_function, kernel_function, madd, mul, normalize, sub
from .materials import MAT_BUMP_HEIGHT, MAT_BUMP_MAP, MAT_NORMAL_MAP, MAT_NORMAL_STRENGTH
from .textures import TEX_HEIGHT_PX, TEX_SCALE_U, TEX_SCALE_V, TEX_WIDTH_PX, full_size_lookup

# tangent steps for the UVs' finite differences, in offsets (1e-7 of the hit's magnitude):
# short against any shape's curvature, long against float64's rounding of the UVs
STEP_OFFSETS = 64.0


@inline_function
def mapped_normal(G, F, X, m, prim, b1, b2, p, ns):
    """The shading normal ns (unit, outward) at a hit on primitive `prim` of material m, turned
    by the material's normal or bump map; ns itself where it has neither. Basic scenes (X None)
    have no image textures, so no maps: their kernels (trace mode's wavefront among them)
    compile none of it."""
    if X is None:
        return ns
    x = np.int64(F.materials[m, MAT_NORMAL_MAP]) - 1
    if x >= 0:
        return _normal_mapped(G, F, X, x, F.materials[m, MAT_NORMAL_STRENGTH], np.int64(prim), b1, b2, p, ns)
    x = np.int64(F.materials[m, MAT_BUMP_MAP]) - 1
    if x >= 0:
        return _bump_mapped(G, F, X, x, F.materials[m, MAT_BUMP_HEIGHT], np.int64(prim), b1, b2, p, ns)
    return ns


@inline_function
def has_map(materials, m):
    """Whether material m turns its normals by a map (it then needs the hit's UVs)."""
    return materials[m, MAT_NORMAL_MAP] > 0.0 or materials[m, MAT_BUMP_MAP] > 0.0


@inline_function
def _uv_directions(G, F, X, k, b1, b2, p, n):
    """(u, v, dp/du, dp/dv, found) at the hit: found False where the UVs do not change."""
    u, v = uv(G, X, k, b1, b2, p)
    # two tangent vectors a1, a2 and the UVs' changes along them give dp/du and dp/dv
    helper = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)
    h = STEP_OFFSETS * offset_epsilon(F.epsilon_floor, p)
    a1 = mul(normalize(cross(n, helper)), h)
    a2 = mul(normalize(cross(n, a1)), h)
    du1, dv1, du2, dv2 = uv_differentials(G, X, k, b1, b2, p, u, v, a1, a2)
    det = du1 * dv2 - du2 * dv1
    if not (abs(det) > 0.0) or not math.isfinite(det):
        return u, v, a1, a2, False
    dpdu = mul(sub(mul(a1, dv2), mul(a2, dv1)), 1.0 / det)
    dpdv = mul(sub(mul(a2, du1), mul(a1, du2)), 1.0 / det)
    return u, v, dpdu, dpdv, True


@kernel_function
def _normal_mapped(G, F, X, x, strength, k, b1, b2, p, n):
    u, v, dpdu, dpdv, found = _uv_directions(G, F, X, k, b1, b2, p, n)
    if not found:
        return n
    t = normalize(sub(dpdu, mul(n, dot(n, dpdu))))
    if t[0] == 0.0 and t[1] == 0.0 and t[2] == 0.0:
        return n
    b = cross(n, t)
    if dot(b, dpdv) < 0.0:
        b = mul(b, -1.0)
    c = full_size_lookup(F, x, u, v)
    nx = (2.0 * c[0] - 1.0) * strength
    ny = (2.0 * c[1] - 1.0) * strength
    nz = 2.0 * c[2] - 1.0
    turned = normalize(
        (
            t[0] * nx + b[0] * ny + n[0] * nz,
            t[1] * nx + b[1] * ny + n[1] * nz,
            t[2] * nx + b[2] * ny + n[2] * nz,
        )
    )
    if not (dot(turned, n) > 0.0):  # into the surface (or zero): no shading frame from it
        return n
    return turned


@kernel_function
def _bump_mapped(G, F, X, x, height, k, b1, b2, p, n):
    u, v, dpdu, dpdv, found = _uv_directions(G, F, X, k, b1, b2, p, n)
    if not found:
        return n
    tex = F.textures
    # one texel of the map's full-size level, in the surface's (unscaled) u and v
    du = 1.0 / (tex[x, TEX_WIDTH_PX] * tex[x, TEX_SCALE_U])
    dv = 1.0 / (tex[x, TEX_HEIGHT_PX] * tex[x, TEX_SCALE_V])
    c = full_size_lookup(F, x, u, v)
    cu = full_size_lookup(F, x, u + du, v)
    cv = full_size_lookup(F, x, u, v + dv)
    h = (c[0] + c[1] + c[2]) / 3.0
    dh_du = ((cu[0] + cu[1] + cu[2]) / 3.0 - h) / du
    dh_dv = ((cv[0] + cv[1] + cv[2]) / 3.0 - h) / dv
    turned = normalize(cross(madd(dpdu, n, dh_du * height), madd(dpdv, n, dh_dv * height)))
    side = dot(turned, n)
    if not (side != 0.0) or not math.isfinite(side):
        return n
    return turned if side > 0.0 else mul(turned, -1.0)
