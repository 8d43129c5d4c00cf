"""Triangles and the BVH: analytic hits, barycentrics, BVH == brute force, meshes vs analytic shapes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

import raylume
from raylume.accel.wide import NODE_REF, NODE_ROWS, leaf_count, leaf_first, leaf_ref
from raylume.compile import compile_scene
from raylume.kernels.geometry.layout import LEAF_COUNTS, LEAF_FIRST_LIMIT
from raylume.kernels.geometry.shape_triangle import INF, intersect_triangle, ray_shear
from raylume.kernels.geometry.shape_triangle import normals as triangle_normals_at
from raylume.kernels.geometry.shapes import PRIM_FACE, PRIM_KIND, TRIANGLE
from raylume.kernels.geometry.traverse import any_hit, closest_hit
from raylume.kernels.geometry.wide_nodes import BVH_WIDTH, TRAVERSAL_STACK
from raylume.kernels.scene import geometry_of
from raylume.scene.procedural import bumpy_sphere


def tri_row(a, b, c):
    return np.array([[*a, *b, *c]], dtype=np.float32)


def hit(o, d, tri, tmin=0.0, tmax=INF):
    d = np.asarray(d, dtype=np.float64)
    d = tuple(d / np.linalg.norm(d))
    return intersect_triangle(tuple(map(float, o)), ray_shear(d), tri, 0, tmin, tmax)


TRI = tri_row((-1, -1, 5), (1, -1, 5), (0, 1, 5))


def test_centre_hit_distance_and_barycentrics_reconstruct_the_point():
    t, b1, b2 = hit((0.1, -0.2, 0), (0, 0, 1), TRI)
    assert t == pytest.approx(5.0, abs=1e-12)
    v0, v1, v2 = TRI[0, :3].astype(float), TRI[0, 3:6].astype(float), TRI[0, 6:].astype(float)
    p = (1 - b1 - b2) * v0 + b1 * v1 + b2 * v2
    np.testing.assert_allclose(p, (0.1, -0.2, 5), atol=1e-12)


def test_back_face_is_hit_too():
    t, _, _ = hit((0, 0, 10), (0, 0, -1), TRI)
    assert t == pytest.approx(5.0)


def test_parallel_ray_misses():
    assert hit((0, 0, 5), (1, 0, 0), TRI)[0] == INF
    assert hit((0, 0, 0), (1, 0, 0), TRI)[0] == INF


def test_outside_and_behind_miss():
    assert hit((2, 0, 0), (0, 0, 1), TRI)[0] == INF
    assert hit((0, 0, 6), (0, 0, 1), TRI)[0] == INF


def test_vertices_and_edges_are_hit():
    for x, y in [(-1, -1), (1, -1), (0, 1), (0, -1), (0.5, 0), (-0.5, 0)]:
        t, b1, b2 = hit((x, y, 0), (0, 0, 1), TRI)
        assert t == pytest.approx(5.0), (x, y)
        assert -1e-12 <= b1 <= 1 and -1e-12 <= b2 <= 1 and b1 + b2 <= 1 + 1e-12


def test_shared_edge_of_two_triangles_has_no_gap():
    """Rays along a diagonal shared by two triangles hit one of them, every time (watertight)."""
    quad = np.array([[0, 0, 3, 1, 0, 3, 1, 1, 3.0], [0, 0, 3, 1, 1, 3, 0, 1, 3.0]], dtype=np.float32)
    rng = np.random.default_rng(1)
    o = np.array([0.3, 0.7, -1.0])
    for s in rng.uniform(0.01, 0.99, 2000):
        target = np.array([s, s, 3.0])
        d = target - o
        d /= np.linalg.norm(d)
        shear = ray_shear(tuple(d))
        hits = [intersect_triangle(tuple(o), shear, quad, k, 0.0, INF)[0] for k in range(2)]
        assert min(hits) < INF


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.floats(-10, 10), min_size=9, max_size=9),
    st.lists(st.floats(-10, 10), min_size=3, max_size=3),
    st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: sum(c * c for c in v) > 1e-4),
)
def test_random_rays_never_nan_and_hits_lie_in_the_triangle(verts, o, d):
    tri = np.array([verts], dtype=np.float32)
    t, b1, b2 = hit(o, d, tri)
    assert not math.isnan(t) and not math.isnan(b1) and not math.isnan(b2)
    if t < INF:
        assert t > 0
        assert b1 >= -1e-9 and b2 >= -1e-9 and b1 + b2 <= 1 + 1e-9
        v = tri[0].astype(np.float64).reshape(3, 3)
        p = (1 - b1 - b2) * v[0] + b1 * v[1] + b2 * v[2]
        dn = np.asarray(d) / np.linalg.norm(d)
        np.testing.assert_allclose(np.asarray(o) + t * dn, p, atol=1e-6 * max(1.0, np.abs(p).max(), t))


# --- BVH against brute force -------------------------------------------------------------------
# The helpers below are compiled in the test process, uncached (test_box_test_is_vectorised reads
# their machine code): the tests that call them share one xdist worker, which compiles them once.
BRUTE_FORCE_WORKER = pytest.mark.xdist_group("bvh_brute_force")


@njit
def _closest_all(S, origins, dirs, X=None):
    n = origins.shape[0]
    out_t = np.empty(n)
    out_i = np.empty(n, np.int64)
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK)
    G = geometry_of(S)
    for k in range(n):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (dirs[k, 0], dirs[k, 1], dirs[k, 2])
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, INF, node_stack, t_stack)
        out_t[k] = t
        out_i[k] = S.prims[prim, PRIM_FACE] if prim >= 0 and S.prims[prim, PRIM_KIND] == TRIANGLE else -1
    return out_t, out_i


@njit
def _any_all(S, origins, dirs, tmax, X=None):
    n = origins.shape[0]
    out = np.empty(n, np.bool_)
    node_stack = np.empty(TRAVERSAL_STACK, np.int32)
    t_stack = np.empty(TRAVERSAL_STACK, np.float32)
    G = geometry_of(S)
    for k in range(n):
        out[k] = any_hit(
            G,
            X,
            (origins[k, 0], origins[k, 1], origins[k, 2]),
            (dirs[k, 0], dirs[k, 1], dirs[k, 2]),
            0.0,
            tmax[k],
            node_stack,
            t_stack,
        )
    return out


@njit
def _brute(tris, origins, dirs):
    n = origins.shape[0]
    out_t = np.full(n, np.inf)
    out_i = np.full(n, -1, np.int64)
    for k in range(n):
        o = (origins[k, 0], origins[k, 1], origins[k, 2])
        d = (dirs[k, 0], dirs[k, 1], dirs[k, 2])
        shear = ray_shear(d)
        for f in range(tris.shape[0]):
            t, b1, b2 = intersect_triangle(o, shear, tris, f, 0.0, out_t[k])
            if t < out_t[k]:
                out_t[k] = t
                out_i[k] = f
    return out_t, out_i


def _mesh_scene(tmp_path, vertices, faces, name="m.ply"):
    path = tmp_path / name
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return raylume.scene_from_dict({"objects": [{"type": "mesh", "file": str(path)}]})


def _random_rays(rng, n, center, spread):
    origins = center + rng.normal(size=(n, 3)) * spread * 3
    targets = center + rng.normal(size=(n, 3)) * spread * 0.5
    dirs = targets - origins
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return origins, dirs


@BRUTE_FORCE_WORKER
@pytest.mark.parametrize("kind", ["soup", "bumpy"])
def test_bvh_closest_hit_equals_brute_force(tmp_path, kind):
    rng = np.random.default_rng(7)
    if kind == "soup":  # random overlapping triangles: the hardest case for a BVH
        centers = rng.uniform(-1, 1, size=(3000, 1, 3))
        v = (centers + rng.normal(scale=0.08, size=(3000, 3, 3))).reshape(-1, 3)
        f = np.arange(len(v)).reshape(-1, 3)
    else:
        v, f = bumpy_sphere(20000)
    scene = _mesh_scene(tmp_path, v, f)
    compiled = compile_scene(scene)
    origins, dirs = _random_rays(rng, 3000, np.zeros(3), 1.0)
    t_bvh, i_bvh = _closest_all(compiled.kernel, origins, dirs)
    tris = (v.astype(np.float32)[f]).reshape(-1, 9)
    t_ref, i_ref = _brute(tris, origins, dirs)
    assert (t_ref < INF).sum() > 500
    np.testing.assert_allclose(t_bvh, t_ref, rtol=1e-12)  # same hits, to the last bits
    same = i_bvh == i_ref
    # where two triangles give the very same t (shared edges), either index is right
    assert same.mean() > 0.999
    occluded = _any_all(compiled.kernel, origins, dirs, np.where(np.isfinite(t_ref), t_ref * 1.0001, 1e30))
    np.testing.assert_array_equal(occluded, np.isfinite(t_ref))
    shorter = _any_all(compiled.kernel, origins, dirs, np.where(np.isfinite(t_ref), t_ref * 0.9999, 1e30))
    assert not shorter[np.isfinite(t_ref)].any()


@BRUTE_FORCE_WORKER
def test_public_intersect_equals_brute_force_on_all_threads(tmp_path):
    """raylume.intersect (threads take interleaved chunks of rays) against the brute force:
    distances to the last bits, face indices, object ids, misses; directions need not be unit."""
    rng = np.random.default_rng(11)
    v, f = bumpy_sphere(5000)
    trimesh.Trimesh(v, f, process=False).export(tmp_path / "m.ply")
    scene = raylume.scene_from_dict(
        {
            "objects": [
                {"type": "sphere", "center": [0, 0, 40], "radius": 0.5},  # object 0: far away, never hit
                {"type": "mesh", "file": str(tmp_path / "m.ply")},
            ]
        }
    )
    origins, dirs = _random_rays(rng, 5000, np.zeros(3), 1.0)
    t, obj, prim = raylume.intersect(scene, origins, dirs * rng.uniform(0.5, 3.0, size=(len(dirs), 1)))
    t_ref, i_ref = _brute((v.astype(np.float32)[f]).reshape(-1, 9), origins, dirs)
    hit = np.isfinite(t_ref)
    assert 1000 < hit.sum() < len(t_ref)
    np.testing.assert_allclose(t, t_ref, rtol=1e-12)
    assert (obj[hit] == 1).all() and (obj[~hit] == -1).all() and (prim[~hit] == -1).all()
    assert (prim[hit] == i_ref[hit]).mean() > 0.999  # shared edges: either face is right
    with pytest.raises(ValueError, match="non-zero"):
        raylume.intersect(scene, origins[:2], np.zeros((2, 3)))


@BRUTE_FORCE_WORKER
def test_bvh_on_a_real_mesh_equals_brute_force(shared_models, tmp_path):
    from raylume.scene.mesh import load_mesh

    mesh = load_mesh(shared_models / "stanford-bunny.obj")
    scene = raylume.scene_from_dict({"objects": [{"type": "mesh", "file": str(shared_models / "stanford-bunny.obj")}]})
    compiled = compile_scene(scene)
    center = mesh.vertices.mean(axis=0)
    spread = mesh.vertices.std()
    origins, dirs = _random_rays(np.random.default_rng(3), 1500, center, spread)
    t_bvh, _ = _closest_all(compiled.kernel, origins, dirs)
    t_ref, _ = _brute((mesh.vertices.astype(np.float32)[mesh.faces]).reshape(-1, 9), origins, dirs)
    assert np.isfinite(t_ref).sum() > 300
    np.testing.assert_allclose(t_bvh, t_ref, rtol=1e-12)  # same hits, to the last bits


def test_mesh_sphere_depth_agrees_with_analytic_sphere(tmp_path):
    """A finely tessellated sphere and the analytic sphere give the same depth, up to the
    tessellation's sagitta (the chord's distance below the true surface)."""
    mesh = trimesh.creation.icosphere(subdivisions=6, radius=1.0)  # 81920 faces
    path = tmp_path / "sphere.ply"
    mesh.export(path)
    common = {
        "render": {"width": 64, "height": 64, "mode": "cast"},
        "camera": {"position": [0, 0, -4], "look_at": [0, 0, 0]},
    }
    mesh_scene = raylume.scene_from_dict({**common, "objects": [{"type": "mesh", "file": str(path)}]})
    sphere_scene = raylume.scene_from_dict(
        {**common, "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}]}
    )
    d_mesh = raylume.render(mesh_scene).aovs["depth"]
    d_sphere = raylume.render(sphere_scene).aovs["depth"]
    both = np.isfinite(d_mesh) & np.isfinite(d_sphere)
    assert both.sum() > 500
    edge_len = np.linalg.norm(mesh.vertices[mesh.edges[:, 0]] - mesh.vertices[mesh.edges[:, 1]], axis=1).max()
    sagitta = edge_len**2 / 8
    # along a ray the gap grows as the surface turns away; skip the grazing rim
    central = both & (d_sphere < 3.5)
    assert np.all(d_mesh[central] - d_sphere[central] >= -1e-5)
    assert np.all(d_mesh[central] - d_sphere[central] <= 3 * sagitta)
    # silhouettes differ at most by a pixel ring
    assert (np.isfinite(d_mesh) != np.isfinite(d_sphere)).sum() < 0.02 * 64 * 64


def test_plane_and_two_triangles_agree():
    common = {
        "render": {"width": 40, "height": 30, "mode": "cast"},
        "camera": {"position": [0, 2, -3], "look_at": [0, 0, 2]},
    }
    big = 50.0
    quad = [
        {"type": "triangle", "vertices": [[-big, 0, -big], [big, 0, -big], [big, 0, big]]},
        {"type": "triangle", "vertices": [[-big, 0, -big], [big, 0, big], [-big, 0, big]]},
    ]
    plane = [{"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0]}]
    a = raylume.render(raylume.scene_from_dict({**common, "objects": quad}))
    b = raylume.render(raylume.scene_from_dict({**common, "objects": plane}))
    near = np.isfinite(b.aovs["depth"]) & (b.aovs["depth"] < 40)
    np.testing.assert_allclose(a.aovs["depth"][near], b.aovs["depth"][near], rtol=1e-5)
    np.testing.assert_allclose(a.aovs["normal"][near], b.aovs["normal"][near], atol=1e-6)
    assert set(np.unique(a.aovs["prim"][near])) <= {0} and set(np.unique(a.aovs["object"][near])) <= {0, 1}


def test_transformed_mesh_lands_where_the_transform_says(tmp_path):
    box = trimesh.creation.box(extents=(1, 1, 1))  # centred at the origin
    path = tmp_path / "box.ply"
    box.export(path)
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 33, "height": 33, "mode": "cast"},
            "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1], "fov": 40},
            "objects": [
                {
                    "type": "mesh",
                    "file": str(path),
                    "transform": {"scale": [2, 2, 0.5], "rotate": [0, 90, 0], "translate": [0, 0, 10]},
                }
            ],
        }
    )
    img = raylume.render(scene)
    # rotated 90 degrees about y, the box's x extent (2) now lies along z: the front face is at z = 9
    assert img.aovs["depth"][16, 16] == pytest.approx(9.0, abs=1e-5)
    np.testing.assert_allclose(img.aovs["normal"][16, 16], [0, 0, -1], atol=1e-6)
    # and its z extent (0.5) along x: half-width 0.25 at distance 9 subtends atan(0.25/9)
    row = np.isfinite(img.aovs["depth"][16])
    half_width_px = row.sum() / 2
    expected = math.tan(math.atan(0.25 / 9)) / math.tan(math.radians(20)) * 16.5
    assert abs(half_width_px - expected) <= 1.0


def test_mirrored_mesh_keeps_outward_normals(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=3)
    path = tmp_path / "s.ply"
    mesh.export(path)
    for scale in ([1, 1, 1], [-1, 1, 1]):
        scene = raylume.scene_from_dict(
            {
                "render": {"width": 16, "height": 16, "mode": "cast"},
                "objects": [{"type": "mesh", "file": str(path), "transform": {"scale": scale, "translate": [0, 0, 4]}}],
            }
        )
        compiled = compile_scene(scene)
        tri = compiled.kernel.triangles.reshape(-1, 3, 3).astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        outward = np.einsum("ij,ij->i", n, tri.mean(axis=1) - [0, 0, 4])
        assert (outward > 0).all()


def test_stats_report_triangles_and_bvh(tmp_path):
    v, f = bumpy_sphere(5000)
    img = raylume.render(_mesh_scene(tmp_path, v, f), width=16, height=16)
    s = img.stats
    assert s["triangles"] == len(f) and s["primitives"] == len(f)
    # wide nodes of up to BVH_WIDTH children over leaves of up to 4 triangles
    assert s["bvh_nodes"] > len(f) / (4 * BVH_WIDTH) and s["bvh_bytes"] > 0 and s["build_seconds"] > 0


def test_rays_through_a_shared_diagonal_hit_inside_the_renderer(tmp_path):
    """Pixel centres exactly on the diagonal of a quad split in two: every pixel is covered,
    through the whole kernel pipeline (camera, traversal, fast-math callers), not only when the
    triangle test is called on its own."""
    for faces in ([[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]):
        path = tmp_path / "quad.obj"
        trimesh.Trimesh([[-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], faces, process=False).export(path)
        for fov, size in ((90, 4), (60, 4), (90, 64)):
            scene = raylume.scene_from_dict(
                {
                    "render": {"width": size, "height": size, "mode": "cast"},
                    "camera": {"fov": fov},
                    "objects": [{"type": "mesh", "file": str(path)}],
                }
            )
            assert (raylume.render(scene).aovs["object"] == 0).all(), (faces, fov, size)


# --- the wide BVH: structure, vector code, awkward rays -----------------------------------------


@BRUTE_FORCE_WORKER
def test_box_test_is_vectorised():
    """The wide box test runs as 8-wide vector instructions (ymm vfmadd/vmulps/vmaxps/vminps/
    vcmpps with AVX2 and FMA) inside the traversal that every mode inlines: fails loudly if a change
    turns it back into scalar code."""
    import re

    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features().flatten().split(",")
    if "+avx2" not in features or "+fma" not in features:
        pytest.skip("the CPU has no AVX2 and FMA: no 8-wide float32 registers or multiply-adds to check for")
    assert BVH_WIDTH == 8
    v, f = bumpy_sphere(500)
    tris = compile_scene(raylume.scene_from_dict({"objects": [{"type": "triangle", "vertices": v[f[0]].tolist()}]}))
    _closest_all(tris.kernel, np.zeros((1, 3)), np.ones((1, 3)))
    asm = "\n".join(_closest_all.inspect_asm().values())
    for op in ("vmaxps", "vminps", "vcmp[a-z]*ps", "vfmadd[0-9]*ps", "vmulps"):
        assert re.search(rf"\b{op}\s+[^\n]*%ymm", asm), f"no 8-wide {op} in the traversal: the box test is scalar"


@pytest.mark.parametrize("width", [2, 4, 8])
def test_collapsed_bvh_keeps_every_leaf_and_box(width):
    """Every leaf of the binary tree appears in exactly one lane; every lane's box is the
    binary child's box; unused lanes hold the empty box; children follow their parent."""
    from raylume.accel.bvh import build_bvh
    from raylume.accel.wide import collapse, wide_depth

    rng = np.random.default_rng(5)
    lo = rng.uniform(-1, 1, size=(3000, 3))
    hi = lo + rng.uniform(0, 0.1, size=(3000, 3))
    binary = build_bvh(lo, hi, max_leaf_size=4)
    wide = collapse(binary, width)
    b, ix = wide.node_bounds, wide.node_index
    assert b.shape == (len(ix), NODE_ROWS, width) and b.dtype == np.float32 and ix.dtype == np.int32
    assert np.shares_memory(b, ix)  # one record per node
    refs = ix[:, NODE_REF, :]
    leaves = sorted(zip(leaf_first(refs[refs < 0]).tolist(), leaf_count(refs[refs < 0]).tolist(), strict=True))
    leaf = binary.node_axis < 0
    assert leaves == sorted(map(tuple, binary.node_index[leaf].tolist()))
    used = np.isfinite(b[:, 0, :]) & (b[:, 0, :] <= b[:, 3, :])
    assert (used.sum(axis=1) >= 2).all() or len(ix) == 1
    assert np.all(b[:, :3][~np.broadcast_to(used[:, None], b[:, :3].shape)] == np.inf)
    assert (refs[~used] == 0).all()
    inner = used & (refs >= 0)
    m_of = np.nonzero(inner)
    children = refs[inner]
    assert (children > m_of[0]).all() and sorted(children.tolist()) == list(range(1, len(ix)))
    for m, k, c in zip(*m_of, children, strict=True):  # a child's lanes lie within its box
        sub = used[c]
        assert (b[c, :3][:, sub] >= b[m, :3, k : k + 1]).all() and (b[c, 3:6][:, sub] <= b[m, 3:6, k : k + 1]).all()
    assert wide_depth(wide) <= int(np.ceil(np.log2(len(binary.node_axis)))) + 1


