"""Mesh import: round trips through every format, transforms, normals, UVs,
errors, the example meshes and the shared real-world models."""

import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image as PILImage

from raylume.compile import compile_scene
from raylume.errors import SceneError
from raylume.scene.document import scene_from_dict
from raylume.scene.mesh import MeshData, MeshError, load_mesh, obj_uv_problem, transform_matrix
from raylume.scene.procedural import bumpy_sphere, vertex_normals

REPO = Path(__file__).resolve().parents[1]
SHARED_MODELS = REPO.parent / "shared" / "models"
EXAMPLE_MESHES = REPO / "examples" / "meshes"


def signed_volume(d: MeshData) -> float:
    v, f = d.vertices, d.faces
    return float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0)


def area(d: MeshData) -> float:
    v, f = d.vertices, d.faces
    return float(np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum() / 2)


def same_point_sets(a, b, tol=1e-5) -> bool:
    """Every point of a is near a point of b and vice versa (small meshes only)."""
    dist = np.linalg.norm(np.asarray(a)[:, None, :] - np.asarray(b)[None, :, :], axis=2)
    return bool(dist.min(axis=1).max() < tol and dist.min(axis=0).max() < tol)


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# A tetrahedron whose vertices sit on distinct axes, so transforms are easy to check by hand.
TETRA_OBJ = "v 0 0 0\nv 1 0 0\nv 0 2 0\nv 0 0 3\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
TETRA = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=float)


# ---------------------------------------------------------------- round trips

SHAPES = {
    "box": lambda: trimesh.creation.box(extents=(1.0, 2.0, 3.0)),
    "icosphere": lambda: trimesh.creation.icosphere(subdivisions=2, radius=1.5),
    "annulus": lambda: trimesh.creation.annulus(r_min=0.5, r_max=1.0, height=0.4, sections=24),
}


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "off", "glb"])
@pytest.mark.parametrize("shape", list(SHAPES))
def test_round_trip(tmp_path, shape, ext):
    original = SHAPES[shape]()
    path = tmp_path / f"{shape}.{ext}"
    original.export(path)
    d = load_mesh(path)
    assert d.vertices.dtype == np.float64 and d.vertices.shape[1] == 3
    assert d.faces.dtype == np.int32 and d.faces.shape == (len(original.faces), 3)
    assert d.degenerate == 0
    # STL stores each triangle's own corners: the loader welds them back together.
    assert len(d.vertices) == len(original.vertices)
    assert same_point_sets(d.vertices, original.vertices)
    assert area(d) == pytest.approx(original.area, rel=1e-5)
    assert signed_volume(d) == pytest.approx(original.volume, rel=1e-5)
    assert d.uvs is None


