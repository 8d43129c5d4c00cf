"""Z-buffer rasterization of triangles: binning, scan conversion, deferred shading.

How a triangle is scan-converted
--------------------------------
Each vertex is mapped by one linear map of ``v = X - O`` (camera origin O) to homogeneous
screen coordinates ``h = (xs * w, ys * w, w)``: ``w`` is the camera depth ``z = dot(v, F)``
and ``(xs, ys)`` the pixel position of the point (column, row, pixel centres at +0.5) with
the camera of DESIGN.md. For a triangle with homogeneous vertices h0, h1, h2 the three
*edge functions* ``E_k(p) = (h_i x h_j) . (x, y, 1)`` ((i, j, k) a rotation of (0, 1, 2))
are affine in the pixel position, and (2D homogeneous rasterization, Olano and Greer 1997)

* ``lambda_k = E_k / det`` (``det = h0 . (h1 x h2)``) are the barycentric weights of the
  triangle point seen through the pixel, each divided by its depth z, so
* ``1 / z = sum_k lambda_k`` -- depth, interpolated perspective-correctly, straight from
  the screen-space edge functions (``1/z`` is affine in screen space), and
* ``b_k = lambda_k * z = E_k / sum(E)`` are the perspective-correct barycentrics of the
  original triangle (used for smooth normals), and
* the pixel centre is covered exactly when all ``lambda_k >= 0``: then ``1/z > 0`` and the
  point is inside -- the very condition under which the ray through the pixel centre hits
  the triangle in front of the camera. Parts of a triangle behind the camera are never
  covered, whatever its vertices' depths.

Near plane: a triangle is clipped against ``z = near`` (Sutherland-Hodgman, at most a
quadrilateral) to find its screen bounding box, the range of rows and columns it may cover
(vertices behind the camera have no screen position, so the box needs the clipped polygon).
Inside that box the clip edge is the fourth edge function ``1/z <= 1/near``. The near
distance is tiny (``raster.py``: 1e-30 of the scene's extent), as the ray caster sees
everything at t > 0: homogeneous edge functions never divide by z, and 1/z is kept in
float64, so a tiny near plane costs no precision (the depth buffer of a GPU would).

Fill rule and watertightness: a pixel centre exactly on an edge (``E_k == 0``) belongs to
the triangle only when that edge is a *top* or *left* edge (its inward normal points right,
or exactly down when horizontal). The edge coefficients ``h_i x h_j`` are computed with the
two vertices in a canonical (lexicographic) order and negated when swapped, so the two
triangles sharing an edge get exactly opposite coefficients and exactly opposite edge
values at every pixel centre (IEEE negation is exact, rounding is symmetric); exactly one
of them covers each pixel centre on the shared edge, none covers it twice, and no centre is
left uncovered. This needs bit-identical arithmetic wherever a shared vertex or edge is
evaluated, so these kernels run without the 'contract' (FMA fusing) and 'arcp' fast-math
flags, whose use may differ between two copies of the same expression.

Parallelism and determinism: the screen is cut into bands of BAND_ROWS rows. Triangles are
binned to the bands their boxes overlap (count, prefix sum, fill: O(T + entries)), each
band's list in ascending triangle order; then every band is rasterized by one thread,
which owns that band's part of the Z-buffer, so there are no races. Within a band the
triangles are drawn in index order and a fragment replaces the stored one only when
strictly nearer, so at equal depth the lower triangle index wins: the image does not depend
on the number of threads. Shading is deferred: the Z-buffer keeps 1/z and the triangle
index, and a last pass shades each visible pixel once with the ray tracer's own `surface`,
the material's `albedo` (image textures included) and `unshadowed_lighting` (direct.py: no
shadows, reflection or refraction).
"""

import math
import threading
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange

from ..film.camera import CAM_CONE_SPREAD, CAM_FORWARD, CAM_POSITION, CAM_RIGHT, CAM_UP, obliquity
from ..film.image_pass import Aovs
from ..geometry.shapes import PRIM_MATERIAL, surface
from ..geometry.wide_nodes import traversal_stacks
from ..integrators.direct import unshadowed_lighting
from ..scene import environment_of, geometry_of, lights_of, surfaces_of
from ..shading.environment import environment_radiance
from ..shading.materials import MAT_EMISSION, MAT_TEXTURE, albedo, aov_albedo
from ..shading.normal_map import has_map, mapped_normal
from ..shading.textures import IMAGE, TEX_KIND
from ..variants import path_features
from ..vec import add, dot, hadamard, kernel_function, madd, mul, normalize, row3

