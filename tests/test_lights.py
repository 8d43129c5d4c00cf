"""Light kinds as modules (docs/architecture.md, "Adding a light"): each kind lives in its module,
the registry and (for the scene's own lights) its model class, and nowhere else; every module
answers every question the integrators ask; one light table serves trace and path mode, its rows
in the documented order; a kind the registry does not know gets no light."""

import re
from pathlib import Path

import numpy as np
import pytest

import raylume
from raylume.compile import compile_scene
from raylume.kernels.shading import lights as LI
from raylume.scene.model import LIGHT_TYPES

SRC = Path(raylume.__file__).parent
ROOM = "kernels/shading/lights"
FLAGS = ("DELTA", "INFINITE", "VISIBLE", "FALLOFF", "EVERYWHERE")


def test_the_registry_knows_the_scene_models_light_types():
    assert sorted(kind.NAME for kind in LI.SCENE_KINDS) == sorted(LIGHT_TYPES)
    assert sorted(kind.KIND for kind in LI.KINDS) == list(range(len(LI.KINDS)))


@pytest.mark.parametrize("kind", LI.KINDS, ids=lambda kind: kind.NAME)
def test_every_kind_module_answers_every_question(kind):
    assert kind.__file__.endswith(f"{ROOM}/{kind.NAME}.py")
    for flag in FLAGS:
        assert isinstance(getattr(kind, flag), bool), f"{kind.NAME}.{flag}"
    for question in ("power", "sample", "pdf"):
        assert callable(getattr(kind, question)), f"{kind.NAME} has no {question}"
    if kind in LI.SCENE_KINDS:
        assert callable(kind.pack)
        assert kind.EVERYWHERE or callable(kind.trace_sample), f"trace mode cannot sample {kind.NAME}"
    if kind.FALLOFF:
        assert callable(kind.trace_falloff)
    if kind.VISIBLE:
        assert callable(kind.hit)


@pytest.mark.parametrize("name", list(LIGHT_TYPES))
def test_a_scene_light_kind_lives_in_its_module_the_registry_and_its_model_class(name):
    model = LIGHT_TYPES[name].__name__
    module = rf"lights\.{name}\b|lights import .*\b{name}\b|^from \. import .*\b{name}\b"
    pattern = re.compile(rf"\b{model}\b|{module}", re.M)
    touched = {p.relative_to(SRC).as_posix() for p in SRC.rglob("*.py") if pattern.search(p.read_text())}
    # the table's builder places the rows that are not the scene's own lights (ambient's sum)
    touched -= {"compile/lights.py"} if name == "ambient" else set()
    touched = {p for p in touched if not re.fullmatch(rf"{ROOM}/\w+\.py", p) or p.endswith("registry.py")}
    assert touched <= {f"{ROOM}/registry.py", "scene/model.py"}, touched
    doc = (SRC.parents[1] / "docs" / "architecture.md").read_text()
    for place in (f"{ROOM}/NAME.py", f"{ROOM}/registry.py", "scene/model.py"):
        assert place in doc


def _table(lights, objects=(), environment=None):
    scene = {"lights": list(lights), "objects": list(objects)}
    if environment is not None:
        scene["environment"] = environment
    return compile_scene(raylume.Scene.model_validate(scene)).kernel


def test_one_table_for_both_modes_in_the_documented_order():
    """Area lights first, then the scene's other lights, emissive surfaces, the summed ambient
    row and the environment (path mode's distribution), then each ambient light by itself;
    `order` finds every scene light in the scene's order."""
    S = _table(
        [
            {"type": "ambient", "intensity": 0.1},
            {"type": "point", "position": [0, 2, 0], "intensity": 2.0},
            {"type": "quad", "position": [0, 3, 0], "u": [1, 0, 0], "v": [0, 0, 1], "intensity": 3.0},
            {"type": "ambient", "intensity": 0.2},
        ],
        [{"type": "sphere", "center": [0, 0, 4], "radius": 1, "material": {"type": "diffuse", "emission": [1, 1, 1]}}],
        {"color": [0.5, 0.5, 0.5]},
    )
    names = [LI.KINDS[k].NAME for k in S.light_kind]
    assert names == ["quad", "point", "surface", "ambient", "environment", "ambient", "ambient"]
    assert S.n_area_lights == 1 and S.ambient_row == 3 and S.environment_row == 4
    assert len(S.light_cdf) == 6  # the distribution covers the first five rows
    assert list(S.light_order) == [5, 1, 0, 6]
    np.testing.assert_array_equal(S.light_data[3, 3:6], [0.1 + 0.2] * 3)  # the ambient lights' sum
    np.testing.assert_array_equal(S.light_data[S.light_order, 3], [0.1, 2.0, 3.0, 0.2])