def test_obj_keeps_vertex_and_face_order(tmp_path):
    d = load_mesh(write(tmp_path / "tetra.obj", TETRA_OBJ))
    assert np.array_equal(d.vertices, TETRA)
    assert np.array_equal(d.faces, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    assert d.normals is None and d.uvs is None


def test_quads_and_polygons_are_triangulated(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nf 1 2 3 4\nf 1 4 5\n"
    d = load_mesh(write(tmp_path / "quad.obj", text))
    assert len(d.faces) == 3
    assert area(d) == pytest.approx(1.5)
    normals = np.cross(
        d.vertices[d.faces[:, 1]] - d.vertices[d.faces[:, 0]], d.vertices[d.faces[:, 2]] - d.vertices[d.faces[:, 0]]
    )
    assert np.all(normals[:, 2] > 0)  # counter-clockwise winding of the file is kept


def test_gltf_scene_nodes_are_baked_and_concatenated(tmp_path):
    scene = trimesh.Scene()
    box = trimesh.creation.box(extents=(1, 1, 1))
    scene.add_geometry(box, node_name="a", transform=transform_matrix(translate=(5, 0, 0)))
    # Second instance mirrored: its winding must still come out outward.
    scene.add_geometry(box, node_name="b", transform=transform_matrix(translate=(-5, 0, 0), scale=(-2, 1, 1)))
    scene.add_geometry(trimesh.creation.icosphere(subdivisions=1), node_name="c")
    path = tmp_path / "scene.glb"
    scene.export(path)
    d = load_mesh(path)
    assert len(d.faces) == 12 + 12 + 80
    assert d.vertices[:, 0].max() == pytest.approx(5.5) and d.vertices[:, 0].min() == pytest.approx(-6.0)
    expected = 1.0 + 2.0 + trimesh.creation.icosphere(subdivisions=1).volume
    assert signed_volume(d) == pytest.approx(expected, rel=1e-5)


def test_gltf_with_external_buffer(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=1)
    files = trimesh.Scene(mesh).export(file_type="gltf")  # {"model.gltf": ..., "gltf_buffer_*.bin": ...}
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    d = load_mesh(tmp_path / "model.gltf")
    assert len(d.faces) == 80 and signed_volume(d) == pytest.approx(mesh.volume, rel=1e-5)
    for name in files:
        if name.endswith(".bin"):
            (tmp_path / name).unlink()
    with pytest.raises(MeshError, match="model.gltf"):
        load_mesh(tmp_path / "model.gltf")


# ------------------------------------------------------------------ transforms


def test_transform_matrix_convention():
    ry = transform_matrix(rotate=(0, 90, 0))[:3, :3]
    assert np.allclose(ry @ [1, 0, 0], [0, 0, -1])  # +x -> -z
    assert np.allclose(ry @ [0, 0, 1], [1, 0, 0])  # +z -> +x
    assert np.allclose(transform_matrix(rotate=(90, 0, 0))[:3, :3] @ [0, 1, 0], [0, 0, 1])  # x: +y -> +z
    assert np.allclose(transform_matrix(rotate=(0, 0, 90))[:3, :3] @ [1, 0, 0], [0, 1, 0])  # z: +x -> +y
    # x first, then y: +y -> +z (about x) -> +x (about y); the other order would leave +z.
    assert np.allclose(transform_matrix(rotate=(90, 90, 0))[:3, :3] @ [0, 1, 0], [1, 0, 0])
    # Scale first, then rotate, then translate.
    m = transform_matrix(translate=(1, 2, 3), rotate=(0, 0, 90), scale=(2, 1, 1))
    assert np.allclose(m @ [1, 0, 0, 1], [1, 4, 3, 1])
    assert np.allclose(transform_matrix(scale=3.0)[:3, :3], 3 * np.eye(3))
    assert transform_matrix().dtype == np.float64 and np.array_equal(transform_matrix(), np.eye(4))
    with pytest.raises(ValueError):
        transform_matrix(scale=(1, 2))
    with pytest.raises(ValueError):
        transform_matrix(translate=(0, np.nan, 0))


def test_loaded_vertices_land_where_the_matrix_says(tmp_path):
    path = write(tmp_path / "tetra.obj", TETRA_OBJ)
    d = load_mesh(path, rotate=(0, 90, 0))
    assert np.allclose(d.vertices, [[0, 0, 0], [0, 0, -1], [0, 2, 0], [3, 0, 0]])
    d = load_mesh(path, translate=(10, 20, 30), rotate=(0, 0, 90), scale=(2, 1, 1))
    # (x, y, z) -> scale (2x, y, z) -> about z (-y, 2x, z) -> translate
    assert np.allclose(d.vertices, [[10, 20, 30], [10, 22, 30], [8, 20, 30], [10, 20, 33]])
    assert signed_volume(d) == pytest.approx(2 * 1.0, rel=1e-12)  # tetra volume 1, det 2


@pytest.mark.parametrize("scale", [(-1, 1, 1), (1, -1, 1), (1, 1, -2), (-1, -1, -1), -0.5])
def test_mirroring_flips_winding_and_keeps_normals_outward(tmp_path, scale):
    sphere = trimesh.creation.icosphere(subdivisions=2)
    path = tmp_path / "sphere.obj"
    sphere.export(path, include_normals=True)
    for smooth in (None, True):  # file normals, then file normals requested explicitly
        d = load_mesh(path, translate=(1, 2, 3), scale=scale, smooth=smooth)
        assert signed_volume(d) > 0
        radial = d.vertices - (1, 2, 3)
        assert np.einsum("ij,ij->i", d.normals, radial).min() > 0
    d = load_mesh(tmp_path / "sphere.obj", scale=scale, smooth=False)
    assert d.normals is None and signed_volume(d) > 0
    sphere.export(tmp_path / "plain.off")  # no normals in the file: computed ones
    d = load_mesh(tmp_path / "plain.off", scale=scale, smooth=True)
    assert signed_volume(d) > 0 and np.einsum("ij,ij->i", d.normals, d.vertices).min() > 0


def test_normals_use_inverse_transpose(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=3)
    sphere.vertex_normals = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1)[:, None]
    sphere.export(tmp_path / "sphere.ply")
    abc = np.array([1.0, 2.0, 3.0])
    d = load_mesh(tmp_path / "sphere.ply", rotate=(30, -40, 70), scale=abc)
    r = transform_matrix(rotate=(30, -40, 70))[:3, :3]
    local = d.vertices @ r  # undo the rotation: points on the axis-aligned ellipsoid
    expected = (local / abc**2) @ r.T  # ellipsoid gradient, rotated back to world
    expected /= np.linalg.norm(expected, axis=1)[:, None]
    assert d.normals.dtype == np.float32
    assert np.allclose(d.normals, expected, atol=1e-5)


@pytest.fixture(scope="module")
def tetra_file(tmp_path_factory):
    return write(tmp_path_factory.mktemp("tetra") / "tetra.obj", TETRA_OBJ)


vec = st.tuples(*[st.floats(-100, 100)] * 3)
scale_component = st.one_of(st.floats(0.1, 10), st.floats(-10, -0.1))


@settings(max_examples=60, deadline=None)
@given(translate=vec, rotate=st.tuples(*[st.floats(-360, 360)] * 3), scale=st.tuples(*[scale_component] * 3))
def test_any_transform_matches_matrix_and_keeps_volume_positive(tetra_file, translate, rotate, scale):
    d = load_mesh(tetra_file, translate=translate, rotate=rotate, scale=scale)
    m = transform_matrix(translate, rotate, scale)
    assert np.allclose(d.vertices, TETRA @ m[:3, :3].T + m[:3, 3], atol=1e-9)
    assert signed_volume(d) == pytest.approx(abs(np.prod(scale)), rel=1e-6)


# ------------------------------------------------------------- normals and UVs


def test_obj_file_normals(tmp_path):
    # Deliberately non-geometric, non-unit normals: they must come from the file.
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 2\nvn 0 3 4\nvn 1 0 0\nf 1//1 2//2 3//3\n"
    path = write(tmp_path / "tri.obj", text)
    expected = [[0, 0, 1], [0, 0.6, 0.8], [1, 0, 0]]
    assert np.allclose(load_mesh(path).normals, expected)
    assert np.allclose(load_mesh(path, smooth=True).normals, expected)
    assert load_mesh(path, smooth=False).normals is None


def test_broken_file_normals_are_replaced_by_computed_ones(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nvn 0 1 0\nvn 1 0 0\nf 1//1 2//2 3//3\n"
    n = load_mesh(write(tmp_path / "tri.obj", text)).normals
    assert np.allclose(n, [[0, 0, 1], [0, 1, 0], [1, 0, 0]])  # zero-length vn -> face normal


def test_obj_unused_vertices_are_dropped_by_trimesh(tmp_path):
    # trimesh only keeps referenced vertices; the rest keep their relative order.
    text = "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 2 3 4\n"
    d = load_mesh(write(tmp_path / "unused.obj", text))
    assert np.array_equal(d.vertices, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert np.array_equal(d.faces, [[0, 1, 2]])


def test_obj_per_corner_normals_split_vertices(tmp_path):
    # A cube with one normal per side: trimesh splits each corner into three vertices.
    box = trimesh.creation.box()
    lines = [f"v {x} {y} {z}" for x, y, z in box.vertices]
    sides, side_of_face = np.unique(box.face_normals.round(6), axis=0, return_inverse=True)
    lines += [f"vn {x} {y} {z}" for x, y, z in sides]
    lines += [f"f {a + 1}//{s + 1} {b + 1}//{s + 1} {c + 1}//{s + 1}" for s, (a, b, c) in zip(side_of_face, box.faces)]
    d = load_mesh(write(tmp_path / "cube.obj", "\n".join(lines) + "\n"))
    assert len(d.faces) == 12 and len(d.vertices) == 24  # 8 corners x 3 sides
    geometric = np.cross(
        d.vertices[d.faces[:, 1]] - d.vertices[d.faces[:, 0]], d.vertices[d.faces[:, 2]] - d.vertices[d.faces[:, 0]]
    )
    geometric /= np.linalg.norm(geometric, axis=1)[:, None]
    for corner in range(3):  # every corner carries its own face's normal: hard edges survive
        assert np.allclose(d.normals[d.faces[:, corner]], geometric)
    assert signed_volume(d) == pytest.approx(1.0)


def test_computed_normals_are_smooth_across_uv_seams(tmp_path):
    # Same cube, split by UV seams only: computed normals must not crease there.
    box = trimesh.creation.box()
    lines = [f"v {x} {y} {z}" for x, y, z in box.vertices]
    lines += [f"vt {i / 40} {i / 40}" for i in range(36)]
    lines += [f"f {a + 1}/{3 * i + 1} {b + 1}/{3 * i + 2} {c + 1}/{3 * i + 3}" for i, (a, b, c) in enumerate(box.faces)]
    path = write(tmp_path / "cube_uv.obj", "\n".join(lines) + "\n")
    d = load_mesh(path, smooth=True)
    assert len(d.vertices) == 36 and d.uvs.shape == (36, 2) and d.uvs.dtype == np.float32
    welded = vertex_normals(box.vertices, box.faces)  # the same cube without seams
    for p, n in zip(box.vertices, welded):  # all copies of a corner share its welded normal
        same = np.all(d.vertices == p, axis=1)
        assert same.sum() > 1
        assert np.allclose(d.normals[same], n, atol=1e-6)
    assert load_mesh(path).normals is None  # default: flat, the file has no normals


def test_obj_uvs(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n"
    d = load_mesh(write(tmp_path / "quad.obj", text))
    assert d.uvs.dtype == np.float32 and d.uvs.shape == (4, 2)
    assert np.allclose(d.uvs, d.vertices[:, :2])  # vt equals (x, y) here


def test_glb_normals_and_uvs(tmp_path):
    mesh = trimesh.creation.uv_sphere(count=(12, 12))
    uv = np.column_stack([mesh.vertices[:, 0] * 0.5 + 0.5, mesh.vertices[:, 1] * 0.5 + 0.5])
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv)
    _ = mesh.vertex_normals  # cached normals are exported
    mesh.export(tmp_path / "sphere.glb")
    d = load_mesh(tmp_path / "sphere.glb")
    assert d.normals is not None and d.uvs is not None
    idx = np.argmin(np.linalg.norm(d.vertices[:, None] - mesh.vertices[None], axis=2), axis=1)
    assert np.allclose(d.uvs, uv[idx], atol=1e-6)
    assert np.allclose(d.normals, mesh.vertex_normals[idx], atol=1e-5)


def test_stl_smooth_normals_after_welding(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=2)
    sphere.export(tmp_path / "sphere.stl")
    assert load_mesh(tmp_path / "sphere.stl").normals is None
    d = load_mesh(tmp_path / "sphere.stl", smooth=True)
    assert len(d.vertices) == len(sphere.vertices)
    assert np.einsum("ij,ij->i", d.normals, d.vertices / 1.0).min() > 0.98  # nearly radial


def test_degenerate_faces_dropped_and_counted(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\nf 1 2 4\nf 2 3 1\n"
    d = load_mesh(write(tmp_path / "degen.obj", text))
    assert d.degenerate == 2  # repeated index, and three collinear points
    assert np.array_equal(d.faces, [[0, 1, 2], [1, 2, 0]])


# ---------------------------------------------------------------------- errors


def assert_mesh_error(path, match=None, **kwargs):
    with pytest.raises(MeshError) as info:
        load_mesh(path, **kwargs)
    message = str(info.value)
    assert Path(path).name in message, message
    if match:
        assert match in message, message
    return message


def test_error_missing_directory_extension_empty(tmp_path):
    assert_mesh_error(tmp_path / "nope.obj", "does not exist")
    (tmp_path / "folder.obj").mkdir()
    assert_mesh_error(tmp_path / "folder.obj", "directory")
    assert_mesh_error(write(tmp_path / "mesh.xyz", "v 0 0 0\n"), "unsupported extension")
    assert_mesh_error(write(tmp_path / "noext", "v 0 0 0\n"), "unsupported extension")
    for ext in ("obj", "ply", "stl", "off", "glb", "gltf"):
        assert_mesh_error(write(tmp_path / f"empty.{ext}", ""), "empty")


def test_error_unreadable_even_as_root(tmp_path, monkeypatch):
    path = write(tmp_path / "locked.obj", TETRA_OBJ)
    real_open = open

    def deny(file, *args, **kwargs):
        if Path(file) == path:
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", deny)
    assert_mesh_error(path, "Permission denied")


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "off", "glb", "gltf"])
def test_error_garbage_content(tmp_path, ext):
    assert_mesh_error(write(tmp_path / f"garbage.{ext}", "this is not a mesh\nat all\n"))
    (tmp_path / f"binary.{ext}").write_bytes(bytes(range(256)) * 8)
    assert_mesh_error(tmp_path / f"binary.{ext}")


@pytest.mark.parametrize("ext", ["obj", "stl", "off", "glb"])
def test_error_content_of_another_format(tmp_path, ext):
    trimesh.creation.box().export(tmp_path / "box.ply")
    (tmp_path / f"box.{ext}").write_bytes((tmp_path / "box.ply").read_bytes())
    assert_mesh_error(tmp_path / f"box.{ext}")


def test_error_no_triangles(tmp_path):
    assert_mesh_error(write(tmp_path / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"), "no triangles")
    assert_mesh_error(write(tmp_path / "lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n"), "no triangles")
    trimesh.PointCloud(np.random.default_rng(0).random((10, 3))).export(tmp_path / "cloud.ply")
    assert_mesh_error(tmp_path / "cloud.ply", "no triangles")
    assert_mesh_error(write(tmp_path / "comment.obj", "# nothing here\n"), "no triangles")


def test_error_ply_without_a_vertex_property_names_it(tmp_path):
    # trimesh's PLY reader raises KeyError('y') here; the message says what is missing
    header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nelement face 1\n"
    body = "property list uchar int vertex_indices\nend_header\n0\n1\n2\n3 0 1 2\n"
    assert_mesh_error(write(tmp_path / "xonly.ply", header + body), "no 'y'")


def test_error_face_index_out_of_range(tmp_path):
    assert_mesh_error(write(tmp_path / "oor.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n"), "index")
    assert_mesh_error(write(tmp_path / "oor_neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -7\n"), "index")
    assert_mesh_error(write(tmp_path / "oor.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n"), "index")
    ply = (
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"
    )
    assert_mesh_error(write(tmp_path / "oor.ply", ply), "index")


TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"


@pytest.mark.parametrize(
    ("faces", "words"),
    [
        ("f 1 2 0\n", ["line 7 (f 1 2 0)", "vertex index 0 is invalid (OBJ indices start at 1)"]),
        ("f 1 2 7\n", ["line 7 (f 1 2 7)", "vertex index 7 is out of range (the file has 3 v lines)"]),
        ("f 1/1 2/2 -4/3\n", ["vertex index -4 is out of range (only 3 v lines come before it)"]),
    ],
)
def test_error_obj_face_index_zero_or_out_of_range_names_line_and_index(tmp_path, faces, words):
    # trimesh reads index 0 as the first vertex (here: a zero-area face) and says only "an index
    # that does not exist" for one past the end
    message = assert_mesh_error(write(tmp_path / "bad.obj", TRIANGLE_OBJ + faces), "could not be parsed as OBJ")
    assert all(w in message for w in words), message


@pytest.mark.parametrize(
    ("lines", "words"),
    [
        ("v 0 1 abc\nf 1 2 3\n", ["line 1 (v 0 1 abc)", "'abc' is not a number"]),
        ("vn 0 0 z\nf 1 2 3\n", ["line 1 (vn 0 0 z)", "'z' is not a number"]),
        ("vt 0 q\nf 1 2 3\n", ["line 1 (vt 0 q)", "'q' is not a number"]),
        ("f 1 2 x\n", ["line 1 (f 1 2 x)", "vertex index 'x' is not a whole number"]),
        # trimesh reads the file's coordinates as 2D points here, and the error came from numpy
        ("v 0 1\nf 1 2 3\n", ["line 1 (v 0 1)", "a vertex takes 3, 4, 6 or 7 numbers, not 2"]),
    ],
)
def test_error_obj_malformed_line_is_named(tmp_path, lines, words):
    message = assert_mesh_error(write(tmp_path / "bad.obj", lines + TRIANGLE_OBJ), "could not be parsed as OBJ")
    assert all(w in message for w in words), message


def test_error_truncated_binary_stl_says_it_is_cut_short(tmp_path):
    # trimesh falls back to its ASCII reader, which finds no triangles
    trimesh.creation.icosphere(subdivisions=1).export(tmp_path / "whole.stl")
    data = (tmp_path / "whole.stl").read_bytes()
    assert len(data) == 84 + 50 * 80
    (tmp_path / "cut.stl").write_bytes(data[:2000])
    message = assert_mesh_error(tmp_path / "cut.stl", "could not be parsed as STL")
    assert "counts 80 triangles, which take 4084 bytes, but the file has 2000" in message, message


def test_obj_uv_index_out_of_range_is_named_when_a_texture_needs_the_uvs(tmp_path):
    # trimesh drops every texture coordinate of the file, silently; untextured, the mesh loads
    mesh = load_mesh(write(tmp_path / "uv.obj", TRIANGLE_OBJ + "f 1/5 2/1 3/1\n"))
    assert mesh.uvs is None and "texture coordinate index 5 is out of range (the file has 3 vt lines)" in (
        obj_uv_problem(tmp_path / "uv.obj") or ""
    )
    assert obj_uv_problem(write(tmp_path / "plain.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")) is None
    PILImage.fromarray(np.zeros((2, 2, 3), np.uint8)).save(tmp_path / "t.png")
    texture = {"type": "image", "file": "t.png"}
    scene = scene_from_dict(
        {"objects": [{"type": "mesh", "file": "uv.obj", "material": {"texture": texture}}]}, source="s.toml"
    ).with_base_dir(tmp_path)
    with pytest.raises(SceneError) as caught:
        compile_scene(scene, source="s.toml")
    message = str(caught.value)
    assert message.startswith("s.toml: objects[0].file: the mesh has no texture coordinates"), message
    assert "its texture coordinates could not be used: line 7 (f 1/5 2/1 3/1): texture coordinate index 5" in message


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_error_non_finite_vertices(tmp_path, bad):
    assert_mesh_error(write(tmp_path / f"{bad}.obj", f"v 0 0 {bad}\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), "NaN or infinite")


def test_error_every_face_degenerate(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n"
    assert_mesh_error(write(tmp_path / "flat.obj", text), "degenerate")


def test_error_bad_transform_names_file(tmp_path):
    path = write(tmp_path / "tetra.obj", TETRA_OBJ)
    assert_mesh_error(path, "scale", scale=(1, 0, 1))
    assert_mesh_error(path, "scale", scale=(1, 2))
    assert issubclass(MeshError, ValueError)


# ---------------------------------------------------------------------- scale


def test_four_million_triangles_load(tmp_path):
    v, f = bumpy_sphere(4_000_000)
    path = tmp_path / "big.ply"
    trimesh.Trimesh(v, f, process=False).export(path)  # binary PLY, float32 positions
    del v
    start = time.perf_counter()
    d = load_mesh(path)
    elapsed = time.perf_counter() - start
    print(f"4M-triangle PLY loaded in {elapsed:.2f}s")
    assert np.array_equal(d.faces, f) and d.degenerate == 0
    assert elapsed < 30.0


# -------------------------------------------------------------- bundled files

EXAMPLE_FILES = sorted(p.name for p in EXAMPLE_MESHES.glob("*") if p.suffix in {".obj", ".ply"})


@pytest.mark.parametrize("name", EXAMPLE_FILES)
def test_example_meshes_load(name):
    d = load_mesh(EXAMPLE_MESHES / name)
    assert len(d.faces) > 500 and (EXAMPLE_MESHES / name).stat().st_size < 400_000


def test_example_meshes_present():
    assert {"teapot.obj", "suzanne.obj", "spot.obj", "bumpy_sphere.ply"} <= set(EXAMPLE_FILES)


# Face counts after triangulation (suzanne's quads) and degenerate-face removal.
SHARED_FACES = {
    "cow.obj": 5804,
    "nefertiti.obj": 99938,
    "spot.obj": 5856,
    "stanford-bunny.obj": 69451,
    "suzanne.obj": 968,
    "teapot.obj": 6320,
}


@pytest.mark.skipif(not SHARED_MODELS.is_dir(), reason=f"shared models folder {SHARED_MODELS} is absent")
@pytest.mark.parametrize("name", sorted(SHARED_FACES))
def test_shared_models_load(name):
    path = SHARED_MODELS / name
    if not path.exists():
        pytest.skip(f"{path} is absent")
    start = time.perf_counter()
    d = load_mesh(path)
    print(
        f"{name}: {len(d.vertices)} vertices, {len(d.faces)} faces, {d.degenerate} degenerate, "
        f"{time.perf_counter() - start:.3f}s"
    )
    assert len(d.faces) == SHARED_FACES[name]
    assert np.isfinite(d.vertices).all() and d.faces.max() < len(d.vertices)
    assert (d.normals is not None) == (name == "suzanne.obj")  # the only one with vn
    assert (d.uvs is not None) == (name == "spot.obj")  # the only one with vt
    smooth = load_mesh(path, smooth=True).normals
    assert np.allclose(np.linalg.norm(smooth, axis=1), 1.0, atol=1e-5)


# ---------------------------------------------------------------- PLY triangle strips

# A 1 x 3 ribbon in the z = 0 plane: vertex 2k is (0, k), vertex 2k + 1 is (1, k).
RIBBON = np.array([[x, y, 0.0] for y in range(4) for x in range(2)])
# Row 1 joins two strips with degenerate triangles (3, 3 and 4, 4); row 2 uses restart markers.
STRIPS = [[0, 1, 2, 3, 3, 4, 4, 5, 6, 7], [-1, 2, 3, 4, 5, -1]]
# The alternating rule: (s0, s1, s2), (s2, s1, s3), (s2, s3, s4), ... (zero-area joins dropped).
STRIP_FACES = [[0, 1, 2], [2, 1, 3], [4, 5, 6], [6, 5, 7], [2, 3, 4], [4, 3, 5]]


def strip_ply(fmt: str, count_type: str = "int") -> bytes:
    header = (
        f"ply\nformat {fmt} 1.0\ncomment a ribbon made of triangle strips, as igea.ply stores its faces\n"
        f"element vertex {len(RIBBON)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"property uchar confidence\nelement tristrips {len(STRIPS)}\n"
        f"property list {count_type} int vertex_indices\nend_header\n"
    ).encode()
    if fmt == "ascii":
        rows = [f"{x:g} {y:g} {z:g} 7" for x, y, z in RIBBON] + [" ".join(map(str, [len(s), *s])) for s in STRIPS]
        return header + ("\n".join(rows) + "\n").encode()
    e = ">" if fmt == "binary_big_endian" else "<"
    vertex = np.zeros(len(RIBBON), dtype=[("p", f"{e}f4", 3), ("c", "u1")])
    vertex["p"], vertex["c"] = RIBBON, 7
    count = {"int": f"{e}i4", "uchar": "u1", "ushort": f"{e}u2"}[count_type]
    body = b"".join(np.array([len(s)], count).tobytes() + np.array(s, f"{e}i4").tobytes() for s in STRIPS)
    return header + vertex.tobytes() + body


@pytest.mark.parametrize(
    "fmt, count_type",
    [
        ("ascii", "int"),
        ("ascii", "uchar"),
        ("binary_big_endian", "int"),
        ("binary_little_endian", "uchar"),
        ("binary_little_endian", "ushort"),
    ],
)
def test_ply_triangle_strips(tmp_path, fmt, count_type):
    path = tmp_path / "strips.ply"
    path.write_bytes(strip_ply(fmt, count_type))
    d = load_mesh(path)
    np.testing.assert_allclose(d.vertices, RIBBON)
    np.testing.assert_array_equal(d.faces, STRIP_FACES)
    assert d.degenerate == 0  # strip joins are not faces of the model
    assert area(d) == pytest.approx(3.0)
    v, f = d.vertices, d.faces
    assert (np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])[:, 2] > 0).all()  # one winding throughout


def test_ply_strip_index_out_of_range(tmp_path):
    text = strip_ply("ascii").decode().replace("6 7\n", "6 70\n")
    assert_mesh_error(write(tmp_path / "bad.ply", text), match="outside the range")


# ---------------------------------------------------------------- fit and handedness (mesh objects)


def _mesh_scene(path, **keys):
    import raylume

    return raylume.scene_from_dict({"objects": [{"type": "mesh", "file": str(path), **keys}]})


def test_fit_scales_the_largest_side_to_size_and_centres_the_box(tmp_path):
    from raylume.scene.placement import bounds, load_mesh_object

    trimesh.creation.box(extents=(1.0, 2.0, 4.0)).export(tmp_path / "box.ply")
    fit = {"center": [1, 2, 3], "size": 2}
    scene = _mesh_scene(tmp_path / "box.ply", transform={"rotate": [0, 90, 0], "fit": fit})
    lo, hi = bounds(load_mesh_object(scene.objects[0], tmp_path))
    # rotated 90 degrees about y: the 4-long side lies along x, then halved to 2
    np.testing.assert_allclose(lo, [0.0, 1.5, 2.75], atol=1e-12)
    np.testing.assert_allclose(hi, [2.0, 2.5, 3.25], atol=1e-12)
    mirrored = _mesh_scene(tmp_path / "box.ply", handedness="right", transform={"fit": fit})
    d = load_mesh_object(mirrored.objects[0], tmp_path)
    assert signed_volume(d) > 0
    np.testing.assert_allclose(bounds(d)[1] - bounds(d)[0], [0.5, 1.0, 2.0], atol=1e-12)


@pytest.mark.parametrize("extra", [{"translate": [0, 1, 0]}, {"scale": 2}, {"scale": [1, 1, 2]}])
def test_fit_beside_translate_or_scale_is_refused_naming_the_key(extra):
    from raylume.errors import SceneError

    with pytest.raises(SceneError, match=r"objects\[0\]\.transform: fit sets the mesh's size and position"):
        _mesh_scene("m.obj", transform={"fit": {"size": 1}, **extra})
    with pytest.raises(SceneError, match=r"objects\[0\]\.transform\.fit\.size"):
        _mesh_scene("m.obj", transform={"fit": {"size": 0}})


def test_right_handed_meshes_are_mirrored_across_x_with_normals_outward(tmp_path):
    from raylume.scene.placement import load_mesh_object

    sphere = trimesh.creation.icosphere(subdivisions=2)
    sphere.apply_translation((2, 0, 0))
    sphere.export(tmp_path / "sphere.obj", include_normals=True)
    left = load_mesh_object(_mesh_scene(tmp_path / "sphere.obj").objects[0], tmp_path)
    right = load_mesh_object(_mesh_scene(tmp_path / "sphere.obj", handedness="right").objects[0], tmp_path)
    np.testing.assert_allclose(right.vertices, left.vertices * [-1, 1, 1])
    assert signed_volume(right) > 0  # winding reversed with the mirror: still counter-clockwise outside
    radial = right.vertices - (-2, 0, 0)
    assert np.einsum("ij,ij->i", right.normals, radial).min() > 0
    assert right.normals[right.vertices[:, 0].argmin(), 0] < -0.9  # the far left points left


@pytest.mark.parametrize("handedness, side", [("left", "right"), ("right", "left")])
def test_a_plus_x_feature_appears_on_the_side_the_handedness_says(tmp_path, handedness, side):
    """The default camera looks along +z with +x on the image's right (DESIGN.md): a file's +x
    feature shows on the right as authored, and on the left once mirrored as right-handed."""
    import raylume

    body = trimesh.creation.box(extents=(1, 1, 1))
    arm = trimesh.creation.box(extents=(1, 0.2, 0.2))
    arm.apply_translation((1, 0, 0))
    trimesh.util.concatenate([body, arm]).export(tmp_path / "arm.obj")
    scene = raylume.scene_from_dict(
        {
            "camera": {"position": [0, 0, -6], "look_at": [0, 0, 0]},
            "objects": [{"type": "mesh", "file": str(tmp_path / "arm.obj"), "handedness": handedness}],
        }
    )
    hit = raylume.render(scene, width=64, height=64, mode="cast").aovs["object"] == 0
    cols = np.nonzero(hit)[1]
    arm_side = "right" if cols.max() - 32 > 32 - cols.min() else "left"
    assert arm_side == side


def test_the_example_spot_faces_plus_z_as_a_mesh_scene_assumes():
    """`raylume render examples/meshes/spot.obj` shows a mesh file's +z side (its front, as glTF
    has it): the cow's head, its highest vertices (the horns and ears), lies on the +z side of
    its bounding box. The repo's copy is the shared model turned 180 degrees about y, exactly."""
    v = load_mesh(EXAMPLE_MESHES / "spot.obj").vertices
    head = v[v[:, 1] > np.quantile(v[:, 1], 0.95)]
    assert head[:, 2].mean() > 0.5 * (v[:, 2].min() + v[:, 2].max()) + 0.2
    shared = SHARED_MODELS / "spot.obj"
    if shared.exists():
        original = load_mesh(shared).vertices
        np.testing.assert_array_equal(v[:, [0, 2]], -original[:, [0, 2]])
        np.testing.assert_array_equal(v[:, 1], original[:, 1])


def _numpy_nondegenerate(v, f, sin2):
    """place_mesh's degenerate test as numpy had it: the gathers, np.cross and einsum."""
    e1, e2 = v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]
    cross = np.cross(e1, e2)
    area2 = np.einsum("ij,ij->i", cross, cross)
    return area2 > sin2 * np.einsum("ij,ij->i", e1, e1) * np.einsum("ij,ij->i", e2, e2)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([np.int32, np.int64]))
def test_compiled_degenerate_test_is_numpys_to_the_face(seed, dtype):
    """The compiled pass (scene/mesh_faces.py) classifies every face as the numpy expression
    did, near the threshold too: faces whose third vertex lies a hair off the first edge's
    line, at the float64 rounding of sin^2 = 1e-20, and repeated indices."""
    from raylume.scene.mesh import _DEGENERATE_SIN2
    from raylume.scene.mesh_faces import nondegenerate_faces

    rng = np.random.default_rng(seed)
    n = 300
    v = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-3, 4)
    f = rng.integers(0, n, size=(2000, 3))
    # nearly collinear: the third vertex on the first edge's line, moved by ~1e-10 of its length
    a, b = v[f[:500, 0]], v[f[:500, 1]]
    s = rng.uniform(-2, 3, size=(500, 1))
    wobble = rng.normal(size=(500, 3)) * 10.0 ** rng.uniform(-12, -8, size=(500, 1))
    near = a + s * (b - a) + wobble * np.linalg.norm(b - a, axis=1, keepdims=True)
    v = np.concatenate([v, near])
    f[:500, 2] = n + np.arange(500)
    f = f.astype(dtype)
    expected = _numpy_nondegenerate(v, f.astype(np.int64), _DEGENERATE_SIN2)
    good, outside = nondegenerate_faces(v, f, _DEGENERATE_SIN2)
    assert outside == 0
    np.testing.assert_array_equal(good, expected)
    assert 0 < expected[:500].sum() < 500  # the near faces straddle the threshold


def test_a_face_index_outside_the_vertices_is_refused():
    from raylume.scene.mesh import place_mesh

    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    for bad in ([0, 1, 3], [0, -1, 2]):
        with pytest.raises(MeshError, match="Inline mesh has a face index outside the range of its 3 vertices"):
            place_mesh(v, np.array([[0, 1, 2], bad]), None, None, np.eye(4), None, "Inline mesh")


def test_used_bounds_are_the_used_vertices_box():
    from raylume.scene.mesh_faces import used_bounds

    rng = np.random.default_rng(5)
    v = rng.normal(size=(50, 3))
    f = rng.integers(0, 40, size=(30, 3))  # vertices 40.. unused, and some below 40 too
    used = np.unique(f)
    lo, hi = used_bounds(v, f)
    np.testing.assert_array_equal(lo, v[used].min(axis=0))
    np.testing.assert_array_equal(hi, v[used].max(axis=0))


@pytest.mark.parametrize("endian, fmt", [("little", "<"), ("big", ">")])
def test_binary_ply_of_quads_and_triangles_reads_as_its_ascii_twin(tmp_path, endian, fmt):
    """A pyramid of one quad and four triangles (as Blender writes binary PLY): trimesh's binary
    reader takes faces of one size only ("unexpected length"); raylume reads it, the same
    triangles as the ASCII file gives through trimesh, with its u, v."""
    import struct

    verts = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1), (0.5, 1, 0.5)]
    uvs = [(0, 0), (1, 0), (1, 1), (0, 1), (0.5, 0.5)]
    faces = [(0, 1, 2, 3), (0, 4, 1), (1, 4, 2), (2, 4, 3), (3, 4, 0)]
    header = (
        "ply\nformat {} 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
        "property float u\nproperty float v\nelement face 5\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = b"".join(struct.pack(f"{fmt}5f", *v, *uv) for v, uv in zip(verts, uvs)) + b"".join(
        struct.pack(f"{fmt}B{len(f)}i", len(f), *f) for f in faces
    )
    binary = tmp_path / "pyramid_bin.ply"
    binary.write_bytes(header.format(f"binary_{endian}_endian").encode() + body)
    rows = [" ".join(map(str, (*v, *uv))) for v, uv in zip(verts, uvs)] + [
        " ".join(map(str, (len(f), *f))) for f in faces
    ]
    ascii_ = write(tmp_path / "pyramid_ascii.ply", header.format("ascii") + "\n".join(rows) + "\n")
    got, want = load_mesh(binary), load_mesh(ascii_)

    def triangles(m):  # each as its corners from the least one on, keeping the winding
        corners = [tuple(map(tuple, np.round(m.vertices[f], 6).tolist())) for f in m.faces]
        return sorted(min(c[k:] + c[:k] for k in range(3)) for c in corners)

    assert len(got.faces) == 6 and triangles(got) == triangles(want)
    assert got.uvs is not None and want.uvs is not None
    uv_at = lambda m: {tuple(np.round(v, 6)): tuple(np.round(uv, 6)) for v, uv in zip(m.vertices, m.uvs)}  # noqa: E731
    assert uv_at(got) == uv_at(want) == {tuple(map(float, v)): tuple(map(float, uv)) for v, uv in zip(verts, uvs)}