# Helpers that take arrays are inlined (forceinline: LLVM's alwaysinline): a call that passes
# array descriptors by value costs more than the helper's work (26 ns a triangle, measured).
# Fast-math flags of the raster kernels: no 'nnan'/'ninf' (inf is meaningful), and no
# 'contract'/'arcp', so that shared vertices and edges are evaluated bit-identically.
RFAST = {"nsz", "afn"}

BAND_ROWS = 8  # rows per screen band: the unit of parallel work and of binning
N_CHUNKS = 256  # triangle chunks for binning; fixed, so the band lists never depend on threads


@kernel_function(fastmath=RFAST, error_model="numpy", forceinline=True)
def _vertex(tri, extra, n_main, t, k):
    """Vertex k of triangle t: rows below n_main are in `tri` (float32), the rest in `extra`."""
    if t < n_main:
        return (float(tri[t, 3 * k]), float(tri[t, 3 * k + 1]), float(tri[t, 3 * k + 2]))
    e = t - n_main
    return (extra[e, 3 * k], extra[e, 3 * k + 1], extra[e, 3 * k + 2])


@kernel_function(fastmath=RFAST, error_model="numpy")
def _project(view, p):
    """Homogeneous screen coordinates (x * w, y * w, w) of the world point p."""
    vx = p[0] - view[0, 0]
    vy = p[1] - view[0, 1]
    vz = p[2] - view[0, 2]
    return (
        view[1, 0] * vx + view[1, 1] * vy + view[1, 2] * vz,
        view[2, 0] * vx + view[2, 1] * vy + view[2, 2] * vz,
        view[3, 0] * vx + view[3, 1] * vy + view[3, 2] * vz,
    )


@kernel_function(fastmath=RFAST, error_model="numpy", forceinline=True)
def _homogeneous(view, tri, extra, n_main, t):
    return (
        _project(view, _vertex(tri, extra, n_main, t, 0)),
        _project(view, _vertex(tri, extra, n_main, t, 1)),
        _project(view, _vertex(tri, extra, n_main, t, 2)),
    )


@kernel_function(fastmath=RFAST, error_model="numpy")
def _before(a, b):
    """Lexicographic order of two homogeneous vertices (branch-free: the order is random)."""
    return (a[0] < b[0]) | ((a[0] == b[0]) & ((a[1] < b[1]) | ((a[1] == b[1]) & (a[2] < b[2]))))


@kernel_function(fastmath=RFAST, error_model="numpy")
def _edge(hi, hj):
    """Coefficients of E(x, y) = c0 x + c1 y + c2 = (hi x hj) . (x, y, 1), evaluated in a
    canonical vertex order so that the reversed edge gives exactly the negated values."""
    swap = _before(hj, hi)
    a0 = hj[0] if swap else hi[0]
    a1 = hj[1] if swap else hi[1]
    a2 = hj[2] if swap else hi[2]
    b0 = hi[0] if swap else hj[0]
    b1 = hi[1] if swap else hj[1]
    b2 = hi[2] if swap else hj[2]
    sign = -1.0 if swap else 1.0  # multiplying by -1 is an exact negation
    return ((a1 * b2 - a2 * b1) * sign, (a2 * b0 - a0 * b2) * sign, (a0 * b1 - a1 * b0) * sign)


@kernel_function(fastmath=RFAST, error_model="numpy")
def _setup(h0, h1, h2):
    """Edge functions oriented so that the inside is E >= 0, and 1/|det| (0: degenerate).

    Returns (e0, e1, e2, inv_det); E_k is opposite vertex k (its weight lambda_k * det)."""
    e0 = _edge(h1, h2)
    e1 = _edge(h2, h0)
    e2 = _edge(h0, h1)
    det = h0[0] * e0[0] + h0[1] * e0[1] + h0[2] * e0[2]
    if not (det != 0.0 and abs(det) < math.inf):
        return e0, e1, e2, 0.0
    if det < 0.0:
        e0 = (-e0[0], -e0[1], -e0[2])
        e1 = (-e1[0], -e1[1], -e1[2])
        e2 = (-e2[0], -e2[1], -e2[2])
    return e0, e1, e2, 1.0 / abs(det)


