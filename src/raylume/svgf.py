"""Spatiotemporal variance-guided filtering (SVGF): a real-time denoiser for path-traced frames
of one sample per pixel, after C. Schied et al., "Spatiotemporal Variance-Guided Filtering:
Real-Time Reconstruction for Path-Traced Global Illumination", High-Performance Graphics 2017.
The live view (`raylume view --denoise`) shows its frames while the camera moves.

Each frame, `Svgf.filter(rgb, albedo, normal, depth, camera, emitted)` takes the noisy
radiance and the primary-hit AOVs of the same pixel centres (albedo, the normal facing the
camera, the distance along the ray, inf where nothing is hit), the frame's camera array
(kernels/film/camera.py) and, optionally, the light seen directly (the same camera rays with
max_depth 1). That part has no noise at one sample a pixel (the rays go through the pixel
centres); it is kept out of the filter and added back, so that an emitter neither bleeds into
its surroundings nor makes their variance look huge (seen_light.py does the same for OIDN).

1. Demodulate: the illumination is the radiance divided by the albedo (at least MIN_ALBEDO a
   channel), so that texture and colour edges are not blurred: only the illumination is.
2. Reproject: each pixel's world point (camera ray x depth) is projected into the previous
   frame's camera, which may have had another size; its four bilinear neighbours there count
   where they lie on the same surface (normals within NORMAL_COS, the point within
   PLANE_PIXELS pixel footprints of their tangent plane), else the matching pixels of its 3 x 3
   neighbourhood; a pixel with none is disoccluded and starts a new history.
3. Accumulate over time: colour and the first two moments of luminance are exponential moving
   averages (weight ALPHA for the new frame, or 1 / history length while that is larger;
   histories count MAX_HISTORY frames at most).
4. Estimate the variance of luminance from the moments; where a history is shorter than
   SHORT_HISTORY frames, from a 7 x 7 edge-aware neighbourhood's moments instead (whose mean
   colour then replaces the pixel's), raised by SHORT_HISTORY / length.
5. Filter with ITERATIONS edge-aware a-trous wavelet passes (the 5 x 5 B3-spline kernel, taps
   1, 2, 4, 8, 16 pixels apart), each tap weighed by
   - luminance: exp(-|l_p - l_q| / (SIGMA_L sqrt(g(var_p)) + EPS)), g a 3 x 3 Gaussian,
   - normals: max(0, n_p . n_q) ^ 128, as exp(-128 (1 - n_p . n_q)) (the same to within
     1 % where the weight matters),
   - depth: exp(-|(x_q - x_p) . n_p| / (SIGMA_Z |p - q| footprint_p)): the distance of q's
     world point from p's tangent plane against a pixel's footprint there (the paper compares
     clip-space depth against its screen-space gradient: the same test, exact for planes);
   the variance is filtered with the squared weights. The first pass's output is the next
   frame's colour history, as in the paper.
6. Remodulate by the albedo and add the emitted part back. Pixels where nothing is hit (the
   background or the environment, exact at one sample) pass unfiltered and never weigh in.
   Non-finite or negative input counts as 0; the output is finite and >= 0.

Speed: the weights use exp(-x) ~ (1 + x / 256) ^ -256 (within 2 % for the x that matter, and 0
from x = CUTOFF on), plain arithmetic, and an a-trous pass runs tap by tap over a row of pixels
held in planes padded by the widest tap (no bounds checks), so that LLVM vectorises it (8
floats at a time: ~1.7 ns a tap on this project's machine, against ~9 ns a tap pixel by pixel;
there is no vector exp in Numba without Intel's SVML). Rows run in bands on `threads` threads
(the kernels release the GIL; Numba's prange was 5-10x slower with other work on the cores). The
kernels are compiled once into Numba's disk cache.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .kernels.film.camera import CAM_FORWARD, CAM_HALF_HEIGHT, CAM_HALF_WIDTH, CAM_POSITION, CAM_RIGHT, CAM_UP
from .kernels.vec import FAST

ALPHA = 0.2  # weight of the new frame in the colour's moving average
MOMENTS_ALPHA = 0.2  # ... and in the moments'
MAX_HISTORY = 32  # frames a history counts at most
SHORT_HISTORY = 4  # below this many frames the variance is estimated spatially
ITERATIONS = 5  # a-trous passes (taps 1, 2, 4, 8, 16 pixels apart)
SIGMA_L = 4.0  # luminance edge-stopping, in standard deviations
SIGMA_Z = 1.0  # depth edge-stopping, in pixel footprints per pixel of distance
SIGMA_N = 128.0  # normal edge-stopping: the power of the cosine
NORMAL_COS = 0.9  # reprojection: a history sample's normal within ~25 degrees
PLANE_PIXELS = 2.0  # reprojection: its point within this many pixel footprints of the tangent plane
MIN_ALBEDO = 0.01  # demodulation divides by at least this
EPS = 1e-10
CUTOFF = 24.0  # weights exp(-x) for x >= CUTOFF are 0

# float32 constants: arithmetic on float32 planes stays float32 (8 lanes a vector, not 4)
_F = np.float32
_ZERO, _ONE, _CUTOFF, _INV256, _SIGMA_N = _F(0.0), _F(1.0), _F(CUTOFF), _F(1.0 / 256.0), _F(SIGMA_N)
_LR, _LG, _LB = _F(0.2126), _F(0.7152), _F(0.0722)
_B3 = (_F(1.0 / 16.0), _F(1.0 / 4.0), _F(3.0 / 8.0), _F(1.0 / 4.0), _F(1.0 / 16.0))

# the padded planes of a frame (channel first, rows and columns padded by `pad` on each side)
# guides: the world point, the normal, the kind of pixel (KIND_*), 1 / (SIGMA_Z footprint)
G_POS, G_NORMAL, G_KIND, G_INV_FOOTPRINT, G_PLANES = 0, 3, 6, 7, 8
# Pixels of different kinds never weigh in each other's filter: nothing hit, a surface whose
# light is modulated by its albedo, a black one (albedo below MIN_ALBEDO: emission only).
KIND_NONE, KIND_SURFACE, KIND_BLACK = 0.0, 1.0, 2.0
C_RGB, C_VAR, C_LUM, C_PLANES = 0, 3, 4, 5  # colour being filtered, its variance, its luminance

_JIT = dict(cache=True, fastmath=FAST, error_model="numpy")


@njit(**_JIT)
def _exp_neg(x):
    """exp(-x) for x >= 0 as (1 + x / 256) ^ -256, 0 from CUTOFF on: within 2 % for x < 4,
    vectorisable (x is float32)."""
    y = _ONE + min(max(x, _ZERO), _CUTOFF) * _INV256
    for _ in range(8):
        y = y * y
    return _ONE / y if x < _CUTOFF else _ZERO


@njit(**_JIT)
def _finite(x):
    """x where finite and > 0, else 0."""
    return x if (x > 0.0 and x < np.inf) else 0.0


@njit(nogil=True, **_JIT)
def _prepare(j0, j1, rgb, emitted, albedo, normal, depth, cam, pad, illum, mod, guides):
    """The demodulated illumination (rgb less emitted, over the albedo), the modulation and the
    guides: world points, unit normals, the kind of pixel (KIND_*), the inverse
    footprint (a pixel's world size at its depth, times SIGMA_Z)."""
    H, W = depth.shape
    px, py, pz = cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2]
    pixel = 2.0 * cam[CAM_HALF_HEIGHT] / H
    for j in range(j0, j1):
        b = 1.0 - (j + 0.5) / H * 2.0
        jj = j + pad
        for i in range(W):
            ii = i + pad
            a = (i + 0.5) / W * 2.0 - 1.0
            t = depth[j, i]
            hit = t > 0.0 and t < np.inf
            a0, a1, a2 = _finite(albedo[j, i, 0]), _finite(albedo[j, i, 1]), _finite(albedo[j, i, 2])
            black = not hit or max(a0, a1, a2) < MIN_ALBEDO  # only emission: not modulated
            for c in range(3):
                m = 1.0 if black else max(_finite(albedo[j, i, c]), MIN_ALBEDO)
                mod[c, j, i] = m
                illum[c, j, i] = max(_finite(rgb[j, i, c]) - _finite(emitted[j, i, c]), 0.0) / m
            n0, n1, n2 = normal[j, i, 0], normal[j, i, 1], normal[j, i, 2]
            ln = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if hit and ln > 0.0 and ln < np.inf:
                dx = cam[CAM_FORWARD] + cam[CAM_RIGHT] * a + cam[CAM_UP] * b
                dy = cam[CAM_FORWARD + 1] + cam[CAM_RIGHT + 1] * a + cam[CAM_UP + 1] * b
                dz = cam[CAM_FORWARD + 2] + cam[CAM_RIGHT + 2] * a + cam[CAM_UP + 2] * b
                s = t / np.sqrt(dx * dx + dy * dy + dz * dz)
                guides[G_POS, jj, ii] = px + dx * s
                guides[G_POS + 1, jj, ii] = py + dy * s
                guides[G_POS + 2, jj, ii] = pz + dz * s
                guides[G_NORMAL, jj, ii] = n0 / ln
                guides[G_NORMAL + 1, jj, ii] = n1 / ln
                guides[G_NORMAL + 2, jj, ii] = n2 / ln
                guides[G_KIND, jj, ii] = KIND_BLACK if black else KIND_SURFACE
                guides[G_INV_FOOTPRINT, jj, ii] = 1.0 / (SIGMA_Z * t * pixel)
            else:
                for c in range(G_PLANES):
                    guides[c, jj, ii] = 0.0


