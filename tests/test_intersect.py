"""Ray-primitive intersection against analytic answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from raylume.kernels.geometry.shape_plane import intersect_plane
from raylume.kernels.geometry.shape_sphere import intersect_sphere
from raylume.kernels.geometry.wide_nodes import BVH_WIDTH, INF, box_entries

O = (0.0, 0.0, 0.0)
Z = (0.0, 0.0, 1.0)


def test_sphere_hit_from_outside_returns_near_root():
    assert intersect_sphere(O, Z, (0.0, 0.0, 5.0), 1.0, 0.0, INF) == pytest.approx(4.0, abs=1e-12)


def test_sphere_hit_from_inside_returns_far_root():
    assert intersect_sphere(O, Z, (0.0, 0.0, 0.5), 2.0, 0.0, INF) == pytest.approx(2.5, abs=1e-12)


def test_sphere_behind_origin_is_missed():
    assert intersect_sphere(O, Z, (0.0, 0.0, -5.0), 1.0, 0.0, INF) == INF


def test_sphere_tangent_ray_touches_once():
    t = intersect_sphere((1.0, 0.0, 0.0), Z, (0.0, 0.0, 5.0), 1.0, 0.0, INF)
    assert t == pytest.approx(5.0, abs=1e-6)


def test_sphere_just_outside_tangent_is_missed():
    assert intersect_sphere((1.0 + 1e-9, 0.0, 0.0), Z, (0.0, 0.0, 5.0), 1.0, 0.0, INF) == INF


def test_sphere_respects_tmax():
    assert intersect_sphere(O, Z, (0.0, 0.0, 5.0), 1.0, 0.0, 3.9) == INF


def test_huge_ground_sphere_is_precise():
    """The seed's radius-5000 ground sphere: the hit lies on the surface to ~1e-9."""
    d = (0.0, -math.sin(0.3), math.cos(0.3))
    center = (0.0, -5001.0, 0.0)
    t = intersect_sphere(O, d, center, 5000.0, 0.0, INF)
    p = tuple(t * c for c in d)
    r = math.dist(p, center)
    assert abs(r - 5000.0) < 1e-9


@settings(max_examples=200, deadline=None)
@given(
    st.tuples(*[st.floats(-100, 100)] * 3),
    st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: sum(c * c for c in v) > 1e-3),
    st.tuples(*[st.floats(-100, 100)] * 3),
    st.floats(1e-3, 100),
)
def test_sphere_hits_lie_on_the_sphere(o, d, c, r):
    n = math.sqrt(sum(x * x for x in d))
    d = tuple(x / n for x in d)
    t = intersect_sphere(o, d, c, r, 0.0, INF)
    if t == INF:
        # a miss means the line's closest approach is outside, or the sphere is behind
        oc = [c[k] - o[k] for k in range(3)]
        along = sum(oc[k] * d[k] for k in range(3))
        closest = math.sqrt(max(0.0, sum(x * x for x in oc) - along * along))
        assert closest >= r * (1 - 1e-9) or along < r
    else:
        assert t > 0 and math.isfinite(t)
        p = [o[k] + t * d[k] for k in range(3)]
        assert abs(math.dist(p, c) - r) <= 1e-9 * max(1.0, r, math.dist(o, c))


def test_plane_hit_and_parallel_miss():
    assert intersect_plane(O, Z, (0.0, 0.0, 3.0), (0.0, 0.0, -1.0), 0.0, INF) == pytest.approx(3.0)
    assert intersect_plane(O, (1.0, 0.0, 0.0), (0.0, 0.0, 3.0), (0.0, 0.0, 1.0), 0.0, INF) == INF
    assert intersect_plane(O, Z, (0.0, 0.0, -3.0), (0.0, 0.0, 1.0), 0.0, INF) == INF


def _entry(lo_hi, o, d, tmax):
    """Entry distance of the ray into a box in lane 0 of a wide node whose other lanes are
    empty (and must never be entered)."""
    bounds = np.empty((1, 6, BVH_WIDTH), np.float32)
    bounds[0, :3], bounds[0, 3:] = np.inf, -np.inf
    bounds[0, :, 0] = lo_hi
    out = box_entries(bounds, 0, tuple(map(float, o)), tuple(map(float, d)), tmax, np.empty(BVH_WIDTH))
    assert (out[1:] == INF).all()
    return out[0]


