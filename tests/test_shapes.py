"""The analytic shapes added through the shape registry (disk, quad, cylinder): exact hits
against closed-form geometry, normals, UVs, bounds, the rasterizer against the ray caster,
clear errors for degenerate shapes, and the places a shape's code may live."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

import raylume
from raylume.compile import compile_scene
from raylume.kernels.geometry.shapes import normals, uv
from raylume.kernels.scene import geometry_of
from raylume.kernels.variants import features

RNG = np.random.default_rng(20261128)


def one(obj: dict):
    return raylume.scene_from_dict({"objects": [obj]})


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def frame(n):
    n = unit(n)
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = unit(np.cross(n, helper))
    return e1, np.cross(n, e1)


def shoot(scene, origins, targets):
    """raylume.intersect from each origin towards each target: (t, object, prim, |target - origin|)."""
    d = targets - origins
    t, obj, prim = raylume.intersect(scene, origins, d)
    return t, obj, prim, np.linalg.norm(d, axis=1)


# --- exact hits -------------------------------------------------------------------------------


def test_disk_hits_inside_its_radius_and_misses_outside():
    for _ in range(5):
        c, n, r = RNG.normal(size=3) * 3, unit(RNG.normal(size=3)), RNG.uniform(0.2, 3)
        sc = one({"type": "disk", "center": c.tolist(), "normal": n.tolist(), "radius": r})
        e1, e2 = frame(n)
        phi = RNG.uniform(0, 2 * math.pi, 400)
        rho = np.concatenate([RNG.uniform(0, 0.99, 200), RNG.uniform(1.01, 2, 200)]) * r
        q = c + rho[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        side = np.where(RNG.random(400) < 0.5, 1.0, -1.0)  # two-sided: from either side
        o = q + side[:, None] * (n * RNG.uniform(0.5, 5, 400)[:, None] + RNG.normal(size=(400, 3)))
        t, obj, prim, dist = shoot(sc, o, q)
        inside = rho < r
        np.testing.assert_allclose(t[inside], dist[inside], rtol=1e-9)
        assert (obj[inside] == 0).all() and (prim[inside] == 0).all()
        assert np.isinf(t[~inside]).all() and (obj[~inside] == -1).all()


def test_quad_hits_its_parallelogram_and_nothing_beyond():
    for _ in range(5):
        c = RNG.normal(size=3) * 2
        u, v = RNG.normal(size=3), RNG.normal(size=3)  # not orthogonal, not equal length
        sc = one({"type": "quad", "position": c.tolist(), "u": u.tolist(), "v": v.tolist()})
        n = unit(np.cross(u, v))
        a = RNG.uniform(-1, 1, 600)
        b = RNG.uniform(-1, 1, 600)
        margin = np.maximum(np.abs(a), np.abs(b))
        keep = (margin < 0.49) | (margin > 0.51)
        a, b = a[keep], b[keep]
        q = c + a[:, None] * u + b[:, None] * v
        side = np.where(RNG.random(len(q)) < 0.5, 1.0, -1.0)
        o = q + side[:, None] * (n * RNG.uniform(0.5, 4, len(q))[:, None] + 0.5 * RNG.normal(size=(len(q), 3)))
        t, obj, _, dist = shoot(sc, o, q)
        inside = np.maximum(np.abs(a), np.abs(b)) < 0.5
        np.testing.assert_allclose(t[inside], dist[inside], rtol=1e-9)
        assert np.isinf(t[~inside]).all() and (obj[~inside] == -1).all()


@pytest.mark.parametrize("capped", [True, False])
def test_cylinder_side_and_caps_against_closed_form_points(capped):
    p0, p1, r = np.array([0.3, -1.0, 2.0]), np.array([1.0, 1.5, 2.6]), 0.7
    sc = one({"type": "cylinder", "p0": p0.tolist(), "p1": p1.tolist(), "radius": r, "capped": capped})
    axis = unit(p1 - p0)
    h = np.linalg.norm(p1 - p0)
    e1, e2 = frame(axis)
    phi = RNG.uniform(0, 2 * math.pi, 300)
    radial = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    # side points seen from outside, from where their normal faces: nothing lies in front
    z = RNG.uniform(0.01, 0.99, 300) * h
    q = p0 + z[:, None] * axis + r * radial
    o = q + radial * RNG.uniform(0.2, 3, 300)[:, None] + axis * RNG.normal(size=300)[:, None] * 0.5
    t, obj, _, dist = shoot(sc, o, q)
    np.testing.assert_allclose(t, dist, rtol=1e-9)
    # cap points seen from beyond the cap's plane
    rho = RNG.uniform(0, 0.98, 300) * r
    top = p1 + rho[:, None] * radial
    across = RNG.normal(size=(300, 1)) * e1 + RNG.normal(size=(300, 1)) * e2
    o = top + axis * RNG.uniform(0.3, 3, 300)[:, None] + 0.2 * across  # above the cap's plane
    t, obj, _, dist = shoot(sc, o, top)
    if capped:
        np.testing.assert_allclose(t, dist, rtol=1e-9)
    else:  # an open tube: the ray goes down the tube, hitting the inside wall if anything
        assert (np.isinf(t) | (t > dist * (1 + 1e-9))).all()
    # rays passing beside the cylinder miss it
    o = p0 + 0.5 * h * axis + (r * 1.05) * e1 - 5 * e2
    t, obj, _, _ = shoot(sc, o[None], (o + 10 * e2)[None])
    assert np.isinf(t[0])


# --- normals, UVs, bounds ---------------------------------------------------------------------


def test_normals_and_uvs_of_the_new_shapes():
    sc = raylume.scene_from_dict(
        {
            "objects": [
                {"type": "disk", "center": [0, 1, 5], "normal": [0, 0, -2], "radius": 2},
                {"type": "quad", "position": [0, 0, 4], "u": [2, 0, 0], "v": [1, 1, 0]},
                {"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 2, 0], "radius": 0.5},
            ]
        }
    )
    S = compile_scene(sc).kernel
    G = geometry_of(S)
    X = features(S)
    prim_of = {int(S.prims[k, 3]): k for k in range(len(S.prims))}
    # disk: the given normal; v is the distance from the centre over the radius
    ng, ns = normals(G, X, prim_of[0], 0.0, 0.0, (1.0, 1.0, 5.0))
    np.testing.assert_allclose(ng, (0, 0, -1)) and np.testing.assert_allclose(ns, ng)
    assert uv(G, X, prim_of[0], 0.0, 0.0, (1.0, 1.0, 5.0))[1] == pytest.approx(0.5)
    # quad: u x v normalised; (0, 0) at centre - u/2 - v/2, (1, 1) at centre + u/2 + v/2
    ng, _ = normals(G, X, prim_of[1], 0.0, 0.0, (0.0, 0.0, 4.0))
    np.testing.assert_allclose(ng, (0, 0, 1))
    assert uv(G, X, prim_of[1], 0.0, 0.0, (-1.5, -0.5, 4.0)) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert uv(G, X, prim_of[1], 0.0, 0.0, (1.5, 0.5, 4.0)) == pytest.approx((1.0, 1.0), abs=1e-12)
    assert uv(G, X, prim_of[1], 0.0, 0.0, (0.5, -0.5, 4.0)) == pytest.approx((1.0, 0.0), abs=1e-12)
    # cylinder: radial on the side (part 0), the axis on the caps (part 1 at p0, 2 at p1)
    np.testing.assert_allclose(normals(G, X, prim_of[2], 0.0, 0.0, (0.5, 1.3, 0.0))[0], (1, 0, 0), atol=1e-12)
    np.testing.assert_allclose(normals(G, X, prim_of[2], 1.0, 0.0, (0.1, 0.0, 0.1))[0], (0, -1, 0))
    np.testing.assert_allclose(normals(G, X, prim_of[2], 2.0, 0.0, (0.1, 2.0, 0.1))[0], (0, 1, 0))
    assert uv(G, X, prim_of[2], 0.0, 0.0, (0.5, 1.5, 0.0))[1] == pytest.approx(0.75)


def test_bounds_are_tight_boxes_of_the_shapes():
    """Points on the rims (disk, cylinder) or the corners (quad) lie inside the box and reach
    each of its faces."""
    from raylume.kernels.geometry import shape_cylinder, shape_disk, shape_quad
    from raylume.kernels.geometry.shapes import ANALYTIC, Shape

    for obj in [
        {"type": "disk", "center": [1, 2, 3], "normal": [1, 2, 2], "radius": 1.5},
        {"type": "cylinder", "p0": [0, 0, 0], "p1": [1, 2, -1], "radius": 0.4},
        {"type": "quad", "position": [0, 1, 0], "u": [1, 0.5, 0], "v": [0, 0.2, 2]},
    ]:
        sc = one(obj)
        S = compile_scene(sc).kernel
        kind = Shape(int(S.prims[0, 0]))
        lo, hi = ANALYTIC[kind].bounds(S.shapes[:1])
        row = S.shapes[0]
        phi = np.linspace(0, 2 * math.pi, 20001)
        if kind == Shape.DISK:
            n = row[shape_disk.NORMAL : shape_disk.NORMAL + 3]
            e1, e2 = frame(n)
            pts = row[:3] + row[shape_disk.RADIUS] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        elif kind == Shape.CYLINDER:
            a = row[shape_cylinder.AXIS : shape_cylinder.AXIS + 3]
            e1, e2 = frame(a)
            ring = row[shape_cylinder.RADIUS] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
            pts = np.concatenate([row[0:3] + ring, row[3:6] + ring])
        else:
            pts = shape_quad.corners(S.shapes[:1])[0]
        assert (pts >= lo - 1e-12).all() and (pts <= hi + 1e-12).all()
        np.testing.assert_allclose(pts.min(axis=0), lo[0], atol=1e-6)
        np.testing.assert_allclose(pts.max(axis=0), hi[0], atol=1e-6)


def test_transforms_move_and_scale_the_new_shapes():
    moved = one(
        {
            "type": "disk",
            "center": [0, 0, 0],
            "normal": [0, 0, 1],
            "radius": 1,
            "transform": {"translate": [0, 0, 5], "rotate": [0, 90, 0], "scale": 2},
        }
    )
    # rotated 90 degrees about y the normal is +x; scaled 2, the radius 2; moved to z = 5
    t, obj, _ = raylume.intersect(moved, np.array([[-3.0, 1.9, 5.0], [-3.0, 2.1, 5.0]]), np.array([[1.0, 0, 0]] * 2))
    np.testing.assert_allclose(t[0], 3.0) and np.testing.assert_array_equal(obj, [0, -1])
    quad = one(
        {"type": "quad", "u": [1, 0, 0], "v": [0, 1, 0], "transform": {"scale": [2, 3, 1], "translate": [0, 0, 4]}}
    )
    t, obj, _ = raylume.intersect(quad, np.array([[0.99, 1.49, 0.0], [1.01, 0.0, 0.0]]), np.array([[0, 0, 1.0]] * 2))
    np.testing.assert_allclose(t[0], 4.0) and np.testing.assert_array_equal(obj, [0, -1])


def test_spheres_planes_and_triangles_take_a_transform_too():
    """DESIGN: every shape takes `transform`. A sphere scaled 2, turned and moved hits where a
    sphere written with the new centre and radius does; a turned plane where the plane through
    the turned point and normal does; a triangle where its moved corners, written out, do."""
    origins = RNG.uniform(-4, 4, (400, 3)) + [0, 0, -10]
    targets = RNG.uniform(-2, 2, (400, 3))
    pairs = [
        ({"type": "sphere", "center": [0.5, 0, 0], "radius": 0.5,
          "transform": {"scale": 2, "rotate": [0, 90, 0], "translate": [0, 1, 0]}},
         {"type": "sphere", "center": [0, 1, -1], "radius": 1.0}),  # (0.5, 0, 0) turned to (0, 0, -0.5)
        ({"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "transform": {"rotate": [90, 0, 0],
          "translate": [0, 0, 1]}}, {"type": "plane", "point": [0, 0, 1], "normal": [0, 0, 1]}),
        ({"type": "triangle", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]],
          "transform": {"scale": [2, 3, 1], "translate": [-1, -1, 0.5]}},
         {"type": "triangle", "vertices": [[-1, -1, 0.5], [1, -1, 0.5], [-1, 2, 0.5]]}),
    ]  # fmt: skip
    for placed, written in pairs:
        t_placed, obj_placed, _, _ = shoot(one(placed), origins, targets)
        t_written, obj_written, _, _ = shoot(one(written), origins, targets)
        assert (obj_written == 0).sum() > 50, written["type"]
        np.testing.assert_array_equal(obj_placed, obj_written)
        np.testing.assert_allclose(t_placed, t_written, rtol=1e-12)
    with pytest.raises(
        raylume.SceneError, match=r"objects\[0\]\.transform: .*sphere's transform.scale must be uniform"
    ):
        one({"type": "sphere", "center": [0, 0, 0], "radius": 1, "transform": {"scale": [1, 2, 1]}})


def test_a_turned_sphere_turns_its_texture():
    """A sphere's UVs follow its transform's rotation: the point of the turned sphere where a
    point of the unturned one went has that point's (u, v)."""
    from raylume.kernels.geometry.shape_sphere import uv as sphere_uv

    turn = {"rotate": [30, 70, -20], "translate": [1, 2, 3]}
    rows = compile_scene(one({"type": "sphere", "center": [0, 0, 0], "radius": 1, "transform": turn})).kernel.shapes
    plain = compile_scene(one({"type": "sphere", "center": [0, 0, 0], "radius": 1})).kernel.shapes
    from raylume.kernels.geometry.transform import transform_point
    from raylume.scene.mesh import transform_matrix

    m = transform_matrix(turn["translate"], turn["rotate"], (1.0, 1.0, 1.0))
    for p in RNG.normal(size=(50, 3)):
        p = unit(p)
        expected = sphere_uv(plain, 0, tuple(p))
        assert sphere_uv(rows, 0, tuple(transform_point(m, p))) == pytest.approx(expected, abs=1e-9)