@njit(**_JIT)
def _same_surface(kind, x, y, z, n0, n1, n2, tolerance, prev, ppad, qj, qi):
    """Whether the previous frame's pixel (qj, qi) shows the surface at point (x, y, z) with
    normal n: of the same kind, its normal close, its point near the tangent plane."""
    qj, qi = qj + ppad, qi + ppad
    if prev[G_KIND, qj, qi] != kind:
        return False
    if n0 * prev[G_NORMAL, qj, qi] + n1 * prev[G_NORMAL + 1, qj, qi] + n2 * prev[G_NORMAL + 2, qj, qi] < NORMAL_COS:
        return False
    d = (prev[G_POS, qj, qi] - x) * n0 + (prev[G_POS + 1, qj, qi] - y) * n1 + (prev[G_POS + 2, qj, qi] - z) * n2
    return abs(d) <= tolerance


@njit(nogil=True, **_JIT)
def _reproject(j0, j1, illum, guides, pad, pcam, pguides, ppad, pcolor, pmoments, plength, color, moments, length):
    """Temporal accumulation: each pixel's history fetched from the previous frame (through its
    camera pcam, at its size) where that saw the same surface, blended with this frame."""
    H, W = illum.shape[1:]
    PH, PW = plength.shape
    cx, cy, cz = pcam[CAM_POSITION], pcam[CAM_POSITION + 1], pcam[CAM_POSITION + 2]
    fx, fy, fz = pcam[CAM_FORWARD], pcam[CAM_FORWARD + 1], pcam[CAM_FORWARD + 2]
    w2 = pcam[CAM_HALF_WIDTH] * pcam[CAM_HALF_WIDTH]
    h2 = pcam[CAM_HALF_HEIGHT] * pcam[CAM_HALF_HEIGHT]
    ppixel = 2.0 * pcam[CAM_HALF_HEIGHT] / PH
    for j in range(j0, j1):
        for i in range(W):
            r, g, b = illum[0, j, i], illum[1, j, i], illum[2, j, i]
            lum = 0.2126 * r + 0.7152 * g + 0.0722 * b
            kind = guides[G_KIND, j + pad, i + pad]
            valid = kind != KIND_NONE
            n = hr = hg = hb = m1 = m2 = hl = 0.0
            if valid:
                jj, ii = j + pad, i + pad
                x, y, z = guides[G_POS, jj, ii], guides[G_POS + 1, jj, ii], guides[G_POS + 2, jj, ii]
                n0, n1, n2 = guides[G_NORMAL, jj, ii], guides[G_NORMAL + 1, jj, ii], guides[G_NORMAL + 2, jj, ii]
                vx, vy, vz = x - cx, y - cy, z - cz
                forward = vx * fx + vy * fy + vz * fz
                if forward > 0.0:
                    a = (vx * pcam[CAM_RIGHT] + vy * pcam[CAM_RIGHT + 1] + vz * pcam[CAM_RIGHT + 2]) / (forward * w2)
                    v = (vx * pcam[CAM_UP] + vy * pcam[CAM_UP + 1] + vz * pcam[CAM_UP + 2]) / (forward * h2)
                    sx = (a + 1.0) * 0.5 * PW - 0.5  # in the previous frame's pixels, centres at integers
                    sy = (1.0 - v) * 0.5 * PH - 0.5
                    footprint = 1.0 / (SIGMA_Z * guides[G_INV_FOOTPRINT, jj, ii])
                    tolerance = PLANE_PIXELS * max(footprint, np.sqrt(vx * vx + vy * vy + vz * vz) * ppixel)
                    if sx > -1.0 and sx < PW and sy > -1.0 and sy < PH:
                        x0, y0 = int(np.floor(sx)), int(np.floor(sy))
                        tx, ty = sx - x0, sy - y0
                        for k in range(4):
                            qi, qj = x0 + (k & 1), y0 + (k >> 1)
                            if qi < 0 or qi >= PW or qj < 0 or qj >= PH:
                                continue
                            if not _same_surface(kind, x, y, z, n0, n1, n2, tolerance, pguides, ppad, qj, qi):
                                continue
                            w = (tx if k & 1 else 1.0 - tx) * (ty if k >> 1 else 1.0 - ty)
                            n += w
                            hr += w * pcolor[0, qj, qi]
                            hg += w * pcolor[1, qj, qi]
                            hb += w * pcolor[2, qj, qi]
                            m1 += w * pmoments[0, qj, qi]
                            m2 += w * pmoments[1, qj, qi]
                            hl += w * plength[qj, qi]
                        if n < 0.01:  # no bilinear neighbour on this surface: those of a 3 x 3 neighbourhood
                            n = hr = hg = hb = m1 = m2 = hl = 0.0
                            ci, cj = int(np.floor(sx + 0.5)), int(np.floor(sy + 0.5))
                            for qj in range(max(cj - 1, 0), min(cj + 2, PH)):
                                for qi in range(max(ci - 1, 0), min(ci + 2, PW)):
                                    if _same_surface(kind, x, y, z, n0, n1, n2, tolerance, pguides, ppad, qj, qi):
                                        n += 1.0
                                        hr += pcolor[0, qj, qi]
                                        hg += pcolor[1, qj, qi]
                                        hb += pcolor[2, qj, qi]
                                        m1 += pmoments[0, qj, qi]
                                        m2 += pmoments[1, qj, qi]
                                        hl += plength[qj, qi]
            if n > 0.0:
                inv = 1.0 / n
                frames = min(np.floor(hl * inv + 0.5) + 1.0, MAX_HISTORY)
                alpha = max(ALPHA, 1.0 / frames)
                beta = max(MOMENTS_ALPHA, 1.0 / frames)
                color[0, j, i] = hr * inv + alpha * (r - hr * inv)
                color[1, j, i] = hg * inv + alpha * (g - hg * inv)
                color[2, j, i] = hb * inv + alpha * (b - hb * inv)
                moments[0, j, i] = m1 * inv + beta * (lum - m1 * inv)
                moments[1, j, i] = m2 * inv + beta * (lum * lum - m2 * inv)
                length[j, i] = frames
            else:
                color[0, j, i] = r
                color[1, j, i] = g
                color[2, j, i] = b
                moments[0, j, i] = lum
                moments[1, j, i] = lum * lum
                length[j, i] = 1.0 if valid else 0.0


