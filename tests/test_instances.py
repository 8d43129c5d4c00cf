"""Instances (`instances` on mesh objects): a two-level BVH against the same scene flattened
into plain triangles (written by trimesh, placed by numpy), against the analytic ellipsoid,
shadows (any-hit), the `instance` AOV in every mode, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

import raylume
from raylume.accel.wide import NODE_REF, leaf_count, leaf_first
from raylume.cli import app
from raylume.scene.mesh import transform_matrix

# Placements of the instances: uniform and non-uniform scales, rotations, mirrors (det < 0).
PLACEMENTS = [
    ((-2.2, 0.0, 6.0), (10, 20, 30), (0.6, 0.6, 0.6)),
    ((0.0, 0.4, 7.0), (0, 45, 0), (1.0, -1.0, 1.0)),  # mirrored
    ((2.1, -0.6, 6.0), (5, 0, 70), (0.7, 1.5, -0.4)),  # mirrored, non-uniform
    ((0.3, -1.9, 5.0), (80, 10, 0), (1.8, 0.35, 0.9)),  # non-uniform
]


def matrices():
    return np.stack([transform_matrix(t, r, s) for t, r, s in PLACEMENTS])


def blob() -> trimesh.Trimesh:
    """A lumpy closed mesh with no symmetry (so a wrong transform shows)."""
    m = trimesh.creation.icosphere(subdivisions=3)
    v = m.vertices * (1.0 + 0.15 * np.sin(3 * m.vertices[:, :1]) * np.cos(2 * m.vertices[:, 1:2]))
    return trimesh.Trimesh(v * [1.0, 0.7, 1.2] + [0.2, 0.1, -0.1], m.faces, process=False)


def flattened(mesh: trimesh.Trimesh, mats: np.ndarray) -> trimesh.Trimesh:
    """Every instance's copy in world space in one mesh, copy i's faces after copy i-1's, winding
    reversed where the matrix mirrors (outward normals stay outward)."""
    verts, faces = [], []
    for i, m in enumerate(mats):
        f = mesh.faces[:, ::-1] if np.linalg.det(m[:3, :3]) < 0 else mesh.faces
        verts.append(mesh.vertices @ m[:3, :3].T + m[:3, 3])
        faces.append(f + i * len(mesh.vertices))
    return trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)


HEADER = """
[render]
width = {w}
height = {h}
max_depth = 2
[camera]
position = [0, 0.5, -1]
look_at = [0, -0.2, 6]
fov = 60
[[lights]]
type = "ambient"
intensity = 0.3
[[lights]]
type = "point"
position = [-3, 5, 0]
intensity = 0.8
[[objects]]
type = "plane"
point = [0, -2.6, 0]
normal = [0, 1, 0]
material = {{ color = [0.8, 0.8, 0.8] }}
"""


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """(instanced scene, flattened scene, mesh, matrices), 64 x 48."""
    d = tmp_path_factory.mktemp("instances")
    mesh = blob()
    mesh.export(d / "blob.ply")
    mats = matrices()
    np.save(d / "placements.npy", mats[:, :3, :])  # the (N, 3, 4) form
    flattened(mesh, mats).export(d / "flat.ply")
    head = HEADER.format(w=64, h=48)
    obj = '[[objects]]\ntype = "mesh"\nmaterial = {{ color = [0.9, 0.5, 0.2], specular = 40 }}\nfile = "{}"\n'
    (d / "inst.toml").write_text(head + obj.format("blob.ply") + 'instances = "placements.npy"\n')
    (d / "flat.toml").write_text(head + obj.format("flat.ply"))
    return raylume.load_scene(d / "inst.toml"), raylume.load_scene(d / "flat.toml"), mesh, mats


def grid_rays(n=64):
    """Rays from a point in front of the instances, through a grid that covers them all."""
    a = np.linspace(-0.65, 0.65, n)
    x, y = np.meshgrid(a, a)
    d = np.stack([x, y - 0.05, np.ones_like(x)], axis=-1).reshape(-1, 3)
    return np.tile([[0.0, 0.1, -1.0]], (len(d), 1)), d


def test_ids_and_depths_match_the_flattened_scene(scenes):
    inst, flat, mesh, mats = scenes
    o, d = grid_rays()
    t, obj, prim, ids = raylume.intersect(inst, o, d, instances=True)
    tf, objf, primf, idsf = raylume.intersect(flat, o, d, instances=True)
    # the same rays as the image they are (kernels/geometry/query.py: 4 x 2 packets where the scene takes
    # packets; the instanced one ray by ray): every array the same, stored in the image's order
    for scene, want in ((inst, (t, obj, prim, ids)), (flat, (tf, objf, primf, idsf))):
        image = raylume.intersect(scene, o.reshape(64, 64, 3), d.reshape(64, 64, 3), instances=True)
        for got, expected in zip(image, want, strict=True):
            np.testing.assert_array_equal(got.reshape(-1), expected)
    hit = np.isfinite(tf)
    assert hit.sum() > 1000 and (obj == 1).sum() > 400  # the instances and the plane are both seen
    np.testing.assert_array_equal(np.isfinite(t), hit)
    np.testing.assert_allclose(t[hit], tf[hit], rtol=1e-5, atol=1e-5)
    np.testing.assert_array_equal(obj, objf)
    on = obj == 1
    faces = len(mesh.faces)
    # the flattened mesh's face p is copy p // F's face p % F
    np.testing.assert_array_equal(ids[on], primf[on] // faces)
    np.testing.assert_array_equal(prim[on], primf[on] % faces)
    assert set(np.unique(ids[on])) == set(range(len(mats)))
    np.testing.assert_array_equal(ids[obj == 0], 0)  # the plane: an object without instances
    np.testing.assert_array_equal(idsf[hit], 0)
    np.testing.assert_array_equal(ids[~hit], -1)


def test_occluded_is_the_nearest_hit_between_tmin_and_tmax(scenes):
    """raylume.occluded through the two-level BVH (any-hit: instances and their meshes nearest
    first, stopping at the first hit) against intersect's nearest hit beyond tmin: blocked
    exactly when that hit lies before tmax; and the flattened scene's answers."""
    inst, flat, _, _ = scenes
    o, d = grid_rays()
    rng = np.random.default_rng(3)
    tmin = rng.uniform(0.0, 6.5, len(o))  # the instances lie at t = 4.7 to ~9
    tmax = tmin + rng.uniform(0.2, 3.0, len(o))
    on_instances = raylume.intersect(inst, o, d)[1] == 1
    t = raylume.intersect(inst, o, d, tmin=tmin)[0]
    blocked = raylume.occluded(inst, o, d, tmin=tmin, tmax=tmax)
    assert on_instances.sum() > 400 and 0.2 < blocked[on_instances].mean() < 0.8
    clear = np.abs(t - tmax) > 1e-6 * tmax  # the nearest hit not at tmax itself (rounding)
    assert clear.mean() > 0.99
    np.testing.assert_array_equal(blocked[clear], (t < tmax)[clear])
    flat_blocked = raylume.occluded(flat, o, d, tmin=tmin, tmax=tmax)
    assert (blocked == flat_blocked).mean() > 0.999


