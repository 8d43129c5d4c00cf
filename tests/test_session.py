"""raylume.Session: compile once, render many times; the film's passes; the compiled scene
shipped by pickle. References are one-shot renders (raylume.render), which compile afresh."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

import raylume
import raylume.compile
from raylume.denoise import is_available
from raylume.session import Session

EXAMPLES = Path(__file__).parent.parent / "examples"

SCENE = {
    "render": {"width": 48, "height": 36},
    "lights": [
        {"type": "ambient", "intensity": 0.2},
        {"type": "point", "position": [2, 2, -2], "intensity": 0.7},
        {"type": "quad", "position": [0, 3, 2], "u": [1, 0, 0], "v": [0, 0, 1], "intensity": 0.3, "samples": 4},
    ],
    "materials": {
        "glass": {"color": [1, 1, 1], "transparency": 0.8, "reflective": 0.1, "ior": 1.5},
        "mirror": {"color": [0.9, 0.9, 0.9], "reflective": 0.6, "specular": 200},
    },
    "objects": [
        {
            "type": "plane",
            "point": [0, -1, 0],
            "normal": [0, 1, 0],
            "material": {"texture": {"type": "checker", "scale": 0.5}},
        },
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "glass"},
        {"type": "sphere", "center": [-1.6, -0.4, 4], "radius": 0.6, "material": "mirror"},
        *[{"type": "sphere", "center": [x, -0.8, 6], "radius": 0.2} for x in (-2, -1, 0, 1, 2)],
        {"type": "disk", "center": [1.8, 0, 4], "normal": [-1, 0, -1], "radius": 0.5},
        {"type": "quad", "position": [0, 1.5, 5], "u": [1.5, 0, 0], "v": [0.3, 0.8, 0]},
        {"type": "cylinder", "p0": [2.2, -1, 6], "p1": [2.2, 0.5, 6], "radius": 0.3},
    ],
}
CAMERA_B = {"position": [1.5, 1.0, -1.5], "look_at": [0, 0, 3]}


@pytest.fixture(scope="module")
def scene():
    return raylume.scene_from_dict(SCENE)


def test_a_session_renders_two_cameras_as_two_one_shot_renders_without_a_second_build(scene, monkeypatch):
    builds = []
    geometry = raylume.compile.geometry  # the stage that builds the world BVH
    real_build = geometry.build_bvh
    monkeypatch.setattr(geometry, "build_bvh", lambda *a, **k: builds.append(1) or real_build(*a, **k))
    session = Session(scene)
    assert len(builds) == 1  # more than 8 primitives: a real BVH
    a = session.render(spp=2)
    b = session.render(camera=CAMERA_B, spp=2, mode="cast")
    assert len(builds) == 1 and session.bvh_builds == 1
    assert b.stats["build_seconds"] == 0.0

    one_a = raylume.render(scene, spp=2)
    moved = scene.model_copy(update={"camera": scene.camera.model_copy(update=CAMERA_B)})
    one_b = raylume.render(moved, spp=2, mode="cast")
    assert len(builds) == 3
    assert a.rgb.tobytes() == one_a.rgb.tobytes()
    assert b.rgb.tobytes() == one_b.rgb.tobytes()
    for name in ("depth", "normal", "object", "prim", "albedo"):
        assert a.aovs[name].tobytes() == one_a.aovs[name].tobytes(), name
        assert b.aovs[name].tobytes() == one_b.aovs[name].tobytes(), name
    assert not np.array_equal(a.aovs["depth"], b.aovs["depth"])  # the camera did move


def test_a_camera_given_as_a_partial_dict_keeps_the_scenes_other_camera_keys(scene):
    session = Session(scene)
    wide = session.render(camera={"fov": 80}, mode="cast")
    model = scene.camera.model_copy(update={"fov": 80.0})
    assert wide.rgb.tobytes() == session.render(camera=model, mode="cast").rgb.tobytes()
    with pytest.raises(raylume.SceneError, match="camera.fov"):
        session.render(camera={"fov": 500})


def test_a_rasterizing_session_builds_its_bvh_only_when_a_ray_mode_needs_it(scene):
    session = Session(scene, accelerate=False)
    session.render(mode="raster")
    assert session.bvh_builds == 0
    traced = session.render(mode="trace")
    assert session.bvh_builds == 1
    assert traced.rgb.tobytes() == raylume.render(scene).rgb.tobytes()


def test_a_pickled_compiled_scene_renders_the_same_image(scene):
    session = Session(scene)
    shipped = pickle.loads(pickle.dumps(session.compiled))
    assert "Path" not in repr(shipped) and "PosixPath" not in pickle.dumps(session.compiled).decode("latin1")
    # the BVH's node records arrive once, as the two views of one array that they were
    k = shipped.kernel
    assert np.shares_memory(k.node_bounds, k.node_index) and np.shares_memory(k.inst_node_bounds, k.inst_node_index)
    assert np.array_equal(k.node_index, session.compiled.kernel.node_index)
    # and start on a cache line, there as here (kernels/geometry/layout.py: RECORD_ALIGNMENT)
    for records in (session.compiled.kernel.node_bounds, k.node_bounds, k.inst_node_bounds):
        assert records.ctypes.data % 64 == 0
    elsewhere = Session.from_compiled(scene, shipped)
    for mode in ("trace", "cast"):
        assert elsewhere.render(mode=mode, spp=3).rgb.tobytes() == session.render(mode=mode, spp=3).rgb.tobytes()


@pytest.mark.parametrize("mode", ["trace", "cast"])
@pytest.mark.parametrize("pixel_filter", ["box", "gaussian", "mitchell"])
def test_the_film_gives_the_same_bits_in_one_pass_or_several(scene, mode, pixel_filter):
    session = Session(scene)
    whole = raylume.Film(40, 30, pixel_filter, total_spp=9)
    session.add_samples(whole, 9, mode=mode, seed=7)
    passes = raylume.Film(40, 30, pixel_filter, total_spp=9)
    for count in (1, 3, 5):
        session.add_samples(passes, count, mode=mode, seed=7)
    assert passes.spp == 9
    assert whole.sums.tobytes() == passes.sums.tobytes()
    assert whole.rgb().tobytes() == passes.rgb().tobytes()
    # and a one-shot render of 9 spp is that film read out
    image = session.render(width=40, height=30, spp=9, mode=mode, seed=7, filter=pixel_filter, aovs=False)
    assert image.rgb.tobytes() == whole.rgb().tobytes()


@pytest.mark.parametrize("mode", ["trace", "path"])
@pytest.mark.parametrize("pixel_filter", ["box", "gaussian", "mitchell"])
def test_films_of_consecutive_samples_hold_what_one_film_of_them_all_holds(scene, mode, pixel_filter):
    """Film.first_sample: films of one seed whose sample ranges follow each other hold the same
    samples as one film of their total (the sums to rounding: added in another order). The last
    film is of one sample, after others: a point of the filter's area, not the pixel's centre.
    The texture filter is off: a film's ray cone is set by its own total."""
    session = Session(scene.with_render(texture_filter=False))
    whole = raylume.Film(40, 30, pixel_filter, total_spp=9)
    session.add_samples(whole, 9, mode=mode, seed=7)
    parts = [raylume.Film(40, 30, pixel_filter, total_spp=n, first_sample=k) for k, n in ((0, 4), (4, 4), (8, 1))]
    for film in parts:
        session.add_samples(film, film.total_spp, mode=mode, seed=7)
    together = sum(film.sums for film in parts)
    np.testing.assert_allclose(together, whole.sums, rtol=1e-12, atol=1e-12)
    assert not np.array_equal(parts[1].sums, parts[0].sums)  # the second film's samples are new ones
    centre = raylume.Film(40, 30, pixel_filter, total_spp=1)
    session.add_samples(centre, 1, mode=mode, seed=7)
    assert not np.array_equal(parts[2].sums, centre.sums)
    with pytest.raises(ValueError, match="first_sample"):
        raylume.Film(4, 4, total_spp=1, first_sample=-1)


