"""Procedural meshes: counts, closedness, orientation, no degenerate faces."""

import time

import numpy as np
import pytest
import trimesh

from raylume.scene.procedural import bumpy_sphere, grid_plane, uv_sphere, vertex_normals


def signed_volume(v, f):
    """Divergence theorem: positive when faces wind outward."""
    return float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0)


def assert_closed_and_consistent(f):
    """Every directed edge appears once and its reverse once: closed (watertight)
    and consistently wound, checked with numpy so it scales to large meshes."""
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]).astype(np.int64)
    n = int(f.max()) + 1
    code = directed[:, 0] * n + directed[:, 1]
    assert len(np.unique(code)) == len(code), "a directed edge is used twice (inconsistent winding)"
    reverse = directed[:, 1] * n + directed[:, 0]
    assert np.isin(reverse, code).all(), "an edge has only one face (hole)"


def min_sin2(v, f):
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    c = np.cross(e1, e2)
    return float((np.einsum("ij,ij->i", c, c) / (np.einsum("ij,ij->i", e1, e1) * np.einsum("ij,ij->i", e2, e2))).min())


@pytest.mark.parametrize("n", [1000, 1234, 5000, 20_000, 123_457, 1_000_000, 5_000_000])
def test_bumpy_sphere_triangle_count(n):
    v, f = bumpy_sphere(n)
    assert v.dtype == np.float64 and v.shape[1] == 3
    assert f.dtype == np.int32 and f.shape[1] == 3
    assert abs(len(f) - n) <= 0.02 * n


@pytest.mark.parametrize("n", [1000, 5000, 123_457])
def test_bumpy_sphere_closed_outward_nondegenerate(n):
    v, f = bumpy_sphere(n)
    assert f.min() == 0 and f.max() == len(v) - 1  # every vertex used
    assert_closed_and_consistent(f)
    assert signed_volume(v, f) > 0
    assert min_sin2(v, f) > 1e-12  # no zero-area triangles, poles included


def test_bumpy_sphere_is_bumpy_and_bounded():
    v, f = bumpy_sphere(20_000, radius=2.0, bumpiness=0.2)
    r = np.linalg.norm(v, axis=1)
    assert r.min() >= 2.0 * 0.8 - 1e-12 and r.max() <= 2.0 * 1.2 + 1e-12
    assert r.max() - r.min() > 0.2  # actually displaced, not a plain sphere
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0


def test_bumpy_sphere_deterministic_and_seeded():
    a = bumpy_sphere(5000, seed=3)[0]
    assert np.array_equal(a, bumpy_sphere(5000, seed=3)[0])
    assert not np.allclose(a, bumpy_sphere(5000, seed=4)[0])
    with pytest.raises(ValueError):
        bumpy_sphere(1000, bumpiness=1.0)


def test_bumpy_sphere_millions_fast():
    start = time.perf_counter()
    v, f = bumpy_sphere(4_000_000)
    elapsed = time.perf_counter() - start
    assert abs(len(f) - 4_000_000) <= 0.02 * 4_000_000
    assert elapsed < 10.0, f"4M triangles took {elapsed:.1f}s"


def test_uv_sphere_matches_analytic_sphere():
    v, f = uv_sphere(20_000, radius=2.0, center=(1.0, -2.0, 3.0))
    assert np.allclose(np.linalg.norm(v - (1.0, -2.0, 3.0), axis=1), 2.0)
    assert_closed_and_consistent(f)
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * 8, rel=2e-3)
    assert mesh.area == pytest.approx(4 * np.pi * 4, rel=2e-3)


def test_uv_sphere_tiny_counts_still_closed():
    for n in (1, 6, 7, 50):
        v, f = uv_sphere(n)
        assert len(f) >= 6
        assert_closed_and_consistent(f)
        assert signed_volume(v, f) > 0


def test_grid_plane():
    v, f = grid_plane(4, 3, size=2.0)
    assert v.shape == (20, 3) and f.shape == (24, 3) and f.dtype == np.int32
    assert np.all(v[:, 1] == 0) and v[:, 0].min() == -1 and v[:, 2].max() == 1
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    assert np.allclose(normals[:, [0, 2]], 0) and np.all(normals[:, 1] > 0)  # front faces +y
    assert np.abs(normals).sum() / 2 == pytest.approx(4.0)  # total area size^2
    with pytest.raises(ValueError):
        grid_plane(0, 3)


def test_vertex_normals_sphere_radial_and_unit():
    v, f = uv_sphere(5000)
    n = vertex_normals(v, f)
    assert n.dtype == np.float32 and n.shape == v.shape
    assert np.allclose(np.linalg.norm(n, axis=1), 1, atol=1e-6)
    assert np.einsum("ij,ij->i", n, v).min() > 0.99  # close to the radial direction


def test_vertex_normals_area_weighted_and_unused_vertex():
    # A big face in z=0 and a small one in x=0 share vertex 0; an unused vertex 5.
    v = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 1], [0, 1, 0], [7, 7, 7]], dtype=float)
    f = np.array([[0, 1, 2], [0, 3, 4]])
    n = vertex_normals(v, f)
    expected = np.array([0.0, 0.0, 100.0]) + np.array([-1.0, 0.0, 0.0])  # twice the areas
    assert np.allclose(n[0], expected / np.linalg.norm(expected), atol=1e-6)
    assert np.allclose(n[5], [0, 1, 0])  # unit fallback, not NaN
