"""Compile every kernel variant ahead of time, into Numba's on-disk cache.

A cold start compiles each kernel the first time a render needs it (seconds to a minute per
mode). `warm_kernels()` renders tiny images that need every variant (each mode with the two
variants of variants.features: a basic scene, and one with other shapes and instances), so that
later renders, and other processes sharing the cache folder, start at once:

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

from .scene.document import scene_from_dict
from .session import Session

_MATERIALS = {"m": {"color": [0.8, 0.6, 0.4], "specular": 50, "reflective": 0.2}}
_LIGHTS = [{"type": "ambient", "intensity": 0.2}, {"type": "point", "position": [0, 2, -2], "intensity": 0.8}]
_OBJECTS = {
    # spheres alone in one BVH leaf: trace mode's wavefront without the BVH (variants.trace_features)
    "spheres": [{"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"}],
    # spheres and opaque triangles only: features() is None
    "basic": [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"},
        {"type": "triangle", "vertices": [[-2, -1, 4], [2, -1, 4], [0, 2, 4]], "material": "m"},
    ],
}


def _all_objects() -> list:
    """Any other shape, and a mesh of two triangles (an OBJ written once per process) with two
    instances, one mirrored: the scene's Instances as the feature argument (path mode always
    compiles this variant); the instances compile the top-level build too."""
    import tempfile
    from pathlib import Path

    path = Path(tempfile.gettempdir()) / f"raylume-warmup-{os.getpid()}.obj"
    if not path.exists():
        path.write_text("v -1 -1 4\nv 1 -1 4\nv 1 1 4\nv -1 1 4\nf 1 2 3\nf 1 3 4\n")
    instances = [{"translate": [0, 0, 0]}, {"translate": [0.5, 0, 1], "scale": [-1, 1, 1]}]
    return [
        {"type": "sphere", "center": [0, 0, 3], "radius": 1, "material": "m"},
        {"type": "quad", "position": [0, -1, 3], "u": [4, 0, 0], "v": [0, 0, 4], "material": "m"},
        {"type": "mesh", "file": str(path), "material": "m", "instances": instances},
    ]


def _scene(kind: str):
    if kind == "all" and kind not in _OBJECTS:
        _OBJECTS[kind] = _all_objects()
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


def _render(kind: str, mode: str, integrator: str = "path") -> Callable[[], None]:
    def job() -> None:
        session = Session(_scene(kind))
        session.render(mode=mode, spp=2, aovs=True, integrator=integrator)  # spp > 1: the pixel filter's code too
        if mode != "raster":
            session.render(mode=mode, spp=1, aovs=False, integrator=integrator)

    job.__name__ = f"{mode} ({kind})" if integrator == "path" else f"{mode} {integrator} ({kind})"
    return job


def _bvh() -> None:
    """The BVH builder and the collapse, the threaded top part included (warm-up scenes are
    too small to build a BVH: compile.SMALL_SCENE)."""
    from .accel import bvh
    from .accel.wide import collapse

    lo = np.random.default_rng(0).uniform(0.0, 1.0, (2 * bvh._TOP + 1, 3))
    collapse(bvh.build_bvh(lo, lo + 0.01))


_bvh.__name__ = "bvh build"


def _svgf() -> None:
    """The live view's filter of moving frames (svgf.py): two frames, the second reprojecting."""
    from .kernels.film.camera import camera_frame
    from .svgf import Svgf

    svgf, camera = Svgf(), camera_frame([0, 0, 0], [0, 0, 1], [0, 1, 0], 50.0, 8, 6)
    rgb, normal = np.full((6, 8, 3), 0.5, np.float32), np.zeros((6, 8, 3), np.float32)
    normal[..., 2] = -1.0
    for _ in range(2):
        svgf.filter(rgb, rgb, normal, np.full((6, 8), 2.0, np.float32), camera)


_svgf.__name__ = "svgf"