def test_box_slab_test_including_axis_parallel_rays():
    box = [-1, -1, 2, 1, 1, 4]
    assert _entry(box, O, Z, INF) == pytest.approx(2.0)
    # parallel to x and y axes, inside the slab: hit; outside the slab: miss
    assert _entry(box, (0.5, 0.5, 0.0), Z, INF) == pytest.approx(2.0)
    assert _entry(box, (1.5, 0.0, 0.0), Z, INF) == INF
    # origin inside the box: entry distance 0
    assert _entry(box, (0.0, 0.0, 3.0), Z, INF) == 0.0
    # box beyond tmax is culled
    assert _entry(box, O, Z, 1.5) == INF
    # origins between float32 values are rounded outward: a ray grazing the box's face from
    # an origin a hair inside (in float64) still enters it
    assert _entry(box, (1.0 - 1e-12, 0.0, 0.0), Z, INF) == pytest.approx(2.0)


def _textbook_slab(lo, hi, o, d, tmax):
    """Kay-Kajiya slabs with min/max per axis; axis-parallel rays handled by an explicit
    inside-the-slab check instead of a huge inverse."""
    tnear, tfar = 0.0, tmax
    for k in range(3):
        if d[k] == 0.0:
            if not lo[k] <= o[k] <= hi[k]:
                return INF
            continue
        t0, t1 = (lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]
        tnear, tfar = max(tnear, min(t0, t1)), min(tfar, max(t0, t1))
    return tnear if tnear <= tfar else INF


coord = st.floats(-10, 10, allow_nan=False, width=32)  # scene coordinates: float32 in the BVH
component = st.one_of(st.sampled_from([0.0, -0.0]), st.floats(-1, 1, allow_nan=False).filter(lambda x: abs(x) > 1e-3))


def slab_cases(test):
    """The hypothesis cases of a box test against the textbook slabs, test(a, b, o, d, tmax):
    a box between corners a and b, a ray, its tmax; with the two cases that once failed."""
    # parallel to the z slab, 1.8e-38 inside its face at 0: the slab once ended at t = 6.2,
    # before the entry at 8
    test = example(
        a=(0.0, 0.0, 0.0), b=(0.0, -2.0, -1.0), o=(4.0, -1.0, -1.8289849851155408e-38), d=(-0.5, 0.0, 0.0), tmax=INF
    )(test)
    # an entry distance in the subnormal range (2.24e-45), once computed as 2.8e-45
    test = example(
        a=(0.0, 2.0, 1.401298464324817e-45), b=(1.0, 0.0, 1.0), o=(0.0, 1.0, 0.0), d=(1.0, 0.0, 0.625), tmax=INF
    )(test)
    test = given(
        st.tuples(coord, coord, coord),
        st.tuples(coord, coord, coord),
        st.tuples(coord, coord, coord),
        st.tuples(component, component, component).filter(lambda d: any(d)),
        st.sampled_from([INF, 5.0]),
    )(test)
    return settings(max_examples=500, deadline=None)(test)


def slab_box(a, b, o, d):
    """The box (lo, hi) of a slab case's corners; a ray running exactly in the plane of one of
    its faces, parallel to it, is left out (assume): the box tests cull it (0 * 1/d = 0 ends the
    slab), measure zero, and it could only graze what the box holds."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    assume(not any(d[k] == 0.0 and o[k] in (lo[k], hi[k]) for k in range(3)))
    return lo, hi


def assert_as_textbook_slabs(got, lo, hi, o, d, tmax):
    """A box test's entry distance `got` (+inf: culled) against the textbook slabs: float32
    arithmetic, rounded so that a box the ray enters is never culled and the entry distance
    never overestimated."""
    want = _textbook_slab(lo, hi, o, d, tmax)
    # the origin moves outward by up to 2**-23 |o| before its rounding to float32 and the
    # offset -o/d by 2**-22 of itself (wide_nodes.ray_axis_ir), so distances may be short, and
    # near misses admitted, by that much
    slack = 2.0**-21 * (1.0 + max(map(abs, o))) / min(abs(c) for c in d if c != 0.0)
    if want == INF:
        # misses agree, except within rounding (the slab interval is widened)
        assert got == INF or _textbook_slab(lo - slack, hi + slack, o, d, tmax * (1 + 1e-5)) < INF
    else:
        # short of it by the relative widening and the origin's and the offsets' outward moves
        assert got <= want and want - got <= 2e-6 * want + slack


@slab_cases
def test_box_test_agrees_with_the_textbook_slab_test(a, b, o, d, tmax):
    """Near/far planes picked by the direction's sign, against min/max of both slab distances
    with exact division and zero components handled explicitly; zero and negative-zero
    components included."""
    lo, hi = slab_box(a, b, o, d)
    assert_as_textbook_slabs(_entry(np.concatenate([lo, hi]), o, d, tmax), lo, hi, o, d, tmax)