@njit(nogil=True, **_JIT)
def _variance(j0, j1, color, moments, length, guides, pad, out):
    """The colour to filter, its variance of luminance and luminance (padded planes of out):
    the variance from the temporal moments, or (short histories) from a 7 x 7 edge-aware
    neighbourhood's moments, whose mean colour then replaces the pixel's."""
    H, W = length.shape
    for j in range(j0, j1):
        jj = j + pad
        for i in range(W):
            ii = i + pad
            r, g, b = color[0, j, i], color[1, j, i], color[2, j, i]
            var = 0.0
            frames = length[j, i]
            kind = guides[G_KIND, jj, ii]
            if kind != KIND_NONE:
                if frames >= SHORT_HISTORY:
                    var = max(moments[1, j, i] - moments[0, j, i] ** 2, 0.0)
                else:
                    x, y, z = guides[G_POS, jj, ii], guides[G_POS + 1, jj, ii], guides[G_POS + 2, jj, ii]
                    n0, n1, n2 = guides[G_NORMAL, jj, ii], guides[G_NORMAL + 1, jj, ii], guides[G_NORMAL + 2, jj, ii]
                    inv_fp = guides[G_INV_FOOTPRINT, jj, ii]
                    sw = sr = sg = sb = m1 = m2 = 0.0
                    for qj in range(max(j - 3, 0), min(j + 4, H)):
                        for qi in range(max(i - 3, 0), min(i + 4, W)):
                            q, k = qj + pad, qi + pad
                            if guides[G_KIND, q, k] != kind:
                                continue
                            dn = n0 * guides[G_NORMAL, q, k] + n1 * guides[G_NORMAL + 1, q, k]
                            dn += n2 * guides[G_NORMAL + 2, q, k]
                            d = (guides[G_POS, q, k] - x) * n0 + (guides[G_POS + 1, q, k] - y) * n1
                            d += (guides[G_POS + 2, q, k] - z) * n2
                            dist = max(np.sqrt(float((qj - j) ** 2 + (qi - i) ** 2)), 1.0)
                            w = _exp_neg(np.float32(abs(d) * inv_fp / dist + SIGMA_N * (1.0 - dn)))
                            sw += w
                            sr += w * color[0, qj, qi]
                            sg += w * color[1, qj, qi]
                            sb += w * color[2, qj, qi]
                            m1 += w * moments[0, qj, qi]
                            m2 += w * moments[1, qj, qi]
                    inv = 1.0 / sw  # the pixel itself weighs 1
                    r, g, b = sr * inv, sg * inv, sb * inv
                    var = max(m2 * inv - (m1 * inv) ** 2, 0.0) * SHORT_HISTORY / max(frames, 1.0)
            out[C_RGB, jj, ii] = r
            out[C_RGB + 1, jj, ii] = g
            out[C_RGB + 2, jj, ii] = b
            out[C_VAR, jj, ii] = var
            out[C_LUM, jj, ii] = 0.2126 * r + 0.7152 * g + 0.0722 * b


