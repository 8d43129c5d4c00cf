"""Small scenes swept instead of walked (kernels/geometry/sweep.py): the float32 candidates hold
every triangle the exact test hits, and the hits are the BVH walk's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

import raylume
from raylume.compile import compile_scene
from raylume.kernels.geometry.shape_triangle import INF, intersect_triangle, ray_shear
from raylume.kernels.geometry.shapes import (
    NO_HIT,
    PRIM_KIND,
    PRIM_ROW,
    PRIM_WIDTH,
    QUAD,
    TRIANGLE,
    offset_epsilon,
    sample_surface,
)
from raylume.kernels.geometry.sweep import SWEEP_LANES, SWEEP_ROWS, sweep_candidates, sweep_table
from raylume.kernels.geometry.traverse import (
    any_hit,
    any_hit_between,
    any_hit_leaving,
    closest_hit,
    closest_hit_leaving,
)
from raylume.kernels.geometry.wide_nodes import traversal_stacks
from raylume.kernels.integrators.shadow import scale_free_shadows, shadow_ray, shadow_segment
from raylume.kernels.scene import emitters_of, geometry_of, media_of
from raylume.kernels.variants import features

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def triangle_table(tris: np.ndarray) -> np.ndarray:
    """The sweep table of a scene of these triangles alone."""
    prims = np.zeros((len(tris), PRIM_WIDTH), np.int32)
    prims[:, PRIM_KIND] = TRIANGLE
    prims[:, PRIM_ROW] = np.arange(len(tris))
    return sweep_table(tris, prims, np.zeros((0, 1)), len(tris), instanced=False)


@njit
def _candidates(table, o, d, tmin, tmax):
    o, d = (o[0], o[1], o[2]), (d[0], d[1], d[2])
    return sweep_candidates(table, o, d, tmin, tmax, NO_HIT, NO_HIT)


def exact_hits(tris, o, d, tmin, tmax) -> set[int]:
    """Rows the exact float64 test (shape_triangle.intersect_triangle) hits in (tmin, tmax)."""
    shear = ray_shear(tuple(d))
    return {r for r in range(len(tris)) if intersect_triangle(tuple(o), shear, tris, r, tmin, tmax)[0] < INF}


def candidate_rows(table, o, d, tmin, tmax) -> set[int]:
    mask = int(_candidates(table, np.asarray(o), np.asarray(d), tmin, tmax))
    return {r for r in range(SWEEP_LANES) if mask >> r & 1}


def scene_and_ray(seed: int, n: int, scale_exp: int, shift_exp: int, how: str, finite: bool):
    """n triangles, a fan sharing vertices and edges, at a scale and an offset from the origin
    (where float32 loses the most), and a ray (o, d, tmin, tmax): at random, aimed at a vertex or
    an edge of one of them, or leaving one of them as a path does (offset to the side it goes
    to); its span ending a hair beyond or before its nearest hit ("up to"), or starting a hair
    before it ("from")."""
    rng = np.random.default_rng(seed)
    scale = 10.0**scale_exp
    shift = rng.uniform(-1, 1, 3) * scale * 10.0**shift_exp
    centre = rng.uniform(-1, 1, 3)
    ring = rng.uniform(-1, 1, (n + 1, 3))
    tris = np.concatenate([np.broadcast_to(centre, (n, 3)), ring[:-1], ring[1:]], axis=1)
    tris = (tris * scale + np.tile(shift, 3)).astype(np.float32)
    v = tris[int(rng.integers(n))].astype(np.float64).reshape(3, 3)
    o = shift + rng.uniform(-3, 3, 3) * scale
    if how in ("vertex", "up to", "from"):
        d = v[int(rng.integers(3))] - o
    elif how == "edge":
        a = rng.uniform()
        d = a * v[0] + (1 - a) * v[1] - o
    else:
        d = rng.normal(size=3)
    if how in ("leaving", "arriving"):
        p = rng.dirichlet((1, 1, 1)) @ v
        ng = np.cross(v[1] - v[0], v[2] - v[0])
        side = 1.0 if np.dot(d, ng) > 0 else -1.0
        if how == "arriving":  # a hair in front of the surface, going into it: a hit at t ~ 1e-7 |p|
            side = -side
        o = p + ng / np.linalg.norm(ng) * offset_epsilon(0.0, tuple(p)) * side
    d = d / np.linalg.norm(d)
    tmin, tmax = 0.0, float(rng.uniform(0, 5) * scale) if finite else INF
    if how in ("up to", "from"):
        hits = [intersect_triangle(tuple(o), ray_shear(tuple(d)), tris, r, 0.0, INF)[0] for r in range(n)]
        t = min(hits)
        if t < INF and how == "up to":  # tmax a hair beyond or before the nearest exact hit
            tmax = float(np.nextafter(t, INF if finite else 0.0))
        elif t < INF:  # tmin a hair before it (the near end of the span at the hit)
            tmin = float(np.nextafter(t, 0.0))
    return tris, o, d, tmin, tmax


HOWS = ["random", "vertex", "edge", "leaving", "arriving", "up to", "from"]


@settings(max_examples=400, deadline=None)
@given(
    st.integers(0, 2**32 - 1),
    st.integers(5, 32),
    st.integers(-3, 4),
    st.integers(0, 3),
    st.sampled_from(HOWS),
    st.booleans(),
)
def test_every_triangle_the_exact_test_hits_is_a_candidate(seed, n, scale_exp, shift_exp, how, finite):
    tris, o, d, tmin, tmax = scene_and_ray(seed, n, scale_exp, shift_exp, how, finite)
    assert exact_hits(tris, o, d, tmin, tmax) <= candidate_rows(triangle_table(tris), o, d, tmin, tmax)


def test_many_rays_hit_and_are_candidates():
    """The same on 3,000 fixed cases, of which most hit something (the check is not empty)."""
    rng = np.random.default_rng(7)
    hit = 0
    for k in range(3000):
        case = scene_and_ray(
            k,
            int(rng.integers(5, 33)),
            int(rng.integers(-3, 5)),
            int(rng.integers(0, 4)),
            HOWS[k % len(HOWS)],
            k % 4 == 0,
        )
        tris, o, d, tmin, tmax = case
        hits = exact_hits(tris, o, d, tmin, tmax)
        assert hits <= candidate_rows(triangle_table(tris), o, d, tmin, tmax), k
        hit += bool(hits)
    assert hit > 1000


def test_candidates_are_few():
    """The float32 test is a filter worth having: a ray into a closed box has few candidates
    (its hit, what lies beyond it within the margin), not every triangle."""
    S = compile_scene(raylume.load(EXAMPLES / "cornell.toml")).kernel
    rng = np.random.default_rng(1)
    counts = []
    for _ in range(300):
        o = np.array([278.0, 273.0, 280.0]) + rng.uniform(-200, 200, 3)
        d = rng.normal(size=3)
        counts.append(len(candidate_rows(S.sweep, o, d / np.linalg.norm(d), 0.0, INF)))
    assert 1 <= np.mean(counts) <= 4


def test_the_distance_leaves_out_what_lies_just_beyond_the_ray():
    """The distance is filtered on each lane's plane, within ~1e-5 (R + |t|) / |cos| (module
    docstring): a triangle a thousandth of R beyond a shadow ray's end, as the Cornell box's
    ceiling lies 0.1 above its light, is no candidate, and one a thousandth before it is."""
    rng = np.random.default_rng(3)
    checked = 0
    for seed in range(300):
        tris, *_ = scene_and_ray(seed, 12, int(rng.integers(-2, 4)), int(rng.integers(0, 3)), "random", False)
        row = int(rng.integers(len(tris)))
        v = tris[row].astype(np.float64).reshape(3, 3)
        target = rng.dirichlet((1, 1, 1)) @ v
        normal = np.cross(v[1] - v[0], v[2] - v[0])
        normal /= np.linalg.norm(normal)
        r = np.abs(tris).max() + np.abs(target).max() * 2
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        cos = abs(d @ normal)
        if cos < 0.1:
            continue
        o = target - d * rng.uniform(0.1, 2.0) * r
        t = float((target - o) @ normal / (d @ normal))
        gap = 1e-3 * (r + t) / cos
        assert row not in candidate_rows(triangle_table(tris), o, d, 0.0, t - gap), seed
        assert row in candidate_rows(triangle_table(tris), o, d, 0.0, t + gap), seed
        checked += 1
    assert checked > 100


def test_small_scenes_are_swept():
    """The Cornell box (30 triangles and its quad light: 32 lanes) is swept; a scene of too many
    triangles, of four, or with instances walks the BVH."""
    S = compile_scene(raylume.load(EXAMPLES / "cornell.toml")).kernel
    assert S.sweep.shape[1] == SWEEP_LANES
    tris = np.random.default_rng(2).uniform(-1, 1, (33, 9)).astype(np.float32)
    assert triangle_table(tris).shape[1] == 0
    assert triangle_table(tris[:4]).shape[1] == 0
    assert triangle_table(tris[:32]).shape[1] == SWEEP_LANES
    prims = np.zeros((32, PRIM_WIDTH), np.int32)
    prims[:, PRIM_KIND], prims[:, PRIM_ROW] = TRIANGLE, np.arange(32)
    assert sweep_table(tris[:32], prims, np.zeros((0, 1)), 32, instanced=True).shape[1] == 0
    assert compile_scene(raylume.load(EXAMPLES / "materials.toml")).kernel.sweep.shape[1] == 0  # no triangles


@njit
def _trace(S, X, O, D, tmax, leaving, out_t, out_prim, out_b, out_blocked, stacks):
    G = geometry_of(S)
    node_stack, t_stack = stacks
    for i in range(O.shape[0]):
        o, d = (O[i, 0], O[i, 1], O[i, 2]), (D[i, 0], D[i, 1], D[i, 2])
        if leaving[i] == NO_HIT:
            t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, tmax[i], node_stack, t_stack)
            out_blocked[i] = any_hit(G, X, o, d, 0.0, tmax[i], node_stack, t_stack)
        else:
            t, prim, b1, b2 = closest_hit_leaving(G, X, o, d, 0.0, tmax[i], leaving[i], node_stack, t_stack)
            out_blocked[i] = any_hit_leaving(G, X, o, d, 0.0, tmax[i], leaving[i], node_stack, t_stack)
        out_t[i], out_prim[i], out_b[i, 0], out_b[i, 1] = t, prim, b1, b2


def trace(S, o, d, tmax, leaving):
    n = len(o)
    out = np.empty(n), np.empty(n, np.int64), np.empty((n, 2)), np.empty(n, np.bool_)
    _trace(S, features(S), o, d, tmax, leaving, *out, traversal_stacks())
    return out


def mixed_scene():
    """A box's 12 triangles, three quads (six lanes), two spheres and a disk: swept, the quads
    through their exact triangles and the spheres and the disk tested for every ray."""
    import trimesh

    box = trimesh.creation.box(extents=(2.0, 1.0, 1.5))
    quad = {"type": "quad", "u": [1.5, 0, 0], "v": [0, 0.2, 1.0]}
    doc = {
        "objects": [
            {"type": "mesh", "vertices": box.vertices.tolist(), "faces": box.faces.tolist()},
            {**quad, "position": [0.3, 0.9, 0.1]},
            {**quad, "position": [-0.5, -0.8, 0.4], "u": [0.2, 1.1, 0.3]},
            {**quad, "position": [1.4, 0.0, -0.2], "v": [0, 1.0, 0]},
            {"type": "sphere", "center": [0.0, 0.0, 1.2], "radius": 0.4},
            {"type": "sphere", "center": [-1.3, 0.3, 0.0], "radius": 0.3},
            {"type": "disk", "center": [0.0, -0.9, -0.9], "normal": [0, 1, 0.3], "radius": 0.5},
        ]
    }
    return compile_scene(raylume.scene_from_dict(doc)).kernel


def surface_rays(S, n, rng):
    """Rays leaving the scene's triangles as path mode's do (origin offset by offset_epsilon to
    the side they go to), a third aimed at vertices and edge midpoints; and as many from points
    around the scene aimed into it. Half of each with a finite tmax. Returns (o, d, tmax,
    leaving): the triangle's primitive the first half leaves, NO_HIT for the second."""
    tris = np.asarray(S.triangles, np.float64)
    lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
    size = float((hi - lo).max())
    k = rng.integers(0, len(tris), n)
    v = tris[k].reshape(n, 3, 3)
    p = np.einsum("nj,njk->nk", rng.dirichlet((1, 1, 1), n), v)
    ng = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    ng /= np.linalg.norm(ng, axis=1)[:, None]
    d = rng.normal(size=(n, 3))
    m = n // 3
    targets = np.concatenate([v, (v + np.roll(v, 1, axis=1)) / 2], axis=1)[np.arange(m), rng.integers(0, 6, m)]
    d[:m] = targets[rng.permutation(m)] - p[:m]
    d /= np.linalg.norm(d, axis=1)[:, None]
    side = np.where((d * ng).sum(1) > 0, 1.0, -1.0)
    eps = 1e-7 * np.maximum(np.abs(p).max(axis=1), S.epsilon_floor)
    o = p + ng * (side * eps)[:, None]
    outside = (lo + hi) / 2 + rng.normal(size=(n, 3)) * size
    into = (lo + hi) / 2 + rng.uniform(-0.6, 0.6, (n, 3)) * size - outside
    o = np.concatenate([o, outside])
    d = np.concatenate([d, into / np.linalg.norm(into, axis=1)[:, None]])
    tmax = np.where(rng.random(2 * n) < 0.5, INF, rng.uniform(0, 1.5, 2 * n) * size)
    kinds, rows = S.prims[: S.n_bounded, PRIM_KIND], S.prims[: S.n_bounded, PRIM_ROW]
    prim_of_row = np.full(len(tris), -1)
    prim_of_row[rows[kinds == TRIANGLE]] = np.flatnonzero(kinds == TRIANGLE)
    leaving = np.concatenate([prim_of_row[k], np.full(n, NO_HIT)])
    return np.ascontiguousarray(o), np.ascontiguousarray(d), tmax, leaving


