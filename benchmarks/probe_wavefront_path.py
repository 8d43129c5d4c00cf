"""A probe, not product code: path mode on the Cornell box as a wavefront, to measure what
shading across paths in SIMD would give (issue 44), beside path mode's kernel in this process.
It led to path mode's wavefront kernel (kernels/integrators/path_wavefront.py); its recorded
figures compare it with the scalar kernel, which RAYLUME_PATH_KERNEL=scalar still selects.

    python benchmarks/probe_wavefront_path.py [--size 256] [--spp 8] [--rounds 6] [--max-depth 8]

Tiles of one image row (256 paths, one sample each) go through the bounce's stages together:
closest hits path by path (the same sweep as path mode), the diffuse surfaces into a queue, the
queue's shading as one `vector_loop` (next-event sample of the quad light with its power-heuristic
weight, the cosine sample, the throughput: LLVM vectorises it, 4 paths an AVX2 register), shadow
rays path by path, Russian roulette from segment 5, the survivors compacted. It knows only
what the Cornell box has: diffuse surfaces of one colour each and one quad light (read from the
scene), a pinhole camera; its random numbers are the sampler's keys but not path mode's streams,
so the images agree in expectation only (the means are printed, and the rays per sample).
`--scalar` runs the same stages with the shading loop inlined and left scalar, which separates
the wavefront's own effect from the SIMD's. 1 thread, CPU time, rounds alternating with path
mode; docs/architecture.md (path mode) records the figures.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from numba import njit

import raylume
from raylume.compile import compile_scene
from raylume.kernels.film.sampler import (
    DIM_BSDF,
    DIM_LIGHT,
    dimension_key,
    key_uniform2,
    pixel_sample,
    sample_key,
    sub_key,
)
from raylume.kernels.geometry.shape_quad import CENTER, NORMAL, U, V, area
from raylume.kernels.geometry.shapes import NO_HIT, PRIM_KIND, PRIM_MATERIAL, PRIM_ROW, QUAD, TRIANGLE, offset_epsilon
from raylume.kernels.geometry.traverse import any_hit_between, closest_hit_leaving
from raylume.kernels.geometry.wide_nodes import traversal_stacks
from raylume.kernels.scene import geometry_of
from raylume.kernels.shading.materials import MAT_COLOR, MAT_EMISSION
from raylume.kernels.variants import path_features
from raylume.kernels.vec import turn_in_lanes, vector_loop

CORNELL = Path(__file__).resolve().parent.parent / "examples" / "cornell.toml"
T = 256  # paths a tile
# the paths' state: rows of a flat array, row * T + slot (constant offsets: LLVM vectorises the
# loops over it; a 2D (rows, n) array's run-time stride needed too many alias checks)
OX, OY, OZ, DX, DY, DZ, BR, BG, BB, PX, PY, PZ, NX, NY, NZ, U1, U2, U3, U4, AR, AG, AB = range(22)
SX, SY, SZ, CR, CG, CB, NDX, NDY, NDZ, PREV, ROWS = range(22, 33)
INV_PI = 1.0 / math.pi


@vector_loop(fastmath=True)
def shade_diffuse(R, m, Q):
    """For queue slots 0..m-1: next-event sample of the quad light Q (corner 0-2, edges u 3-5 and
    v 6-8, unit normal 9-11, area 12, radiance 13-15), its MIS weight (power heuristic), the
    diffuse BSDF's cosine sample, the throughput."""
    for k in range(m):
        px, py, pz = R[PX * T + k], R[PY * T + k], R[PZ * T + k]
        nx, ny, nz = R[NX * T + k], R[NY * T + k], R[NZ * T + k]
        u1, u2 = R[U1 * T + k], R[U2 * T + k]
        yx = Q[0] + u1 * Q[3] + u2 * Q[6]
        yy = Q[1] + u1 * Q[4] + u2 * Q[7]
        yz = Q[2] + u1 * Q[5] + u2 * Q[8]
        tx, ty, tz = yx - px, yy - py, yz - pz
        d2 = tx * tx + ty * ty + tz * tz
        inv = 1.0 / math.sqrt(d2)
        wx, wy, wz = tx * inv, ty * inv, tz * inv
        cos_s = nx * wx + ny * wy + nz * wz
        cos_l = abs(Q[9] * wx + Q[10] * wy + Q[11] * wz)
        ok = (cos_s > 0.0) and (cos_l > 0.0)
        pdf_l = d2 / (Q[12] * cos_l) if ok else 1.0
        pdf_b = cos_s * INV_PI
        scale = (cos_s * INV_PI * pdf_l / (pdf_l * pdf_l + pdf_b * pdf_b)) if ok else 0.0
        br, bg, bb = R[BR * T + k] * R[AR * T + k], R[BG * T + k] * R[AG * T + k], R[BB * T + k] * R[AB * T + k]
        R[SX * T + k], R[SY * T + k], R[SZ * T + k] = tx, ty, tz
        R[CR * T + k], R[CG * T + k], R[CB * T + k] = br * Q[13] * scale, bg * Q[14] * scale, bb * Q[15] * scale
        sign = 1.0 if nz >= 0.0 else -1.0
        a = -1.0 / (sign + nz)
        b = nx * ny * a
        sx, sy, sz = 1.0 + sign * nx * nx * a, sign * b, -sign * nx
        vx, vy, vz = b, sign + ny * ny * a, -ny
        r = math.sqrt(R[U3 * T + k])
        c, s = turn_in_lanes(R[U4 * T + k])
        lx, ly, lz = r * c, r * s, math.sqrt(max(0.0, 1.0 - R[U3 * T + k]))
        R[NDX * T + k] = lx * sx + ly * vx + lz * nx
        R[NDY * T + k] = lx * sy + ly * vy + lz * ny
        R[NDZ * T + k] = lx * sz + ly * vz + lz * nz
        R[BR * T + k], R[BG * T + k], R[BB * T + k] = br, bg, bb
        R[PREV * T + k] = lz * INV_PI


