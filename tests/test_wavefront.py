"""Trace mode's wavefront (kernels/integrators/wavefront.py), which renders every basic scene (spheres and
opaque triangles): its images and ray counts are those of the ray-by-ray Whitted tracer
(trace.py), to the last bit, on scenes that take each of its paths; and its vector loops are
vector code in the machine code."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh
from numba import typeof

import raylume
import raylume.render_window as render_window
from raylume.image import Image
from raylume.kernels.geometry import wavefront_spheres
from raylume.kernels.integrators import wavefront
from raylume.kernels.scene import instances_of
from raylume.kernels.variants import features

LIGHTS = [
    {"type": "ambient", "intensity": 0.15},
    {"type": "point", "position": [2, 3, -2], "intensity": [0.6, 0.5, 0.4]},
    {"type": "ambient", "intensity": [0.05, 0.03, 0.011]},  # after another light: added in its turn
    {"type": "directional", "direction": [-1, 4, -2], "intensity": 0.25},
    {"type": "spot", "position": [-2, 4, -1], "direction": [0.5, -1, 0.8], "angle": 35, "inner_angle": 20},
]


def _render_both(scene, monkeypatch, **overrides):
    """(wavefront image, ray-by-ray image): the second forces the scene into the kernels' full
    variant, which traces it with trace.py's trace_ray."""
    compiled = raylume.Session(scene).compiled
    assert features(compiled.kernel) is None, "the scene must be basic to take the wavefront"
    wave = raylume.render(scene, aovs=False, **overrides)
    monkeypatch.setattr(render_window, "features", instances_of)
    single = raylume.render(scene, aovs=False, **overrides)
    monkeypatch.undo()
    return wave, single


def _assert_same(wave, single):
    assert wave.stats["rays"] == single.stats["rays"]
    np.testing.assert_array_equal(wave.rgb, single.rgb)
    assert np.isfinite(wave.rgb).all()


def test_seed_scene_is_the_ray_by_ray_image(monkeypatch):
    # 300 wide: a row is two tiles, the second partial
    wave, single = _render_both(raylume.builtin_scene("seed"), monkeypatch, width=300, height=120)
    _assert_same(wave, single)
    assert wave.rgb.max() > 0.5


def test_many_samples_filters_and_a_lens_straddle_tiles(monkeypatch):
    """3 samples a pixel (256 is no multiple of 3: pixels straddle tiles), a filter with negative
    lobes, a thin lens and a crop window."""
    scene = raylume.builtin_scene("seed").with_render(width=200, height=60, spp=3, filter="mitchell", seed=7)
    scene = scene.model_copy(update={"camera": scene.camera.model_copy(update={"aperture": 0.05})})
    wave, single = _render_both(scene, monkeypatch, crop=(13, 187, 5, 41))
    _assert_same(wave, single)


def _mesh_scene(tmp_path, spheres):
    """An icosphere mesh beside spheres, every light kind of a basic scene, a checker texture,
    a matte and an emissive material; the BVH has inner nodes."""
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=0.8)
    mesh.apply_translation([0.6, 0.2, 4.5])
    mesh.export(tmp_path / "ico.ply")
    objects = [
        {"type": "mesh", "file": str(tmp_path / "ico.ply"), "material": {"color": [0.9, 0.6, 0.3], "specular": 40}},
        {"type": "sphere", "center": [0, -1001, 0], "radius": 1000,
         "material": {"texture": {"type": "checker", "scale": 0.5}, "reflective": 0.3, "specular": 200}},
    ]  # fmt: skip
    objects += spheres
    return raylume.scene_from_dict(
        {
            "render": {"width": 160, "height": 90, "max_depth": 4, "background": [0.1, 0.2, 0.3]},
            "camera": {"position": [0, 0.5, -1], "look_at": [0, 0, 4], "fov": 60},
            "lights": LIGHTS,
            "objects": objects,
        }
    )


def test_a_mesh_beside_spheres_takes_the_bvh_path(monkeypatch, tmp_path):
    spheres = [
        {"type": "sphere", "center": [-1.2, 0, 4], "radius": 0.7,
         "material": {"color": [0.2, 0.4, 1], "reflective": 0.5}},
        {"type": "sphere", "center": [1.5, -0.5, 3], "radius": 0.4, "material": {"emission": [0.5, 0.1, 0.1]}},
        {"type": "sphere", "center": [0, 1.5, 6], "radius": 0.9, "material": {"color": [1, 1, 1]}},
    ]  # fmt: skip
    scene = _mesh_scene(tmp_path, spheres)
    assert raylume.Session(scene).compiled.kernel.node_index.shape[0] > 1
    _assert_same(*_render_both(scene, monkeypatch))


