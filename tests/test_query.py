"""raylume.intersect's and raylume.occluded's rays: directions of any length made unit vectors in
the kernel, chunk by chunk, exactly as numpy's d / np.linalg.norm(d) makes them, rays they cannot
trace refused; occlusion between tmin and tmax against closest hits and the single-ray any-hit."""

from __future__ import annotations

import warnings
from pathlib import Path

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numba import njit
from test_packets import _any_hits  # the single-ray answers, ray by ray

import raylume
from raylume.compile import compile_scene
from raylume.kernels.geometry.query import (
    CHUNK,
    PACKET,
    _unit_rays,
    chunk_layout,
    chunk_scratch,
    grid_width,
    load_chunk,
)
from raylume.kernels.geometry.traverse import closest_hit
from raylume.kernels.geometry.wide_nodes import TRAVERSAL_STACK
from raylume.kernels.scene import geometry_of
from raylume.kernels.variants import geometry_features
from raylume.query_lanes import intersect_rays
from raylume.scene.procedural import bumpy_sphere


@njit
def _unit_chunk(origins, directions, start, end):
    chunk_origins = np.full((CHUNK, 3), -1.0)
    chunk_directions = np.full((CHUNK, 3), -1.0)
    bad = _unit_rays(origins, directions, start, end - start, 1, 0, chunk_origins, chunk_directions)
    return chunk_origins[: end - start], chunk_directions[: end - start], bad


# components from subnormal to overflowing squares, infinities, NaN and zeros
_component = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1.0, 1e-170, 1e160, 5e-324]),
)


@settings(max_examples=150, deadline=None)
@given(
    hnp.arrays(np.float64, st.tuples(st.integers(1, 19), st.just(3)), elements=_component),
    hnp.arrays(np.float64, st.tuples(st.integers(1, 19), st.just(3)), elements=_component),
    st.integers(0, 18),
)
def test_unit_directions_are_numpys_to_the_bit(directions, origins, start):
    """Four rays per vector and the scalar tail alike: each direction is numpy's d / |d| to the
    last bit (NaN where numpy gives NaN), the origins are copied, and the rays counted as bad are
    exactly the zero directions and those with a component that is not finite. A direction
    whose squares would overflow or underflow (a component past 2^500, or all below 2^-500) is
    scaled by a power of two first, so that it still becomes a unit vector (numpy's d / |d| of
    1e160 is 0, of 1e-170 a division by 0)."""
    n = min(len(directions), len(origins))
    directions, origins = np.ascontiguousarray(directions[:n]), np.ascontiguousarray(origins[:n])
    start = min(start, n - 1)
    got_o, got_d, bad = _unit_chunk(origins, directions, start, n)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # nanmax of a row of NaN: "All-NaN slice"
        m = np.nanmax(np.abs(directions), axis=1, keepdims=True) if n else np.zeros((0, 1))
        scaled = directions * np.where(m > 2.0**500, 2.0**-600, np.where(m < 2.0**-500, 2.0**600, 1.0))
        norms = np.linalg.norm(scaled, axis=1, keepdims=True)
        want = scaled / norms
    refused = ~((norms[:, 0] > 0) & np.isfinite(directions).all(axis=1) & np.isfinite(origins).all(axis=1))
    good = ~refused[start:]
    np.testing.assert_allclose(np.linalg.norm(got_d[good], axis=1), 1.0, rtol=1e-15)  # unit vectors, every one
    assert (np.sign(got_d[good]) * np.sign(directions[start:][good]) >= 0).all()  # (a tiny one beside a huge: 0)
    np.testing.assert_array_equal(got_d, want[start:])  # NaN equals NaN here
    assert np.array_equal(got_d.view(np.int64)[~np.isnan(got_d)], want[start:].view(np.int64)[~np.isnan(got_d)])
    np.testing.assert_array_equal(got_o, origins[start:])
    assert bad == refused[start:].sum()