@pytest.mark.parametrize("width", [4, 8])
def test_wide_depth_is_the_longest_path_from_the_root(width):
    """wide_depth against the recursive definition (a node is one level above its deepest inner
    child), on a bushy tree, a deep one (boxes spaced geometrically) and a lone leaf."""
    from raylume.accel.bvh import build_bvh
    from raylume.accel.wide import collapse, single_leaf, wide_depth

    def depth(ix, m):
        inner = [int(ix[m, NODE_REF, k]) for k in range(ix.shape[2]) if ix[m, NODE_REF, k] > m]
        return 1 + max((depth(ix, c) for c in inner), default=0)

    rng = np.random.default_rng(7)
    lo = rng.uniform(-1, 1, size=(2000, 3))
    deep = np.stack([1.3 ** np.arange(60.0)] * 3, axis=1)
    for lo_, hi_ in ((lo, lo + 0.05), (deep, deep * 1.01)):
        wide = collapse(build_bvh(lo_, hi_, max_leaf_size=1), width)
        assert wide_depth(wide) == depth(wide.node_index, 0) > 1
    assert wide_depth(single_leaf(lo[:3], lo[:3] + 0.1, width)) == 1


@given(first=st.integers(0, LEAF_FIRST_LIMIT - 1), count=st.sampled_from(LEAF_COUNTS))
def test_a_leaf_reference_gives_back_its_first_primitive_and_count(first, count):
    """A leaf's reference is a negative int32 (an inner child's is its node, >= 0), from which
    its first primitive and count field come back, in Python and in numpy alike."""
    ref = leaf_ref(first, count)
    assert -(2**31) <= ref < 0
    assert (leaf_first(ref), leaf_count(ref)) == (first, count)
    as32 = np.array([ref], np.int32)
    assert (int(leaf_first(as32)[0]), int(leaf_count(as32)[0])) == (first, count)