def test_normals_albedo_and_image_match_the_flattened_scene(scenes):
    """Cast mode's AOVs (normals by the inverse transpose; mirrored copies outward) and a trace
    image (shadow rays through any-hit) against the flattened scene."""
    inst, flat, _, _ = scenes
    a = raylume.Session(inst).render(mode="trace")
    b = raylume.Session(flat).render(mode="trace")
    for name in ("object", "prim", "instance"):
        assert a.aovs[name].dtype == np.int32 and a.aovs[name].shape == (48, 64)
    same = a.aovs["object"] == b.aovs["object"]
    assert same.mean() > 0.99
    on = same & (a.aovs["object"] == 1)
    np.testing.assert_allclose(a.aovs["depth"][same], b.aovs["depth"][same], rtol=1e-5)
    np.testing.assert_allclose(a.aovs["normal"][on], b.aovs["normal"][on], atol=2e-5)
    assert np.isfinite(a.rgb).all()
    close = np.abs(a.rgb - b.rgb).max(axis=-1) < 1e-4
    assert close.mean() > 0.99, close.mean()
    assert (a.aovs["instance"][a.aovs["object"] == 1] >= 0).all()


def test_ellipsoid_hit_distances_are_analytic(tmp_path):
    """A fine sphere mesh placed by a non-uniform, rotated, mirrored matrix: every hit lies
    between the ellipsoids that matrix makes of the mesh's circumscribed sphere (its vertices)
    and of its inscribed one (its nearest face plane), both solved in the sphere's own space."""
    sphere = trimesh.creation.icosphere(subdivisions=4)
    sphere.export(tmp_path / "sphere.ply")
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    r_in = np.min(np.abs((normals * v[f[:, 0]]).sum(1)) / np.linalg.norm(normals, axis=1))
    r_out = np.linalg.norm(v, axis=1).max()
    m = transform_matrix((0.5, -0.3, 8.0), (20, 35, -10), (1.5, -0.8, 1.1))
    np.save(tmp_path / "m.npy", m[None])
    (tmp_path / "s.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "sphere.ply"\ninstances = "m.npy"\n')
    rng = np.random.default_rng(3)
    d = rng.normal(size=(3000, 3)) * [0.09, 0.09, 0.0] + [0, 0, 1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.zeros_like(d)
    t, obj, prim, ids = raylume.intersect(raylume.load_scene(tmp_path / "s.toml"), o, d, instances=True)
    # in the sphere's space the ray is o' + t d' (d' not unit): |o' + t d'| = r
    inv = np.linalg.inv(m)
    oo = (inv[:3, :3] @ o.T).T + inv[:3, 3]
    dd = (inv[:3, :3] @ d.T).T
    a_, b_ = (dd * dd).sum(1), 2 * (oo * dd).sum(1)

    def first_hit(r):
        disc = b_ * b_ - 4 * a_ * ((oo * oo).sum(1) - r * r)
        return np.where(disc >= 0, (-b_ - np.sqrt(np.maximum(disc, 0))) / (2 * a_), np.inf)

    outer, inner = first_hit(r_out), first_hit(r_in)
    through = np.isfinite(inner)  # rays through the inscribed ellipsoid must hit the mesh between
    assert through.sum() > 1000 and (~np.isfinite(outer)).sum() > 100
    # the inverse matrix is stored in float32: the instance moves by ~1e-7 of its coordinates
    assert (t[through] >= outer[through] * (1 - 1e-6)).all() and (t[through] <= inner[through] * (1 + 1e-6)).all()
    np.testing.assert_array_equal(np.isfinite(t[~np.isfinite(outer)]), False)  # beyond the vertices: misses
    assert (obj[through] == 0).all() and (ids[through] == 0).all()


def write_scene(tmp_path, instances: str, mesh=True):
    trimesh.creation.box().export(tmp_path / "box.ply")
    text = f'[render]\nwidth = 8\nheight = 8\n[[objects]]\ntype = "mesh"\nfile = "box.ply"\ninstances = {instances}\n'
    (tmp_path / "s.toml").write_text(text)
    return tmp_path / "s.toml"


BAD = [
    ("missing", None, '"nowhere.npy"', "does not exist"),
    ("nan", np.full((2, 3, 4), np.nan), '"bad.npy"', "NaN"),
    ("singular", np.zeros((1, 3, 4)), '"bad.npy"', "singular"),
    # well conditioned, but the inverse (1e40) is beyond float32: it was inf, the instance drawn
    # by the rasterizer alone, and numpy's overflow warning printed
    ("tiny-scale", np.diag([1.0, 1e-40, 1.0, 1.0])[None], '"bad.npy"', "beyond float32"),
    ("huge-scale", np.diag([1.0, 1e39, 1.0, 1.0])[None], '"bad.npy"', "beyond float32"),
    ("shape", np.zeros((2, 3, 3)), '"bad.npy"', "(N, 4, 4) or (N, 3, 4)"),
    (
        "projective",
        np.array([[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]], float),
        '"bad.npy"',
        "bottom row",
    ),
    ("empty", np.zeros((0, 4, 4)), '"bad.npy"', "no matrices"),
    ("inline-empty", None, "[]", "at least one"),
]


@pytest.mark.parametrize("name,array,value,words", BAD, ids=[b[0] for b in BAD])
def test_bad_instances_exit_2_naming_file_and_key(tmp_path, name, array, value, words):
    if array is not None:
        np.save(tmp_path / "bad.npy", array)
    scene = write_scene(tmp_path, value)
    out = tmp_path / "out.png"
    result = CliRunner().invoke(app, ["render", str(scene), "-o", str(out), "--quiet"])
    assert result.exit_code == 2, result.output
    message = result.output
    assert "objects[0].instances" in message and words in message, message
    if value.startswith('"'):
        assert value.strip('"') in message  # the file
    assert "Traceback" not in message
    assert not out.exists()


def test_inline_transforms_equal_the_npy_form(scenes, tmp_path):
    inst, _, mesh, mats = scenes
    mesh.export(tmp_path / "blob.ply")
    rows = ", ".join(f"{{ translate = {list(t)}, rotate = {list(r)}, scale = {list(s)} }}" for t, r, s in PLACEMENTS)
    head = HEADER.format(w=8, h=8)
    (tmp_path / "s.toml").write_text(head + f'[[objects]]\ntype = "mesh"\nfile = "blob.ply"\ninstances = [{rows}]\n')
    o, d = grid_rays(16)
    a = raylume.intersect(inst, o, d, instances=True)
    b = raylume.intersect(raylume.load_scene(tmp_path / "s.toml"), o, d, instances=True)
    on = a[1] == 1
    np.testing.assert_allclose(a[0][on], b[0][on], rtol=1e-9)
    np.testing.assert_array_equal(a[3][on], b[3][on])


def test_a_numpy_array_of_matrices_equals_the_npy_form(scenes):
    """From Python, the (N, 4, 4) array itself, as vertices and faces take arrays (it was
    refused with every matrix printed); a bad one gets one line, with the array's shape."""
    inst, _, _, mats = scenes
    obj = inst.objects[-1]
    given = inst.replace(objects=[*inst.objects[:-1], obj.model_copy(update={"instances": None})])
    table = given.model_dump()
    table["objects"][-1]["instances"] = mats
    table["objects"][-1]["file"] = str(inst.base_dir / obj.file)
    from_array = raylume.scene_from_dict(table)
    o, d = grid_rays(16)
    a = raylume.intersect(inst, o, d, instances=True)
    b = raylume.intersect(from_array, o, d, instances=True)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    table["objects"][-1]["instances"] = mats[:, :3, :3]
    with pytest.raises(raylume.SceneError, match=r"\(N, 4, 4\) or \(N, 3, 4\) matrices .*shape \(\d+, 3, 3\)\)$"):
        raylume.scene_from_dict(table)


@pytest.mark.parametrize("mode", ["cast", "path", "raster"])
def test_every_mode_renders_instances(scenes, mode):
    inst, flat, _, _ = scenes
    img = raylume.Session(inst).render(mode=mode, spp=2, width=32, height=24)
    assert np.isfinite(img.rgb).all() and img.rgb.max() > 0
    ids = img.aovs["instance"]
    on = img.aovs["object"] == 1
    assert on.sum() > 20 and (ids[on] >= 0).all() and (ids[img.aovs["object"] == -1] == -1).all()
    if mode == "raster":  # drawn as plain triangles: the same ids as the ray caster's
        cast = raylume.Session(inst).render(mode="cast", width=32, height=24)
        same = cast.aovs["object"] == img.aovs["object"]
        assert (cast.aovs["instance"][same] == ids[same]).mean() > 0.97


def test_emissive_instances_light_path_mode(tmp_path):
    """An emissive instanced mesh seen directly shows its emission (every copy)."""
    trimesh.creation.box(extents=(1, 1, 1)).export(tmp_path / "box.ply")
    (tmp_path / "s.toml").write_text(
        '[render]\nwidth = 16\nheight = 16\nmode = "path"\nspp = 16\n'
        "[camera]\nposition = [0, 0, -3]\nlook_at = [0, 0, 0]\n"
        '[[objects]]\ntype = "mesh"\nfile = "box.ply"\n'
        'material = { type = "diffuse", color = [0, 0, 0], emission = [2, 1, 0.5] }\n'
        "instances = [{ translate = [0, 0, 0] }, { translate = [5, 0, 0] }]\n"
    )
    img = raylume.render(raylume.load_scene(tmp_path / "s.toml"))
    centre = img.rgb[8, 8]
    np.testing.assert_allclose(centre, [2, 1, 0.5], rtol=1e-6)


# Glowing copies of the blob over a diffuse floor, seen from above: a scaled, a mirrored and
# non-uniformly scaled, a rotated and stretched copy (the pdf of a light sample must account for
# what each matrix does to the triangles' areas).
GLOW = [
    ((-1.2, 1.4, 0.6), (10, 20, 30), (0.15, 0.15, 0.15)),
    ((0.9, 1.1, -0.4), (0, 45, 0), (0.25, -0.12, 0.2)),
    ((0.2, 2.0, 1.2), (70, 0, 20), (0.1, 0.3, 0.15)),
]
GLOW_SCENE = """
[render]
width = 20
height = 16
mode = "path"
max_depth = 3
[camera]
position = [0, 5, -3]
look_at = [0, 0, 0.3]
fov = 60
[[objects]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
material = {{ type = "diffuse", color = [0.8, 0.8, 0.8] }}
[[objects]]
type = "mesh"
file = "{file}"
material = {{ type = "diffuse", color = [0.5, 0.5, 0.5], emission = [24, 16, 8] }}
"""
SEEDS = 12  # independent renders per estimate: the per-pixel standard errors come from them


def _seed_renders(scene, spp, strategy=None, monkeypatch=None):
    """(SEEDS, H, W) luminance-like means of SEEDS renders with different seeds."""
    if strategy is not None:
        monkeypatch.setenv("RAYLUME_PATH_STRATEGY", strategy)
    session = raylume.Session(scene)
    out = np.stack([session.render(spp=spp, seed=s, aovs=False).rgb.mean(axis=2) for s in range(SEEDS)])
    if strategy is not None:
        monkeypatch.delenv("RAYLUME_PATH_STRATEGY")
    return out


@pytest.fixture(scope="module")
def glow_scenes(tmp_path_factory):
    d = tmp_path_factory.mktemp("glow")
    mesh = blob()
    mesh.export(d / "blob.ply")
    mats = np.stack([transform_matrix(t, r, s) for t, r, s in GLOW])
    np.save(d / "glow.npy", mats)
    flattened(mesh, mats).export(d / "flat.ply")
    (d / "inst.toml").write_text(GLOW_SCENE.format(file="blob.ply") + 'instances = "glow.npy"\n')
    (d / "flat.toml").write_text(GLOW_SCENE.format(file="flat.ply"))
    return raylume.load_scene(d / "inst.toml"), raylume.load_scene(d / "flat.toml")


Z = 4.5  # standard errors allowed (as tests/test_path.py): a false alarm about once in 150 000


@pytest.mark.parametrize("strategy", ["mis", "light"])
def test_emissive_instances_are_light_sampled_as_the_flattened_meshes(glow_scenes, strategy, monkeypatch):
    """Next-event estimation of an emissive instanced mesh (one emitter row, an instance then a
    triangle picked, the point moved to world space) against the same copies flattened into
    one plain emissive mesh (one emitter row per triangle): the images agree within their
    standard errors, computed per pixel from independent renders (seeds), over the whole
    image and each quarter of it. With light sampling alone ("light") the pdf is tested
    without BSDF sampling's help."""
    inst, flat = glow_scenes
    a = _seed_renders(inst, 4, strategy, monkeypatch)
    b = _seed_renders(flat, 4, strategy, monkeypatch)
    assert np.isfinite(a).all() and np.isfinite(b).all()
    mean = a.mean(axis=0) - b.mean(axis=0)
    var = a.var(axis=0, ddof=1) / SEEDS + b.var(axis=0, ddof=1) / SEEDS  # per-pixel se^2
    assert (var > 0).mean() > 0.9  # the floor is lit everywhere, by sampled light
    h, w = mean.shape
    for name, part in (
        ("image", np.s_[:, :]),
        ("top left", np.s_[: h // 2, : w // 2]),
        ("top right", np.s_[: h // 2, w // 2 :]),
        ("bottom left", np.s_[h // 2 :, : w // 2]),
        ("bottom right", np.s_[h // 2 :, w // 2 :]),
    ):
        diff, se = mean[part].sum(), math.sqrt(var[part].sum())
        assert abs(diff) < Z * se, (strategy, name, diff, se, a.mean(), b.mean())


def test_light_sampling_emissive_instances_lowers_the_noise(glow_scenes, monkeypatch):
    """MIS (next-event estimation and BSDF sampling) against BSDF sampling alone, the only way
    an instanced emitter was found before: the per-pixel variance over seeds drops."""
    inst, _ = glow_scenes
    mis = _seed_renders(inst, 4)
    bsdf = _seed_renders(inst, 4, "bsdf", monkeypatch)
    v_mis, v_bsdf = mis.var(axis=0, ddof=1).mean(), bsdf.var(axis=0, ddof=1).mean()
    assert v_mis < v_bsdf, (v_mis, v_bsdf)
    # and the two estimate the same image
    diff = mis.mean(axis=0) - bsdf.mean(axis=0)
    se = math.sqrt((mis.var(axis=0, ddof=1) / SEEDS + bsdf.var(axis=0, ddof=1) / SEEDS).sum())
    assert abs(diff.sum()) < Z * se, (diff.sum(), se)


def test_top_level_lanes_hold_one_instance_each_and_bound_it(scenes):
    """The TLAS gives each instance a lane of its own, whose box holds every vertex of that
    copy (placed by numpy) and is no larger than the box of the object box's corners moved by
    the matrix (the box built from the BLAS's second-level boxes is tighter for rotated copies)."""
    inst, _, mesh, mats = scenes
    from raylume.compile import compile_scene

    k = compile_scene(inst).kernel
    bounds, index = k.inst_node_bounds, k.inst_node_index
    n_tlas = int(k.instance_index[:, 0].min())  # the BLASes' nodes follow the TLAS's
    lanes = [(m, j) for m in range(n_tlas) for j in range(index.shape[2]) if index[m, NODE_REF, j] < 0]
    assert sorted(int(leaf_first(index[m, NODE_REF, j])) for m, j in lanes) == list(range(len(mats)))
    assert all(leaf_count(index[m, NODE_REF, j]) == 1 for m, j in lanes)
    v = np.asarray(mesh.vertices).astype(np.float32).astype(np.float64)  # as the scene stores them
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)])
    corners = v.min(axis=0) + corners * (v.max(axis=0) - v.min(axis=0))
    tighter = 0
    for m, j in lanes:
        row = int(leaf_first(index[m, NODE_REF, j]))
        a = mats[k.instance_index[row, 1]]
        lo, hi = bounds[m, :3, j].astype(np.float64), bounds[m, 3:6, j].astype(np.float64)
        placed = v @ a[:3, :3].T + a[:3, 3]
        assert (placed >= lo).all() and (placed <= hi).all()
        moved = corners @ a[:3, :3].T + a[:3, 3]
        assert (lo >= moved.min(axis=0) - 1e-6).all() and (hi <= moved.max(axis=0) + 1e-6).all()
        tighter += np.prod(hi - lo) < 0.95 * np.prod(moved.max(axis=0) - moved.min(axis=0))
    assert tighter >= 2  # the rotated copies


def test_an_instance_costs_at_most_128_bytes(tmp_path):
    """10 000 instances of one mesh, scattered and overlapping: inverse matrix, indices and the
    top-level BVH's nodes together, per instance; the mesh is stored once."""
    blob().export(tmp_path / "blob.ply")
    rng = np.random.default_rng(1)
    n = 10_000
    mats = np.stack(
        [transform_matrix(rng.uniform(-50, 50, 3), rng.uniform(0, 360, 3), rng.uniform(0.5, 2, 3)) for _ in range(n)]
    )
    np.save(tmp_path / "m.npy", mats.astype(np.float32))
    (tmp_path / "s.toml").write_text('[[objects]]\ntype = "mesh"\nfile = "blob.ply"\ninstances = "m.npy"\n')
    from raylume.compile import compile_scene

    stats = compile_scene(raylume.load_scene(tmp_path / "s.toml")).stats
    faces = len(blob().faces)
    assert stats["instances"] == n and stats["triangles"] == faces
    assert stats["instanced_triangles"] == n * faces
    assert stats["bytes_per_instance"] <= 128, stats["bytes_per_instance"]


def test_more_matrices_than_an_object_holds_are_refused_before_they_are_copied(tmp_path, monkeypatch):
    """The count is checked on the file's own array: the float64 copy of a 2^25 + 1 int8 file
    had peaked at 3.7 GB before the refusal. (The limit lowered for the test.)"""
    from raylume.scene import instances

    monkeypatch.setattr(instances, "MAX_INSTANCES", 4)
    np.save(tmp_path / "many.npy", np.tile(np.eye(4, dtype=np.int8), (5, 1, 1)))
    scene = write_scene(tmp_path, '"many.npy"')
    result = CliRunner().invoke(app, ["render", str(scene), "-o", str(tmp_path / "o.png"), "--quiet"])
    assert result.exit_code == 2 and "holds 5 matrices, more than the 4 supported" in result.output, result.output