def _camera_rays(n):
    """n rays of a camera 3 units in front of the mesh, 64 pixels a row across +-0.42 (eight
    neighbours within 6 degrees: coherent, traced as packets), rows 0.06 apart."""
    ys, xs = np.divmod(np.arange(n), 64)
    d = np.stack([(xs - 31.5) * 0.0133, (ys - ys.max() / 2) * 0.06, np.ones(n)], axis=1)
    return np.broadcast_to([0.0, 0.0, -3.0], d.shape).copy(), d


@pytest.fixture(scope="module")
def bumpy(tmp_path_factory):
    import trimesh

    v, f = bumpy_sphere(4000)
    path = tmp_path_factory.mktemp("query") / "bumpy.ply"
    trimesh.Trimesh(v, f, process=False).export(path)
    return compile_scene(raylume.scene_from_dict({"objects": [{"type": "mesh", "file": str(path), "smooth": False}]}))


@pytest.mark.parametrize("threads", [1, 2])
def test_intersect_takes_directions_of_any_length(bumpy, threads):
    """raylume.intersect with directions scaled by factors from 1e-3 to 1e3 gives, ray for ray,
    the hits of the kernel given numpy's unit directions (packets and single rays alike: a
    camera's rays, then the same rays shuffled), also in a last chunk that is not a multiple of
    four rays."""
    rng = np.random.default_rng(threads)
    n = 3 * CHUNK + 7
    o, d = _camera_rays(n)
    for order in (np.arange(n), rng.permutation(n)):
        dd = d[order] * 10.0 ** rng.uniform(-3, 3, size=(n, 1))
        previous = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            got = raylume.intersect(bumpy, o, dd)
        finally:
            numba.set_num_threads(previous)
        unit = dd / np.linalg.norm(dd, axis=1, keepdims=True)
        want = np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32)
        S = bumpy.for_camera((0.0, 0.0, 0.0))
        assert intersect_rays(S, geometry_features(S), o, unit, *want, 1) == 0
        for g, w in zip(got, want[:3], strict=True):
            np.testing.assert_array_equal(g, w)
        assert np.isfinite(got[0]).sum() > n // 4 and not np.isfinite(got[0]).all()  # hits and misses


@pytest.mark.parametrize("scale", [2.0**-1000, 2.0**-530, 2.0**515, 2.0**1000])
def test_directions_of_any_finite_length_find_the_same_hits(bumpy, scale):
    """Directions whose squared length overflows or underflows float64 (numpy's norm gives inf
    or 0) hit what their unit vectors hit, to the bit (scaled by powers of two: the same
    directions), as the vector path (whole groups of four) and the scalar tail (the last three)
    alike."""
    o, d = _camera_rays(64 + 3)
    want = raylume.intersect(bumpy, o, d)
    for query_d in (d * scale, d[::-1].copy()[::-1] * scale):
        got = raylume.intersect(bumpy, o, query_d)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)
    np.testing.assert_array_equal(raylume.occluded(bumpy, o, d * scale), np.isfinite(want[0]))


@pytest.mark.parametrize(
    ("where", "value"),
    [("direction", 0.0), ("direction", np.nan), ("direction", np.inf), ("origin", np.inf), ("origin", np.nan)],
)
def test_intersect_refuses_rays_it_cannot_trace(bumpy, where, value):
    """A zero, NaN or infinite direction, or an origin that is not finite, anywhere among the
    rays (here the last of a chunk's odd tail) is a ValueError, as it was when numpy checked."""
    n = CHUNK + 3
    o = np.zeros((n, 3))
    o[:, 2] = -3.0
    d = np.tile([0.0, 0.0, 1.0], (n, 1))
    if where == "direction":
        d[-1] = value
    else:
        o[-1, 1] = value
    with pytest.raises(ValueError, match="directions must be finite and non-zero, origins finite"):
        raylume.intersect(bumpy, o, d)
    t, obj, _ = raylume.intersect(bumpy, o[:-1], d[:-1])  # the others are fine
    assert (obj == 0).all() and np.allclose(t, 2.0, atol=0.1)


