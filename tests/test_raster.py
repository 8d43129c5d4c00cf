"""The Z-buffer rasterizer (`--mode raster`) against the ray caster and against exact counts.

Independent checks: the ray caster's depth/object/prim AOVs on the same scenes (a second
method), exact rational arithmetic for which pixel centres a triangle covers (with the
top-left rule written out from its definition), invariants (a closed mesh has no cracks,
an edge shared by two triangles covers each pixel centre exactly once, the image does not
depend on the thread count).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.ndimage import binary_dilation, binary_fill_holes

import raylume
from raylume.kernels.film.camera import camera_of
from raylume.kernels.geometry.shape_sphere import sphere_cap
from raylume.kernels.raster.raster_kernel import coverage_count, view_matrix
from raylume.scene.procedural import bumpy_sphere

LIGHTS = [
    {"type": "ambient", "intensity": 0.2},
    {"type": "point", "position": [2, 1, -3], "intensity": 0.6},
    {"type": "directional", "direction": [1, 4, -4], "intensity": 0.2},
]


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("raster_meshes")
    paths = {}
    v, f = bumpy_sphere(20000, radius=1.0)
    trimesh.Trimesh(v, f, process=False).export(folder / "bumpy.ply")
    paths["bumpy"] = str(folder / "bumpy.ply")
    trimesh.creation.icosphere(subdivisions=3).export(folder / "ico.ply")
    paths["ico"] = str(folder / "ico.ply")
    trimesh.creation.box(extents=(1.2, 0.8, 0.8)).export(folder / "box.ply")
    paths["box"] = str(folder / "box.ply")
    trimesh.creation.torus(major_radius=0.8, minor_radius=0.25, major_sections=48, minor_sections=24).export(
        folder / "torus.ply"
    )
    paths["torus"] = str(folder / "torus.ply")
    return paths


def scene(objects, camera=None, lights=LIGHTS, **render):
    doc = {"objects": objects, "lights": lights, "camera": camera or {"position": [0, 0, -3.2]}}
    if render:
        doc["render"] = render
    return raylume.scene_from_dict(doc)


def both(sc, width, height):
    r = raylume.render(sc, mode="raster", width=width, height=height)
    c = raylume.render(sc, mode="cast", width=width, height=height)
    return r, c


def boundary_band(labels: np.ndarray) -> np.ndarray:
    """Pixels on or next to a change of label: the thin line where two exact methods may
    legitimately disagree (pixel centres within rounding of an edge)."""
    edge = np.zeros(labels.shape, bool)
    edge[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    edge[:, :-1] |= labels[:, 1:] != labels[:, :-1]
    edge[1:, :] |= labels[1:, :] != labels[:-1, :]
    edge[:-1, :] |= labels[1:, :] != labels[:-1, :]
    return binary_dilation(edge)


def assert_agrees_with_cast(r, c, *, max_edge_fraction, depth_rtol, pixels_exempt=None):
    """object and prim equal, and depth within depth_rtol, except on a thin line of edge
    pixels: at most max_edge_fraction of the image, all on the cast image's boundaries."""
    ro, co = r.aovs["object"], c.aovs["object"]
    rp, cp = r.aovs["prim"], c.aovs["prim"]
    differ = (ro != co) | (rp != cp)
    if pixels_exempt is not None:
        differ &= ~pixels_exempt
    assert differ.mean() <= max_edge_fraction, f"{differ.sum()} pixels disagree"
    labels = co.astype(np.int64) * (1 << 32) + cp
    assert not (differ & ~boundary_band(labels)).any(), "a disagreement away from any edge"
    same = ~differ & (co >= 0)
    d_r, d_c = r.aovs["depth"][same], c.aovs["depth"][same]
    np.testing.assert_allclose(d_r, d_c, rtol=depth_rtol)
    assert np.isinf(r.aovs["depth"][ro < 0]).all()


# --- AOVs, determinism --------------------------------------------------------------------------


