"""examples/pbrt/cornell.pbrt against examples/cornell.toml: the same box read from pbrt-v4's
format (inline meshes copied from the OBJ files, the light a bilinear patch instead of a quad)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

import raylume
from raylume.scene.checks import SceneWarning
from raylume.scene.load import load_scene
from raylume.scene.mesh import load_mesh
from raylume.scene.placement import load_mesh_object

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_the_pbrt_cornell_box_is_the_toml_one():
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        pbrt = load_scene(EXAMPLES / "pbrt" / "cornell.pbrt")
    toml = load_scene(EXAMPLES / "cornell.toml")
    assert pbrt.render.model_dump() == toml.render.model_dump()
    for key in ("position", "up", "fov"):
        np.testing.assert_allclose(getattr(pbrt.camera, key), getattr(toml.camera, key), atol=1e-9)
    meshes = [obj for obj in toml.objects if obj.type == "mesh"]
    assert len(pbrt.objects) == len(meshes) + 1
    for ours, theirs in zip(pbrt.objects, meshes):
        a = load_mesh_object(ours, pbrt.base_dir)
        b = load_mesh(toml.base_dir / theirs.file)
        np.testing.assert_array_equal(a.vertices, b.vertices)
        np.testing.assert_array_equal(a.faces, b.faces)
        assert pbrt.material_of(ours) == toml.material_of(theirs)
    light = pbrt.objects[-1]
    corners = np.array(light.vertices)
    np.testing.assert_allclose(corners.min(axis=0), [213, 548.7, 227])
    np.testing.assert_allclose(corners.max(axis=0), [343, 548.7, 332])
    assert light.material.emission == toml.material_of(toml.objects[-1]).emission


def test_the_pbrt_cornell_box_renders_like_the_toml_one():
    """The light is two triangles here and a quad there: the images agree within the noise."""
    size = {"width": 24, "height": 24, "spp": 64}
    ours = raylume.render(EXAMPLES / "pbrt" / "cornell.pbrt", aovs=False, **size).rgb
    theirs = raylume.render(EXAMPLES / "cornell.toml", aovs=False, seed=1, **size).rgb
    blocks = lambda image: image.reshape(3, 8, 3, 8, 3).mean(axis=(1, 3))  # noqa: E731
    np.testing.assert_allclose(blocks(ours), blocks(theirs), rtol=0.12, atol=0.01)