@pytest.mark.parametrize("threads", [1, 2])
def test_occluded_is_a_hit_between_tmin_and_tmax(bumpy, threads):
    """raylume.occluded on a camera's rays (packets) and the same rays shuffled (ray by ray):
    with tmin 0, blocked exactly where intersect's nearest hit lies before tmax; with tmin
    past that hit, blocked where the ray meets the far side of the closed mesh; and every
    answer the single-ray any_hit's, ray for ray, for spans that start and end anywhere."""
    rng = np.random.default_rng(threads + 10)
    n = 4 * CHUNK + 5
    o, d = _camera_rays(n)
    d = d * 2.0
    t, _, _ = raylume.intersect(bumpy, o, d)
    hit = np.isfinite(t)
    assert 0.2 < hit.mean() < 0.9
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        for order in (np.arange(n), rng.permutation(n)):
            oo, dd, tt, hh = o[order], d[order], t[order], hit[order]
            tmax = np.where(hh, tt * rng.choice([0.999, 1.001], size=n), 10.0)
            np.testing.assert_array_equal(raylume.occluded(bumpy, oo, dd, tmax=tmax), hh & (tt < tmax))
            assert raylume.occluded(bumpy, oo, dd).tolist() == hh.tolist()  # tmax inf by default
            behind = raylume.occluded(bumpy, oo, dd, tmin=np.where(hh, tt * 1.0001, 0.0))
            assert behind[hh].mean() > 0.99 and not behind[~hh].any()
            tmin = rng.uniform(0, 4, size=n)
            tmax = tmin + rng.uniform(0, 2, size=n)
            unit = dd / np.linalg.norm(dd, axis=1, keepdims=True)
            got = raylume.occluded(bumpy, oo, dd, tmin=tmin, tmax=tmax)
            want = _any_hits(bumpy.for_camera((0.0, 0.0, 0.0)), oo, unit, tmin, tmax)
            np.testing.assert_array_equal(got, want)
            assert 0.05 < want.mean() < 0.95
    finally:
        numba.set_num_threads(previous)


def test_occluded_keeps_the_rays_shape_and_refuses_what_intersect_refuses(bumpy):
    o = np.zeros((2, 3, 3))
    o[..., 2] = -3.0
    d = np.zeros((2, 3, 3))
    d[..., 2] = 1.0
    d[1, 2] = [0.0, 1.0, 0.0]  # up: misses
    blocked = raylume.occluded(bumpy, o, d, tmax=[[5.0], [1.0]])  # tmax per row, broadcast
    assert blocked.shape == (2, 3) and blocked.dtype == np.bool_
    assert blocked.tolist() == [[True, True, True], [False, False, False]]
    with pytest.raises(ValueError, match="broadcast"):
        raylume.occluded(bumpy, o, d, tmax=np.ones(4))
    d[0, 1] = 0.0
    with pytest.raises(ValueError, match="directions must be finite and non-zero"):
        raylume.occluded(bumpy, o, d)


@njit
def _closest(S, origins, directions, tmin, tmax):
    """closest_hit ray by ray on unit directions: (t, primitive) the query must give."""
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK, np.float32)
    G = geometry_of(S)
    out = np.empty((origins.shape[0], 2))
    for k in range(origins.shape[0]):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (directions[k, 0], directions[k, 1], directions[k, 2])
        t, prim, _, _ = closest_hit(G, None, o, d, tmin[k], tmax[k], node_stack, t_stack)
        out[k, 0], out[k, 1] = t, prim
    return out