def test_aovs_have_the_design_dtypes_and_shapes(meshes):
    sc = scene(
        [
            {"type": "mesh", "file": meshes["torus"], "smooth": True},
            {"type": "sphere", "center": [1.2, 0.5, 1.0], "radius": 0.5},
            {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]},
        ],
        background=[0.1, 0.2, 0.3],
    )
    progress = []
    img = raylume.render(sc, mode="raster", width=72, height=56, progress=lambda d, t: progress.append((d, t)))
    H, W = 56, 72
    assert img.rgb.dtype == np.float32 and img.rgb.shape == (H, W, 3)
    assert np.isfinite(img.rgb).all() and (img.rgb >= 0).all()
    a = img.aovs
    assert a["depth"].dtype == np.float32 and a["depth"].shape == (H, W)
    assert a["normal"].dtype == np.float32 and a["normal"].shape == (H, W, 3)
    assert a["object"].dtype == np.int32 and a["object"].shape == (H, W)
    assert a["prim"].dtype == np.int32 and a["prim"].shape == (H, W)
    assert a["albedo"].dtype == np.float32 and a["albedo"].shape == (H, W, 3)
    hit = a["object"] >= 0
    assert hit.any() and (~hit).any()
    assert set(np.unique(a["object"])) == {-1, 0, 1, 2}
    assert np.isinf(a["depth"][~hit]).all() and np.isfinite(a["depth"][hit]).all() and (a["depth"][hit] > 0).all()
    assert (a["prim"][~hit] == -1).all() and (a["prim"][a["object"] >= 1] == 0).all()
    assert (a["normal"][~hit] == 0).all() and (a["albedo"][~hit] == 0).all()
    np.testing.assert_allclose(np.linalg.norm(a["normal"][hit], axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(img.rgb[~hit], np.broadcast_to([0.1, 0.2, 0.3], img.rgb[~hit].shape), atol=1e-7)
    # normals face the camera: against the ray through the pixel centre
    cam = camera_of(sc.camera, W, H)
    i, j = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    d = cam[3:6] + cam[6:9] * (i / W * 2 - 1)[..., None] + cam[9:12] * (1 - j / H * 2)[..., None]
    assert (np.einsum("hwc,hwc->hw", a["normal"], d)[hit] < 1e-6).all()
    assert img.stats["mode"] == "raster" and img.stats["rays"] == 0 and img.stats["render_seconds"] > 0
    assert progress and progress[-1] == (H, H)


def test_image_does_not_depend_on_thread_count(meshes):
    sc = scene(
        [
            {"type": "mesh", "file": meshes["bumpy"]},
            {"type": "mesh", "file": meshes["box"], "transform": {"translate": [0.3, 0.2, -0.8]}},
        ]
    )
    one = raylume.render(sc, mode="raster", width=64, height=64, threads=1)
    two = raylume.render(sc, mode="raster", width=64, height=64, threads=2)
    assert np.array_equal(one.rgb, two.rgb)
    for name in ("depth", "normal", "object", "prim", "albedo"):
        assert np.array_equal(one.aovs[name], two.aovs[name]), name


# --- against the ray caster ----------------------------------------------------------------------


def test_depth_object_and_prim_agree_with_the_ray_caster_on_meshes(meshes):
    sc = scene(
        [
            {"type": "mesh", "file": meshes["bumpy"], "transform": {"translate": [-0.4, 0, 0.5]}},
            {
                "type": "mesh",
                "file": meshes["torus"],
                "transform": {"translate": [0.7, 0.3, -0.4], "rotate": [60, 20, 0]},
            },
            {
                "type": "mesh",
                "file": meshes["box"],
                "transform": {"translate": [0.2, -0.7, -0.2], "rotate": [10, 35, 0]},
            },
        ]
    )
    r, c = both(sc, 160, 120)
    assert (c.aovs["object"] >= 0).mean() > 0.3
    assert_agrees_with_cast(r, c, max_edge_fraction=0.003, depth_rtol=1e-5)


def test_spheres_and_planes_agree_with_the_ray_caster_up_to_tessellation():
    sc = scene(
        [
            {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": {"texture": {"type": "checker"}}},
            {"type": "sphere", "center": [0, 0, 1], "radius": 1},
            {"type": "sphere", "center": [1.8, 0.3, 3], "radius": 0.7},
            {"type": "sphere", "center": [0, -5001, 0], "radius": 4999.5},  # just below the plane
        ],
        camera={"position": [0, 0.5, -3], "look_at": [0, -0.2, 1]},
    )
    r, c = both(sc, 128, 96)
    ro, co = r.aovs["object"], c.aovs["object"]
    # The plane is exact; spheres are polygons within a quarter pixel of their silhouettes,
    # so their depth is off by the chords' sagitta -- most where the view grazes the surface.
    assert_agrees_with_cast(r, c, max_edge_fraction=0.02, depth_rtol=0.06)
    plane = (ro == 0) & (co == 0)
    np.testing.assert_allclose(r.aovs["depth"][plane], c.aovs["depth"][plane], rtol=1e-6)
    checker_same = (r.aovs["albedo"][plane] == c.aovs["albedo"][plane]).all(axis=1)
    assert checker_same.mean() > 0.995  # a centre within rounding of a cell border may differ
    for k in (1, 2):
        inner = (ro == k) & (co == k) & ~boundary_band(co)
        np.testing.assert_allclose(r.aovs["depth"][inner], c.aovs["depth"][inner], rtol=0.01)
        np.testing.assert_allclose(r.aovs["normal"][inner], c.aovs["normal"][inner], atol=0.02)


def test_lighting_matches_trace_where_nothing_casts_a_shadow(meshes):
    """A convex matte mesh cannot shadow itself: `trace` at max_depth 0 is then exactly the
    rasterizer's ambient + diffuse shading."""
    sc = scene([{"type": "mesh", "file": meshes["ico"], "material": {"color": [0.9, 0.6, 0.3]}}])
    r = raylume.render(sc, mode="raster", width=96, height=96)
    t = raylume.render(sc, mode="trace", width=96, height=96, max_depth=0)
    same = (r.aovs["object"] == t.aovs["object"]) & (r.aovs["prim"] == t.aovs["prim"])
    assert same.mean() > 0.99
    np.testing.assert_allclose(r.rgb[same], t.rgb[same], atol=1e-5)
    assert r.rgb[r.aovs["object"] == 0].std() > 0.05  # really lit, not flat


# --- cracks, near plane, behind the camera ----------------------------------------------------------


@pytest.mark.parametrize("name", ["bumpy", "ico", "torus"])
def test_closed_mesh_leaves_no_background_pixel_inside_its_silhouette(meshes, name):
    sc = scene(
        [{"type": "mesh", "file": meshes[name], "transform": {"rotate": [30, 40, 0]}}],
        camera={"position": [0, 0, -2.6]},
    )
    img = raylume.render(sc, mode="raster", width=150, height=150)
    covered = img.aovs["object"] == 0
    # fill_holes closes background regions not connected to the border: pinholes, cracks;
    # the torus's hole is connected to the border only around the mesh, so compare the
    # torus against the ray caster instead, which has no cracks (watertight test).
    if name == "torus":
        cast = raylume.render(sc, mode="cast", width=150, height=150).aovs["object"] == 0
        holes = cast & ~covered & ~boundary_band(cast.astype(int))
    else:
        holes = binary_fill_holes(covered) & ~covered
    assert covered.sum() > 2000
    assert not holes.any(), f"{holes.sum()} background pixels inside the silhouette"


def test_triangles_crossing_the_near_plane_and_behind_the_camera(meshes):
    cases = [
        # a ground triangle running from behind the camera to far in front of it
        [{"type": "triangle", "vertices": [[-4, -1, -6], [4, -1, -6], [0, -1, 30]]}],
        # one vertex behind the camera, beside it, two in front
        [{"type": "triangle", "vertices": [[-0.5, 0.2, -1], [2, -1, 3], [-1, -1.5, 2]]}],
        # two vertices behind, one in front
        [{"type": "triangle", "vertices": [[-3, 1, -2], [3, 0.5, -1], [0.2, -0.5, 4]]}],
        # the camera inside a closed mesh: every pixel sees it, every triangle crosses the view
        [{"type": "mesh", "file": meshes["ico"], "transform": {"scale": 3}}],
        # a plane through the camera's view, the camera above it
        [{"type": "plane", "point": [0, -0.3, 0], "normal": [0.1, 1, -0.2]}],
    ]
    for objects in cases:
        sc = scene(objects, camera={"position": [0, 0, 0], "look_at": [0, 0, 1]})
        r, c = both(sc, 80, 64)
        assert (c.aovs["object"] >= 0).sum() > 100, objects
        assert_agrees_with_cast(r, c, max_edge_fraction=0.01, depth_rtol=1e-5)
    behind = scene(
        [
            {"type": "triangle", "vertices": [[-3, -3, -1], [3, -3, -1], [0, 3, -0.5]]},
            {"type": "sphere", "center": [0, 0, -3], "radius": 1},
        ],
        camera={"position": [0, 0, 0], "look_at": [0, 0, 1]},
    )
    img = raylume.render(behind, mode="raster", width=48, height=48)
    assert (img.aovs["object"] == -1).all() and np.isinf(img.aovs["depth"]).all()


# --- exact coverage ---------------------------------------------------------------------------------

# A camera whose projection is exact in binary floating point: at the origin looking down +z
# with w = h = 1 (fov 90, square image): pixel x = W/2 (X/Z + 1), y = H/2 (1 - Y/Z).
EXACT_CAM = np.array([0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0], dtype=np.float64)


def world_from_screen(points, size, depths):
    """World vertices at the given camera depths that project exactly to screen points."""
    out = []
    for (x, y), z in zip(points, depths):
        X = (x / (size / 2) - 1) * z
        Y = (1 - y / (size / 2)) * z
        out += [X, Y, z]
    return out


def top_left_count(tri2d, size):
    """Pixel centres covered by a screen triangle under the top-left rule, by exact rationals:
    inside all edges, or exactly on an edge whose interior lies to its right (a left edge)
    or, for a horizontal edge, below it (a top edge); rows grow downwards."""
    P = [(Fraction(x), Fraction(y)) for x, y in tri2d]
    covered = np.zeros((size, size), bool)
    edges = []
    for k in range(3):
        a, b, opp = P[k], P[(k + 1) % 3], P[(k + 2) % 3]
        nx, ny = -(b[1] - a[1]), b[0] - a[0]  # a normal of the edge
        if nx * (opp[0] - a[0]) + ny * (opp[1] - a[1]) < 0:
            nx, ny = -nx, -ny  # now pointing into the triangle
        owned = nx > 0 or (nx == 0 and ny > 0)
        edges.append((a, nx, ny, owned))
    for j in range(size):
        for i in range(size):
            px, py = Fraction(2 * i + 1, 2), Fraction(2 * j + 1, 2)
            ok = True
            for a, nx, ny, owned in edges:
                e = nx * (px - a[0]) + ny * (py - a[1])
                if e < 0 or (e == 0 and not owned):
                    ok = False
                    break
            covered[j, i] = ok
    return covered


SIZE = 32


def count_exact(triangles9):
    view = view_matrix(EXACT_CAM, SIZE, SIZE)
    return coverage_count(view, 1e-6, SIZE, SIZE, np.asarray(triangles9, dtype=np.float64).reshape(-1, 9))


@pytest.mark.parametrize(
    "tri2d, depths",
    [
        # vertices on pixel centres, edges through many centres (slopes 0, 1, 1/2, vertical)
        ([(3.5, 3.5), (27.5, 3.5), (3.5, 27.5)], (1, 1, 1)),
        ([(3.5, 3.5), (3.5, 27.5), (27.5, 3.5)], (1, 2, 4)),  # opposite winding, perspective
        ([(16.5, 2.5), (28.5, 26.5), (4.5, 26.5)], (0.5, 1, 2)),
        ([(2.0, 5.5), (30.0, 5.5), (16.0, 30.0)], (1, 4, 2)),
        ([(1.25, 30.75), (29.5, 1.5), (30.5, 29.0)], (2, 1, 0.5)),
    ],
)
def test_single_triangle_covers_exactly_the_analytic_pixel_centres(tri2d, depths):
    expected = top_left_count(tri2d, SIZE)
    got = count_exact(world_from_screen(tri2d, SIZE, depths))
    assert got.max() <= 1
    assert got.sum() == expected.sum()
    assert np.array_equal(got == 1, expected)


def test_rendered_triangle_covers_the_pixel_centres_its_projection_contains():
    """Through the whole pipeline (scene camera, fov 53.13): the object AOV equals the exact
    count of pixel centres inside the projected triangle (no centre is near an edge)."""
    verts = [[-0.83, -0.61, 2.3], [0.97, -0.17, 2.9], [-0.11, 0.79, 1.7]]
    sc = scene([{"type": "triangle", "vertices": verts}], camera={"position": [0, 0, 0]})
    W, H = 61, 47
    img = raylume.render(sc, mode="raster", width=W, height=H)
    cam = camera_of(sc.camera, W, H)
    O, F, R, U = (np.asarray(cam[k : k + 3]) for k in (0, 3, 6, 9))
    pts = []
    for v in np.asarray(verts, dtype=np.float32).astype(np.float64):
        rel = [Fraction(float(c)) for c in v - O]
        dot = lambda a, b: sum(Fraction(float(x)) * y for x, y in zip(a, b))  # noqa: E731
        z = dot(F, rel)
        a = dot(R, rel) / (dot(R, [Fraction(float(c)) for c in R]) * z)
        b = dot(U, rel) / (dot(U, [Fraction(float(c)) for c in U]) * z)
        pts.append(((a + 1) * W / 2, (1 - b) * H / 2))
    inside = np.zeros((H, W), bool)
    for j in range(H):
        for i in range(W):
            p = (Fraction(2 * i + 1, 2), Fraction(2 * j + 1, 2))
            e = [
                (q[0] - p0[0]) * (p[1] - p0[1]) - (q[1] - p0[1]) * (p[0] - p0[0])
                for p0, q in zip(pts, pts[1:] + pts[:1])
            ]
            lengths = [abs(q[0] - p0[0]) + abs(q[1] - p0[1]) for p0, q in zip(pts, pts[1:] + pts[:1])]
            assert all(abs(ek) > 1e-6 * lk for ek, lk in zip(e, lengths)), "a centre lies on an edge"
            inside[j, i] = all(ek > 0 for ek in e) or all(ek < 0 for ek in e)
    assert inside.sum() > 300
    assert np.array_equal(img.aovs["object"] == 0, inside)


def test_shared_edges_through_pixel_centres_are_covered_exactly_once():
    """A grid of triangles whose vertices all sit on pixel centres, at varied depths: every
    centre inside the grid is covered once, including those on shared edges and vertices."""
    xs = [4.5, 9.5, 15.5, 21.5, 27.5]
    depth = {0: 1.0, 1: 2.0, 2: 0.5, 3: 4.0, 4: 1.0}
    tris = []
    for a in range(4):
        for b in range(4):
            q = [(xs[a], xs[b]), (xs[a + 1], xs[b]), (xs[a + 1], xs[b + 1]), (xs[a], xs[b + 1])]
            z = [depth[(a + b) % 5], depth[(a + 1 + b) % 5], depth[(a + b + 2) % 5], depth[(a + b + 1) % 5]]
            corners = list(zip(q, z))
            split = [(0, 1, 2), (0, 2, 3)] if (a + b) % 2 else [(0, 1, 3), (1, 2, 3)]
            for k, tri in enumerate(split):
                order = tri if k % 2 else tri[::-1]  # mixed windings
                pts = [corners[m] for m in order]
                tris.append(world_from_screen([p for p, _ in pts], SIZE, [d for _, d in pts]))
    got = count_exact(tris)
    outer = [(4.5, 4.5), (27.5, 4.5), (27.5, 27.5), (4.5, 27.5)]
    expected = top_left_count(outer[:3], SIZE) | top_left_count([outer[0], outer[2], outer[3]], SIZE)
    assert got.max() == 1
    assert np.array_equal(got == 1, expected)


def convex_hull(points):
    pts = sorted(set(points))

    def half(seq):
        out = []
        for p in seq:
            while (
                len(out) >= 2
                and (out[-1][0] - out[-2][0]) * (p[1] - out[-2][1]) - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])
                <= 0
            ):
                out.pop()
            out.append(p)
        return out[:-1]

    return half(pts) + half(pts[::-1])


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    points=st.lists(st.tuples(st.integers(0, 62), st.integers(0, 62)), min_size=3, max_size=9),
    centre=st.tuples(st.floats(0.1, 0.9), st.floats(0.1, 0.9)),
    depths=st.lists(st.sampled_from([0.25, 0.5, 1.0, 2.0, 8.0]), min_size=10, max_size=10),
    flips=st.lists(st.booleans(), min_size=9, max_size=9),
)
def test_a_triangle_fan_covers_its_polygon_without_gaps_or_overlaps(points, centre, depths, flips):
    """Property: a convex polygon (vertices on the half-pixel grid, so edges often pass
    through pixel centres) split into a fan around an interior vertex, with random depths
    and windings: no centre is covered twice, every centre strictly inside is covered once."""
    hull = convex_hull([(x / 2, y / 2) for x, y in points])
    if len(hull) < 3:
        return
    # an interior fan centre on the quarter-pixel grid (a convex combination, snapped)
    w0, w1 = centre
    cx = (1 - w0) * hull[0][0] + w0 * ((1 - w1) * hull[1][0] + w1 * hull[2][0])
    cy = (1 - w0) * hull[0][1] + w0 * ((1 - w1) * hull[1][1] + w1 * hull[2][1])
    c = (round(cx * 4) / 4, round(cy * 4) / 4)
    n = len(hull)

    def side(p, a, b):
        return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])

    if not all(side(c, hull[k], hull[(k + 1) % n]) > 0 for k in range(n)):
        return  # snapping moved the centre onto or out of the boundary
    tris = []
    for k in range(n):
        a, b = hull[k], hull[(k + 1) % n]
        pts, zs = [c, a, b], [depths[0], depths[k + 1], depths[(k + 1) % n + 1]]
        if flips[k]:
            pts, zs = pts[::-1], zs[::-1]
        tris.append(world_from_screen(pts, SIZE, zs))
    got = count_exact(tris)
    assert got.max() <= 1
    ii, jj = np.meshgrid(np.arange(SIZE) + 0.5, np.arange(SIZE) + 0.5)
    strictly_inside = np.ones((SIZE, SIZE), bool)
    for k in range(n):
        a, b = hull[k], hull[(k + 1) % n]
        strictly_inside &= (b[0] - a[0]) * (jj - a[1]) - (b[1] - a[1]) * (ii - a[0]) > 0
    assert (got[strictly_inside] == 1).all()
    outside = np.zeros((SIZE, SIZE), bool)
    for k in range(n):
        a, b = hull[k], hull[(k + 1) % n]
        outside |= (b[0] - a[0]) * (jj - a[1]) - (b[1] - a[1]) * (ii - a[0]) < 0
    assert (got[outside] == 0).all()


# --- sphere tessellation ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "center, radius, eye",
    [
        ((0, 0, 3), 1.0, (0, 0, 0)),
        ((0, -5001, 0), 5000.0, (0, 0, 0)),  # the seed's ground: the camera 1 above a huge sphere
        ((0.2, 0.1, 0.3), 2.0, (0, 0, 0)),  # the camera inside
    ],
)
def test_sphere_cap_vertices_lie_on_the_sphere_and_cover_the_visible_part(center, radius, eye):
    tris = sphere_cap(center, radius, eye, px_per_rad=300.0)
    assert tris.dtype == np.float64 and tris.shape[1] == 9 and 100 < len(tris) < 3_000_000
    v = tris.reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(v - center, axis=1), radius, rtol=1e-12)
    # every vertex is visible from the eye (in front of the tangent plane), or on the horizon
    n = (v - center) / radius
    facing = np.einsum("ij,ij->i", n, np.asarray(eye) - v)
    inside = np.linalg.norm(np.subtract(eye, center)) < radius
    assert inside or (facing >= -1e-9 * radius).all()
