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


def test_disk_matrix_must_be_a_similarity():
    disk = {"type": "disk", "radius": 1, "transform": {"matrix": SHEAR}}
    with pytest.raises(SceneError, match="similarity"):
        scene_from_dict({"objects": [disk]})
    turn = [[0, 0, 2, 1], [0, 2, 0, 0], [-2, 0, 0, 0], [0, 0, 0, 1]]
    scene_from_dict({"objects": [{**disk, "transform": {"matrix": turn}}]})