@pytest.mark.parametrize("count", [1, 3, 6])
def test_one_leaf_of_spheres_any_count(monkeypatch, count):
    """A root leaf of one sphere (tested alone), of three (a block of spheres) and of six (more
    than a block); every light kind; a textured sphere; reflections to depth 5."""
    rng = np.random.default_rng(count)
    objects = [
        {
            "type": "sphere",
            "center": [float(x) for x in rng.uniform([-2, -1, 3], [2, 1, 7])],
            "radius": float(rng.uniform(0.4, 1.2)),
            "material": {"color": [float(c) for c in rng.uniform(0, 1, 3)], "specular": 300, "reflective": 0.4},
        }
        for _ in range(count)
    ]
    objects[0]["material"]["texture"] = {"type": "checker", "scale": 0.3}  # looked up ray by ray
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 90, "height": 70, "max_depth": 5},
            "camera": {"position": [0, 0, 0], "look_at": [0, 0, 4]},
            "lights": LIGHTS,
            "objects": objects,
        }
    )
    index = raylume.Session(scene).compiled.kernel.node_index
    assert index.shape[0] == 1 or count == 6
    _assert_same(*_render_both(scene, monkeypatch))


def test_from_inside_an_absorbing_sphere_under_an_environment(monkeypatch, tmp_path):
    """The camera inside a reflective sphere whose material absorbs (rays leave it: Beer-Lambert),
    a second sphere outside, and an image environment for the rays that miss."""
    rng = np.random.default_rng(1)
    Image(rng.uniform(0.1, 2.0, (8, 16, 3)).astype(np.float32), {}, {}, "clamp").save(tmp_path / "sky.exr")
    scene = raylume.scene_from_dict(
        {
            "render": {"width": 80, "height": 60, "max_depth": 3},
            "camera": {"position": [0, 0, 0], "look_at": [0, 0, 1]},
            "lights": LIGHTS,
            "environment": {"file": str(tmp_path / "sky.exr")},
            "objects": [
                {"type": "sphere", "center": [0, 0, 0.5], "radius": 2,
                 "material": {"color": [0.8, 0.8, 0.8], "reflective": 0.6, "absorption": [0.1, 0.3, 0.5]}},
                {"type": "sphere", "center": [0, 0, 5], "radius": 1, "material": {"color": [1, 0.2, 0.2]}},
            ],
        }
    )  # fmt: skip
    _assert_same(*_render_both(scene, monkeypatch))


def _asm(function, *args) -> str:
    function.compile(tuple(typeof(a) for a in args))
    cres = function.overloads[tuple(typeof(a) for a in args)]
    return cres.library.get_asm_str()


def test_the_vector_loops_are_vector_code():
    """8 float64 lanes where the CPU prefers 512-bit vectors (zmm), else 4 (ymm: AVX2, Intel's
    AVX-512 cores, kernels/vector_width.py): packed square roots and divisions
    where a stage has them, packed arithmetic in the others. Should LLVM stop vectorising a
    loop, this fails (the images would not change)."""
    n = 16
    R = np.zeros(wavefront.WAVE_ROWS * wavefront.STRIDE)
    I = np.zeros(wavefront.WAVE_INT_ROWS * wavefront.STRIDE, dtype=np.int64)
    rows = (wavefront.OX, wavefront.OY, wavefront.OZ, wavefront.DX, wavefront.DY, wavefront.DZ, wavefront.T, 0)
    spheres = np.zeros((2, 4))
    dividing = {
        "tile_closest": (wavefront_spheres.tile_closest, (R, I, rows, n, spheres, 0, 2)),
        "tile_blocks": (wavefront_spheres.tile_blocks, (R, I, rows, n, spheres, 0, 2, False)),
        "_light_directions": (wavefront._light_directions, (R, I, n, False, 0.0, 0.0, 0.0)),
        "_pinhole_directions": (wavefront._pinhole_directions, (R, n, np.zeros(17), 0, 0, n, n, 0.1)),
        "_sphere_surfaces": (wavefront._sphere_surfaces, (R, I, n, 0.0)),
    }
    for name, (function, args) in dividing.items():
        asm = _asm(function, *args)
        for op in ("vsqrtpd", "vdivpd"):
            assert re.search(rf"{op}\s+[^\n]*%[yz]mm", asm), f"no packed {op} in {name}"
    others = {
        "_add_local_and_reflect": (wavefront._add_local_and_reflect, (R, I, n, False), "vmulpd"),
        "_gather_light": (wavefront._gather_light, (R, I, n, 0.0, 0.0, 0.0), "vmulpd"),
        "_needs_shadow": (wavefront._needs_shadow, (R, I, n), "vcmp"),
    }
    for name, (function, args, op) in others.items():
        assert re.search(rf"{op}\w*\s+[^\n]*%[yz]mm", _asm(function, *args)), f"no packed {op} in {name}"