def test_a_films_texture_filter_narrows_with_the_samples_before_it(scene, monkeypatch):
    """A film after others filters textures as a film of all their samples does (the ray cone
    of first_sample + total_spp samples): its samples equal the second pass of that film."""
    session = Session(scene)
    whole = raylume.Film(40, 30, "box", total_spp=32)
    session.add_samples(whole, 16, mode="path", seed=3)
    first_half = whole.sums.copy()
    session.add_samples(whole, 16, mode="path", seed=3)

    def second_film() -> np.ndarray:
        film = raylume.Film(40, 30, "box", total_spp=16, first_sample=16)
        session.add_samples(film, 16, mode="path", seed=3)
        return film.sums

    np.testing.assert_allclose(second_film(), whole.sums - first_half, rtol=1e-9, atol=1e-9)
    # the control: the same samples under a 16-sample film's wider cone blur the checker's edges
    import raylume.session as session_module

    cone = session_module.set_cone_spread
    monkeypatch.setattr(session_module, "set_cone_spread", lambda cam, h, spp, on: cone(cam, h, 16, on))
    assert not np.allclose(second_film(), whole.sums - first_half, rtol=1e-9, atol=1e-9)


def test_a_film_refuses_more_samples_than_it_was_made_for(scene):
    session = Session(scene)
    film = raylume.Film(8, 8, total_spp=2)
    session.add_samples(film, 2)
    with pytest.raises(ValueError, match="takes 2 samples"):
        session.add_samples(film, 1)


