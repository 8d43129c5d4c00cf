"""The wavefront's sphere tests (kernels/geometry/wavefront_spheres.py), eight rays per vector, against
the scalar sphere test (shape_sphere.intersect_sphere) ray by ray: the same closest hits to the
last bit, and the same shadow answers, the sign-only test towards directional lights included,
on random rays and on the cases where signs and zeros decide (rays from a sphere's surface,
tangent rays, b = +0 and -0, rays away from the sphere)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from raylume.kernels.geometry.shape_sphere import intersect_sphere
from raylume.kernels.geometry.wavefront_spheres import tile_blocks, tile_closest
from raylume.kernels.integrators.wavefront import STRIDE

INF = math.inf
OX, OY, OZ, DX, DY, DZ, T = (r * STRIDE for r in range(7))
FLAG = 0

finite = st.floats(-6.0, 6.0, allow_nan=False, allow_infinity=False)


@st.composite
def rays(draw, centre, radius):
    """A ray aimed near the sphere, or from a point of its surface, or along an axis (signed
    zeros in the direction)."""
    kind = draw(st.sampled_from(["near", "surface", "axis", "random"]))
    c = np.array(centre)
    if kind == "surface":
        n = np.array([draw(finite), draw(finite), draw(finite)])
        n = n / np.linalg.norm(n) if np.linalg.norm(n) > 1e-3 else np.array([0.0, 1.0, 0.0])
        o = c + radius * n
    else:
        o = np.array([draw(finite), draw(finite), draw(finite)])
    if kind == "axis":
        d = np.zeros(3)
        d[draw(st.integers(0, 2))] = draw(st.sampled_from([1.0, -1.0]))
        d = np.where(d == 0, draw(st.sampled_from([0.0, -0.0])), d)
    else:
        aim = c + np.array([draw(finite), draw(finite), draw(finite)]) * (radius / 4 if kind == "near" else 1.0)
        d = aim - o
        if np.linalg.norm(d) < 1e-6:
            d = np.array([0.0, 0.0, 1.0])
        d = d / np.linalg.norm(d)
    return o, d


@st.composite
def cases(draw):
    spheres = [
        ([draw(finite), draw(finite), draw(finite)], draw(st.floats(0.05, 3.0))) for _ in range(draw(st.integers(1, 4)))
    ]
    n = draw(st.integers(1, 19))
    ray_list = [draw(rays(*spheres[draw(st.integers(0, len(spheres) - 1))])) for _ in range(n)]
    tmax = [draw(st.one_of(st.just(INF), st.floats(0.01, 20.0))) for _ in range(n)]
    return spheres, ray_list, tmax


def _scratch(ray_list, spheres):
    """The flat scratch rows of the rays (padded as the wavefront's are) and the sphere table."""
    R = np.zeros(8 * STRIDE)
    for i, (o, d) in enumerate(ray_list):
        for r, v in zip((OX, OY, OZ, DX, DY, DZ), (*o, *d)):
            R[r + i] = v
    table = np.array([[*c, r] for c, r in spheres], dtype=np.float64)
    return R, np.zeros(2 * STRIDE, dtype=np.int64), table


TANGENT = ([([0.0, 0.0, 5.0], 1.0)], [(np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))], [INF])
ON_SURFACE_LEAVING = ([([0.0, 0.0, 5.0], 1.0)], [(np.array([0.0, 0.0, 4.0]), np.array([0.0, 0.0, -1.0]))], [INF])
B_ZERO = ([([0.0, 0.0, 0.0], 1.0)], [(np.array([0.0, 0.5, 0.0]), np.array([1.0, 0.0, -0.0]))], [INF])


@settings(max_examples=150, deadline=None)
@given(cases())
@example(TANGENT)
@example(ON_SURFACE_LEAVING)
@example(B_ZERO)
def test_closest_hits_are_the_scalar_tests(case):
    spheres, ray_list, _ = case
    R, I, table = _scratch(ray_list, spheres)
    m = len(ray_list)
    R[T : T + m] = INF
    I[:m] = -1
    tile_closest(R, I, (OX, OY, OZ, DX, DY, DZ, T, 0), m, table, 0, len(spheres))
    for i, (o, d) in enumerate(ray_list):
        best, prim = INF, -1
        for k, (c, r) in enumerate(spheres):
            t = intersect_sphere((o[0], o[1], o[2]), (d[0], d[1], d[2]), (c[0], c[1], c[2]), r, 0.0, best)
            if t < best:
                best, prim = t, k
        assert R[T + i] == best or (math.isnan(best) and math.isnan(R[T + i])), (i, R[T + i], best)
        assert I[i] == prim


@settings(max_examples=150, deadline=None)
@given(cases())
@example(TANGENT)
@example(ON_SURFACE_LEAVING)
@example(B_ZERO)
def test_shadow_answers_are_the_scalar_tests(case):
    """Towards a directional light (every tmax infinite: the sign-only test) and a point light
    (tmax finite), rays already blocked or needing no ray left alone."""
    spheres, ray_list, tmax = case
    for directional in (True, False):
        R, I, table = _scratch(ray_list, spheres)
        m = len(ray_list)
        limits = [INF] * m if directional else tmax
        R[T : T + m] = limits
        state = np.array([(0, 0, 1, -1)[i % 4] if i % 5 else 0 for i in range(m)], dtype=np.int64)
        I[:m] = state
        tile_blocks(R, I, (OX, OY, OZ, DX, DY, DZ, T, 0), m, table, 0, len(spheres), directional)
        for i, (o, d) in enumerate(ray_list):
            if state[i] != 0:
                assert I[i] == state[i]
                continue
            blocked = any(
                intersect_sphere((o[0], o[1], o[2]), (d[0], d[1], d[2]), (c[0], c[1], c[2]), r, 0.0, limits[i]) < INF
                for c, r in spheres
            )
            assert I[i] == (1 if blocked else 0), (directional, i, o, d, limits[i])


@pytest.mark.parametrize("m", [1, 7, 8, 9, 16, 250])
def test_lanes_past_the_count_are_left_alone(m):
    """Slots from m on hold rays that would hit; they must not change, nor count."""
    spheres = [([0.0, 0.0, 5.0], 1.0)]
    ray_list = [(np.zeros(3), np.array([0.0, 0.0, 1.0]))] * min(m + 8, STRIDE)
    R, I, table = _scratch(ray_list, spheres)
    R[T : T + STRIDE] = INF
    I[:STRIDE] = -1
    tile_closest(R, I, (OX, OY, OZ, DX, DY, DZ, T, 0), m, table, 0, 1)
    assert (R[T : T + m] == 4.0).all() and (I[:m] == 0).all()
    assert (R[T + m : T + STRIDE] == INF).all() and (I[m:STRIDE] == -1).all()
    I[:STRIDE] = 0
    tile_blocks(R, I, (OX, OY, OZ, DX, DY, DZ, T, 0), m, table, 0, 1, True)
    assert (I[:m] == 1).all() and (I[m:STRIDE] == 0).all()