def test_leaves_and_bvhs_beyond_what_a_reference_holds_are_refused(monkeypatch):
    from raylume.accel import wide
    from raylume.accel.bvh import build_bvh
    from raylume.errors import SceneError

    lo = np.zeros((40, 3))  # one point forty times: no split separates them
    with pytest.raises(ValueError, match="a leaf of 40 primitives"):
        wide.collapse(build_bvh(lo, lo + 1.0, max_leaf_size=64))
    monkeypatch.setattr("raylume.compile.geometry.LEAF_FIRST_LIMIT", 100)
    v, f = bumpy_sphere(200)
    scene = raylume.scene_from_dict({"objects": [{"type": "mesh", "vertices": v.tolist(), "faces": f.tolist()}]})
    with pytest.raises(SceneError, match="200 primitives, more than the 100 a scene holds"):
        compile_scene(scene)
    grid = [{"translate": [x, 0, 0]} for x in range(101)]
    small = {"type": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "faces": [[0, 1, 2]]}
    many = raylume.scene_from_dict({"objects": [{**small, "instances": grid}]})
    with pytest.raises(SceneError, match="101 instances, more than the 100 a scene holds"):
        compile_scene(many)


@pytest.mark.parametrize("n", [16, 200, 5000])
def test_a_single_leaf_of_more_primitives_than_a_leaf_holds_is_a_flat_tree(n):
    """Modes that never trace rays take every primitive in order (single_leaf): beyond a leaf's
    15, leaves of consecutive primitives under nodes in order, a valid BVH: each primitive in
    one leaf, each lane's box holding its primitives' boxes or its child node's lanes, children
    after their parent."""
    from raylume.accel.wide import single_leaf, wide_depth

    rng = np.random.default_rng(n)
    lo = rng.uniform(-1, 1, size=(n, 3))
    hi = lo + rng.uniform(0, 0.1, size=(n, 3))
    tree = single_leaf(lo, hi, BVH_WIDTH)
    b, refs = tree.node_bounds, tree.node_index[:, NODE_REF, :]
    used = b[:, 0, :] <= b[:, 3, :]
    assert (refs[~used] == 0).all()
    leaves = sorted(zip(leaf_first(refs[refs < 0]).tolist(), leaf_count(refs[refs < 0]).tolist(), strict=True))
    assert [f for f, _ in leaves] == list(range(0, n, 15)) and sum(c for _, c in leaves) == n
    assert max(c for _, c in leaves) <= LEAF_COUNTS[-1]
    for m, k in zip(*np.nonzero(used), strict=True):
        if refs[m, k] < 0:
            first, count = leaf_first(refs[m, k]), leaf_count(refs[m, k])
            inside_lo, inside_hi = lo[first : first + count], hi[first : first + count]
        else:
            c = refs[m, k]
            assert c > m
            inside_lo, inside_hi = b[c, :3][:, used[c]].T, b[c, 3:6][:, used[c]].T
        assert (inside_lo >= b[m, :3, k]).all() and (inside_hi <= b[m, 3:6, k]).all()
    assert sorted(refs[used & (refs > 0)].tolist()) == list(range(1, len(b)))
    depth, lanes = 1, BVH_WIDTH  # the levels of nodes needed to hold that many leaves
    while lanes < len(leaves):
        depth, lanes = depth + 1, lanes * BVH_WIDTH
    assert wide_depth(tree) == depth