def test_intersect_finds_the_nearest_hit_between_tmin_and_tmax(bumpy):
    """raylume.intersect with tmin and tmax (numbers, per-ray arrays, a column broadcast over
    the rays' shape): each ray's t is the single-ray closest_hit's between them (inf and -1
    where there is none), in packets (a camera's rays) and ray by ray (shuffled); tmin past the
    first hit finds the mesh's far side."""
    rng = np.random.default_rng(7)
    n = 3 * CHUNK + 3
    o, d = _camera_rays(n)
    t0, _, _ = raylume.intersect(bumpy, o, d)
    hit = np.isfinite(t0)
    S = bumpy.for_camera((0.0, 0.0, 0.0))
    unit = d / np.linalg.norm(d, axis=1, keepdims=True)
    for order in (np.arange(n), rng.permutation(n)):
        oo, dd, uu = o[order], d[order], unit[order]
        tmin = np.where(hit[order], t0[order] * 1.0001, 0.0)  # past the first hit
        tmax = np.where(rng.random(n) < 0.5, np.inf, rng.uniform(2, 4, n))
        t, obj, prim = raylume.intersect(bumpy, oo, dd, tmin=tmin, tmax=tmax)
        want = _closest(S, oo, uu, tmin, tmax)
        found = want[:, 1] >= 0
        np.testing.assert_array_equal(t, np.where(found, want[:, 0], np.inf))
        assert ((obj == -1) == ~found).all() and ((prim == -1) == ~found).all()
        assert (t[found] > tmin[found]).all() and (t[found] < tmax[found]).all()
        far_side = found & hit[order] & np.isinf(tmax)
        assert far_side.sum() > 0.9 * (hit[order] & np.isinf(tmax)).sum()
    # numbers and a column broadcast over a (2, n // 2) grid of rays
    t, _, _ = raylume.intersect(bumpy, o, d, tmax=2.5)
    np.testing.assert_array_equal(t, np.where(t0 < 2.5, t0, np.inf))
    m = n // 2 * 2
    grid = (o[:m].reshape(2, -1, 3), d[:m].reshape(2, -1, 3))
    t, _, _ = raylume.intersect(bumpy, *grid, tmax=[[2.5], [np.inf]])
    np.testing.assert_array_equal(
        t, np.where([[True], [False]] & (t0[:m].reshape(2, -1) >= 2.5), np.inf, t0[:m].reshape(2, -1))
    )


def test_a_negative_tmin_is_refused(bumpy):
    """Rays start at their origin (the box test keeps nothing behind it, as Embree asks tnear >=
    0): a negative or NaN tmin is a ValueError for both queries, numbers and arrays alike."""
    o, d = _camera_rays(16)
    for tmin in (-1e-9, np.full(16, -1.0)):
        for query in (raylume.intersect, raylume.occluded):
            with pytest.raises(ValueError, match="tmin must be at least 0"):
                query(bumpy, o, d, tmin=tmin)
    # NaN (numpy's reading of None, too) would make every ray miss: refused, for tmin and tmax
    for span in ({"tmin": np.where(np.arange(16) == 5, np.nan, 0.0)}, {"tmax": np.nan}, {"tmax": None}):
        for query in (raylume.intersect, raylume.occluded):
            with pytest.raises(ValueError, match="must not be NaN|not None"):
                query(bumpy, o, d, **span)
    t, _, _ = raylume.intersect(bumpy, o, d, tmin=np.zeros(16))  # 0 itself is a start
    np.testing.assert_array_equal(t, raylume.intersect(bumpy, o, d)[0])