@kernel_function(fastmath=RFAST, error_model="numpy")
def _top_left(e):
    """Does a pixel centre exactly on this (inward-oriented) edge belong to the triangle?
    Left edges (inward normal points right, +x) and top edges (horizontal, inward normal
    points down the image, +y) do."""
    return e[0] > 0.0 or (e[0] == 0.0 and e[1] > 0.0)


@kernel_function(fastmath=RFAST, error_model="numpy")
def _extend(box, h):
    """Extend box (xmin, xmax, ymin, ymax) by the projection of h (w >= near > 0), clamped
    to +-1e30 pixels (a clipped vertex at a tiny near distance may project to infinity)."""
    x = min(max(h[0] / h[2], -1e30), 1e30)
    y = min(max(h[1] / h[2], -1e30), 1e30)
    return (min(box[0], x), max(box[1], x), min(box[2], y), max(box[3], y))


@kernel_function(fastmath=RFAST, error_model="numpy")
def _screen_box(h0, h1, h2, near):
    """Screen bounding box of the triangle clipped to w >= near: (xmin, xmax, ymin, ymax),
    empty (xmin > xmax) when the whole triangle lies behind the near plane."""
    if h0[2] >= near and h1[2] >= near and h2[2] >= near:  # the common case: nothing to clip
        r0 = 1.0 / h0[2]
        r1 = 1.0 / h1[2]
        r2 = 1.0 / h2[2]
        x0, x1, x2 = h0[0] * r0, h1[0] * r1, h2[0] * r2
        y0, y1, y2 = h0[1] * r0, h1[1] * r1, h2[1] * r2
        return (
            max(min(x0, x1, x2), -1e30),
            min(max(x0, x1, x2), 1e30),
            max(min(y0, y1, y2), -1e30),
            min(max(y0, y1, y2), 1e30),
        )
    box = (math.inf, -math.inf, math.inf, -math.inf)
    for k in range(3):
        if k == 0:
            a, b = h0, h1
        elif k == 1:
            a, b = h1, h2
        else:
            a, b = h2, h0
        a_in = a[2] >= near
        if a_in:
            box = _extend(box, a)
        if a_in != (b[2] >= near):
            s = (near - a[2]) / (b[2] - a[2])
            q = (a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s, near)
            box = _extend(box, q)
    return box


@kernel_function(fastmath=RFAST, error_model="numpy")
def _pixel_range(lo, hi, n):
    """Indices i in [0, n) whose centres i + 0.5 may lie in [lo, hi] (finite), conservatively
    widened against rounding in the division by w; first > last when there are none.
    Branch-free: whether a tiny triangle's box holds a pixel centre is a coin toss."""
    tol = 1e-7 * (1.0 + max(abs(lo), abs(hi)))
    a = min(max(lo - 0.5 - tol, 0.0), float(n))
    b = max(min(hi - 0.5 + tol, n - 1.0), -1.0) + 1.0  # in [0, n]: truncation is floor
    first = int(a)
    first += int(first < a)
    return first, int(b) - 1


@kernel_function(fastmath=RFAST, error_model="numpy", forceinline=True)
def triangle_bounds(view, near, width, height, tri, extra, n_main, t):
    """(i0, i1, j0, j1): columns and rows of pixel centres triangle t may cover; i0 > i1 or
    j0 > j1 when it covers none (behind the camera, off screen, or between pixel centres)."""
    h0, h1, h2 = _homogeneous(view, tri, extra, n_main, t)
    box = _screen_box(h0, h1, h2, near)
    if not (box[0] <= box[1]):
        return 1, 0, 1, 0  # entirely behind the near plane
    i0, i1 = _pixel_range(box[0], box[1], width)
    j0, j1 = _pixel_range(box[2], box[3], height)
    return i0, i1, j0, j1