@njit(nogil=True, **_JIT)
def _atrous(j0, j1, step, src, guides, pad, dst):
    """One a-trous pass with taps `step` pixels apart, src -> dst (padded planes, pad >= 2 step).
    Rows j0 .. j1 - 1 (a band); in a row, tap by tap over its pixels: first the weights, then the sums
    (two loops of contiguous loads and one stream of stores: both vectorise)."""
    W = src.shape[2] - 2 * pad
    a, b = pad, pad + W  # the row's pixels in the padded planes
    sums = np.empty((5, W), dtype=np.float32)
    weights = np.empty(W, dtype=np.float32)
    inv_l = np.empty(W, dtype=np.float32)
    for j in range(j0, j1):
        jj = j + pad
        sums[...] = 0.0
        for i in range(W):  # 1 / (SIGMA_L sqrt(var) + EPS), var through a 3 x 3 Gaussian of the pixels hit
            s = sw = 0.0
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    w = (0.5 if dy == 0 else 0.25) * (0.5 if dx == 0 else 0.25)
                    w = w if guides[G_KIND, jj + dy, i + pad + dx] != KIND_NONE else 0.0
                    s += w * src[C_VAR, jj + dy, i + pad + dx]
                    sw += w
            inv_l[i] = 1.0 / (SIGMA_L * np.sqrt(s / sw) + EPS) if sw > 0.0 else 0.0
        p0, p1, p2 = guides[G_POS, jj, a:b], guides[G_POS + 1, jj, a:b], guides[G_POS + 2, jj, a:b]
        n0, n1, n2 = guides[G_NORMAL, jj, a:b], guides[G_NORMAL + 1, jj, a:b], guides[G_NORMAL + 2, jj, a:b]
        kp, ifp, lp = guides[G_KIND, jj, a:b], guides[G_INV_FOOTPRINT, jj, a:b], src[C_LUM, jj, a:b]
        for ky in range(5):
            q = jj + (ky - 2) * step
            for kx in range(5):
                o = pad + (kx - 2) * step  # the tap's pixels: columns o .. e - 1 of row q
                e = o + W
                h = _B3[ky] * _B3[kx]
                dist = np.sqrt(np.float32((ky - 2) ** 2 + (kx - 2) ** 2))
                inv_dist = _ONE / (np.float32(step) * dist) if dist > 0 else _ZERO
                q0, q1, q2 = guides[G_POS, q, o:e], guides[G_POS + 1, q, o:e], guides[G_POS + 2, q, o:e]
                m0, m1, m2 = guides[G_NORMAL, q, o:e], guides[G_NORMAL + 1, q, o:e], guides[G_NORMAL + 2, q, o:e]
                kq, lq = guides[G_KIND, q, o:e], src[C_LUM, q, o:e]
                for i in range(W):
                    dn = n0[i] * m0[i] + n1[i] * m1[i] + n2[i] * m2[i]
                    plane = abs((q0[i] - p0[i]) * n0[i] + (q1[i] - p1[i]) * n1[i] + (q2[i] - p2[i]) * n2[i])
                    x = abs(lq[i] - lp[i]) * inv_l[i] + plane * ifp[i] * inv_dist + _SIGMA_N * (_ONE - dn)
                    weights[i] = h * _exp_neg(x) if kq[i] == kp[i] else _ZERO
                cr, cg, cb, cv = src[C_RGB, q, o:e], src[C_RGB + 1, q, o:e], src[C_RGB + 2, q, o:e], src[C_VAR, q, o:e]
                for i in range(W):
                    w = weights[i]
                    sums[0, i] += w
                    sums[1, i] += w * cr[i]
                    sums[2, i] += w * cg[i]
                    sums[3, i] += w * cb[i]
                    sums[4, i] += w * w * cv[i]
        for i in range(W):
            ii = i + pad
            if guides[G_KIND, jj, ii] == KIND_NONE:  # nothing hit: as it was
                for c in range(C_PLANES):
                    dst[c, jj, ii] = src[c, jj, ii]
            else:
                inv = _ONE / sums[0, i]  # at least the centre tap's weight
                r, g, b = sums[1, i] * inv, sums[2, i] * inv, sums[3, i] * inv
                dst[C_RGB, jj, ii] = r
                dst[C_RGB + 1, jj, ii] = g
                dst[C_RGB + 2, jj, ii] = b
                dst[C_VAR, jj, ii] = sums[4, i] * inv * inv
                dst[C_LUM, jj, ii] = _LR * r + _LG * g + _LB * b