# --- rasterizer against the ray caster ---------------------------------------------------------


def test_rasterized_new_shapes_agree_with_the_ray_caster_up_to_tessellation():
    from test_raster import assert_agrees_with_cast, boundary_band

    sc = raylume.scene_from_dict(
        {
            "lights": [
                {"type": "ambient", "intensity": 0.3},
                {"type": "point", "position": [2, 3, -2], "intensity": 0.7},
            ],
            "camera": {"position": [0.5, 1.2, -3], "look_at": [0, 0, 2]},
            "objects": [
                {"type": "disk", "center": [-1.2, 0.2, 2], "normal": [0.3, 0.2, -1], "radius": 0.7},
                {"type": "quad", "position": [0.9, 0.6, 2.5], "u": [1, 0.2, 0], "v": [0.3, 0.9, 0.4]},
                {"type": "cylinder", "p0": [0.2, -1, 1.5], "p1": [-0.2, 0.2, 3.5], "radius": 0.45},
                {"type": "cylinder", "p0": [1.4, -1, 1.2], "p1": [1.4, -0.2, 1.2], "radius": 0.3, "capped": False},
            ],
        }
    )
    r = raylume.render(sc, mode="raster", width=160, height=120)
    c = raylume.render(sc, mode="cast", width=160, height=120)
    assert_agrees_with_cast(r, c, max_edge_fraction=0.02, depth_rtol=0.02)
    ro, co = r.aovs["object"], c.aovs["object"]
    for k in range(4):
        inner = (ro == k) & (co == k) & ~boundary_band(co)
        assert inner.sum() > 30, k
        np.testing.assert_allclose(r.aovs["depth"][inner], c.aovs["depth"][inner], rtol=2e-3)
        # normals agree except on a pixel or two where a cylinder's rim (side against cap) lies
        # within the tessellation's tolerance of the pixel centre
        off = np.abs(r.aovs["normal"][inner] - c.aovs["normal"][inner]).max(axis=1) > 0.03
        assert off.sum() <= max(2, 0.005 * inner.sum()), (k, off.sum())
    # the quad is exact: two triangles
    quad = (ro == 1) & (co == 1)
    np.testing.assert_allclose(r.aovs["depth"][quad], c.aovs["depth"][quad], rtol=1e-6)