@kernel_function(fastmath=RFAST, error_model="numpy", forceinline=True)
def _draw(view, near, tri, extra, n_main, t, i0, i1, j0, j1, zbuf, tid, count, counting):
    """Scan-convert triangle t over rows j0..j1 and columns i0..i1: depth-test into
    (zbuf = 1/z, tid), or, when `counting`, add 1 to count[j, i] for every covered centre."""
    h0, h1, h2 = _homogeneous(view, tri, extra, n_main, t)
    e0, e1, e2, inv_det = _setup(h0, h1, h2)
    if inv_det == 0.0:
        return
    inv_near = 1.0 / near
    tl0 = _top_left(e0)
    tl1 = _top_left(e1)
    tl2 = _top_left(e2)
    for j in range(j0, j1 + 1):
        y = j + 0.5
        r0 = e0[1] * y + e0[2]
        r1 = e1[1] * y + e1[2]
        r2 = e2[1] * y + e2[2]
        for i in range(i0, i1 + 1):
            x = i + 0.5
            a0 = e0[0] * x + r0
            if a0 < 0.0 or (a0 == 0.0 and not tl0):
                continue
            a1 = e1[0] * x + r1
            if a1 < 0.0 or (a1 == 0.0 and not tl1):
                continue
            a2 = e2[0] * x + r2
            if a2 < 0.0 or (a2 == 0.0 and not tl2):
                continue
            inv_z = (a0 + a1 + a2) * inv_det
            if not (inv_z > 0.0 and inv_z <= inv_near):
                continue  # the vanishing point of a degenerate view, or in front of the near plane
            if counting:
                count[j, i] += 1
            elif inv_z > zbuf[j, i]:  # strictly nearer: at equal depth the earlier (lower) index stays
                zbuf[j, i] = inv_z
                tid[j, i] = t


@kernel_function(fastmath=RFAST, error_model="numpy", forceinline=True)
def barycentrics(view, tri, extra, n_main, t, x, y):
    """Perspective-correct weights (b1, b2) of vertices 1 and 2 of triangle t at (x, y)."""
    h0, h1, h2 = _homogeneous(view, tri, extra, n_main, t)
    e0, e1, e2, inv_det = _setup(h0, h1, h2)
    a0 = e0[0] * x + e0[1] * y + e0[2]
    a1 = e1[0] * x + e1[1] * y + e1[2]
    a2 = e2[0] * x + e2[1] * y + e2[2]
    total = a0 + a1 + a2
    if total == 0.0:
        return 0.0, 0.0
    return a1 / total, a2 / total


