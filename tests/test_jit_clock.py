"""JitClock: Numba's compilation time inside a block, so that a build reports compiling the BVH
builder as compilation, not as building."""

from __future__ import annotations

import time

import numpy as np
from numba import njit

import raylume
from raylume.compile import compile_scene
from raylume.kernels.jit_clock import JitClock


def test_the_clock_counts_compilation_and_nothing_else():
    @njit  # a new function: compiled inside the block, once
    def triple(x):
        return 3 * x

    heard = []
    with JitClock(lambda: heard.append(time.perf_counter())) as clock:
        started = time.perf_counter()
        assert triple(2) == 6
        elapsed = time.perf_counter() - started
    assert clock.compiled and len(heard) == 1
    assert 0.0 < clock.seconds <= elapsed
    with JitClock() as again:
        time.sleep(0.05)
        assert triple(3) == 9  # compiled already: nothing to count
    assert not again.compiled and again.seconds == 0.0


def test_a_build_reports_its_compilation_apart():
    """compile_scene's stats hold compile_seconds beside build_seconds, which leaves it out, and
    a render reports the build's compilation under compile_seconds."""
    spheres = [{"type": "sphere", "center": [float(x), 0.0, 5.0], "radius": 0.3} for x in np.linspace(-3, 3, 20)]
    scene = raylume.scene_from_dict({"objects": spheres})  # more than a leaf's worth: a BVH is built
    started = time.perf_counter()
    stats = compile_scene(scene).stats
    elapsed = time.perf_counter() - started
    assert stats["compile_seconds"] >= 0.0 and stats["build_seconds"] >= 0.0
    assert stats["build_seconds"] + stats["compile_seconds"] <= elapsed + 1e-6
    heard = []
    image = raylume.render(scene, width=8, height=8, mode="cast", status=heard.append)
    assert image.stats["compile_seconds"] >= 0.0 and "compiling" in heard
