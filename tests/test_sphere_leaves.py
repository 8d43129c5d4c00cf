"""Leaves of spheres tested four at once (shape_sphere.intersect_spheres): the same bits as the
one-by-one test, vector instructions in the machine code, and hits against closed-form ray-sphere
distances computed here with numpy."""

import re

import numpy as np
from numba import njit

import raylume
from raylume.accel.wide import NODE_REF, SPHERE_BLOCK, leaf_count
from raylume.compile import compile_scene
from raylume.kernels.geometry.shape_sphere import intersect_sphere, intersect_spheres
from raylume.kernels.vec import FAST


# Compiled with the kernels' fast-math flags, as the block test runs inlined in them
@njit(cache=True, fastmath=FAST)
def _block_and_loop(shapes, rows, n, o, d, tmin, tmax):
    """(t, lane) of the block test and of intersect_sphere sphere by sphere (lane -1: no hit)."""
    t4, j = intersect_spheres(shapes, rows, n, o, d, tmin, tmax)
    best, k = tmax, -1
    for i in range(n):
        r = rows[i]
        t = intersect_sphere(o, d, (shapes[r, 0], shapes[r, 1], shapes[r, 2]), shapes[r, 3], tmin, best)
        if t < best:
            best, k = t, i
    return t4, j, best, k


def test_block_equals_one_by_one_to_the_bit():
    rng = np.random.default_rng(3)
    shapes = np.zeros((12, 16))
    shapes[:, :3] = rng.normal(size=(12, 3)) * 3
    shapes[:, 3] = rng.uniform(0.1, 2.0, 12)
    shapes[7, :4] = (0.0, -5001.0, 0.0, 5000.0)  # the seed's ground: a large radius
    shapes[8, :4] = shapes[2, :4]  # two equal spheres: the lower lane wins the tie
    cases = 0
    for _ in range(30_000):
        n = int(rng.integers(1, 5))
        rows = tuple(int(r) for r in rng.integers(0, 12, 4))
        if rng.random() < 0.05:
            rows = (2, 8, 2, 8)
        o = tuple(rng.normal(size=3) * 4)
        if rng.random() < 0.2:  # from inside a sphere
            o = tuple(shapes[rows[0], :3] + rng.normal(size=3) * 0.05)
        d = rng.normal(size=3)
        d = tuple(d / np.linalg.norm(d))
        tmin = float(rng.choice([0.0, 1e-4]))
        tmax = float(rng.choice([np.inf, rng.uniform(0.0, 20.0)]))
        t4, j, t, k = _block_and_loop(shapes, rows, n, o, d, tmin, tmax)
        if k < 0:
            assert t4 == np.inf
        else:
            assert (t4, j) == (t, k)
            cases += 1
    assert cases > 5_000  # enough of them hit


def test_block_test_is_vectorised():
    # A fresh, uncached dispatcher: Numba cannot show the machine code of a kernel that another
    # test worker compiled and this one loaded from the disk cache.
    block_and_loop = njit(fastmath=FAST)(_block_and_loop.py_func)
    block_and_loop(np.zeros((1, 16)), (0, 0, 0, 0), 1, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.0, np.inf)
    asm = next(iter(block_and_loop.inspect_asm().values()))
    for op in ("vsqrtpd", "vdivpd", "vmulpd", "vsubpd"):
        assert re.search(rf"{op}\s+[^\n]*%ymm", asm), f"no 4-wide {op} in the sphere block test"


def test_seed_scene_is_one_leaf_of_four_spheres():
    kernel = compile_scene(raylume.builtin_scene("seed")).kernel
    assert kernel.node_index.shape[0] == 1
    assert leaf_count(kernel.node_index[0, NODE_REF, 0]) == -(SPHERE_BLOCK + 4)


def _closed_form(centers, radii, o, d):
    """Nearest positive root of |o + t d - c|^2 = r^2 over the spheres (d unit), per ray."""
    oc = o[:, None, :] - centers[None]
    b = np.einsum("nkc,nc->nk", oc, d)
    disc = b**2 - (np.einsum("nkc,nkc->nk", oc, oc) - radii**2)
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    t = np.where(-b - root > 1e-9, -b - root, -b + root)
    t = np.where((disc >= 0) & (t > 1e-9), t, np.inf)
    return t.min(axis=1), np.where(np.isfinite(t.min(axis=1)), t.argmin(axis=1), -1)


def test_hits_in_a_bvh_of_sphere_blocks_match_closed_form():
    rng = np.random.default_rng(11)
    centers = rng.uniform(-4, 4, (60, 3))
    radii = rng.uniform(0.2, 0.8, 60)
    scene = raylume.scene_from_dict(
        {"objects": [{"type": "sphere", "center": c.tolist(), "radius": float(r)} for c, r in zip(centers, radii)]}
    )
    compiled = compile_scene(scene)
    refs = compiled.kernel.node_index[:, NODE_REF, :]
    assert ((refs < 0) & (leaf_count(refs) < -SPHERE_BLOCK)).any(), "no leaf became a sphere block"
    o = np.tile([0.0, 0.0, -12.0], (4000, 1))
    d = np.column_stack([rng.uniform(-0.4, 0.4, 4000), rng.uniform(-0.4, 0.4, 4000), np.ones(4000)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t, obj, _ = raylume.intersect(compiled, o, d)
    want_t, want_obj = _closed_form(centers, radii, o, d)
    np.testing.assert_array_equal(obj, want_obj)
    hit = np.isfinite(want_t)
    assert 0.2 < hit.mean() < 0.95
    np.testing.assert_allclose(t[hit], want_t[hit], rtol=1e-12, atol=1e-12)


def test_a_root_leaf_of_five_to_eight_spheres_is_one_block_with_closed_form_hits():
    """Scenes of 5 to 8 spheres (examples/materials.toml has six) are one root leaf tested four
    spheres at a time; its hits, and which sphere, are the closed form's."""
    rng = np.random.default_rng(12)
    for n in (5, 6, 7, 8):
        centers = rng.uniform(-2, 2, (n, 3))
        radii = rng.uniform(0.3, 0.9, n)
        scene = raylume.scene_from_dict(
            {"objects": [{"type": "sphere", "center": c.tolist(), "radius": float(r)} for c, r in zip(centers, radii)]}
        )
        kernel = compile_scene(scene).kernel
        assert kernel.node_index.shape[0] == 1 and leaf_count(kernel.node_index[0, NODE_REF, 0]) == -(SPHERE_BLOCK + n)
        o = np.tile([0.0, 0.0, -9.0], (3000, 1))
        d = np.column_stack([rng.uniform(-0.35, 0.35, 3000), rng.uniform(-0.35, 0.35, 3000), np.ones(3000)])
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        t, obj, _ = raylume.intersect(compile_scene(scene), o, d)
        want_t, want_obj = _closed_form(centers, radii, o, d)
        np.testing.assert_array_equal(obj, want_obj)
        hit = np.isfinite(want_t)
        assert 0.1 < hit.mean() < 0.98, n
        np.testing.assert_allclose(t[hit], want_t[hit], rtol=1e-12, atol=1e-12)
