"""Material kinds as modules (docs/architecture.md, "Adding a material"): each kind lives in its
module, the registry and its model class, and nowhere else; every module answers every question
the integrators ask; a kind the registry does not know is an error on the host and a failure in
the kernels, never another kind's answer. And the `null` material, an index-matched boundary,
against what it must be: invisible."""

import re
from pathlib import Path

import numpy as np
import pytest

import raylume
from raylume.kernels.shading import materials as M
from raylume.scene.model import MATERIAL_TYPES

SRC = Path(raylume.__file__).parent
KIND_ROOM = "kernels/shading/materials"
QUESTIONS = ("pack", "trace_approximation", "evaluate", "sample", "delta_only", "two_sided", "aov_albedo")


def test_the_registry_and_the_scene_model_know_the_same_kinds():
    assert list(M.BY_NAME) == list(MATERIAL_TYPES)
    assert sorted(kind.KIND for kind in M.KINDS) == list(range(len(M.KINDS)))


@pytest.mark.parametrize("kind", M.KINDS, ids=lambda kind: kind.NAME)
def test_every_kind_module_answers_every_question(kind):
    for question in QUESTIONS:
        assert callable(getattr(kind, question)), f"{kind.NAME} has no {question}"
    assert kind.__file__.endswith(f"{KIND_ROOM}/{kind.NAME}.py")


@pytest.mark.parametrize("name", list(MATERIAL_TYPES))
def test_a_kind_lives_in_its_module_the_registry_and_its_model_class(name):
    """The three places of the recipe; the integrators and the compiler ask the registry."""
    model = MATERIAL_TYPES[name].__name__
    pattern = re.compile(
        rf"\b{model}\b|materials\.{name}\b|materials import .*\b{name}\b|^from \. import .*\b{name}\b", re.M
    )
    touched = {p.relative_to(SRC).as_posix() for p in SRC.rglob("*.py") if pattern.search(p.read_text())}
    # kind modules may share a helper (the Phong exponent of a GGX alpha for trace mode)
    touched = {p for p in touched if not re.fullmatch(rf"{KIND_ROOM}/\w+\.py", p) or p.endswith("registry.py")}
    assert touched <= {f"{KIND_ROOM}/registry.py", "scene/model.py"}, touched
    doc = (SRC.parents[1] / "docs" / "architecture.md").read_text()
    for place in (f"{KIND_ROOM}/NAME.py", f"{KIND_ROOM}/registry.py", "scene/model.py"):
        assert place in doc


def test_no_code_outside_the_materials_asks_for_a_kind():
    """Kind-specific code is the kinds' own: nothing else reads the MAT_KIND column."""
    readers = {
        p.relative_to(SRC).as_posix()
        for p in SRC.rglob("*.py")
        if "MAT_KIND" in p.read_text() and KIND_ROOM not in str(p)
    }
    assert readers == set()


