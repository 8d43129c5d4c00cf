"""One render call: compile the scene, run the mode's kernels tile by tile, collect the Image."""

from __future__ import annotations

import math
import os
import time
from concurrent.futures import ThreadPoolExecutor, wait
from typing import Callable

import numba
import numpy as np

from .compile import compile_scene
from .errors import RaylumeError
from .image import Image
from .kernels.frame import aov_lane, cast_lane, trace_lane
from .scene.model import Scene

AOV_NAMES = ("depth", "normal", "object", "prim", "albedo")
# Rows per kernel call are chosen so each call takes about this long: short enough for a
# smooth progress bar and a prompt Ctrl-C, long enough that call overhead does not show.
TARGET_CALL_SECONDS = 0.2


class RenderInterrupted(KeyboardInterrupt):
    """Ctrl-C during a render. `image` holds the rows finished so far (the rest is black)."""

    def __init__(self, image: Image, rows_done: int):
        super().__init__(f"interrupted after {rows_done} of {image.height} rows")
        self.image = image
        self.rows_done = rows_done


def estimate_bytes(width: int, height: int, aovs: bool) -> int:
    """Memory the image buffers need: RGB float32, plus depth, normal, object, prim, albedo."""
    per_pixel = 12 + (4 + 12 + 4 + 4 + 12 if aovs else 0)
    return width * height * per_pixel


def available_bytes() -> int:
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # not on every platform
        return 1 << 62


def check_memory(width: int, height: int, aovs: bool) -> None:
    need = estimate_bytes(width, height, aovs)
    free = available_bytes()
    if need > 0.8 * free:
        raise RaylumeError(
            f"a {width} x {height} render needs about {need / 2**30:.1f} GiB of image buffers"
            f"{' (with AOVs)' if aovs else ''}, more than the {free / 2**30:.1f} GiB of free memory; "
            "render smaller, or without AOVs"
        )


def render(
    scene: Scene,
    *,
    width: int | None = None,
    height: int | None = None,
    spp: int | None = None,
    mode: str | None = None,
    max_depth: int | None = None,
    seed: int | None = None,
    threads: int | None = None,
    aovs: bool = True,
    progress: Callable[[int, int], None] | None = None,
    source: str = "<scene>",
) -> Image:
    """Render `scene` (flags override its [render] table). Returns an Image with linear float32
    RGB, the AOVs of DESIGN.md when `aovs` is true, and the stats dictionary."""
    scene = scene.with_render(width=width, height=height, spp=spp, mode=mode, max_depth=max_depth, seed=seed)
    settings = scene.render
    W, H = settings.width, settings.height
    threads = _set_threads(threads)
    check_memory(W, H, aovs)

    compiled = compile_scene(scene, W, H, source=source, accelerate=settings.mode != "raster")
    if settings.mode == "raster":
        from .raster import rasterize

        rgb, aov_arrays, kernel_seconds, rays = rasterize(scene, compiled, progress=progress, aovs=aovs)
        primary = 0
    else:
        rgb, aov_arrays, kernel_seconds, rays = _ray_render(scene, compiled, aovs, progress, threads)
        primary = W * H * settings.spp
    return Image(rgb, aov_arrays if aovs else {}, _stats(settings, threads, compiled, rays, primary, kernel_seconds), settings.encoding,
                 exposure=settings.exposure)


def _stats(settings, threads, compiled, rays, primary, kernel_seconds) -> dict:
    W, H = settings.width, settings.height
    return {
        "width": W,
        "height": H,
        "spp": settings.spp,
        "mode": settings.mode,
        "threads": threads,
        **compiled.stats,
        "rays": int(rays),
        "primary_rays": int(primary),
        "render_seconds": kernel_seconds,
        "mrays_per_second": float(rays / kernel_seconds / 1e6) if kernel_seconds > 0 else 0.0,
    }


def _set_threads(threads: int | None) -> int:
    if threads is not None:
        if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
            raise ValueError(f"threads must be between 1 and {numba.config.NUMBA_NUM_THREADS}")
        numba.set_num_threads(threads)
    else:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return numba.get_num_threads()


def allocate_aovs(H: int, W: int) -> dict:
    return {
        "depth": np.full((H, W), np.inf, dtype=np.float32),
        "normal": np.zeros((H, W, 3), dtype=np.float32),
        "object": np.full((H, W), -1, dtype=np.int32),
        "prim": np.full((H, W), -1, dtype=np.int32),
        "albedo": np.zeros((H, W, 3), dtype=np.float32),
    }


def _ray_render(scene: Scene, compiled, want_aovs: bool, progress, lanes: int):
    settings = scene.render
    W, H = settings.width, settings.height
    rgb = np.zeros((H, W, 3), dtype=np.float32)
    aov = allocate_aovs(H, W) if want_aovs else {}
    rays_per_row = np.zeros(H, dtype=np.int64)
    background = np.asarray(settings.background, dtype=np.float64)
    S, cam = compiled.kernel, compiled.camera

    def rows(row_begin: int, row_end: int, lane: int) -> None:
        if want_aovs:
            aov_lane(S, cam, W, H, row_begin, row_end, lane, lanes, aov["depth"], aov["normal"], aov["object"],
                     aov["prim"], aov["albedo"], rays_per_row)
        if settings.mode == "cast":
            cast_lane(S, cam, W, H, row_begin, row_end, lane, lanes, settings.spp, settings.seed, background,
                      rgb, rays_per_row)
        else:
            trace_lane(S, cam, W, H, row_begin, row_end, lane, lanes, settings.spp, settings.seed,
                       settings.max_depth, background, rgb, rays_per_row)

    rows(0, 0, 0)  # compile (or load from the cache) before any timing starts
    kernel_seconds = 0.0
    row = 0
    rows_per_call = max(1, min(H, 2 * lanes))
    with ThreadPoolExecutor(max_workers=max(1, lanes - 1), thread_name_prefix="raylume") as pool:
        while row < H:
            end = min(H, row + rows_per_call)
            t0 = time.perf_counter()
            try:
                _run_lanes(pool, lanes, lambda lane: rows(row, end, lane))
            except KeyboardInterrupt:
                # The lanes finish the call in flight (calls last ~TARGET_CALL_SECONDS); keep what is done.
                partial = Image(rgb, aov, {}, settings.encoding, exposure=settings.exposure)
                raise RenderInterrupted(partial, end) from None
            elapsed = time.perf_counter() - t0
            kernel_seconds += elapsed
            per_row = elapsed / (end - row)
            rows_per_call = max(1, min(H, int(math.ceil(TARGET_CALL_SECONDS / max(per_row, 1e-9)))))
            row = end
            if progress is not None:
                progress(row, H)
    return rgb, aov, kernel_seconds, rays_per_row.sum()


def _run_lanes(pool: ThreadPoolExecutor, lanes: int, job: Callable[[int], None]) -> None:
    """job(lane) for every lane: lane 0 on this thread, the others on the pool's threads (the
    kernels release the GIL). Returns when all have finished, also when Ctrl-C interrupts,
    so no kernel is still writing into the buffers afterwards."""
    futures = [pool.submit(job, lane) for lane in range(1, lanes)]
    try:
        job(0)
    finally:
        wait(futures)
    for future in futures:
        future.result()  # re-raises a lane's exception
