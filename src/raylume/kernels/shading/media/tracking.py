"""Free-flight sampling and transmittance along a ray through a medium, the same for every kind:
tentative collisions against a majorant mu (constant over the ray for a homogeneous medium,
constant per cell of a grid's coarse majorant grid, walked cell by cell), each one real or null
by the medium's coefficients there.

Free flights use spectral tracking (Kutz et al., "Spectral and decomposition tracking for
rendering heterogeneous volumes", SIGGRAPH 2017): one grey majorant for the three channels, the
event at each tentative collision chosen in proportion to the path throughput times sigma_a,
sigma_s and the null coefficient mu - sigma_t (the history-aware probabilities), the throughput
reweighted so that every channel stays unbiased, chromatic media included. Transmittance along
shadow rays is exact for a homogeneous medium and ratio tracking (Cramer 1978; Novak et al. 2014)
for a grid. Random numbers come from the key given, one sub-key per tentative collision."""

import math

from ...film.sampler import key_uniform2, sub_key
from ...vec import inline_function, madd
from . import grid, homogeneous
from .grid import density_at
from .table import (
    MED_BOX_MAX,
    MED_BOX_MIN,
    MED_CELLS,
    MED_KIND,
    MED_MX,
    MED_MY,
    MED_MZ,
    MED_SIGMA_A,
    MED_SIGMA_S,
    MED_SIGMA_T_MAX,
)

INF = math.inf
PASSED = 0  # no real collision before the end of the ray
SCATTERED = 1
ABSORBED = 2  # absorbed, or the throughput is zero
# Tentative collisions at most along one ray: a guard against a pathologically dense medium
# (a path stopped here loses its energy, about exp(-MAX_COLLISIONS) of it for a grey medium).
MAX_COLLISIONS = 1 << 16


@inline_function
def coefficients_at(Md, k, p):
    """(sigma_a, sigma_s) of medium k at the point p, RGB each."""
    scale = 1.0
    if int(Md.data[k, MED_KIND]) == grid.KIND:
        scale = density_at(Md.data, Md.density, k, p)
    a, s = MED_SIGMA_A, MED_SIGMA_S
    return (
        (Md.data[k, a] * scale, Md.data[k, a + 1] * scale, Md.data[k, a + 2] * scale),
        (Md.data[k, s] * scale, Md.data[k, s + 1] * scale, Md.data[k, s + 2] * scale),
    )


@inline_function
def _track(Md, k, o, d, t, t_end, mu, key, step, beta, ratio):
    """Tentative collisions in (t, t_end) at the majorant mu. Ratio tracking (ratio True)
    multiplies beta by the null fraction at each; spectral tracking stops at the first real
    one. Returns (status, t, beta, collisions so far)."""
    while mu > 0.0:
        u, v = key_uniform2(sub_key(key, step))
        step += 1
        t -= math.log1p(-u) / mu
        if t >= t_end:
            break
        sa, ss = coefficients_at(Md, k, madd(o, d, t))
        # The null coefficients, at least 0: in the channel whose sigma_t is the majorant,
        # mu - sigma_a - sigma_s rounds to a hair below 0 for some coefficients (0.5 + 0.0001,
        # say), and a throughput times that would turn negative and lose the sample
        n0 = max(mu - sa[0] - ss[0], 0.0)
        n1 = max(mu - sa[1] - ss[1], 0.0)
        n2 = max(mu - sa[2] - ss[2], 0.0)
        if ratio:
            beta = (beta[0] * n0 / mu, beta[1] * n1 / mu, beta[2] * n2 / mu)
            if beta[0] == 0.0 and beta[1] == 0.0 and beta[2] == 0.0:
                return ABSORBED, t, beta, step
        else:
            pa = abs(beta[0] * sa[0]) + abs(beta[1] * sa[1]) + abs(beta[2] * sa[2])
            ps = abs(beta[0] * ss[0]) + abs(beta[1] * ss[1]) + abs(beta[2] * ss[2])
            pn = abs(beta[0] * n0) + abs(beta[1] * n1) + abs(beta[2] * n2)
            c = pa + ps + pn
            if not (c > 0.0):
                return ABSORBED, t, (0.0, 0.0, 0.0), step
            v *= c
            if v < pa:
                return ABSORBED, t, (0.0, 0.0, 0.0), step
            if v < pa + ps:
                w = c / (mu * ps)
                return SCATTERED, t, (beta[0] * ss[0] * w, beta[1] * ss[1] * w, beta[2] * ss[2] * w), step
            w = c / (mu * pn)
            beta = (beta[0] * n0 * w, beta[1] * n1 * w, beta[2] * n2 * w)
        if step >= MAX_COLLISIONS:
            return ABSORBED, t, (0.0, 0.0, 0.0), step
    return PASSED, t_end, beta, step