def test_a_render_on_one_thread_leaves_numbas_thread_count_as_it_found_it(scene):
    """Numba's thread count is the calling thread's: left at a render's `threads`, the next
    Session's BVH build (which reads it) ran on that many threads."""
    import numba

    found = min(2, numba.config.NUMBA_NUM_THREADS)  # two where the machine has them
    numba.set_num_threads(found)
    session = Session(scene)
    assert session.render(width=8, height=6, mode="cast", threads=1).stats["threads"] == 1
    assert numba.get_num_threads() == found
    session.add_samples(raylume.Film(8, 6, total_spp=1), 1, threads=1)
    assert numba.get_num_threads() == found
    with pytest.raises(raylume.RaylumeError, match="crop"):
        session.render(width=8, height=6, mode="cast", threads=1, crop=(0, 99, 0, 6))
    assert numba.get_num_threads() == found


def test_render_settings_errors_are_scene_errors_naming_the_setting(scene):
    with pytest.raises(raylume.SceneError, match="mode"):
        raylume.render(scene, mode="path-tracing")
    with pytest.raises(raylume.SceneError, match="spp"):
        Session(scene).render(spp=0)


@pytest.mark.parametrize("mode", ["trace", "cast", "raster"])
def test_a_crop_equals_that_window_of_the_full_render_bit_for_bit(scene, mode):
    session = Session(scene)
    full = session.render(mode=mode, spp=1 if mode == "raster" else 3, filter="gaussian")
    x0, x1, y0, y1 = 7, 31, 5, 22
    part = session.render(mode=mode, spp=1 if mode == "raster" else 3, filter="gaussian", crop=(x0, x1, y0, y1))
    assert part.rgb.shape == (y1 - y0, x1 - x0, 3)
    assert part.rgb.tobytes() == np.ascontiguousarray(full.rgb[y0:y1, x0:x1]).tobytes()
    for name in ("depth", "normal", "object", "prim", "albedo"):
        want = np.ascontiguousarray(full.aovs[name][y0:y1, x0:x1])
        assert part.aovs[name].tobytes() == want.tobytes(), name
    if mode != "raster":
        assert part.stats["primary_rays"] == (x1 - x0) * (y1 - y0) * 3


@pytest.mark.skipif(not is_available(), reason="pyoidn (raylume[denoise]) is not installed")
def test_a_denoised_crop_is_that_window_of_the_whole_denoised_render():
    """The denoiser's value at a pixel depends on its neighbours: the window denoised alone
    differed from the full render's window everywhere (by up to 0.12 at its border)."""
    session = Session(EXAMPLES / "cornell.toml")
    settings = dict(width=32, height=24, spp=2, mode="path", denoise=True)
    full = session.render(**settings)
    x0, x1, y0, y1 = 5, 21, 3, 17
    part = session.render(**settings, crop=(x0, x1, y0, y1))
    assert part.rgb.shape == (y1 - y0, x1 - x0, 3) and part.stats["crop"] == [x0, x1, y0, y1]
    assert part.rgb.tobytes() == np.ascontiguousarray(full.rgb[y0:y1, x0:x1]).tobytes()
    for name in ("noisy", "depth", "albedo"):
        assert np.array_equal(part.aovs[name], full.aovs[name][y0:y1, x0:x1]), name


@pytest.mark.parametrize("crop", [(0, 0, 0, 5), (5, 3, 0, 5), (0, 49, 0, 5), (0, 5, -1, 5)])
def test_a_crop_outside_the_image_is_refused(scene, crop):
    with pytest.raises(raylume.RaylumeError, match="crop"):
        raylume.render(scene, crop=crop)


@pytest.mark.parametrize("pixel_filter", ["box", "gaussian", "mitchell"])
def test_a_constant_image_stays_constant_under_every_filter_and_spp(pixel_filter):
    """Nothing to hit: every sample sees the background, so every pixel must show it exactly,
    whatever the filter's negative lobes do to the weights (Mitchell at a few spp used to leave
    pixels whose weights cancelled black)."""
    grey = raylume.scene_from_dict({"render": {"width": 24, "height": 16, "background": [0.3, 0.5, 0.7]},
                                    "lights": [{"type": "ambient"}]})  # fmt: skip
    want = np.broadcast_to(np.float32([0.3, 0.5, 0.7]), (16, 24, 3))
    for spp in range(1, 17):
        for mode in ("cast", "trace"):
            img = raylume.render(grey, spp=spp, filter=pixel_filter, mode=mode, aovs=False, seed=spp)
            np.testing.assert_allclose(img.rgb, want, rtol=1e-6, err_msg=f"{pixel_filter} spp {spp} {mode}")


def test_intersect_keeps_the_rays_leading_shape(scene):
    origins = np.zeros((2, 3, 3))
    directions = np.broadcast_to([0.0, 0.0, 1.0], (2, 3, 3)).copy()
    directions[1, 2] = [0.0, 1.0, 0.0]  # up: misses everything
    t, obj, prim = raylume.intersect(scene, origins, directions)
    assert t.shape == obj.shape == prim.shape == (2, 3)
    assert obj[0, 0] == 1 and np.isclose(t[0, 0], 2.0)  # the glass sphere at z = 3, radius 1
    assert obj[1, 2] == -1 and np.isinf(t[1, 2])
