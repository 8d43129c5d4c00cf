"""A scene compiled once and rendered many times: `Session(scene).render(camera=..., ...)`.

Compiling (model -> arrays, mesh loading, the BVH) happens in the constructor; each render
only makes a camera array and a film, then runs the mode's kernels. The viewer, the cluster and
animations render through a Session; `raylume.render` is the one-shot form.

A render's settings are resolved once (settings.py), from the keyword arguments or from a
ResolvedSettings given as `settings=`; the pixels are rendered by render_window.py, in-process,
in rounds of tiles that stop when their noise is low (adaptive.py), or in tiles on a cluster
(cluster.py).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING

import numba
import numpy as np
from pydantic import ValidationError

from .adaptive import render_adaptive
from .compile import CompiledScene, compile_scene
from .errors import RaylumeError, SceneError
from .image import Image
from .kernels.film.camera import camera_of, set_cone_spread
from .kernels.film.film import Film
from .render_window import RENDER_AOVS, add_samples_to_film, render_window
from .scene.checks import warn_about
from .scene.model import Camera, Scene
from .scene.open import SceneLike, open_scene
from .scene.validation_errors import format_validation_error
from .seen_light import SplitStats, denoise_path_image, split_settings
from .settings import (
    ResolvedSettings,
    is_whole_number,
    resolve_settings,
    samples_adaptively,
    settings_of_call,
)

if TYPE_CHECKING:
    from distributed import Client


def estimate_bytes(width: int, height: int, aovs: bool) -> int:
    """Memory a render's buffers need: the film's sums, the RGB image, and the AOVs (depth,
    normal, object, prim, albedo, instance)."""
    per_pixel = Film.max_bytes_per_pixel() + 12 + (4 + 12 + 4 + 4 + 12 + 4 if aovs else 0)
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


def _threads_restored(method):
    """A render method that gives Numba back the thread count it found: Numba's count is the
    calling thread's, and left at a render's `threads`, the next Session's BVH build in that
    thread ran on that many (after a render on 1 thread, a 4M-triangle build on one core of two)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        before = numba.get_num_threads()
        try:
            return method(*args, **kwargs)
        finally:
            numba.set_num_threads(before)

    return wrapper