def _film() -> None:
    """Film.rgb's kernel, which renders under a megapixel (the warm-up's) read in numpy until it
    is compiled: the live view and large images take it."""
    from .kernels.film.film import Film

    Film(8, 6).compile_rgb(always=True)


_film.__name__ = "film"


def _intersect(kind: str) -> Callable[[], None]:
    def job() -> None:
        from .query import intersect

        intersect(_scene(kind), np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]))

    job.__name__ = f"intersect ({kind})"
    return job


# (job, its relative cost: seconds of a cold compile / 10, measured with the two parts side by
# side on a busy 2-core machine). Every mode has two variants, the basic one and the Instances
# one (variants.features), which any other scene uses, whichever shapes it has; path mode and the
# rasterizer's shading pass have only the latter (raster draws instances as plain triangles:
# their Instances are empty).
JOBS: list[tuple[Callable[[], None], float]] = [
    (_render("all", "path"), 39.0),
    (_render("all", "path", "bdpt"), 45.0),
    (_render("all", "trace"), 23.0),
    (_render("basic", "trace"), 21.5),
    (_render("spheres", "trace"), 13.0),
    (_render("all", "raster"), 19.0),
    (_intersect("all"), 6.9),
    (_render("all", "cast"), 6.3),
    (_render("basic", "cast"), 6.0),
    (_intersect("basic"), 2.9),
    (_svgf, 1.0),
    (_bvh, 0.4),
    (_film, 0.05),
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


def warm_in_processes(processes: int, report: Callable[[str], None] | None = None) -> bool:
    """`raylume warmup`: every job, in `processes` processes side by side (Numba compiles under
    one lock per process, so processes are what uses several cores). `report` gets a line at the
    start, each job's line as its process finishes it, each part's total and the whole time.
    Returns whether every part succeeded."""
    import subprocess
    import sys
    import threading

    parts = max(1, min(processes, len(JOBS)))
    started = time.perf_counter()
    if report is not None:
        side_by_side = f"in {parts} processes side by side" if parts > 1 else "in one process"
        report(f"compiling every kernel {side_by_side} (a few minutes on a first run; loaded from the cache after)...")
    procs = [
        subprocess.Popen(
            [sys.executable, "-u", "-m", "raylume.warmup", "--part", f"{i}/{parts}"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for i in range(parts)
    ]
    lock = threading.Lock()

    def relay(proc: subprocess.Popen) -> None:  # each line as it comes, whole lines only
        for line in proc.stdout:
            if report is not None:
                with lock:
                    report(line.rstrip("\n"))

    readers = [threading.Thread(target=relay, args=(proc,), daemon=True) for proc in procs]
    for reader in readers:
        reader.start()
    ok = True
    try:
        for proc, reader in zip(procs, readers):
            reader.join()
            ok = proc.wait() == 0 and ok
    except BaseException:  # Ctrl-C or SIGTERM (raylume warmup's): the parts stop too, not orphaned
        for proc in procs:
            proc.terminate()
        for proc in procs:
            proc.wait()
        raise
    if report is not None:
        report(f"every kernel compiled (or loaded from the cache) in {time.perf_counter() - started:.1f} s")
    return ok


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m raylume.warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", default="0/1", help="I/N: the I-th of N parts of the jobs (0-based)")
    parser.add_argument("--quiet", action="store_true")
    args = parser.parse_args(argv)
    try:
        part, parts = (int(x) for x in args.part.split("/"))
    except ValueError:  # ("x", "1", "1/2/3": a usage error, not a traceback)
        parser.error(f"--part {args.part}: expected I/N with 0 <= I < N")
    if not 0 <= part < parts:
        parser.error(f"--part {args.part}: expected I/N with 0 <= I < N")
    seconds = warm_kernels(part, parts, report=None if args.quiet else print)
    if not args.quiet:
        # counted from 1 here ("part 1 of 2"), as a person counts; --part takes I/N from 0
        print(f"part {part + 1} of {parts} done in {seconds:.1f} s" if parts > 1 else f"done in {seconds:.1f} s")


if __name__ == "__main__":
    main()
