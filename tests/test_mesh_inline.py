"""Inline meshes (vertices and faces in the scene) and whole-matrix transforms, against numpy."""

from __future__ import annotations

import numpy as np
import pytest

from raylume.errors import SceneError
from raylume.scene.document import scene_from_dict
from raylume.scene.instances import instance_matrices
from raylume.scene.placement import load_mesh_object

SHEAR = [[1.0, 0.5, 0.0, 1.0], [0.0, 2.0, 0.0, -1.0], [0.0, 0.0, -1.0, 3.0], [0.0, 0.0, 0.0, 1.0]]
VERTS = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
FACES = [[0, 1, 2], [0, 2, 3]]
FLAT = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]
PROJECTIVE = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]]


def _mesh(**keys):
    return scene_from_dict({"objects": [{"type": "mesh", **keys}]}).objects[0]


def test_inline_mesh_placed_by_its_matrix():
    obj = _mesh(vertices=VERTS, faces=FACES, uvs=[[0, 0], [1, 0], [0, 1], [1, 1]], transform={"matrix": SHEAR})
    mesh = load_mesh_object(obj, base_dir=".")
    m = np.array(SHEAR)
    expected = np.array(VERTS) @ m[:3, :3].T + m[:3, 3]
    np.testing.assert_allclose(mesh.vertices, expected)
    # the matrix mirrors (det < 0): the winding is reversed so that the front stays the front
    assert np.linalg.det(m[:3, :3]) < 0
    np.testing.assert_array_equal(mesh.faces, np.array(FACES)[:, ::-1])
    np.testing.assert_allclose(mesh.uvs, [[0, 0], [1, 0], [0, 1], [1, 1]])


def test_instance_matrices_inline():
    obj = _mesh(vertices=VERTS, faces=FACES, instances=[{"matrix": SHEAR}, {"translate": [1, 2, 3]}])
    m = instance_matrices(obj, base_dir=".")
    np.testing.assert_allclose(m[0], np.array(SHEAR)[:3])
    np.testing.assert_allclose(m[1], [[1, 0, 0, 1], [0, 1, 0, 2], [0, 0, 1, 3]])


@pytest.mark.parametrize(
    ("keys", "words"),
    [
        ({"vertices": VERTS}, "need faces"),
        ({"vertices": VERTS, "faces": [[0, 1, 4]]}, "there are 4 vertices"),
        ({"vertices": VERTS, "faces": FACES, "normals": [[0, 0, 1]]}, "one per vertex"),
        ({"file": "a.obj", "vertices": VERTS, "faces": FACES}, "exactly one"),
        ({}, "exactly one"),
        ({"file": "a.obj", "faces": FACES}, "not with a mesh file"),
        ({"file": "a.obj", "transform": {"matrix": SHEAR, "scale": 2}}, "either the matrix"),
        ({"file": "a.obj", "transform": {"matrix": FLAT}}, "singular"),
        ({"file": "a.obj", "transform": {"matrix": PROJECTIVE}}, "affine"),
    ],
)
def test_bad_inline_meshes_are_named(keys, words):
    with pytest.raises(SceneError, match=words):
        _mesh(**keys)


def test_numpy_tables_give_the_model_that_their_lists_give():
    """The Python API's numpy arrays are checked as a whole (a fast path): the validated mesh
    is the one their rows as lists give, and rendering reads it the same way."""
    rng = np.random.default_rng(3)
    verts = rng.normal(size=(40, 3))
    faces = rng.integers(0, 40, size=(60, 3))
    normals = rng.normal(size=(40, 3))
    uvs = rng.random(size=(40, 2)).astype(np.float32)
    as_arrays = _mesh(vertices=verts, faces=faces.astype(np.int32), normals=normals, uvs=uvs)
    as_lists = _mesh(vertices=verts.tolist(), faces=faces.tolist(), normals=normals.tolist(), uvs=uvs.tolist())
    for key in ("vertices", "faces", "normals", "uvs"):
        assert getattr(as_arrays, key) == getattr(as_lists, key), key
    assert isinstance(as_arrays.faces[0][0], int) and isinstance(as_arrays.vertices[0][0], float)
    assert _mesh(vertices=verts, faces=faces.astype(np.float64)).faces == as_lists.faces  # whole floats


@pytest.mark.parametrize(
    ("keys", "words"),
    [
        ({"vertices": np.array([[0.0, 0, 0], [1, np.nan, 0], [0, 1, 0]]), "faces": [[0, 1, 2]]}, "row 1 holds"),
        (
            {"vertices": np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), "faces": np.array([[0, -1, 2]])},
            "count from 0, got -1",
        ),
        ({"vertices": np.zeros((3, 2)), "faces": [[0, 1, 2]]}, r"3 columns .* shape \(3, 2\)"),
        ({"vertices": np.eye(3), "faces": np.array([[0, 1.5, 2]])}, "whole numbers"),
        ({"vertices": np.eye(3), "faces": np.array([[0, 1, 3]])}, "there are 3 vertices"),
        ({"vertices": np.eye(3), "faces": np.array([["a", "b", "c"]])}, "must be numbers"),
        ({"vertices": np.eye(3), "faces": [[0, 1, 2]], "uvs": np.zeros((3, 3))}, "2 columns"),
    ],
)
def test_bad_numpy_tables_are_named(keys, words):
    with pytest.raises(SceneError, match=words) as caught:
        _mesh(**keys)
    assert "objects[0]" in str(caught.value) or "objects.0" in str(caught.value)


def test_trimesh_arrays_are_numpy_tables():
    """A trimesh mesh's vertices and faces (TrackedArray, an ndarray subclass) take the arrays'
    checks: they went row by row, and complex vertices lost their imaginary parts silently."""
    import trimesh

    box = trimesh.creation.box()
    assert type(box.vertices) is not np.ndarray
    assert _mesh(vertices=box.vertices, faces=box.faces) == _mesh(
        vertices=box.vertices.tolist(), faces=box.faces.tolist()
    )
    with pytest.raises(SceneError, match="must be numbers, got complex128"):
        _mesh(vertices=box.vertices + 1j, faces=box.faces)
    with pytest.raises(SceneError, match=r"3 columns .* shape \(8, 2\)"):
        _mesh(vertices=box.vertices[:, :2], faces=box.faces)


def test_disk_matrix_must_be_a_similarity():
    disk = {"type": "disk", "radius": 1, "transform": {"matrix": SHEAR}}
    with pytest.raises(SceneError, match="similarity"):
        scene_from_dict({"objects": [disk]})
    turn = [[0, 0, 2, 1], [0, 2, 0, 0], [-2, 0, 0, 0], [0, 0, 0, 1]]
    scene_from_dict({"objects": [{**disk, "transform": {"matrix": turn}}]})