@njit
def _image_chunks(origins, directions, width, shares, per_share):
    """Every chunk of an image's rays as intersect_lane loads them: (their copied origins and
    unit directions, in the order they are traced, the chunks' sizes, the bad rays counted)."""
    n = origins.shape[0]
    scratch = chunk_scratch()
    got_o, got_d = np.empty((n, 3)), np.empty((n, 3))
    sizes = np.empty(shares * per_share, np.int64)
    at = bad = 0
    for share in range(shares):
        for segment in range(per_share):
            _, m, _, _, b = load_chunk(origins, directions, True, width, share, segment, scratch[0], scratch[1])
            got_o[at : at + m] = scratch[0][:m]
            got_d[at : at + m] = scratch[1][:m]
            sizes[share * per_share + segment] = m
            at += m
            bad += b
    return got_o[:at], got_d[:at], sizes, bad


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 7), st.integers(8, 300), st.integers(0, 2**32 - 1))
def test_an_images_rays_go_in_packets_of_4_by_2(rows, width, seed):
    """The chunks of an image of rows x width rays hold every ray once (each known by its
    origin), at most CHUNK each; each packet (eight rays in a row of the chunk) is four
    neighbours in one row above four in the next (eight along a lone last row; narrower at a
    band's right end), each with numpy's unit vector of its direction, bad rays counted as
    _unit_rays counts them."""
    rng = np.random.default_rng(seed)
    n = rows * width
    origins = np.stack([np.arange(n, dtype=np.float64), rng.normal(size=n), rng.normal(size=n)], axis=1)
    directions = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1))
    directions[rng.random(n) < 0.02] = 0.0
    got_o, got_d, sizes, bad = _image_chunks(origins, directions, width, *chunk_layout(n, width))
    ids = got_o[:, 0].astype(np.int64)  # the ray each row of the chunks holds
    assert sorted(ids.tolist()) == list(range(n)) and (sizes <= CHUNK).all()
    np.testing.assert_array_equal(got_o, origins[ids])
    with np.errstate(all="ignore"):
        want = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    np.testing.assert_array_equal(got_d, want[ids])
    assert bad == int((np.linalg.norm(directions, axis=1) == 0).sum())
    at = 0
    for m in sizes:
        for p in range(at, at + m, PACKET):
            y, x = np.divmod(ids[p : min(p + PACKET, at + m)], width)
            if y.min() == y.max():  # a lone last row: neighbours along it
                assert rows % 2 == 1 and y[0] == rows - 1 and x.max() - x.min() == len(x) - 1
            else:  # two rows: the same columns in both, at most four
                assert y.max() - y.min() == 1 and x.max() - x.min() < PACKET // 2
                assert sorted(x[y == y.min()].tolist()) == sorted(x[y == y.max()].tolist())
        at += m


def test_rays_trace_as_an_image_when_they_form_one():
    """grid_width: the last axis of rays in rows of at least eight, at least two rows of them."""
    assert grid_width((480, 640)) == 640
    assert grid_width((2, 3, 8)) == 8 and grid_width((2, 1, 8)) == 8
    assert grid_width((1000,)) == 0 and grid_width((1, 640)) == 0 and grid_width((640, 7)) == 0
    assert grid_width((0, 640)) == 0