def test_an_unknown_type_is_refused_with_the_types_allowed(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('[materials.x]\ntype = "velvet"\n[[objects]]\ntype = "sphere"\ncenter = [0, 0, 3]\nradius = 1\n')
    with pytest.raises(raylume.SceneError) as err:
        raylume.load_scene(scene)
    message = str(err.value)
    assert "materials.x.type" in message and "null" in message and "phong" in message
    with pytest.raises(ValueError, match="unknown material type 'velvet'"):
        M.kind_module("velvet")


def test_an_unknown_kind_in_the_table_scatters_nothing():
    """A row whose kind no module defines is never treated as another kind (the last branch of
    each switch is explicit)."""
    table = np.zeros((1, M.MAT_WIDTH))
    table[0, M.MAT_KIND] = len(M.KINDS)
    table[0, M.MAT_COLOR : M.MAT_COLOR + 3] = 0.5
    wo, wi = (0.0, 0.6, 0.8), (0.0, -0.6, 0.8)
    f, pdf = M.bsdf_eval(table, 0, (0.5, 0.5, 0.5), wo, wi)
    assert f == (0.0, 0.0, 0.0) and pdf == 0.0
    table[0, M.MAT_KIND] = M.BY_NAME["diffuse"].KIND
    f, pdf = M.bsdf_eval(table, 0, (0.5, 0.5, 0.5), wo, wi)
    assert f[0] == pytest.approx(0.5 / np.pi) and pdf == pytest.approx(0.8 / np.pi)


@pytest.mark.parametrize(
    "table, key",
    [
        ({"type": "null", "color": [1, 0, 0]}, "color"),
        ({"type": "diffuse", "roughness": 0.2}, "roughness"),
        ({"type": "plastic", "eta": [1, 1, 1]}, "eta"),
        ({"specular": 10, "roughness": 0.1}, "roughness"),
    ],
)
def test_a_key_of_another_type_is_named(table, key):
    with pytest.raises(raylume.SceneError) as err:
        raylume.Scene.model_validate({}).replace(materials={"m": table})
    assert "materials.m" in str(err.value) and repr(key) in str(err.value)


# --- the null material ------------------------------------------------------------------------

LIGHT_BEHIND = {
    "render": {"width": 24, "height": 16, "spp": 1, "mode": "path", "max_depth": 4, "background": [0, 0, 0]},
    "camera": {"position": [0, 0, -4], "look_at": [0, 0, 0], "fov": 40},
    "objects": [
        # an emitter filling the view, far behind a null sphere that covers the middle of it
        {"type": "quad", "position": [0, 0, 6], "u": [40, 0, 0], "v": [0, 40, 0],
         "material": {"type": "diffuse", "color": [0, 0, 0], "emission": [0.25, 0.5, 1.0]}},
        {"type": "sphere", "center": [0, 0, 0], "radius": 1.5, "material": {"type": "null"}},
    ],
}  # fmt: skip


def test_a_null_boundary_lets_every_path_through_unchanged():
    """Seen through a null sphere (two crossings, each a delta transmission of weight 1), the
    emitter's radiance arrives exactly; max_depth 4 leaves room for the two crossings."""
    image = raylume.render(raylume.Scene.model_validate(LIGHT_BEHIND), aovs=True)
    through = image.aovs["object"] == 1
    assert through.sum() > 50 and (~through).sum() > 50  # the sphere covers part of the view
    assert np.all(image.rgb == np.float32([0.25, 0.5, 1.0]))
    # the denoiser's albedo guide: white where the boundary lets all light through, the
    # emitter's (black) colour beside it
    assert np.all(image.aovs["albedo"][through] == 1.0) and np.all(image.aovs["albedo"][~through] == 0.0)


def test_a_null_boundary_is_invisible_in_trace_mode():
    """Trace mode shows it as transparent with index 1: the light arrives through it as it
    arrives beside it (Fresnel reflectance 0, the ray bent by rounding at most)."""
    scene = raylume.Scene.model_validate(LIGHT_BEHIND).replace(
        render={"mode": "trace", "max_depth": 3},
        lights=[{"type": "ambient", "intensity": 1.0}],
        objects=[
            {**LIGHT_BEHIND["objects"][0], "material": {"type": "diffuse", "color": [0.25, 0.5, 1.0]}},
            LIGHT_BEHIND["objects"][1],
        ],
    )
    image = raylume.render(scene)
    assert (image.aovs["object"] == 1).sum() > 50
    np.testing.assert_allclose(image.rgb, np.broadcast_to(np.float32([0.25, 0.5, 1.0]), image.rgb.shape), atol=1e-6)


@pytest.mark.parametrize("integrator", ["path", "bdpt"])
def test_rough_glass_of_index_1_is_invisible(integrator):
    """An interface of ior 1 bends and reflects nothing, rough or not: in a white furnace (a sky
    of radiance 1) the sphere is the sky, as smooth glass of index 1 is (it had rendered black:
    the rough lobes' half vector of a straight-through pair is zero)."""
    scene = raylume.Scene.model_validate(
        {
            "render": {"width": 16, "height": 16, "spp": 4, "mode": "path", "integrator": integrator},
            "camera": {"position": [0, 0, -3], "fov": 40},
            "environment": {"color": [1, 1, 1]},
            "objects": [
                {
                    "type": "sphere",
                    "center": [0, 0, 0],
                    "radius": 1,
                    "material": {"type": "dielectric", "ior": 1.0, "roughness": 0.5},
                }
            ],
        }
    )
    image = raylume.render(scene, aovs=True)
    assert (image.aovs["object"] == 0).sum() > 50  # the sphere fills much of the view
    np.testing.assert_allclose(image.rgb, 1.0, atol=1e-6)
