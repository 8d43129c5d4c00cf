"""Triangles, alone or from meshes: float32 vertices (T, 9) in BVH leaf order, optional
vertex normals (smooth shading) and UVs. The watertight ray-triangle test of Woop, Benthin
and Wald (2013)."""

import math

from numba import njit

from .vec import KERNEL, add, cross, dot, mul, normalize, row3, sub

INF = math.inf
BOUNDED = True


@njit(**KERNEL)
def ray_shear(d):
    """Per-ray constants of the watertight test."""
    ax, ay, az = abs(d[0]), abs(d[1]), abs(d[2])
    kz = 0
    if ay > ax and ay >= az:
        kz = 1
    elif az > ax and az > ay:
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    if d[kz] < 0.0:
        kx, ky = ky, kx
    sz = 1.0 / d[kz]
    return kx, ky, kz, d[kx] * sz, d[ky] * sz, sz


# Shear constants for rays in scenes without triangles (never used, but typed alike).
NO_SHEAR = (0, 1, 2, 0.0, 0.0, 1.0)


# No fastmath here: contracting a*b - c*d into a fused multiply-add would make the edge
# functions of two triangles sharing an edge differ, and rays through the edge could slip by.
@njit(error_model="numpy", _nrt=False)
def intersect_triangle(o, shear, tri, i, tmin, tmax):
    """Watertight ray-triangle test against row i of tri (float32 (T, 9): v0, v1, v2).

    Returns (t, b1, b2): b1, b2 are the barycentric weights of v1 and v2. Edges shared by two
    triangles are evaluated identically from both sides, so closed meshes have no pinholes."""
    kx, ky, kz, sx, sy, sz = shear
    ax = tri[i, kx] - o[kx]
    ay = tri[i, ky] - o[ky]
    az = tri[i, kz] - o[kz]
    bx = tri[i, 3 + kx] - o[kx]
    by = tri[i, 3 + ky] - o[ky]
    bz = tri[i, 3 + kz] - o[kz]
    cx = tri[i, 6 + kx] - o[kx]
    cy = tri[i, 6 + ky] - o[ky]
    cz = tri[i, 6 + kz] - o[kz]
    ax -= sx * az
    ay -= sy * az
    bx -= sx * bz
    by -= sy * bz
    cx -= sx * cz
    cy -= sy * cz
    u = cx * by - cy * bx
    v = ax * cy - ay * cx
    w = bx * ay - by * ax
    # Edge functions within a hair of zero count as inside: inlined into fast-math callers,
    # Numba/LLVM may evaluate the two triangles sharing an edge with different roundings, and a
    # ray exactly through the edge must still hit at least one of them (no pinholes).
    tol = 1e-12 * (abs(u) + abs(v) + abs(w))
    if (u < -tol or v < -tol or w < -tol) and (u > tol or v > tol or w > tol):
        return INF, 0.0, 0.0
    det = u + v + w
    if det == 0.0:
        return INF, 0.0, 0.0
    t = (u * az + v * bz + w * cz) * sz / det
    if t > tmin and t < tmax:
        return t, min(max(v / det, 0.0), 1.0), min(max(w / det, 0.0), 1.0)
    return INF, 0.0, 0.0


@njit(**KERNEL, inline="always")
def normals(G, i, b1, b2):
    """(geometric normal, shading normal) of triangle i at barycentrics (b1, b2): the face
    normal by the winding (v1 - v0) x (v2 - v0), and the interpolated vertex normals when
    the mesh is smooth."""
    tri = G.triangles
    v0 = row3(tri, i, 0)
    ng = normalize(cross(sub(row3(tri, i, 3), v0), sub(row3(tri, i, 6), v0)))
    ns = ng
    if G.triangle_smooth[i]:
        b0 = 1.0 - b1 - b2
        nrm = G.triangle_normals
        s = add(add(mul(row3(nrm, i, 0), b0), mul(row3(nrm, i, 3), b1)), mul(row3(nrm, i, 6), b2))
        if dot(s, s) > 0.0:
            ns = normalize(s)
    return ng, ns


@njit(**KERNEL)
def uv(G, i, b1, b2):
    """The mesh's UVs interpolated; without UVs (and for a `triangle` object) the vertices sit
    at (0, 0), (1, 0), (0, 1)."""
    uvs = G.triangle_uvs
    if uvs.shape[0] <= i:
        return b1, b2
    b0 = 1.0 - b1 - b2
    return (b0 * uvs[i, 0] + b1 * uvs[i, 2] + b2 * uvs[i, 4], b0 * uvs[i, 1] + b1 * uvs[i, 3] + b2 * uvs[i, 5])


@njit(**KERNEL)
def uv_change(G, i, a):
    """Change of the triangle's (u, v) along the vector a in its plane (texture filtering):
    a = e1 db1 + e2 db2 solved for the barycentric change by least squares."""
    tri = G.triangles
    v0 = row3(tri, i, 0)
    e1 = sub(row3(tri, i, 3), v0)
    e2 = sub(row3(tri, i, 6), v0)
    a11 = dot(e1, e1)
    a12 = dot(e1, e2)
    a22 = dot(e2, e2)
    det = a11 * a22 - a12 * a12
    if not (det > 0.0):  # degenerate: never hit, but no division by zero either
        return 0.0, 0.0
    r1 = dot(a, e1)
    r2 = dot(a, e2)
    db1 = (a22 * r1 - a12 * r2) / det
    db2 = (a11 * r2 - a12 * r1) / det
    uvs = G.triangle_uvs
    if uvs.shape[0] <= i:
        return db1, db2
    return (
        db1 * (uvs[i, 2] - uvs[i, 0]) + db2 * (uvs[i, 4] - uvs[i, 0]),
        db1 * (uvs[i, 3] - uvs[i, 1]) + db2 * (uvs[i, 5] - uvs[i, 1]),
    )


# --- emission (path mode samples emissive triangles) -------------------------------------------


@njit(**KERNEL)
def sample(G, i, u1, u2):
    """A uniform point on triangle i for (u1, u2) in [0, 1)^2, and its face normal."""
    tri = G.triangles
    s = math.sqrt(u1)
    v0 = row3(tri, i, 0)
    e1 = sub(row3(tri, i, 3), v0)
    e2 = sub(row3(tri, i, 6), v0)
    return add(add(v0, mul(e1, 1.0 - s)), mul(e2, u2 * s)), normalize(cross(e1, e2))


def area(triangles):
    """One side's area of each of (T, 9) triangles."""
    import numpy as np

    v = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