def _image_rays(rows, width):
    """A rows x width image of camera rays 3 units in front of the mesh, the mesh in its middle
    (its directions not unit vectors)."""
    y, x = np.mgrid[0:rows, 0:width] + 0.5
    pitch = 1.2 / max(rows, width)
    d = np.stack([(x - width / 2) * pitch, (y - rows / 2) * pitch, np.full(x.shape, 1.0)], axis=-1)
    return np.broadcast_to([0.0, 0.0, -3.0], d.shape).copy(), 2.0 * d


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize(("rows", "width"), [(37, 45), (6, 300), (1, 64)])
def test_an_images_rays_find_what_single_rays_find(bumpy, threads, rows, width):
    """raylume.intersect on rays of shape (rows, width, 3), traced in 4 x 2 packets (a lone last
    row, a band's narrower right end, a second band) and stored in the image's order: ray for
    ray, the single-ray closest_hit's hits, with tmin and tmax numbers (and with per-pixel
    ones, which keep the rays in their order); raylume.occluded on them, any_hit's answers; a
    zero direction in a whole group of four or in a narrower one is refused."""
    rng = np.random.default_rng(rows)
    o, d = _image_rays(rows, width)
    flat_o, flat_d = o.reshape(-1, 3), d.reshape(-1, 3)
    unit = flat_d / np.linalg.norm(flat_d, axis=1, keepdims=True)
    S = bumpy.for_camera((0.0, 0.0, 0.0))
    spans = ((0.0, np.inf), (1.0, 2.9), (rng.uniform(0, 3, (rows, width)), rng.uniform(2.5, 5, (rows, width))))
    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        for tmin, tmax in spans:
            t, obj, prim = raylume.intersect(bumpy, o, d, tmin=tmin, tmax=tmax)
            assert t.shape == obj.shape == prim.shape == (rows, width)
            per_ray = [np.broadcast_to(v, (rows, width)).reshape(-1) for v in (tmin, tmax)]
            want = _closest(S, flat_o, unit, *per_ray)
            found = want[:, 1] >= 0
            np.testing.assert_array_equal(t.reshape(-1), np.where(found, want[:, 0], np.inf))
            np.testing.assert_array_equal(prim.reshape(-1) >= 0, found)
            np.testing.assert_array_equal(obj.reshape(-1) == 0, found)
            assert 0.1 < found.mean() < 0.95
            blocked = raylume.occluded(bumpy, o, d, tmin=tmin, tmax=tmax)
            np.testing.assert_array_equal(blocked.reshape(-1), _any_hits(S, flat_o, unit, *per_ray))
        faces = raylume.intersect(bumpy, flat_o, flat_d)[2]  # in a row: the faces hit
        np.testing.assert_array_equal(raylume.intersect(bumpy, o, d)[2].reshape(-1), faces)
        for column in (width // 2 & ~3, width - 1):  # a whole group, and the last (narrower) one
            bad = d.copy()
            bad[rows - 1, column] = 0.0
            with pytest.raises(ValueError, match="directions must be finite and non-zero"):
                raylume.intersect(bumpy, o, bad)
    finally:
        numba.set_num_threads(previous)


@pytest.mark.parametrize("example", ["seed.toml", "meshes.toml"])
def test_camera_rays_find_what_a_cast_render_sees(example):
    """raylume.camera_rays through raylume.intersect (an image: 4 x 2 packets) against the AOVs
    of a one-sample cast render, which makes its rays in its own kernels: the same object and
    primitive at every pixel, and the same distance to float32 (the AOV's precision)."""
    scene = raylume.load_scene(Path(__file__).parents[1] / "examples" / example)
    image = raylume.render(scene, width=64, height=48, spp=1, mode="cast")
    t, obj, prim = raylume.intersect(scene, *raylume.camera_rays(scene, 64, 48))
    assert t.shape == (48, 64)
    np.testing.assert_array_equal(obj, image.aovs["object"])
    np.testing.assert_array_equal(prim, image.aovs["prim"])
    assert 0 < np.isfinite(t).sum() < t.size  # something hit, something missed
    np.testing.assert_allclose(t.astype(np.float32), image.aovs["depth"], rtol=2.0**-23, atol=0)


def test_a_session_is_a_scene_to_query():
    """raylume.intersect and raylume.occluded take a Session (its compiled scene and BVH) and
    answer as for its Scene; what they cannot take is a TypeError naming what they take."""
    scene = raylume.builtin_scene("seed")
    session = raylume.Session(scene)
    origins, directions = raylume.camera_rays(scene, 16, 12)
    for a, b in zip(raylume.intersect(session, origins, directions), raylume.intersect(scene, origins, directions)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(
        raylume.occluded(session, origins, directions), raylume.occluded(scene, origins, directions)
    )
    # the red sphere's centre ray: a hit at distance 2 (the seed: centre (0, -1, 3), radius 1)
    t, obj, _ = raylume.intersect(session, np.zeros((1, 3)), np.array([[0.0, -1.0, 3.0]]))
    assert obj[0] == 0 and t[0] == pytest.approx(np.sqrt(10.0) - 1.0)
    with pytest.raises(TypeError, match="Session, a Scene, a CompiledScene"):
        raylume.intersect(42, origins, directions)