def test_the_power_distribution_follows_each_kind_s_power():
    """Point: 4 pi I; quad: 2 pi area L (both sides); written out here from the definitions."""
    S = _table(
        [
            {"type": "point", "position": [0, 2, 0], "intensity": 2.0},
            {"type": "quad", "position": [0, 3, 0], "u": [2, 0, 0], "v": [0, 0, 1], "intensity": 3.0},
        ]
    )
    weights = np.diff(S.light_cdf)
    np.testing.assert_allclose(weights, [2 * np.pi * 2.0 * 3.0, 4 * np.pi * 2.0])


def test_light_weights_do_not_depend_on_where_the_scene_sits():
    """Path mode picks a light by its share of the power, and an infinite light's (ambient,
    environment, directional) is its radiance over the scene's size: the scene's own size, not
    its distance from the origin. A sphere of radius 1 on a quad, moved 1000 units away, keeps
    its weights; the ambient light's is its radiance over the bounding sphere of the geometry,
    written out here (4 pi^2 r^2 L, r half the box's diagonal)."""

    def weights(offset):
        o = np.asarray(offset, dtype=float)
        return np.diff(
            _table(
                [
                    {"type": "ambient", "intensity": 0.1},
                    {"type": "point", "position": (o + [0, 4, 0]).tolist(), "intensity": 5.0},
                    {"type": "directional", "direction": [0, -1, 0.2], "intensity": 0.5},
                ],
                [
                    {"type": "sphere", "center": (o + [0, 1, 0]).tolist(), "radius": 1},
                    {"type": "quad", "position": o.tolist(), "u": [4, 0, 0], "v": [0, 0, 4]},  # -2..2 in x, z
                ],
            ).light_cdf
        )

    here, away = weights([0, 0, 0]), weights([1000, 0, 1000])
    np.testing.assert_allclose(away, here, rtol=1e-9)
    r = 0.5 * np.linalg.norm([4, 2, 4])  # the box from (-2, 0, -2) to (2, 2, 2)
    assert np.isclose(here[-1], 4 * np.pi**2 * r**2 * 0.1)  # the summed ambient row comes last
    assert np.isclose(here[0], 4 * np.pi * 5.0)  # the point light: 4 pi I


def test_an_environment_near_float32_s_limit_keeps_a_finite_weight(tmp_path):
    """The environment's weight is its mean radiance: summed in float32, a texel of 2e38 among 127
    of 0.5 overflowed to inf (a numpy warning, then an infinite CDF, and path mode's pixels went
    black where bdpt's did not). Its weight is 4 pi^2 r^2 times the mean, written out here."""
    import warnings

    import OpenEXR

    sky = np.full((8, 16, 3), 0.5, np.float32)
    sky[2, 5] = 2e38
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION}, {"RGB": sky}).write(str(tmp_path / "sky.exr"))
    lights = [{"type": "point", "position": [0, 4, 0], "intensity": 1.0}]
    scene = {"lights": lights, "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}]}
    scene["environment"] = {"file": "sky.exr"}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cdf = compile_scene(raylume.Scene.model_validate(scene).with_base_dir(tmp_path)).kernel.light_cdf
    weights = np.diff(cdf)
    mean = (127 * 0.5 + np.float64(np.float32(2e38))) / 128
    r2 = 3.0  # half the diagonal of the unit sphere's box, squared
    assert np.all(np.isfinite(cdf)) and np.isclose(weights[-1], 4 * np.pi**2 * r2 * mean)


def test_an_unknown_kind_in_the_table_sends_no_light():
    """Trace mode's flag functions answer False and the area sampler gives no point for a row
    of a kind no module defines."""
    unknown = len(LI.KINDS)
    for flag in (LI.is_delta, LI.is_everywhere, LI.has_falloff, LI.at_infinity):
        assert flag(unknown) is False
        assert flag(-1) is False
    assert LI.is_delta(LI.BY_NAME["spot"].KIND) and LI.is_everywhere(LI.BY_NAME["ambient"].KIND)
    assert LI.at_infinity(LI.BY_NAME["directional"].KIND) and not LI.at_infinity(LI.BY_NAME["point"].KIND)
