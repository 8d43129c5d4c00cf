"""raylume.intersect's rays: directions of any length made unit vectors in the kernel, chunk by
chunk, exactly as numpy's d / np.linalg.norm(d) makes them, and rays it cannot trace refused."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numba import njit

import raylume
from raylume.compile import compile_scene
from raylume.kernels.query import CHUNK, _unit_rays, intersect_rays
from raylume.kernels.shapes import geometry_features
from raylume.scene.procedural import bumpy_sphere


@njit
def _unit_chunk(origins, directions, start, end):
    chunk_origins = np.full((CHUNK, 3), -1.0)
    chunk_directions = np.full((CHUNK, 3), -1.0)
    bad = _unit_rays(origins, directions, start, end, chunk_origins, chunk_directions)
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
    exactly those raylume.intersect refused when it checked them in numpy."""
    n = min(len(directions), len(origins))
    directions, origins = np.ascontiguousarray(directions[:n]), np.ascontiguousarray(origins[:n])
    start = min(start, n - 1)
    got_o, got_d, bad = _unit_chunk(origins, directions, start, n)
    with np.errstate(all="ignore"):
        norms = np.linalg.norm(directions, axis=1, keepdims=True)
        want = directions / norms
    refused = ~((norms[:, 0] > 0) & np.isfinite(directions).all(axis=1) & np.isfinite(origins).all(axis=1))
    np.testing.assert_array_equal(got_d, want[start:])  # NaN equals NaN here
    assert np.array_equal(got_d.view(np.int64)[~np.isnan(got_d)], want[start:].view(np.int64)[~np.isnan(got_d)])
    np.testing.assert_array_equal(got_o, origins[start:])
    assert bad == refused[start:].sum()


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
    ys, xs = np.divmod(np.arange(n), 41)
    d = np.stack([xs / 41 - 0.5, ys / 19 - 0.5, np.ones(n)], axis=1)
    o = np.broadcast_to([0.0, 0.0, -3.0], d.shape).copy()
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