@njit(nogil=True, **_JIT)
def _remodulate(j0, j1, src, pad, mod, emitted, out):
    """out (H, W, 3) = the filtered illumination times the modulation, plus the emitted part;
    finite and >= 0."""
    H, W = out.shape[:2]
    for j in range(j0, j1):
        for i in range(W):
            for c in range(3):
                out[j, i, c] = _finite(src[C_RGB + c, j + pad, i + pad] * mod[c, j, i] + _finite(emitted[j, i, c]))


@njit(nogil=True, **_JIT)
def _keep_history(j0, j1, src, pad, color):
    """The colour history (unpadded) from a padded pass."""
    H, W = color.shape[1:]
    for j in range(j0, j1):
        for c in range(3):
            for i in range(W):
                color[c, j, i] = src[C_RGB + c, j + pad, i + pad]


class _Frame:
    """One frame at one size: its guides (padded planes), modulation, and its history for the
    next frame (accumulated colour and moments, history lengths)."""

    def __init__(self, H: int, W: int, pad: int):
        self.pad = pad
        self.guides = np.zeros((G_PLANES, H + 2 * pad, W + 2 * pad), dtype=np.float32)
        self.illum = np.zeros((3, H, W), dtype=np.float32)
        self.mod = np.ones((3, H, W), dtype=np.float32)
        self.color = np.zeros((3, H, W), dtype=np.float32)
        self.moments = np.zeros((2, H, W), dtype=np.float32)
        self.length = np.zeros((H, W), dtype=np.float32)
        self.camera: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.length.shape