@njit(fastmath=True)
def render_rows(S, X, img, W, H, spp, seed, stacks, R, I, light, Q, C, max_depth, shade):
    """spp samples of every pixel into img (sums), a row's pixels a tile, one sample at a time,
    through the pinhole C (position, tan of half the vertical fov: pinhole(); the image comes out
    mirrored, which no mean minds). Returns the rays traced."""
    G = geometry_of(S)
    ns, ts = stacks
    mats = S.materials
    fn = S.triangle_face_normals
    cam = (C[0], C[1], C[2])
    tanh = C[3]
    rays = 0
    for j in range(H):
        for s in range(spp):
            # camera rays: one sample of each pixel of row j
            for i in range(W):
                key = sample_key(seed, j * W + i, s)
                ux, uy = pixel_sample(key)
                x = (2.0 * (i + ux) / W - 1.0) * tanh
                y = (1.0 - 2.0 * (j + uy) / H) * tanh
                inv = 1.0 / math.sqrt(x * x + y * y + 1.0)
                R[OX * T + i], R[OY * T + i], R[OZ * T + i] = cam[0], cam[1], cam[2]
                R[DX * T + i], R[DY * T + i], R[DZ * T + i] = -x * inv, y * inv, inv
                R[BR * T + i] = R[BG * T + i] = R[BB * T + i] = 1.0
                R[PREV * T + i] = -1.0  # camera: emission at full weight
                I[0 * T + i] = i  # pixel of slot
                I[1 * T + i] = NO_HIT  # leaving
            live = W
            depth = 0
            while live > 0:
                depth += 1
                m = 0  # shading queue (compacted in place: slot order kept)
                for k in range(live):
                    o = (R[OX * T + k], R[OY * T + k], R[OZ * T + k])
                    d = (R[DX * T + k], R[DY * T + k], R[DZ * T + k])
                    t, prim, b1, b2 = closest_hit_leaving(G, X, o, d, 0.0, np.inf, I[1 * T + k], ns, ts)
                    rays += 1
                    if prim == NO_HIT:
                        continue
                    px = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
                    mat = G.prims[prim, PRIM_MATERIAL]
                    pix = I[0 * T + k]
                    if mats[mat, MAT_EMISSION] > 0.0 or mats[mat, MAT_EMISSION + 1] > 0.0:  # emissive (the light)
                        prev = R[PREV * T + k]
                        w = 1.0
                        if prev >= 0.0:
                            dd = t * t
                            cos_l = abs(Q[9] * d[0] + Q[10] * d[1] + Q[11] * d[2])
                            pdf_l = dd / (Q[12] * cos_l)
                            w = prev * prev / (prev * prev + pdf_l * pdf_l)
                        img[j, pix, 0] += R[BR * T + k] * Q[13] * w
                        img[j, pix, 1] += R[BG * T + k] * Q[14] * w
                        img[j, pix, 2] += R[BB * T + k] * Q[15] * w
                        continue
                    if depth >= max_depth:
                        continue
                    if G.prims[prim, PRIM_KIND] == TRIANGLE:
                        n = (fn[prim, 0], fn[prim, 1], fn[prim, 2])
                    else:
                        n = (0.0, 1.0, 0.0)
                    if n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0.0:
                        n = (-n[0], -n[1], -n[2])
                    eps = offset_epsilon(0.0, px)
                    key = sample_key(seed, j * W + pix, s)
                    lk = dimension_key(key, DIM_LIGHT, depth)
                    bk = dimension_key(key, DIM_BSDF, depth)
                    u1, u2 = key_uniform2(sub_key(lk, 1))
                    u3, u4 = key_uniform2(bk)
                    q = m
                    R[PX * T + q], R[PY * T + q], R[PZ * T + q] = (
                        px[0] + n[0] * eps,
                        px[1] + n[1] * eps,
                        px[2] + n[2] * eps,
                    )
                    R[NX * T + q], R[NY * T + q], R[NZ * T + q] = n
                    R[U1 * T + q], R[U2 * T + q], R[U3 * T + q], R[U4 * T + q] = u1, u2, u3, u4
                    R[AR * T + q], R[AG * T + q], R[AB * T + q] = (
                        mats[mat, MAT_COLOR],
                        mats[mat, MAT_COLOR + 1],
                        mats[mat, MAT_COLOR + 2],
                    )
                    R[BR * T + q], R[BG * T + q], R[BB * T + q] = R[BR * T + k], R[BG * T + k], R[BB * T + k]
                    I[0 * T + q] = pix
                    I[1 * T + q] = prim
                    m += 1
                shade(R, m, Q)
                live = 0
                for q in range(m):
                    # the shadow ray, then the next segment (compacted)
                    c = (R[CR * T + q], R[CG * T + q], R[CB * T + q])
                    pix = I[0 * T + q]
                    if c[0] > 0.0 or c[1] > 0.0 or c[2] > 0.0:
                        o = (R[PX * T + q], R[PY * T + q], R[PZ * T + q])
                        a = (R[SX * T + q], R[SY * T + q], R[SZ * T + q])
                        rays += 1
                        if not any_hit_between(G, X, o, a, 0.0, 1.0 - 1e-5, I[1 * T + q], light, ns, ts):
                            img[j, pix, 0] += c[0]
                            img[j, pix, 1] += c[1]
                            img[j, pix, 2] += c[2]
                    going = True
                    if depth >= 5:
                        beta_max = max(R[BR * T + q], R[BG * T + q], R[BB * T + q])
                        qq = min(beta_max, 0.95)
                        u_rr, _ = key_uniform2(sub_key(sample_key(seed, j * W + pix, s), depth))
                        if u_rr >= qq:
                            going = False
                        else:
                            R[BR * T + q] /= qq
                            R[BG * T + q] /= qq
                            R[BB * T + q] /= qq
                    if going and R[PREV * T + q] > 0.0:
                        z = live
                        R[OX * T + z], R[OY * T + z], R[OZ * T + z] = R[PX * T + q], R[PY * T + q], R[PZ * T + q]
                        R[DX * T + z], R[DY * T + z], R[DZ * T + z] = R[NDX * T + q], R[NDY * T + q], R[NDZ * T + q]
                        R[BR * T + z], R[BG * T + z], R[BB * T + z] = R[BR * T + q], R[BG * T + q], R[BB * T + q]
                        R[PREV * T + z] = R[PREV * T + q]
                        I[0 * T + z] = pix
                        I[1 * T + z] = I[1 * T + q]
                        live += 1
    return rays


