"""Path mode as a wavefront: a row's camera samples, TILE at a time, go through the path tracer
together, so that the shading every diffuse surface needs runs SIMD across paths (Laine,
Karras and Aila, "Megakernels considered harmful", HPG 2013: path state in arrays, one stage a
loop, one queue per material kind; here the diffuse kind's).

In each round every live path runs segment after segment (path.path_segment, the scalar
kernel's own loop body: traversal, emission, media, null boundaries, the shading of every kind
but diffuse) with its state in registers, until it ends or reaches a diffuse surface. There
path_segment draws next-event estimation's light sample and defers the rest: the path's state
goes into its slot's rows and the surface into the diffuse queue. After the round, one vector
loop (`_shade_diffuse`) does for the whole queue what path_segment would have done next: the
light sample's direction and density where it is a point on a surface or the environment's
cell, the BSDF's value and the MIS weight, the shadow ray's ends, the cosine-sampled next
direction (the diffuse kind's lane_sample), the throughput. At the start of the next round
each queued path traces its shadow ray, adds the light that arrives and takes Russian roulette,
then goes on. LLVM vectorises that loop (4 paths an AVX2 register; tests/test_path_wavefront.py checks
the machine code): its square roots and divisions were the slowest chain of a diffuse bounce.

The random numbers are path_segment's, keyed by (seed, pixel, sample, segment), and the diffuse
frame is the scalar kernel's, so images agree with path_ray's in expectation, differing in
rounding (the contribution's products in another order), not in distribution. Each path's
arithmetic depends on nothing but its own state (the vector loop runs without fast-math, so a
lane computes what the loop's scalar remainder would), and each pixel's samples are added in
sample order: an image is the same whatever the threads, tiles and crops.
"""

import math

import numpy as np

from ..film.camera import CAM_CONE_SPREAD, camera_sample, obliquity
from ..film.film import add_in_pixel_order, next_sample, pixel_sums, store_sums
from ..geometry.wide_nodes import scratch_array
from ..shading.environment import environment_at, environment_direction, environment_rotation
from ..shading.lights import SHADOW_SHORTEN
from ..shading.materials import diffuse_lane_sample
from ..vec import at, hadamard, inline_function, kernel_function, turn_in_lanes, vector_loop
from .path import (
    DONE,
    ENVIRONMENT_CELL,
    GO,
    NOTHING_DEFERRED,
    SURFACE_POINT,
    _roulette,
    _shadow,
    finite_sample,
    path_segment,
    path_start,
)
from .shadow import scale_free_shadows

INF = math.inf
INV_PI = 1.0 / math.pi
TILE = 256  # paths a wavefront: its ~80 rows of 8-byte values (~165 KB) stay in the L2 cache
STRIDE = TILE + 8  # slots a row: a cache line of padding keeps rows out of one L1 set (wavefront.py)


def _rows(first: int, n: int) -> tuple[int, ...]:
    return tuple((first + r) * STRIDE for r in range(n))


# The paths' state between rounds, by slot (the sample's place in the tile), float64 rows of S:
# the camera ray, and what the diffuse queue does not carry of path.path_start's state ...
OX, OY, OZ, DX, DY, DZ, LR, LG, LB, CONE, SPREAD, WEIGHT = _rows(0, 12)
ENV_U, ENV_COS = _rows(12, 2)  # an environment cell's light sample: its radiance is looked up last
(ETA2,) = _rows(14, 1)  # the refractions' radiance factors undone (path.path_start's eta2)
STATE_ROWS = 15
# ... and int64 rows of N (the sample's key is in the uint64 row K[slot]), with the place in
# the diffuse queue (-1: none yet, the path starts at the camera) and the light row its shadow
# ray aims at, and the form of that light's sample (path._partial_light)
RAYS, DEPTH, MED, CROSSINGS, LEAVING, QUEUED, LIGHT, FORM = _rows(0, 8)
STATE_INT_ROWS = 8
# The diffuse queue, by place in the queue, float64 rows of Q: what path_segment deferred
# (the point, the facing normals, the colour, the offset, the light sample as
# path_segment defers it, the path's throughput and incoming direction, the BSDF's
# numbers) ...
PX, PY, PZ, GX, GY, GZ, NX, NY, NZ, CR, CG, CB, EPS = _rows(0, 13)
LIGHT_FORM, WX, WY, WZ, LNX, LNY, LNZ, AREA, DIST, IR, IG, IB, DENSITY, WEIGHED = _rows(13, 14)
U1, U2, INR, ING, INB, INX, INY, INZ = _rows(27, 8)
# ... and what _shade_diffuse makes of it: the light's contribution before its shadow ray, the
# shadow ray, the next ray, its throughput and pdf, and whether the path goes on (1.0) at all
TR, TG, TB, SOX, SOY, SOZ, SAX, SAY, SAZ, STMAX = _rows(35, 10)
NOX, NOY, NOZ, NDX, NDY, NDZ, NBR, NBG, NBB, NPDF, GOING = _rows(45, 11)
QUEUE_ROWS = 56
# A round's scalar pass reads the outputs of the places its paths had in the last round while
# it writes the inputs of this round's: the two must be separate rows (a path can take a place
# whose last holder has not yet been read).