@pytest.mark.parametrize("name", ["cornell", "mixed"])
def test_swept_hits_are_the_bvh_walks(name):
    """Closest and any hits in a swept scene against the same scene walked: the same distance
    and blocked flag for every ray, the same primitive and barycentrics wherever the walk's hit
    is not a tie (a ray through an edge or vertex that two triangles share at the same distance:
    the sweep reports the lowest row, the walk the leaf it reached first); and leaving a surface
    (path mode's rays) changes no answer."""
    S = compile_scene(raylume.load(EXAMPLES / "cornell.toml")).kernel if name == "cornell" else mixed_scene()
    assert S.sweep.shape[1] > 0
    walked = S._replace(sweep=S.sweep[:, :0])
    o, d, tmax, leaving = surface_rays(S, 30_000, np.random.default_rng(5))
    none = np.full(len(o), NO_HIT)
    t, prim, b, blocked = trace(S, o, d, tmax, none)
    tw, primw, bw, blockedw = trace(walked, o, d, tmax, none)
    np.testing.assert_array_equal(t, tw)
    np.testing.assert_array_equal(blocked, blockedw)
    assert 0.3 < np.isfinite(t).mean() and 0.1 < blocked.mean() < 0.9
    assert len(np.unique(prim)) > S.n_bounded // 2  # most primitives are hit by some ray
    differ = prim != primw
    aimed = np.zeros(len(o), bool)
    aimed[: len(o) // 6] = True  # rays aimed at vertices and edges: ties are possible there only
    assert not (differ & ~aimed).any()
    np.testing.assert_array_equal(b[~differ], bw[~differ])
    for i in np.flatnonzero(differ):  # a tie: the walk's primitive is hit at the same distance
        row = S.prims[primw[i], PRIM_ROW]
        assert intersect_triangle(tuple(o[i]), ray_shear(tuple(d[i])), S.triangles, row, 0.0, tmax[i])[0] == t[i]
    t_l, prim_l, b_l, blocked_l = trace(S, o, d, tmax, leaving)
    np.testing.assert_array_equal(t_l, t)
    np.testing.assert_array_equal(prim_l, prim)
    np.testing.assert_array_equal(b_l, b)
    np.testing.assert_array_equal(blocked_l, blocked)


@njit
def _shadow_rays(S, W, X, K, U, floor, out, stacks):
    """Shadow rays as path mode makes them (shadow.shadow_ray), from a point of triangle
    primitive K[i, 0] (by U[i, :2]) towards a point of flat primitive K[i, 1] (a triangle or a
    quad, by U[i, 2:]), both drawn by shapes.sample_surface: blocked in S (swept, both
    primitives named), in W (walked), and in S along the unnormalized segment (shadow_segment,
    path mode's where scale_free_shadows)."""
    G, GW = geometry_of(S), geometry_of(W)
    node_stack, t_stack = stacks
    for i in range(U.shape[0]):
        p, ng = sample_surface(G, K[i, 0], U[i, 0], U[i, 1])
        q, _ = sample_surface(G, K[i, 1], U[i, 2], U[i, 3])
        to = (q[0] - p[0], q[1] - p[1], q[2] - p[2])
        dist = np.sqrt(to[0] ** 2 + to[1] ** 2 + to[2] ** 2)
        wi = (to[0] / dist, to[1] / dist, to[2] / dist)
        eps = offset_epsilon(floor, p)
        up = wi[0] * ng[0] + wi[1] * ng[1] + wi[2] * ng[2] > 0.0
        o, aim, tmax = shadow_ray(p, ng, eps if up else -eps, wi, dist)
        out[i, 0] = any_hit_between(G, X, o, aim, 0.0, tmax, K[i, 0], K[i, 1], node_stack, t_stack)
        out[i, 1] = any_hit(GW, X, o, aim, 0.0, tmax, node_stack, t_stack)
        o, seg, tmax = shadow_segment(p, ng, eps if up else -eps, wi, dist)
        out[i, 2] = any_hit_between(G, X, o, seg, 0.0, tmax, K[i, 0], K[i, 1], node_stack, t_stack)


@njit
def _scale_free(S):
    return scale_free_shadows(geometry_of(S), emitters_of(S), media_of(S))


@pytest.mark.parametrize("name", ["cornell", "mixed"])
def test_shadow_rays_leave_their_ends_out_as_the_walk_finds(name):
    """A shadow ray aimed at a point of a flat primitive and ending short of it (shadow.shadow_ray)
    cannot hit that primitive, nor the one it leaves: the sweep leaves both out of its candidates
    (any_hit_between) and answers every ray as the walk does, which tests them all. Points on
    every triangle towards points on every flat primitive, neighbours and coplanar ones (grazing
    rays) among them."""
    S = compile_scene(raylume.load(EXAMPLES / "cornell.toml")).kernel if name == "cornell" else mixed_scene()
    walked = S._replace(sweep=S.sweep[:, :0])
    kinds = S.prims[: S.n_bounded, PRIM_KIND]
    triangles = np.flatnonzero(kinds == TRIANGLE)
    flat = np.flatnonzero((kinds == TRIANGLE) | (kinds == QUAD))
    assert (kinds == QUAD).any()
    rng = np.random.default_rng(11)
    n = 60_000
    K = np.stack([rng.choice(triangles, n), rng.choice(flat, n)], axis=1).astype(np.int64)
    U = rng.random((n, 4))
    out = np.empty((n, 3), np.bool_)
    _shadow_rays(S, walked, features(S), K, U, S.epsilon_floor, out, traversal_stacks())
    assert 0.1 < out[:, 1].mean() < 0.9
    np.testing.assert_array_equal(out[:, 0], out[:, 1])
    # path mode's unnormalized shadow segments: in the Cornell box (triangles and a quad alone)
    # the same answers; the mixed scene has a sphere, whose test wants unit directions
    assert _scale_free(S) == (name == "cornell") and not _scale_free(walked)
    if name == "cornell":
        np.testing.assert_array_equal(out[:, 2], out[:, 1])


@pytest.mark.parametrize("mode", ["path", "bdpt", "cast"])
def test_a_swept_scene_renders_the_walked_ones_image(mode, monkeypatch):
    """The Cornell box's image, swept and walked: identical to the bit (path mode and bdpt's
    subpaths leave surfaces as traverse.closest_hit_leaving takes it)."""
    import raylume.compile.scene as compile_module

    scene = raylume.load(EXAMPLES / "cornell.toml")
    how = dict(mode="path", integrator="bdpt") if mode == "bdpt" else dict(mode=mode)
    swept = raylume.Session(scene).render(width=40, height=32, spp=4, **how).rgb
    monkeypatch.setattr(compile_module, "sweep_table", lambda *a, **k: np.zeros((SWEEP_ROWS, 0), np.float32))
    walked_session = raylume.Session(scene)
    assert walked_session.compiled.kernel.sweep.shape[1] == 0
    walked = walked_session.render(width=40, height=32, spp=4, **how).rgb
    assert swept.max() > 0.1
    np.testing.assert_array_equal(swept, walked)