@njit(parallel=True, fastmath=RFAST, cache=True, error_model="numpy")
def _bin(view, near, width, height, tri, extra, n_main, n_total, bounds):
    """Pass 1 and 2: every triangle's pixel box into `bounds`, the band lists' layout.

    Returns (band_start (NB + 1,), cursor (N_CHUNKS, NB)): entries of band b occupy
    band_start[b]:band_start[b + 1], and chunk c writes its part from cursor[c, b] on."""
    n_bands = (height + BAND_ROWS - 1) // BAND_ROWS
    per_chunk = (n_total + N_CHUNKS - 1) // N_CHUNKS
    counts = np.zeros((N_CHUNKS, n_bands + 1), dtype=np.int64)
    for c in prange(N_CHUNKS):
        for t in range(c * per_chunk, min(n_total, (c + 1) * per_chunk)):
            i0, i1, j0, j1 = triangle_bounds(view, near, width, height, tri, extra, n_main, t)
            if i0 > i1 or j0 > j1:
                bounds[t, 2] = 1
                bounds[t, 3] = 0
                continue
            bounds[t, 0] = i0
            bounds[t, 1] = i1
            bounds[t, 2] = j0
            bounds[t, 3] = j1
            for b in range(j0 // BAND_ROWS, j1 // BAND_ROWS + 1):
                counts[c, b] += 1
    band_start = np.zeros(n_bands + 1, dtype=np.int64)
    total = 0
    for b in range(n_bands):
        band_start[b] = total
        for c in range(N_CHUNKS):
            n = counts[c, b]
            counts[c, b] = total
            total += n
    band_start[n_bands] = total
    return band_start, counts


@njit(parallel=True, fastmath=RFAST, cache=True, error_model="numpy")
def _fill(n_total, bounds, cursor, entries):
    """Pass 3: append each triangle to the lists of the bands its box overlaps (in order)."""
    per_chunk = (n_total + N_CHUNKS - 1) // N_CHUNKS
    for c in prange(N_CHUNKS):
        for t in range(c * per_chunk, min(n_total, (c + 1) * per_chunk)):
            j0 = int(bounds[t, 2])
            j1 = int(bounds[t, 3])
            if j0 > j1:
                continue
            for b in range(j0 // BAND_ROWS, j1 // BAND_ROWS + 1):
                entries[cursor[c, b]] = t
                cursor[c, b] += 1


@njit(parallel=True, fastmath=RFAST, cache=True, error_model="numpy")
def _draw_bands(view, near, height, tri, extra, n_main, bounds, band_start, entries, zbuf, tid):
    """Pass 4: each band, on one thread, clears its rows of the Z-buffer (zbuf = 1/z, tid =
    triangle) and draws its triangles into them in index order."""
    n_bands = band_start.shape[0] - 1
    dummy = np.zeros((1, 1), dtype=np.int32)
    for b in prange(n_bands):
        row_lo = b * BAND_ROWS
        row_hi = min(height, row_lo + BAND_ROWS) - 1
        for j in range(row_lo, row_hi + 1):  # clear this band's part of the Z-buffer
            for i in range(zbuf.shape[1]):
                zbuf[j, i] = 0.0  # 1/z: 0 is infinitely far
                tid[j, i] = -1
        for k in range(band_start[b], band_start[b + 1]):
            t = entries[k]
            _draw(
                view,
                near,
                tri,
                extra,
                n_main,
                t,
                int(bounds[t, 0]),
                int(bounds[t, 1]),
                max(int(bounds[t, 2]), row_lo),
                min(int(bounds[t, 3]), row_hi),
                zbuf,
                tid,
                dummy,
                False,
            )


class RasterView(NamedTuple):
    """The camera array, the view matrix (view_matrix), the image's size and the background."""

    camera: np.ndarray
    view: np.ndarray
    width: int
    height: int
    background: np.ndarray


class Drawn(NamedTuple):
    """What the depth passes leave for shading: the extra triangles (tessellated analytic shapes)
    and which primitive (and part) each triangle draws, each primitive's `instance` AOV, how many
    of the triangles are the scene's own, and per pixel the nearest 1/z and triangle."""

    extra: np.ndarray
    triangle_prim: np.ndarray
    extra_prim: np.ndarray
    extra_part: np.ndarray
    prim_instance: np.ndarray
    n_main: int
    zbuf: np.ndarray
    tid: np.ndarray


@njit(parallel=True, fastmath=RFAST, cache=True, error_model="numpy")
def _shade(S, X, V, D, rgb, A, want_aovs):
    """Pass 5: shade every pixel once from its nearest triangle, as `trace` lights a surface
    (ambient, diffuse, specular; no shadows, reflection or refraction), and fill the AOVs A
    when `want_aovs`."""
    for j in prange(V.height):
        # the scene's lean views, made per row (a parallel loop cannot capture them from outside)
        G = geometry_of(S)
        F = surfaces_of(S)
        L = lights_of(S)
        Env = environment_of(S)
        node_stack, t_stack = traversal_stacks()
        _shade_row(G, F, L, X, Env, V, D, j, rgb, A, want_aovs, node_stack, t_stack)


@kernel_function(fastmath=RFAST, error_model="numpy", forceinline=True)
def _pixel_direction(cam, a, b):
    """forward + right a + up b: the (unnormalised) ray through image point (a, b) in [-1, 1]^2."""
    return (
        cam[CAM_FORWARD] + cam[CAM_RIGHT] * a + cam[CAM_UP] * b,
        cam[CAM_FORWARD + 1] + cam[CAM_RIGHT + 1] * a + cam[CAM_UP + 1] * b,
        cam[CAM_FORWARD + 2] + cam[CAM_RIGHT + 2] * a + cam[CAM_UP + 2] * b,
    )


@kernel_function(fastmath=RFAST, error_model="numpy")
def _shade_row(G, F, L, X, Env, V, D, j, rgb, A, want_aovs, node_stack, t_stack):
    """Row j of pass 5 (a function of its own: Numba's parallel analysis trips over the
    inlined lighting code inside a parallel loop)."""
    cam, view, width, height, background = V
    extra, triangle_prim, extra_prim, extra_part, prim_instance, n_main, zbuf, tid = D
    depth, normal, obj_id, prim_id, albedo_out, inst_id = A
    tri = G.triangles
    o = (cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2])
    y = j + 0.5
    b = 1.0 - y / height * 2.0
    for i in range(width):
        t = tid[j, i]
        if t < 0:
            sky = (background[0], background[1], background[2])
            if Env.present:  # the environment, seen along the pixel centre's ray
                a = (i + 0.5) / width * 2.0 - 1.0
                sky = environment_radiance(Env, normalize(_pixel_direction(cam, a, b)))
            for c in range(3):
                rgb[j, i, c] = sky[c]
            if want_aovs:
                for c in range(3):
                    normal[j, i, c] = 0.0
                    albedo_out[j, i, c] = 0.0
                depth[j, i] = math.inf
                obj_id[j, i] = -1
                prim_id[j, i] = -1
                inst_id[j, i] = -1
            continue
        x_px = i + 0.5
        a = x_px / width * 2.0 - 1.0
        dv = _pixel_direction(cam, a, b)
        scale = math.sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2])
        d = (dv[0] / scale, dv[1] / scale, dv[2] / scale)
        dist = scale / zbuf[j, i]  # z * |F + R a + U b|: distance along the unit ray
        p = madd(o, d, dist)
        b1 = 0.0
        b2 = 0.0
        if t < n_main:
            prim = triangle_prim[t]
            # vertex normals, image textures and normal maps need the point's weights
            mt = G.prims[prim, PRIM_MATERIAL]
            x = int(F.materials[mt, MAT_TEXTURE])
            mapped = has_map(F.materials, mt)
            if G.triangle_smooth[t] or mapped or (x >= 0 and F.textures[x, TEX_KIND] == IMAGE):
                b1, b2 = barycentrics(view, tri, extra, n_main, t, x_px, y)
        else:
            prim = extra_prim[t - n_main]
            b1 = extra_part[t - n_main]  # which part of the shape (a cylinder's side or cap)
        ng, ns, m, obj, face_id = surface(G, X, prim, b1, b2, p)
        ns = mapped_normal(G, F, X, m, prim, b1, b2, p, ns)
        face = ns
        if dot(face, d) > 0.0:
            face = mul(face, -1.0)
        cone = cam[CAM_CONE_SPREAD] * obliquity(cam, d)  # the ray cone of frame.py's primary rays
        col = albedo(G, F, X, m, prim, b1, b2, p, d, ng, cone * dist)
        # as trace_ray: normals turned towards the incoming ray, a shading normal bent past
        # the horizon replaced by the geometric one, the lights' directions from the point
        if dot(ng, d) >= 0.0:
            ng = mul(ng, -1.0)
            ns = mul(ns, -1.0)
        if dot(ns, d) >= 0.0:
            ns = ng
        light, _ = unshadowed_lighting(G, F, L, X, p, ns, mul(d, -1.0), m, node_stack, t_stack)
        # as trace_ray: a glowing surface adds its emission
        shaded = add(hadamard(col, light), row3(F.materials, m, MAT_EMISSION))
        for c in range(3):
            rgb[j, i, c] = shaded[c]
        if want_aovs:
            guide = aov_albedo(F.materials, m, col)
            for c in range(3):
                normal[j, i, c] = face[c]
                albedo_out[j, i, c] = guide[c]
            depth[j, i] = dist
            obj_id[j, i] = obj
            prim_id[j, i] = face_id
            inst_id[j, i] = prim_instance[prim]