class Svgf:
    """A real-time denoiser for a stream of frames of one sample per pixel (the module
    docstring). It keeps the last frame's history and reprojects it into the next frame,
    whatever that frame's camera and size. `iterations`: a-trous passes (0: temporal
    accumulation alone)."""

    def __init__(self, iterations: int = ITERATIONS, threads: int = 1):
        if not 0 <= iterations <= 8:
            raise ValueError(f"svgf: iterations must be 0..8, got {iterations}")
        if threads < 1:
            raise ValueError(f"svgf: threads must be >= 1, got {threads}")
        self.iterations = iterations
        self.threads = threads
        self.pad = max(4, 2 << max(iterations - 1, 0))  # the widest tap reaches 2 * 2^(iterations - 1)
        self._previous: _Frame | None = None
        self._spare: _Frame | None = None
        self._passes: tuple[np.ndarray, np.ndarray] | None = None

    def reset(self) -> None:
        """Forget the history: the next frame starts anew."""
        self._previous = None

    @property
    def history_length(self) -> np.ndarray | None:
        """Frames accumulated in each pixel of the last frame (0 where nothing is hit)."""
        return None if self._previous is None else self._previous.length

    def filter(self, rgb, albedo, normal, depth, camera, emitted=None) -> np.ndarray:
        """The denoised frame (float32 (H, W, 3), finite, >= 0) of `rgb` (H, W, 3), the noisy
        radiance at the pixel centres, with the AOVs `albedo` (H, W, 3), `normal` (H, W, 3)
        and `depth` (H, W) of the same rays, `camera`, the frame's camera array
        (kernels/film/camera.py's camera_of at this size), and `emitted` (H, W, 3), the light
        seen directly at the same rays (max_depth 1), added back unfiltered, or None."""
        depth = np.ascontiguousarray(depth, dtype=np.float32)
        if depth.ndim != 2 or 0 in depth.shape:
            raise ValueError(f"svgf: depth must have shape (H, W), got {depth.shape}")
        H, W = depth.shape
        images = {"rgb": rgb, "albedo": albedo, "normal": normal, "emitted": emitted}
        if emitted is None:
            images["emitted"] = np.zeros((H, W, 3), dtype=np.float32)
        for name, array in images.items():
            images[name] = array = np.ascontiguousarray(array, dtype=np.float32)
            if array.shape != (H, W, 3):
                raise ValueError(f"svgf: {name} has shape {array.shape}; expected {(H, W, 3)}")
        camera = np.array(camera, dtype=np.float64)
        emitted = images["emitted"]
        pad = self.pad
        f = self._spare if self._spare is not None and self._spare.shape == (H, W) else _Frame(H, W, pad)
        self._spare = None
        run = self._run
        rgb, albedo, normal = images["rgb"], images["albedo"], images["normal"]
        run(_prepare, H, rgb, emitted, albedo, normal, depth, camera, pad, f.illum, f.mod, f.guides)
        p = self._previous
        if p is None:  # nothing to reproject: an empty history seen by this frame's camera
            p = _Frame(1, 1, 1)
            p.camera = camera
        history = (p.camera, p.guides, p.pad, p.color, p.moments, p.length)
        run(_reproject, H, f.illum, f.guides, pad, *history, f.color, f.moments, f.length)
        src, dst = self._pass_planes(H, W)
        run(_variance, H, f.color, f.moments, f.length, f.guides, pad, src)
        for k in range(self.iterations):
            run(_atrous, H, 1 << k, src, f.guides, pad, dst)
            src, dst = dst, src
            if k == 0:  # the first pass's output is the next frame's colour history
                run(_keep_history, H, src, pad, f.color)
        out = np.empty((H, W, 3), dtype=np.float32)
        run(_remodulate, H, src, pad, f.mod, emitted, out)
        f.camera = camera
        if self._previous is not None and self._previous.shape == (H, W) and self._previous.pad == pad:
            self._spare = self._previous  # its planes serve the frame after next
        self._previous = f
        return out

    def _run(self, kernel, H: int, *args) -> None:
        """kernel(j0, j1, *args) over rows 0..H-1: in bands on the render's lane threads
        (lanes.py; the kernels release the GIL), or here with one thread."""
        bands = min(self.threads, H)
        if bands == 1:
            kernel(0, H, *args)
            return
        from .lanes import lane_pool

        edges = [H * k // bands for k in range(bands + 1)]
        futures = [lane_pool(bands).submit(kernel, j0, j1, *args) for j0, j1 in zip(edges[:-1], edges[1:])]
        for future in futures:
            future.result()

    def _pass_planes(self, H: int, W: int) -> tuple[np.ndarray, np.ndarray]:
        """Two padded C_PLANES buffers for the passes (their padding stays 0), kept for the
        next frame of this size."""
        shape = (C_PLANES, H + 2 * self.pad, W + 2 * self.pad)
        if self._passes is None or self._passes[0].shape != shape:
            self._passes = (np.zeros(shape, np.float32), np.zeros(shape, np.float32))
        return self._passes