@kernel_function(_nrt=True)
def path_wave_scratch():
    """One thread's wavefront arrays: (S, N, K, Q, live) as the module's rows lay them out."""
    return (
        scratch_array(STATE_ROWS * STRIDE, np.float64),
        scratch_array(STATE_INT_ROWS * STRIDE, np.int64),
        scratch_array(TILE, np.uint64),
        scratch_array(QUEUE_ROWS * STRIDE, np.float64),
        scratch_array(TILE, np.int64),
    )


@vector_loop
def _shade_diffuse(Q, m, unnormalized, cells, rotation):
    """For queue places 0..m-1, the rest of path_segment's shading of a diffuse surface: the
    light sample's contribution (diffuse f, |cos|, the power heuristic; the shadow ray decides
    whether it arrives, and for an environment cell the radiance is looked up after it), the
    shadow ray as path_segment spawns it (shadow.shadow_segment, or normalized as shadow_ray
    unless `unnormalized`), the BSDF's sample and the path's next ray. `cells`: the scene has
    an environment, rotated by `rotation` (environment.environment_rotation)."""
    for q in range(m):
        px, py, pz = Q[PX + q], Q[PY + q], Q[PZ + q]
        gx, gy, gz = Q[GX + q], Q[GY + q], Q[GZ + q]
        nx, ny, nz = Q[NX + q], Q[NY + q], Q[NZ + q]
        cr, cg, cb = Q[CR + q], Q[CG + q], Q[CB + q]
        eps = Q[EPS + q]
        # the light sample: a point on a surface seen from p (sampling.towards_point), the
        # environment's cell (environment.sample_environment; rotation: environment_rotation),
        # or given
        on_surface = Q[LIGHT_FORM + q] == SURFACE_POINT
        cell = Q[LIGHT_FORM + q] == ENVIRONMENT_CELL
        ex, ey, ez = 0.0, 0.0, 1.0
        if cells:  # (the same all along the loop: LLVM makes a loop without the environment)
            cos_phi, sin_phi = turn_in_lanes(Q[WY + q] - 0.5)
            ex, ey, ez = environment_direction(rotation, Q[WX + q], cos_phi, sin_phi)
        qx, qy, qz = Q[WX + q] - px, Q[WY + q] - py, Q[WZ + q] - pz
        d2 = qx * qx + qy * qy + qz * qz
        reach = math.sqrt(d2)
        facing = abs(Q[LNX + q] * qx + Q[LNY + q] * qy + Q[LNZ + q] * qz) * Q[AREA + q]
        seen = on_surface and reach > 0.0 and facing > 0.0
        inv_reach = 1.0 / reach if seen else 1.0
        wx = qx * inv_reach if on_surface else (ex if cell else Q[WX + q])
        wy = qy * inv_reach if on_surface else (ey if cell else Q[WY + q])
        wz = qz * inv_reach if on_surface else (ez if cell else Q[WZ + q])
        dist = reach if on_surface else Q[DIST + q]
        pdf_l = Q[DENSITY + q] * (d2 * reach / facing if seen else 0.0) if on_surface else Q[DENSITY + q]
        br, bg, bb = Q[INR + q], Q[ING + q], Q[INB + q]
        wo_z = -(Q[INX + q] * nx + Q[INY + q] * ny + Q[INZ + q] * nz)
        # next-event estimation: two-sided reflection sees light from its own side only
        wi_z = wx * nx + wy * ny + wz * nz
        up = wx * gx + wy * gy + wz * gz > 0.0
        same = (wo_z > 0.0 and wi_z > 0.0) or (wo_z < 0.0 and wi_z < 0.0)
        lit = pdf_l > 0.0 and up and same and (cr > 0.0 or cg > 0.0 or cb > 0.0)
        pdf_b = abs(wi_z) * INV_PI
        pl = pdf_l if lit else 1.0
        w = pl / (pl * pl + pdf_b * pdf_b) if Q[WEIGHED + q] > 0.0 else 1.0 / pl
        scale = abs(wi_z) * w if lit else 0.0
        Q[TR + q] = br * (cr * INV_PI) * Q[IR + q] * scale
        Q[TG + q] = bg * (cg * INV_PI) * Q[IG + q] * scale
        Q[TB + q] = bb * (cb * INV_PI) * Q[IB + q] * scale
        ox, oy, oz = px + gx * eps, py + gy * eps, pz + gz * eps
        Q[SOX + q], Q[SOY + q], Q[SOZ + q] = ox, oy, oz
        finite = dist < INF
        ax = (px + wx * dist) - ox if finite else wx
        ay = (py + wy * dist) - oy if finite else wy
        az = (pz + wz * dist) - oz if finite else wz
        tmax = 1.0 - SHADOW_SHORTEN if finite else INF
        if not unnormalized:
            span = math.sqrt(ax * ax + ay * ay + az * az)
            inv = 1.0 / span if finite else 1.0
            ax, ay, az = ax * inv, ay * inv, az * inv
            tmax = span * (1.0 - SHADOW_SHORTEN) if finite else INF
        Q[SAX + q], Q[SAY + q], Q[SAZ + q], Q[STMAX + q] = ax, ay, az, tmax
        # the next ray: the cosine's direction in the frame (s, t, n) of sampling.basis(n)
        (lx, ly, lz), pdf = diffuse_lane_sample(wo_z, Q[U1 + q], Q[U2 + q])
        sign = 1.0 if nz >= 0.0 else -1.0
        a = -1.0 / (sign + nz)
        b = nx * ny * a
        sx, sy, sz = 1.0 + sign * nx * nx * a, sign * b, -sign * nx
        tx, ty, tz = b, sign + ny * ny * a, -ny
        dx = sx * lx + tx * ly + nx * lz
        dy = sy * lx + ty * ly + ny * lz
        dz = sz * lx + tz * ly + nz * lz
        Q[NDX + q], Q[NDY + q], Q[NDZ + q] = dx, dy, dz
        # a shading normal may send the path through the surface: it ends there
        going = wo_z != 0.0 and (cr > 0.0 or cg > 0.0 or cb > 0.0) and dx * gx + dy * gy + dz * gz > 0.0
        Q[GOING + q] = 1.0 if going else 0.0
        Q[NOX + q], Q[NOY + q], Q[NOZ + q] = ox, oy, oz
        Q[NBR + q], Q[NBG + q], Q[NBB + q] = br * cr, bg * cg, bb * cb
        Q[NPDF + q] = pdf