def quad_light(S) -> tuple[int, tuple[float, ...]]:
    """The scene's one quad light: its primitive, and (corner, u, v, normal, area, radiance)."""
    k = int(np.flatnonzero(S.prims[: S.n_bounded, PRIM_KIND] == QUAD)[0])
    row = np.asarray(S.shapes[S.prims[k, PRIM_ROW]], np.float64)
    c, u, v = row[CENTER : CENTER + 3], row[U : U + 3], row[V : V + 3]
    m = S.materials[S.prims[k, PRIM_MATERIAL]]
    q = [*(c - 0.5 * u - 0.5 * v), *u, *v, *row[NORMAL : NORMAL + 3], float(area(row[None])[0])]
    # a tuple, passed by value: an array beside R would have to be read again after each store to R
    return k, tuple(float(x) for x in q + list(m[MAT_EMISSION : MAT_EMISSION + 3]))


def pinhole(scene) -> tuple[float, float, float, float]:
    """The scene camera's position and tan of half its vertical fov; the probe's camera rays look
    along +z with +y up, as the Cornell box's camera does (anything else is refused)."""
    c = scene.camera
    forward = np.subtract(c.look_at, c.position)
    if not (forward[0] == forward[1] == 0.0 < forward[2] and tuple(c.up) == (0.0, 1.0, 0.0) and c.aperture == 0.0):
        raise SystemExit("probe_wavefront_path: the camera must be a pinhole looking along +z with +y up")
    return (*map(float, c.position), math.tan(0.5 * math.radians(c.fov)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256, help=f"image width and height, at most {T}")
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--scalar", action="store_true", help="the shading loop inlined and scalar")
    args = ap.parse_args()
    if not 1 <= args.size <= T:
        ap.error(f"--size: a row is one tile of at most {T} paths")
    W = H = args.size
    scene = raylume.load(CORNELL)
    S = compile_scene(scene).kernel
    C = pinhole(scene)
    X = path_features(S)
    light, Q = quad_light(S)
    shade = njit(fastmath=True, inline="always")(shade_diffuse.py_func) if args.scalar else shade_diffuse
    stacks = traversal_stacks()
    R = np.zeros(ROWS * T)
    I = np.zeros(2 * T, np.int64)
    img = np.zeros((H, W, 3))
    render_rows(S, X, img, W, H, 1, 1, stacks, R, I, light, Q, C, args.max_depth, shade)
    session = raylume.Session(scene)  # the scene loaded once, for both
    size = dict(width=W, height=H, mode="path", max_depth=args.max_depth, aovs=False)
    session.render(**size, spp=1, threads=1)
    wave, path = [], []
    for r in range(args.rounds):
        img[:] = 0.0
        t = time.process_time()
        rays = render_rows(S, X, img, W, H, args.spp, 7 + r, stacks, R, I, light, Q, C, args.max_depth, shade)
        wave.append(time.process_time() - t)
        t = time.process_time()
        ref = session.render(**size, spp=args.spp, seed=7 + r, threads=1)
        path.append(time.process_time() - t)
    n = W * H * args.spp
    ratios = np.array(wave) / np.array(path)
    print(
        f"Cornell box {W} x {H}, {args.spp} spp, max_depth {args.max_depth}, 1 thread, {args.rounds} alternating rounds"
    )
    kind = "scalar" if args.scalar else "SIMD"
    for name, times, traced in ((f"wavefront ({kind} shading)", wave, rays), ("path mode", path, ref.stats["rays"])):
        t = float(np.median(times))
        print(f"  {name:28} {t:.3f} s, {t / n * 1e9:.0f} ns a sample, {traced / n:.2f} rays a sample")
    spread = f"{ratios.min():.3f}-{ratios.max():.3f}"
    print(f"  per-round ratio wavefront / path mode: median {np.median(ratios):.3f}, range {spread}")
    means = img.mean((0, 1)) / args.spp, np.asarray(ref.rgb, np.float64).mean((0, 1))
    print(f"  mean RGB: wavefront {means[0].round(5)}, path mode {means[1].round(5)}")


if __name__ == "__main__":
    from common import run_main  # (a missing bench-extra module in one line)

    run_main(main)