def _spheres(n: int) -> list:
    return [{"type": "sphere", "center": [float(k), 0.0, 5.0], "radius": 0.3} for k in range(n)]


@pytest.mark.parametrize(
    "objects",
    [
        _spheres(1),
        _spheres(4),  # the seed's count: one leaf
        _spheres(12),  # a BVH with inner nodes
        [*_spheres(3), {"type": "triangle", "vertices": [[-1, -1, 4], [1, -1, 4], [0, 1, 4]]}],
    ],
)
def test_the_hosts_sphere_leaf_is_the_kernels(objects):
    """variants.sphere_leaf (numpy, which picks trace_lane's variant) answers as the kernel's
    _sphere_leaf: the seed's variant, compiled without the BVH's code, never meets a BVH; and
    the host's wavefront tables hold the leaf's spheres where the kernel looks for them."""
    from raylume.kernels.scene import geometry_of
    from raylume.kernels.variants import sphere_leaf, sphere_leaf_range, trace_features

    S = raylume.Session(raylume.scene_from_dict({"objects": objects})).compiled.kernel
    first, count = wavefront._sphere_leaf(geometry_of(S))
    assert sphere_leaf(S) == (count > 0)
    if count > 0:
        assert sphere_leaf_range(S.node_index, S.prims) == (first, count)
        rows = wavefront.wavefront_tables(S)[1][first : first + count]  # centre, radius
        want = sorted((*o["center"], o["radius"]) for o in objects)
        assert sorted(map(tuple, rows.tolist())) == want
    assert (trace_features(S, True) is None) == (count > 0)


def test_the_seed_takes_the_sphere_leaf_variant():
    from raylume.kernels.variants import trace_features

    seed = raylume.builtin_scene("seed")
    S = raylume.Session(seed).compiled.kernel
    assert trace_features(S, True) is None
    assert trace_features(S, False) == 0  # samples not at the pixel centres: the variant that samples
    # what the seed's variant compiles no code for: a spot light, an absorbing material
    spot = {"type": "spot", "position": [0, 2, 0], "direction": [0, -1, 1], "angle": 30}
    spot_light = raylume.scene_from_dict({"lights": [spot]}).lights[0]
    with_spot = seed.model_copy(update={"lights": [*seed.lights, spot_light]})
    assert trace_features(raylume.Session(with_spot).compiled.kernel, True) == 0
    red = seed.materials["red"].model_copy(update={"absorption": (0.5, 0.5, 0.5)})
    absorbing = seed.model_copy(update={"materials": {**seed.materials, "red": red}})
    assert trace_features(raylume.Session(absorbing).compiled.kernel, True) == 0


def test_the_seed_variant_renders_as_the_basic_one(monkeypatch):
    """The seed's first picture (B None: pixel centres, no BVH, no running sums) is the picture of
    the basic variant (B 0) to the bit, rays included."""
    scene = raylume.builtin_scene("seed").with_render(width=200, height=90)
    first = raylume.render(scene, aovs=False)
    monkeypatch.setattr(render_window, "trace_features", lambda S, centres_only: 0)
    basic = raylume.render(scene, aovs=False)
    _assert_same(first, basic)


def test_the_hosts_wavefront_rows_start_on_cache_lines():
    """The rows' arrays start on a 64-byte boundary and are zeros, with room on either side
    against false sharing (every row then starts on a cache line: STRIDE is a multiple of 64
    bytes), and the materials table holds the materials' columns the kernel reads."""
    from raylume.kernels.geometry.wide_nodes import SCRATCH_PAD
    from raylume.kernels.shading.materials import MAT_COLOR, MAT_REFLECTIVE

    S = raylume.Session(raylume.builtin_scene("seed")).compiled.kernel
    R, I = wavefront.wavefront_rows()
    M, _ = wavefront.wavefront_tables(S)
    assert (wavefront.STRIDE * 8) % 64 == 0
    for rows, count in ((R, wavefront.WAVE_ROWS), (I, wavefront.WAVE_INT_ROWS)):
        assert rows.ctypes.data % 64 == 0 and rows.shape == (count * wavefront.STRIDE,) and not rows.any()
        before = (rows.ctypes.data - rows.base.ctypes.data) // rows.itemsize
        assert before >= SCRATCH_PAD and rows.base.size - before - rows.size >= SCRATCH_PAD
    np.testing.assert_array_equal(M[:, 0:3], S.materials[:, MAT_COLOR : MAT_COLOR + 3])
    np.testing.assert_array_equal(M[:, 7], S.materials[:, MAT_REFLECTIVE])