@inline_function
def _enqueue(S, Q, N, k, q, st, deferred):
    """The deferred diffuse surface of slot k, path state st, into queue place q."""
    p, ng, ns, colour, eps, form, aim, n_l, area, dist, li, density, weighed, u1, u2, light = deferred
    d, beta = st[1], st[2]
    Q[at(PX, q)], Q[at(PY, q)], Q[at(PZ, q)] = p
    Q[at(GX, q)], Q[at(GY, q)], Q[at(GZ, q)] = ng
    Q[at(NX, q)], Q[at(NY, q)], Q[at(NZ, q)] = ns
    Q[at(CR, q)], Q[at(CG, q)], Q[at(CB, q)] = colour
    Q[at(WX, q)], Q[at(WY, q)], Q[at(WZ, q)] = aim
    Q[at(LNX, q)], Q[at(LNY, q)], Q[at(LNZ, q)] = n_l
    Q[at(LIGHT_FORM, q)], Q[at(AREA, q)] = form, area
    Q[at(IR, q)], Q[at(IG, q)], Q[at(IB, q)] = li
    Q[at(INR, q)], Q[at(ING, q)], Q[at(INB, q)] = beta
    Q[at(INX, q)], Q[at(INY, q)], Q[at(INZ, q)] = d
    Q[at(EPS, q)], Q[at(DIST, q)], Q[at(DENSITY, q)] = eps, dist, density
    Q[at(WEIGHED, q)], Q[at(U1, q)], Q[at(U2, q)] = 1.0 if weighed else 0.0, u1, u2
    N[at(QUEUED, k)], N[at(LIGHT, k)], N[at(FORM, k)] = q, light, form
    if form == ENVIRONMENT_CELL:
        S[at(ENV_COS, k)], S[at(ENV_U, k)] = aim[0], aim[1]