def view_matrix(cam: np.ndarray, width: int, height: int) -> np.ndarray:
    """float64 (4, 3): the camera origin, then the rows mapping v = X - O to (x w, y w, w),
    (x, y) in pixels (columns from the left, rows from the top) and w = dot(v, F)."""
    cam = np.asarray(cam, dtype=np.float64)
    f, r, u = (cam[k : k + 3] for k in (CAM_FORWARD, CAM_RIGHT, CAM_UP))
    view = np.empty((4, 3), dtype=np.float64)
    view[0] = cam[CAM_POSITION : CAM_POSITION + 3]
    view[1] = 0.5 * width * (r / np.dot(r, r) + f)
    view[2] = 0.5 * height * (f - u / np.dot(u, u))
    view[3] = f
    return view


# Scratch buffers (Z-buffer, triangle boxes, band lists) are kept between frames, one set per
# Python thread, and reused while large enough: a sequence of frames then does not pay for
# fresh pages (first-touch page faults cost ~15% of a 1024 x 1024 frame). release_scratch()
# frees them.
_scratch = threading.local()


def _buffer(name, shape, dtype):
    """A scratch array of this shape: a view of the kept buffer when it is large enough."""
    size = int(np.prod(shape))
    kept = getattr(_scratch, name, None)
    if kept is None or kept.size < size or kept.dtype != dtype:
        kept = np.empty(max(size, 1), dtype=dtype)
        setattr(_scratch, name, kept)
    return kept[:size].reshape(shape)


