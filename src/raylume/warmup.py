"""Compile every kernel variant ahead of time, into Numba's on-disk cache.

A cold start compiles each kernel the first time a render needs it (seconds to a minute per
mode). `warm_kernels()` renders tiny images that need every variant (each mode against the
feature sets of shapes.features: basic scenes, scenes with planes, scenes with the other
shapes, scenes with instances), so that later renders, and other processes sharing the cache folder, start at once:

    python -m raylume.warmup              # everything, in this process
    python -m raylume.warmup --part 1/2   # the second half of the jobs (run halves side by side)

The test suite runs two halves in parallel processes before its workers start, so that two
pytest workers never compile the same kernel at the same time.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from collections.abc import Callable

import numpy as np

from .scene.load import scene_from_dict
from .session import Session

_MATERIALS = {"m": {"color": [0.8, 0.6, 0.4], "specular": 50, "reflective": 0.2}}
_LIGHTS = [{"type": "ambient", "intensity": 0.2}, {"type": "point", "position": [0, 2, -2], "intensity": 0.8}]
_OBJECTS = {
    # spheres and opaque triangles only: features() is None
    "basic": [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"},
        {"type": "triangle", "vertices": [[-2, -1, 4], [2, -1, 4], [0, 2, 4]], "material": "m"},
    ],
    # planes beside them: an int8 feature array
    "planes": [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"},
        {"type": "plane", "point": [0, -1, 0], "normal": [0, 1, 0], "material": "m"},
    ],
    # any other shape: a float64 feature array (path mode always compiles this one)
    "all": [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"},
        {"type": "quad", "position": [0, -1, 3], "u": [4, 0, 0], "v": [0, 0, 4], "material": "m"},
    ],
}


def _instanced_objects() -> list:
    """A mesh of two triangles (an OBJ written once per process) with two instances, one
    mirrored: Instances (kernels/scene.py) as the feature argument."""
    import tempfile
    from pathlib import Path

    path = Path(tempfile.gettempdir()) / f"raylume-warmup-{os.getpid()}.obj"
    if not path.exists():
        path.write_text("v -1 -1 4\nv 1 -1 4\nv 1 1 4\nv -1 1 4\nf 1 2 3\nf 1 3 4\n")
    instances = [{"translate": [0, 0, 0]}, {"translate": [0.5, 0, 1], "scale": [-1, 1, 1]}]
    return [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"},
        {"type": "mesh", "file": str(path), "material": "m", "instances": instances},
    ]


def _scene(kind: str):
    if kind == "instances" and kind not in _OBJECTS:
        _OBJECTS[kind] = _instanced_objects()
    return scene_from_dict(
        {
            "render": {"width": 8, "height": 8},
            "camera": {"position": [0, 0, -1], "look_at": [0, 0, 3]},
            "materials": _MATERIALS,
            "lights": _LIGHTS,
            "objects": _OBJECTS[kind],
        },
        source=f"<warm-up: {kind}>",
    )


def _render(kind: str, mode: str) -> Callable[[], None]:
    def job() -> None:
        session = Session(_scene(kind))
        session.render(mode=mode, spp=2, aovs=True)  # spp > 1: the pixel filter's code path too
        if mode != "raster":
            session.render(mode=mode, spp=1, aovs=False)

    job.__name__ = f"{mode} ({kind})"
    return job


def _bvh() -> None:
    """The BVH builder and the collapse, the threaded top part included (warm-up scenes are
    too small to build a BVH: compile.SMALL_SCENE)."""
    from .accel import bvh
    from .accel.wide import collapse

    lo = np.random.default_rng(0).uniform(0.0, 1.0, (2 * bvh._TOP + 1, 3))
    collapse(bvh.build_bvh(lo, lo + 0.01))


_bvh.__name__ = "bvh build"


def _intersect(kind: str) -> Callable[[], None]:
    def job() -> None:
        from .query import intersect

        intersect(_scene(kind), np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]))

    job.__name__ = f"intersect ({kind})"
    return job


# (job, its share of a cold compile in percent, measured on 2 cores): path mode's kernels take
# a third of it, the three trace variants another third. Path mode has one variant for every
# scene, instances included (shapes.path_features); raster draws instances as plain triangles.
JOBS: list[tuple[Callable[[], None], float]] = [
    (_render("all", "path"), 32.0),
    (_render("basic", "raster"), 20.0),
    # the raster kernels of the other feature sets: tests of textured, unusual-shape and
    # instanced scenes each compiled one (~60 s on 2 busy cores), the same one in both workers
    (_render("all", "raster"), 20.0),
    (_render("planes", "raster"), 20.0),
    (_render("instances", "raster"), 20.0),
    (_render("planes", "trace"), 15.0),
    (_render("all", "trace"), 12.0),
    (_render("basic", "trace"), 11.0),
    (_render("basic", "cast"), 2.3),
    (_render("all", "cast"), 1.9),
    (_render("planes", "cast"), 1.7),
    (_intersect("all"), 1.5),
    (_intersect("planes"), 1.4),
    (_intersect("basic"), 1.3),
    (_render("instances", "trace"), 12.0),
    (_render("instances", "cast"), 2.0),
    (_intersect("instances"), 1.5),
    (_bvh, 8.0),
]


def part_of(jobs: list, part: int, parts: int) -> list:
    """The jobs of part `part` of `parts`: each job, heaviest first, goes to the part with the
    least work so far (so that parts run side by side finish together)."""
    loads = [0.0] * parts
    mine = []
    for job, cost in sorted(jobs, key=lambda jc: -jc[1]):
        k = loads.index(min(loads))
        loads[k] += cost
        if k == part:
            mine.append(job)
    return mine


def warm_kernels(part: int = 0, parts: int = 1, report: Callable[[str], None] | None = None) -> float:
    """Compile (or load from the cache) the kernels of `part` of `parts` of the warm-up jobs;
    returns the seconds taken."""
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # tiny scenes: no warnings wanted about them
        for job in part_of(JOBS, part, parts):
            t = time.perf_counter()
            job()
            if report is not None:
                report(f"{job.__name__}: {time.perf_counter() - t:.1f} s")
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m raylume.warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", default="0/1", help="I/N: the I-th of N parts of the jobs (0-based)")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    part, parts = (int(x) for x in args.part.split("/"))
    if not 0 <= part < parts:
        parser.error(f"--part {args.part}: expected I/N with 0 <= I < N")
    seconds = warm_kernels(part, parts, report=None if args.quiet else print)
    if not args.quiet:
        print(f"warm-up part {part}/{parts}: {seconds:.1f} s")


if __name__ == "__main__":
    main()