@inline_function
def _grid_walk(Md, k, o, d, tmax, key, beta, ratio):
    """_track over the part of (0, tmax) inside grid k's box, majorant cell by majorant cell
    (Amanatides and Woo's traversal). Returns (status, t, beta)."""
    t0, t1 = 0.0, tmax
    for a in range(3):
        lo, hi = Md.data[k, MED_BOX_MIN + a], Md.data[k, MED_BOX_MAX + a]
        if d[a] != 0.0:
            ta, tb = (lo - o[a]) / d[a], (hi - o[a]) / d[a]
            t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        elif o[a] < lo or o[a] > hi:
            return PASSED, tmax, beta
    if not (t0 < t1):
        return PASSED, tmax, beta
    mx, my, mz = int(Md.data[k, MED_MX]), int(Md.data[k, MED_MY]), int(Md.data[k, MED_MZ])
    cx, nx, dx, sx = _axis_start(Md, k, o, d, t0, 0, mx)
    cy, ny, dy, sy = _axis_start(Md, k, o, d, t0, 1, my)
    cz, nz, dz, sz = _axis_start(Md, k, o, d, t0, 2, mz)
    base = int(Md.data[k, MED_CELLS])
    t = t0
    collisions = 0
    while True:
        t_exit = min(nx, ny, nz, t1)
        mu = Md.majorants[base + (cz * my + cy) * mx + cx]
        status, t_hit, beta, collisions = _track(Md, k, o, d, t, t_exit, mu, key, collisions, beta, ratio)
        if status != PASSED:
            return status, t_hit, beta
        if t_exit >= t1:
            return PASSED, tmax, beta
        t = t_exit
        if nx <= ny and nx <= nz:
            cx, nx = cx + sx, nx + dx
            if cx < 0 or cx >= mx:
                return PASSED, tmax, beta
        elif ny <= nz:
            cy, ny = cy + sy, ny + dy
            if cy < 0 or cy >= my:
                return PASSED, tmax, beta
        else:
            cz, nz = cz + sz, nz + dz
            if cz < 0 or cz >= mz:
                return PASSED, tmax, beta


@inline_function
def _axis_start(Md, k, o, d, t0, a, m):
    """Along axis a, the majorant cell the ray enters at t0, where it leaves that cell's slab,
    the distance across one slab and the step (+1, -1 or 0)."""
    lo, hi = Md.data[k, MED_BOX_MIN + a], Md.data[k, MED_BOX_MAX + a]
    size = (hi - lo) / m
    c = min(max(int(math.floor((o[a] + d[a] * t0 - lo) / size)), 0), m - 1)
    if d[a] > 0.0:
        return c, (lo + (c + 1) * size - o[a]) / d[a], size / d[a], 1
    if d[a] < 0.0:
        return c, (lo + c * size - o[a]) / d[a], -size / d[a], -1
    return c, INF, INF, 0


@inline_function
def free_flight(Md, k, o, d, tmax, key, beta):
    """Where the ray (o, d) in medium k first scatters before tmax, by spectral tracking:
    (status PASSED / SCATTERED / ABSORBED, t, the throughput beta reweighted)."""
    if int(Md.data[k, MED_KIND]) == homogeneous.KIND:
        status, t, beta, _ = _track(Md, k, o, d, 0.0, tmax, Md.data[k, MED_SIGMA_T_MAX], key, 0, beta, False)
        return status, t, beta
    return _grid_walk(Md, k, o, d, tmax, key, beta, False)


@inline_function
def transmittance(Md, k, o, d, tmax, key):
    """Transmittance of medium k along (o, d) over (0, tmax), RGB: exact for a homogeneous
    medium, an unbiased ratio-tracking estimate for a grid."""
    if int(Md.data[k, MED_KIND]) == homogeneous.KIND:
        return homogeneous.exact_transmittance(Md.data, k, tmax)
    _, _, tr = _grid_walk(Md, k, o, d, tmax, key, (1.0, 1.0, 1.0), True)
    return tr