class Parts(NamedTuple):
    """What raster.py gives the passes beside the scene: which primitive each of the scene's
    triangles is, the tessellated analytic shapes (extra triangles, their primitives and parts)
    and each primitive's `instance` AOV."""

    triangle_prim: np.ndarray
    extra: np.ndarray
    extra_prim: np.ndarray
    extra_part: np.ndarray
    prim_instance: np.ndarray


def release_scratch() -> None:
    """Free this thread's scratch buffers."""
    for name in ("zbuf", "tid", "bounds", "entries"):
        if hasattr(_scratch, name):
            delattr(_scratch, name)


def rasterize_arrays(S, cam, width, height, near, parts: Parts, background, rgb, A: Aovs, want_aovs):
    """Run the passes over the kernel scene's triangles (row t is primitive
    parts.triangle_prim[t]) plus `parts.extra` (float64 (E, 9): tessellated analytic shapes,
    triangle e drawing primitive extra_prim[e], part extra_part[e]) and write the image (every
    pixel) and, when `want_aovs`, the AOVs A. Compile by calling it on empty input first.
    parts.prim_instance (int32 per primitive) is each primitive's `instance` AOV (raster.py
    draws instances as plain triangles)."""
    triangle_prim, extra, extra_prim, extra_part, prim_instance = parts
    tri = S.triangles
    n_main = tri.shape[0]
    n_total = n_main + extra.shape[0]
    view = view_matrix(cam, width, height)
    bounds = _buffer("bounds", (n_total, 4), np.int16)  # pixel boxes; sides are at most 16384
    band_start, cursor = _bin(view, near, width, height, tri, extra, n_main, n_total, bounds)
    entries = _buffer("entries", (int(band_start[-1]),), np.int32)
    _fill(n_total, bounds, cursor, entries)
    zbuf = _buffer("zbuf", (height, width), np.float64)
    tid = _buffer("tid", (height, width), np.int32)
    # Bands differ a lot in work (the middle of an object against empty sky): hand them out
    # one at a time (dynamic scheduling), which changes which thread draws a band, not the image.
    previous = numba.set_parallel_chunksize(1)
    try:
        _draw_bands(view, near, height, tri, extra, n_main, bounds, band_start, entries, zbuf, tid)
    finally:
        numba.set_parallel_chunksize(previous)
    # One variant of the shading pass for every scene, as path mode has: its parallel loop
    # compiles in ~90 s of CPU a variant, and the basic variant is only a few % faster.
    V = RasterView(cam, view, width, height, background)
    D = Drawn(extra, triangle_prim, extra_prim, extra_part, prim_instance, n_main, zbuf, tid)
    _shade(S, path_features(S), V, D, rgb, A, want_aovs)


@njit(cache=True, fastmath=RFAST, error_model="numpy")
def coverage_count(view, near, width, height, tri):
    """How many of the triangles (float32 or float64 (T, 9)) cover each pixel centre, by the
    same edge functions and fill rule as the Z-buffer pass (for tests of the fill rule)."""
    count = np.zeros((height, width), dtype=np.int32)
    zbuf = np.zeros((1, 1), dtype=np.float64)
    tid = np.zeros((1, 1), dtype=np.int32)
    n = tri.shape[0]
    for t in range(n):
        i0, i1, j0, j1 = triangle_bounds(view, near, width, height, tri, tri, n, t)
        if i0 <= i1 and j0 <= j1:
            _draw(view, near, tri, tri, n, t, i0, i1, j0, j1, zbuf, tid, count, True)
    return count