def test_new_shapes_render_in_every_mode_without_bad_values():
    sc = raylume.scene_from_dict(
        {
            "lights": [{"type": "ambient", "intensity": 0.2}, {"type": "directional", "direction": [1, 2, -1]}],
            "materials": {
                "glass": {"transparency": 0.9, "reflective": 0.1},
                "tex": {
                    "texture": {
                        "type": "image",
                        "file": str(Path(__file__).parents[1] / "examples/textures/planks.jpg"),
                    }
                },
            },
            "objects": [
                {"type": "disk", "center": [0, 0, 3], "normal": [0, 0, -1], "radius": 1, "material": "tex"},
                {"type": "cylinder", "p0": [0.8, -1, 2], "p1": [0.8, 1, 2], "radius": 0.3, "material": "glass"},
                {"type": "quad", "position": [0, -1, 3], "u": [4, 0, 0], "v": [0, 0, 4], "material": "tex"},
            ],
        }
    )
    for mode in ("cast", "trace", "raster"):
        img = raylume.render(sc, mode=mode, width=40, height=30, spp=2)
        assert np.isfinite(img.rgb).all() and (img.aovs["object"] >= 0).mean() > 0.3, mode


# --- degenerate shapes are clear errors --------------------------------------------------------


@pytest.mark.parametrize(
    "obj, key",
    [
        ({"type": "disk", "radius": 0}, "objects[0].radius"),
        ({"type": "disk", "radius": 1, "normal": [0, 0, 0]}, "objects[0].normal"),
        ({"type": "disk", "radius": 1, "transform": {"scale": [1, 2, 1]}}, "objects[0].transform"),
        ({"type": "quad", "u": [1, 0, 0], "v": [2, 0, 0]}, "objects[0]"),
        ({"type": "quad", "u": [0, 0, 0], "v": [0, 1, 0]}, "objects[0]"),
        ({"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 1, 0], "radius": -1}, "objects[0].radius"),
        ({"type": "cylinder", "p0": [1, 1, 1], "p1": [1, 1, 1], "radius": 1}, "objects[0]"),
    ],
)
def test_degenerate_shapes_are_refused_naming_the_key(obj, key):
    with pytest.raises(raylume.SceneError) as err:
        one(obj)
    assert key in str(err.value)
    assert "Traceback" not in str(err.value)


# --- where a shape's code lives ----------------------------------------------------------------

SRC = Path(raylume.__file__).parent
# docs/architecture.md, "Adding a shape": its module, the switches, the model and compile's registry.
PLACES = {"kernels/geometry/shapes.py", "scene/model.py", "compile/objects.py"}


@pytest.mark.parametrize("name, model", [("disk", "Disk"), ("quad", "Quad"), ("cylinder", "Cylinder")])
def test_a_shape_lives_in_its_module_and_the_documented_registries(name, model):
    pattern = re.compile(rf"\bshape_{name}\b|\b{model}\b")
    touched = {str(p.relative_to(SRC)) for p in SRC.rglob("*.py") if pattern.search(p.read_text())}
    # other shape modules may reuse its helpers (the cylinder draws its caps as disks)
    touched = {p for p in touched if not re.fullmatch(r"kernels/geometry/shape_\w+\.py", p)}
    assert touched <= PLACES, touched - PLACES
    assert (SRC / "kernels" / "geometry" / f"shape_{name}.py").exists()
    doc = (SRC.parents[1] / "docs" / "architecture.md").read_text()
    for place in PLACES:
        assert place in doc


@pytest.mark.parametrize(
    ("extra", "basic"),
    [
        ([], True),
        ([{"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0]}], False),
        ([{"type": "quad", "position": [0, 0, 4], "u": [2, 0, 0], "v": [1, 1, 0]}], False),
        ([{"type": "cylinder", "p0": [0, 0, 0], "p1": [0, 2, 0], "radius": 0.5}], False),
    ],
)
def test_the_basic_variant_is_for_spheres_and_triangles_alone(extra, basic):
    """features(S) is None (the kernels' basic variant) exactly when every primitive is a sphere
    or a triangle, as the primitive table's kinds say."""
    objects = [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1},
        {"type": "triangle", "vertices": [[0, 0, 2], [1, 0, 2], [0, 1, 2]]},
        *extra,
    ]
    S = compile_scene(raylume.scene_from_dict({"objects": objects})).kernel
    kinds = set(S.prims[:, 0].tolist())
    assert (kinds <= {0, 1}) == basic
    assert S.basic_shapes == basic
    assert (features(S) is None) == basic