class Session:
    """A scene compiled once (geometry, materials, lights, BVH) that renders many times.

        session = raylume.Session("seed")  # or a Scene, a scene file, a mesh file
        a = session.render(width=300, height=300)
        b = session.render(camera={"position": [0, 1, -2]}, mode="cast", spp=4)

    `accelerate=False` skips the BVH until a ray mode needs it (rasterizing never does)."""

    def __init__(
        self,
        scene: SceneLike = None,
        *,
        source: str = "<scene>",
        accelerate: bool = True,
        defines: dict[str, str] | None = None,
        status: Callable[[str], None] | None = None,
    ):
        """`scene`: a Scene, a path to a scene, glTF or mesh file, or a built-in scene's name
        (as raylume.render takes it; None: the built-in `seed`); `defines`: a Mitsuba scene's $parameters (as --define).
        `status` hears "compiling the BVH builder" and "building" when the build compiles the
        BVH builder's kernels (the first build on a machine)."""
        scene, label = open_scene(scene, defines=defines)
        self.scene = scene
        self.source = label if source == "<scene>" else source
        self.bvh_builds = 0
        self._build_status = status
        self._compile(accelerate)

    @classmethod
    def from_compiled(cls, scene: Scene, compiled: CompiledScene) -> Session:
        """A Session around an already compiled scene (e.g. one unpickled on another machine)."""
        session = cls.__new__(cls)
        session.scene = scene
        session.source = "<compiled>"
        session.bvh_builds = 0
        session.compiled = compiled
        session._accelerated = True
        session._unreported_build = 0.0
        session._unreported_compile = 0.0
        session._build_status = None
        return session

    def _compile(self, accelerate: bool, status: Callable[[str], None] | None = None) -> None:
        status = status or self._build_status
        self.compiled = compile_scene(self.scene, source=self.source, accelerate=accelerate, status=status)
        self._accelerated = accelerate
        self.bvh_builds += int(accelerate)
        # reported by the next render: the build's time, and the BVH builder's compilation apart
        self._unreported_build = self.compiled.stats["build_seconds"]
        self._unreported_compile = self.compiled.stats.get("compile_seconds", 0.0)

    @_threads_restored
    def render(
        self,
        camera: Camera | dict | None = None,
        *,
        width: int | None = None,
        height: int | None = None,
        spp: int | None = None,
        mode: str | None = None,
        integrator: str | None = None,
        max_depth: int | None = None,
        seed: int | None = None,
        filter: str | None = None,
        exposure: float | None = None,
        tonemap: str | None = None,
        denoise: bool | None = None,
        noise_threshold: float | None = None,
        min_spp: int | None = None,
        time_limit: float | None = None,
        threads: int | None = None,
        aovs: bool = True,
        progress: Callable[[int, int], None] | None = None,
        crop: tuple[int, int, int, int] | None = None,
        status: Callable[[str], None] | None = None,
        cluster: str | Client | None = None,
        settings: ResolvedSettings | None = None,
    ) -> Image:
        """Render through `camera` (a Camera, a dict of camera keys replacing the scene's, or
        None for the scene's own); other arguments override the scene's [render] table.
        Returns an Image: linear float32 RGB, the AOVs (depth, normal, object, prim, albedo, instance)
        when `aovs` (and `noisy`, the image before denoising, when `denoise`: path mode), and
        stats. `status` is called with "compiling" before the kernels' first
        call (JIT compilation, or loading from the cache) and "rendering" after it. A scene
        without objects, or without lights in a lit mode, gives a SceneWarning.

        `cluster`: a Dask scheduler's address (`tcp://HOST:PORT`), `local` / `local:N` (a local
        cluster of N worker processes) or a `distributed.Client`: the image is rendered in
        tiles on its workers, bit-identical to the in-process render (raylume.cluster).

        `exposure`, `tonemap`: how the Image encodes 8-bit outputs (Image.save, to_uint8).

        `noise_threshold`, `time_limit`: adaptive sampling (raylume.adaptive): tiles stop taking
        samples once their noise is below the threshold (after `min_spp` samples), or all once the
        time is spent; `spp` is then the most a pixel takes, the AOVs add `spp` (the samples each
        pixel took) and the stats `adaptive`. Raster mode and bdpt sample every pixel alike, with
        a SceneWarning; a cluster samples adaptively by the threshold alone (a time limit is
        ignored there, with a SceneWarning), its tiles on the same grid, so the same image.

        `settings`: settings already resolved (raylume.settings.resolve_settings), in place of
        width ... time_limit, threads and crop."""
        settings = settings_of_call(self.scene, locals(), settings, self.source)
        table = settings.render
        warn_about(self.scene, table.mode)
        cam_model = self._camera(camera)
        cut = None
        if table.denoise and table.mode == "path" and settings.crop is not None:
            # the denoiser's value at a pixel depends on the pixels around it, so a denoised crop
            # is the window of the whole image denoised (the window denoised alone had differed)
            cut, settings = settings.crop, dataclasses.replace(settings, crop=None)
        window = settings.window
        x0, x1, y0, y1 = window
        lanes = _use_threads(settings.threads)
        check_memory(x1 - x0, y1 - y0, aovs)
        if table.mode != "raster" and not self._accelerated:
            self._compile(True, status)
        build_seconds, self._unreported_build = self._unreported_build, 0.0
        build_compile_seconds, self._unreported_compile = self._unreported_compile, 0.0
        clock = _CompileClock(status)
        extra: dict = {}  # mode-specific statistics
        denoising = table.denoise and table.mode == "path"
        adaptive = samples_adaptively(table, on_cluster=cluster is not None, warn_if_ignored=True)
        if cluster is not None:
            from .cluster import render_on_cluster  # loads Dask only when asked

            part = render_on_cluster(
                cluster, self.compiled, cam_model, settings, aovs=aovs or denoising, progress=progress, status=clock
            )
            extra["cluster"] = part.cluster
            worker_compile_seconds = part.cluster["compile_seconds"]  # the longest of the workers'
            if adaptive:
                extra["adaptive"] = part.adaptive
        elif adaptive:
            worker_compile_seconds = 0.0
            part = render_adaptive(
                self.compiled, cam_model, table, window, aovs=aovs or denoising, lanes=lanes, progress=progress,
                status=clock,
            )  # fmt: skip
            extra["adaptive"] = part.adaptive
        else:
            worker_compile_seconds = 0.0
            part = render_window(
                self.compiled, cam_model, table, window, aovs=aovs or denoising, lanes=lanes, progress=progress,
                status=clock,
            )  # fmt: skip
        rgb, aov_arrays, kernel_seconds, rays = part.rgb, part.aovs, part.seconds, part.rays
        primary = primary_rays(table, (x1 - x0) * (y1 - y0), part.adaptive if adaptive else None)
        if table.mode != "raster":
            extra["rejected_samples"] = part.rejected
        if table.mode == "path":
            extra["integrator"] = table.integrator
        if part.strategies:
            extra["bdpt_strategies"] = dict(sorted(part.strategies.items()))
        if denoising:
            noisy = rgb
            albedo, normal = aov_arrays["albedo"], aov_arrays["normal"]
            rgb, split = self._denoised(cam_model, settings, noisy, albedo, normal, part.adaptive if adaptive else None)
            rays += split.rays
            extra["denoise_seconds"] = split.seconds
            extra["denoise_edge_pixels"] = split.edge_pixels
            extra["denoise_edge_spp"] = split.edge_spp
            aov_arrays["noisy"] = noisy
        if cut is not None:
            x0, x1, y0, y1 = cut
            rgb = rgb[y0:y1, x0:x1]
            aov_arrays = {name: array[y0:y1, x0:x1] for name, array in aov_arrays.items()}
        stats = {
            "width": table.width,
            "height": table.height,
            "crop": list(window) if settings.crop is not None else list(cut) if cut is not None else None,
            "spp": table.spp,
            "mode": table.mode,
            "threads": lanes,
            **self.compiled.stats,
            "build_seconds": build_seconds,
            "rays": int(rays),
            "primary_rays": int(primary),
            "render_seconds": kernel_seconds,
            "compile_seconds": clock.seconds + build_compile_seconds + worker_compile_seconds,
            "mrays_per_second": float(rays / kernel_seconds / 1e6) if kernel_seconds > 0 else 0.0,
            **extra,
        }
        if not aovs:
            aov_arrays = {k: v for k, v in aov_arrays.items() if k in RENDER_AOVS}
        return Image(rgb, aov_arrays, stats, table.encoding, exposure=table.exposure, tonemap=table.tonemap)

    @_threads_restored
    def add_samples(
        self,
        film: Film,
        spp: int,
        camera: Camera | dict | None = None,
        *,
        mode: str | None = None,
        integrator: str | None = None,
        max_depth: int | None = None,
        seed: int | None = None,
        threads: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        aovs: dict | None = None,
    ) -> dict:
        """Add the next `spp` samples per pixel to `film` (cast, trace or path mode): a
        progressive pass. Passes that add up to film.total_spp give the film the same bits as
        one render of total_spp. `aovs`: arrays of the film's window (as
        render_window.allocate_aovs makes them) that the pass also fills with the primary-hit
        AOVs (depth, normal, object, prim, albedo, instance). Returns {"rays", "render_seconds"}."""
        if not is_whole_number(spp) or spp < 1:
            raise ValueError(f"spp must be a whole number of samples per pixel, at least 1 (got {spp!r})")
        if film.spp + spp > film.total_spp:
            raise ValueError(
                f"the film takes {film.total_spp} samples per pixel; {film.spp} are in and {spp} more would exceed it"
            )
        film_size = {"width": film.width, "height": film.height}
        asked = {"mode": mode, "integrator": integrator, "max_depth": max_depth, "seed": seed}
        settings = resolve_settings(self.scene, {**film_size, **asked}, threads=threads, source=self.source)
        table = settings.render
        if table.mode == "raster":
            raise ValueError("raster mode draws whole images; it adds no samples to a film")
        if not self._accelerated:
            self._compile(True)
        cam_model = self._camera(camera)
        S = self.compiled.for_camera(cam_model.position)
        # the texture filter's ray cone narrows with the samples of the sequence up to the film's
        # end: films that follow each other end as narrow as one render of all their samples
        cone_spp = film.first_sample + film.total_spp
        cam = camera_of(cam_model, film.width, film.height)
        set_cone_spread(cam, film.height, cone_spp, table.texture_filter)
        lanes = _use_threads(settings.threads)
        seconds, rays = add_samples_to_film(S, cam, film, spp, table, aovs or {}, progress, lanes)
        return {"rays": int(rays), "render_seconds": seconds}

    @_threads_restored
    def _denoised(
        self,
        camera: Camera,
        settings: ResolvedSettings,
        noisy: np.ndarray,
        albedo: np.ndarray,
        normal: np.ndarray,
        adaptive: dict | None,
    ) -> tuple[np.ndarray, SplitStats]:
        """A path-mode image of `settings`' window denoised (seen_light.denoise_path_image): the
        light seen directly and the edges rendered here, on settings.threads, at the render's
        spp or an adaptive one's mean (`adaptive`: its statistics). The one way both a still
        (render) and a cluster's animation frame (animation.render_animation) are denoised, so
        that frame K is the still of frame K."""
        lanes = _use_threads(settings.threads)
        table = split_settings(settings.render, adaptive)
        return denoise_path_image(self.compiled, camera, table, settings.window, lanes, noisy, albedo, normal)

    def _camera(self, camera) -> Camera:
        if camera is None:
            return self.scene.camera
        if isinstance(camera, Camera):
            return camera
        if not isinstance(camera, Mapping):
            raise TypeError(f"camera must be a raylume.Camera or a dict of camera keys, got {camera!r}")
        try:
            return Camera.model_validate({**self.scene.camera.model_dump(), **dict(camera)})
        except ValidationError as exc:
            raise SceneError(format_validation_error(exc, self.source, Camera, table=("camera",))) from None


class _CompileClock:
    """Passes status messages on, and times the kernels' warm-up: from status("compiling") to
    the next status, less the kernel time given with it (the rasterizer times its own)."""

    def __init__(self, status: Callable[[str], None] | None):
        self.status = status
        self.seconds = 0.0
        self._since: float | None = None

    def __call__(self, what: str, kernel_seconds: float = 0.0) -> None:
        now = time.perf_counter()
        if self._since is not None:
            self.seconds += max(now - self._since - kernel_seconds, 0.0)
        self._since = now if what == "compiling" else None
        if self.status is not None:
            self.status(what)


def primary_rays(table, pixels: int, adaptive: dict | None) -> int:
    """The stats' primary_rays of a render of `pixels` pixels: spp a pixel, the samples an adaptive
    render took (`adaptive`: its statistics), none for the rasterizer."""
    if table.mode == "raster":
        return 0
    return int(adaptive["samples"]) if adaptive is not None else pixels * table.spp


def _use_threads(count: int) -> int:
    """Run Numba's parallel code (the BVH build, the rasterizer) on `count` threads, as the lanes."""
    numba.set_num_threads(count)
    return count