@inline_function
def _store_result(S, N, k, st):
    """What is left of an ended path in slot k: its radiance and rays."""
    S[at(LR, k)], S[at(LG, k)], S[at(LB, k)] = st[3]
    N[at(RAYS, k)] = st[4]


@inline_function
def _store_kept(S, N, k, st):
    """What the diffuse queue does not carry of a deferred path's state st (_resume_diffuse)."""
    _, _, _, L, rays, depth, _, _, cone, med, _, _, crossings, leaving, eta2 = st
    S[at(LR, k)], S[at(LG, k)], S[at(LB, k)] = L
    S[at(CONE, k)], S[at(ETA2, k)] = cone, eta2
    N[at(RAYS, k)], N[at(DEPTH, k)], N[at(MED, k)] = rays, depth, med
    N[at(CROSSINGS, k)], N[at(LEAVING, k)] = crossings, leaving


@inline_function
def _resume_diffuse(G, F, X, Em, Env, Md, S, N, Q, k, q, key, node_stack, t_stack):
    """Slot k's path state after its diffuse surface in queue place q: the light its shadow ray
    lets through added, the next ray taken and Russian roulette. Returns (the path goes on,
    its state)."""
    L = (S[at(LR, k)], S[at(LG, k)], S[at(LB, k)])
    rays, depth, med, leaving = N[at(RAYS, k)], N[at(DEPTH, k)], N[at(MED, k)], N[at(LEAVING, k)]
    c = (Q[at(TR, q)], Q[at(TG, q)], Q[at(TB, q)])
    if c[0] > 0.0 or c[1] > 0.0 or c[2] > 0.0:
        rays += 1
        origin = (Q[at(SOX, q)], Q[at(SOY, q)], Q[at(SOZ, q)])
        aim = (Q[at(SAX, q)], Q[at(SAY, q)], Q[at(SAZ, q)])
        tr = _shadow(
            G, F, X, Em, Md, origin, aim, Q[at(STMAX, q)], med, N[at(LIGHT, k)], key, depth, leaving,
            node_stack, t_stack,
        )  # fmt: skip
        if N[at(FORM, k)] == ENVIRONMENT_CELL and (tr[0] > 0.0 or tr[1] > 0.0 or tr[2] > 0.0):
            tr = hadamard(tr, environment_at(Env, S[at(ENV_U, k)], S[at(ENV_COS, k)]))
        L = (L[0] + c[0] * tr[0], L[1] + c[1] * tr[1], L[2] + c[2] * tr[2])
    o = (Q[at(NOX, q)], Q[at(NOY, q)], Q[at(NOZ, q)])
    d = (Q[at(NDX, q)], Q[at(NDY, q)], Q[at(NDZ, q)])
    going, beta = Q[at(GOING, q)] != 0.0, (Q[at(NBR, q)], Q[at(NBG, q)], Q[at(NBB, q)])
    eta2 = S[at(ETA2, k)]  # (a diffuse surface refracts nothing)
    if going:
        going, beta = _roulette(beta, eta2, key, depth)
    cone, crossings = S[at(CONE, k)], N[at(CROSSINGS, k)]
    return going, (o, d, beta, L, rays, depth, Q[at(NPDF, q)], False, cone, med, o, 0.0, crossings, leaving, eta2)