@BRUTE_FORCE_WORKER
def test_awkward_rays_against_brute_force(tmp_path):
    """A grid of coplanar triangles and degenerate ones: rays exactly through vertices and
    along edges (in the plane, grazing), axis-parallel rays, zero and NaN directions. Closest
    hit equals the brute force (the same triangle test, no BVH), any-hit agrees with it."""
    n = 12
    g = np.linspace(-1, 1, n + 1)
    xs, ys = np.meshgrid(g, g)
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    q = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    f = np.concatenate([np.stack([q, q + 1, q + n + 2], 1), np.stack([q, q + n + 2, q + n + 1], 1)])
    # degenerate: a zero-area sliver (collinear) and a point, above the grid
    v = np.concatenate([v, [[0, 0, 0.5], [0.5, 0.5, 0.5], [1, 1, 0.5], [0.2, 0.2, 0.7]]])
    m = len(v)
    f = np.concatenate([f, [[m - 4, m - 3, m - 2], [m - 1, m - 1, m - 1]]])
    scene = _mesh_scene(tmp_path, v, f, "grid.ply")
    compiled = compile_scene(scene)
    assert compiled.stats["bvh_nodes"] > 1
    rng = np.random.default_rng(2)
    targets = np.concatenate([v[: (n + 1) ** 2], (v[f[:50, 0]] + v[f[:50, 1]]) / 2])  # vertices, edge midpoints
    o_down = np.concatenate([targets + [0, 0, 2], targets + rng.normal(scale=0.5, size=targets.shape) + [0, 0, 2]])
    d_down = np.concatenate([np.broadcast_to([0.0, 0.0, -1.0], targets.shape), targets - o_down[len(targets) :]])
    # in the plane of the grid, along grid lines and diagonals, from outside
    o_flat = np.array([[-2, gy, 0] for gy in g] + [[gx, -2, 0] for gx in g] + [[-2, -2, 0], [2, -2, 0]], float)
    d_flat = np.array([[1, 0, 0]] * len(g) + [[0, 1, 0]] * len(g) + [[1, 1, 0], [-1, 1, 0]], float)
    o_odd = np.array([[0.1, 0.1, 1.0], [0.1, 0.1, 1.0], [0.1, 0.1, 1.0], [np.nan, 0, 1], [0.3, 0.3, 1.0]])
    d_odd = np.array([[0, 0, 0], [np.nan, 0, -1], [0, np.nan, np.nan], [0, 0, -1], [0, 0, -np.inf]])
    origins = np.concatenate([o_down, o_flat, o_odd])
    dirs = np.concatenate([d_down, d_flat, d_odd])
    with np.errstate(invalid="ignore"):
        norm = np.linalg.norm(dirs, axis=1, keepdims=True)
        dirs = np.where(norm > 0, dirs / np.where(norm > 0, norm, 1), dirs)
    t_bvh, i_bvh = _closest_all(compiled.kernel, origins, dirs)
    tris = (v.astype(np.float32)[f]).reshape(-1, 9)
    t_ref, i_ref = _brute(tris, origins, dirs)
    finite = np.isfinite(origins).all(axis=1) & np.isfinite(dirs).all(axis=1)
    assert np.isinf(t_bvh[~finite]).all()  # NaN or infinite rays hit nothing
    np.testing.assert_allclose(t_bvh[finite], t_ref[finite], rtol=1e-12)
    assert (t_ref[: len(o_down)] < INF).all()  # every downward ray hits the grid (no pinholes)
    assert (i_bvh == i_ref)[finite & (t_ref < INF)].mean() > 0.5  # ties at shared vertices/edges
    tmax = np.where(np.isfinite(t_ref), t_ref * 1.0001, 1e30)
    np.testing.assert_array_equal(_any_all(compiled.kernel, origins, dirs, tmax)[finite], np.isfinite(t_ref)[finite])