@inline_function
def path_wave_row(G, F, Em, Env, Md, X, P, j, film, wave, node_stack, t_stack, strategy):
    """path_row's samples of row j (frame.py) by the wavefront: the same film sums in the same
    order, each sample path-traced in expectation as path_ray traces it. Returns the rays traced
    and the samples rejected (not finite, or negative)."""
    cam, filt, width, height, window, samples, seed, max_depth, bg = P
    first, count, total_spp = samples
    x0, y0, x1, y1 = window
    S, N, K, Q, live = wave
    spread = cam[CAM_CONE_SPREAD]
    unnormalized = scale_free_shadows(G, Em, Md)
    rotation = environment_rotation(Env)
    rays = 0
    rejected = 0
    n = (x1 - x0) * count
    i, s = x0, first  # the next camera sample
    pixel, total = x0, pixel_sums(film, j - y0, 0)  # the film's running sums (add_in_pixel_order)
    for start in range(0, n, TILE):
        m = min(TILE, n - start)
        first_i, first_s = i, s
        for k in range(m):
            o, d, w, key = camera_sample(cam, filt, seed, i, j, s, total_spp, width, height)
            S[at(OX, k)], S[at(OY, k)], S[at(OZ, k)] = o
            S[at(DX, k)], S[at(DY, k)], S[at(DZ, k)] = d
            S[at(SPREAD, k)], S[at(WEIGHT, k)], K[at(0, k)] = spread * obliquity(cam, d), w, key
            N[at(QUEUED, k)] = -1
            live[at(0, k)] = k
            i, s = next_sample(i, s, samples)
        alive = m
        while alive > 0:
            # each live path from the camera or its diffuse surface on to its next diffuse
            # surface (deferred: queued) or its end; the queue is shaded after the round
            queued = 0
            still = 0
            for a in range(alive):
                k = live[at(0, a)]
                key = K[at(0, k)]
                q = N[at(QUEUED, k)]
                if q >= 0:
                    going, st = _resume_diffuse(G, F, X, Em, Env, Md, S, N, Q, k, q, key, node_stack, t_stack)
                else:
                    going = True
                    st = path_start(
                        Md, (S[at(OX, k)], S[at(OY, k)], S[at(OZ, k)]), (S[at(DX, k)], S[at(DY, k)], S[at(DZ, k)])
                    )
                status = GO if going else DONE
                deferred = NOTHING_DEFERRED
                while status == GO:  # other kinds' surfaces, media and null boundaries: in registers
                    status, st, deferred = path_segment(
                        G, F, X, Em, Env, Md, st, S[at(SPREAD, k)], max_depth, bg, key, node_stack, t_stack, strategy,
                        unnormalized, True,
                    )  # fmt: skip
                if status == DONE:
                    _store_result(S, N, k, st)
                    continue
                _store_kept(S, N, k, st)
                _enqueue(S, Q, N, k, queued, st, deferred)
                queued += 1
                live[at(0, still)] = k
                still += 1
            alive = still
            if queued > 0:
                _shade_diffuse(Q, queued, unnormalized, Env.present, rotation)
        # the tile's samples into the film, in sample order
        i, s = first_i, first_s
        for k in range(m):
            col = (S[at(LR, k)], S[at(LG, k)], S[at(LB, k)])
            rays += N[at(RAYS, k)]
            if not finite_sample(col):
                rejected += 1
                col = (0.0, 0.0, 0.0)
            pixel, total = add_in_pixel_order(film, j - y0, x0, pixel, total, i, col, S[at(WEIGHT, k)])
            i, s = next_sample(i, s, samples)
    if n > 0:
        store_sums(film, j - y0, pixel - x0, total)
    return rays, rejected