def test_four_triangles_at_once_equal_the_scalar_test_to_the_bit():
    """intersect_triangles (BVH leaves of 2-4 triangles, one vector test) gives the scalar
    test's nearest hit row by row: the same t, lane and barycentrics to the last bit, the
    first row on ties; degenerate rows, rays through shared edges and vertices, rays leaving a
    triangle (which pass inside it at t <= 0: the divisions are skipped there when tmin >= 0)
    and a tmin below 0 included.
    So does traversal's block test, on the column table of a small scene (blocks at the table's
    end included: their loads reach into its padding) and on the rows of a large one."""
    from raylume.kernels.geometry.shape_triangle import (
        COLUMNS_UP_TO,
        intersect_triangle_block,
        intersect_triangles,
        triangle_columns,
    )

    rng = np.random.default_rng(4)
    tris = rng.uniform(-1, 1, size=(400, 9)).astype(np.float32)
    tris[5] = tris[4]  # a duplicate: ties go to the first row
    tris[9, 3:6] = tris[9, 0:3]  # degenerate: two equal vertices
    tris[13, 6:9] = (tris[13, 0:3] + tris[13, 3:6]) / 2  # degenerate: collinear
    tris[16:20] = [[0, 0, 0, 1, 0, 0, 0, 1, 0], [1, 0, 0, 1, 1, 0, 0, 1, 0], [1, 1, 0, 2, 1, 0, 1, 2, 0], [0] * 9]
    cols = triangle_columns(tris)
    np.testing.assert_array_equal(cols[:, : len(tris)].T, tris)
    no_cols = triangle_columns(np.zeros((COLUMNS_UP_TO + 1, 9), np.float32))  # a large scene's: none
    assert no_cols.shape[1] < len(tris)
    checked = behind = 0
    for k in range(1500):
        first = int(rng.integers(0, 397)) if k % 3 else (16 if k % 2 else 400 - int(rng.integers(1, 5)))
        count = min(int(rng.integers(1, 5)), 400 - first)
        if k % 5 == 0:  # through a vertex or an edge midpoint of the block
            v = tris[first].astype(np.float64).reshape(3, 3)
            target = v[k % 3] if k % 2 else (v[0] + v[1]) / 2
        else:
            target = rng.uniform(-1, 1, 3)
        o = rng.uniform(-3, 3, 3)
        d = target - o
        d /= np.linalg.norm(d)
        if k % 4 == 1:  # leaving a point of the block's first triangle, as shadow rays and bounces do
            b = rng.dirichlet([1, 1, 1])
            o = b @ tris[first].astype(np.float64).reshape(3, 3)
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
        o, d = tuple(o), tuple(d)
        shear = ray_shear(d)
        tmax = INF if k % 7 else 2.0
        tmin = (0.0, -1.0, 1e-6)[k % 3]  # the kernels' own tmin may be < 0
        want = (INF, 0, 0.0, 0.0)
        for j in range(count):
            t, b1, b2 = intersect_triangle(o, shear, tris, first + j, tmin, min(tmax, want[0]))
            if t < want[0]:
                want = (t, j, b1, b2)
        got = intersect_triangles(o, shear, tris, first, count, tmin, tmax)
        assert got == want, (k, first, count)
        assert intersect_triangle_block(o, shear, tris, cols, first, count, tmin, tmax) == want, (k, first, count)
        assert intersect_triangle_block(o, shear, tris, no_cols, first, count, tmin, tmax) == want, (k, first, count)
        behind += tmin < 0 and want[0] < 0
        checked += want[0] < INF
    assert checked > 200 and behind > 10  # hits behind the origin, found where tmin < 0


@njit
def _face_normals_at_hits(G, n):
    out = np.empty((n, 3))
    for i in range(n):
        ng, _ = triangle_normals_at(G, i, 0.25, 0.25)
        out[i] = ng
    return out


def test_face_normals_of_small_scenes_are_read_and_large_ones_computed_alike():
    """Scenes of at most COLUMNS_UP_TO triangles read each hit's geometric normal from a table
    made once (face_normals), larger ones compute it at the hit: both the unit normal of the
    winding (v1 - v0) x (v2 - v0), against numpy's (the table's to float64 rounding, the
    computed one to float32's, as it always was), zero for a degenerate triangle."""
    from raylume.kernels.geometry.shape_triangle import COLUMNS_UP_TO, face_normals

    rng = np.random.default_rng(8)
    tris = rng.uniform(-1, 1, size=(300, 9)).astype(np.float32)
    tris[7, 6:9] = tris[7, 0:3]  # degenerate
    v = tris.astype(np.float64).reshape(-1, 3, 3)
    want = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    length = np.linalg.norm(want, axis=1)
    want[length > 0] /= length[length > 0, None]
    S = compile_scene(
        raylume.scene_from_dict({"objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}]})
    ).kernel
    S = S._replace(triangles=tris, triangle_smooth=np.zeros(len(tris), bool))  # the table's rows
    small = S._replace(triangle_face_normals=face_normals(tris))
    large = S._replace(triangle_face_normals=face_normals(np.zeros((COLUMNS_UP_TO + 1, 9))))
    assert large.triangle_face_normals.shape[0] == 0  # a large scene's: none
    read = _face_normals_at_hits(geometry_of(small), len(tris))
    computed = _face_normals_at_hits(geometry_of(large), len(tris))
    np.testing.assert_allclose(read, want, rtol=0, atol=1e-15)
    np.testing.assert_allclose(computed, want, rtol=0, atol=1e-5)
    assert not read[7].any() and not computed[7].any()
