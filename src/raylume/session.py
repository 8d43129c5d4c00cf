"""A scene compiled once and rendered many times: `Session(scene).render(camera=..., ...)`.

Compiling (model -> arrays, mesh loading, the BVH) happens in the constructor; each render
only makes a camera array and a film, then runs the mode's kernels. The viewer, the cluster and
animations render through a Session; `raylume.render` is the one-shot form.

Ray modes run one *lane* per thread over the whole image (kernels/frame.py: each lane claims
the next row left, so a lane slowed by the machine takes fewer; lanes.py keeps the threads from
one render to the next). The calling thread only waits and watches: it polls the lanes' row
counters for the progress bar, and on Ctrl-C raises a flag that every lane checks before each
row, so the render stops within a row's time and keeps the rows that are done.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import wait
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numba
import numpy as np
from pydantic import ValidationError

from .compile import CompiledScene, compile_scene
from .errors import RaylumeError, SceneError
from .frame_stack import on_roomy_frame_stack
from .image import Image
from .kernels.camera import camera_of, set_cone_spread
from .kernels.film import Film
from .kernels.frame import (
    AOV_ROWS,
    CONTROL_SIZE,
    PASS_ROWS,
    PROGRESS_STRIDE,
    STOP,
    aov_lane,
    cast_lane,
    path_lane,
    trace_lane,
)
from .kernels.shapes import features, path_features
from .lanes import lane_pool
from .scene.checks import warn_about
from .scene.model import Camera, RenderSettings, Scene
from .scene.open import SceneLike, open_scene
from .scene.validation_errors import format_validation_error

if TYPE_CHECKING:
    from distributed import Client

AOV_NAMES = ("depth", "normal", "object", "prim", "albedo", "instance")
POLL_SECONDS = 0.05  # how often the waiting thread updates progress and notices Ctrl-C


class RenderInterrupted(KeyboardInterrupt):
    """Ctrl-C during a render. `image` holds the rows finished so far (the rest is black)."""

    def __init__(self, image: Image, rows_done: int, done: str | None = None):
        self.done = done or f"{rows_done} of {image.height} rows"  # what was finished, in words
        super().__init__(f"interrupted after {self.done}")
        self.image = image
        self.rows_done = rows_done


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


def allocate_aovs(H: int, W: int) -> dict:
    return {
        "depth": np.full((H, W), np.inf, dtype=np.float32),
        "normal": np.zeros((H, W, 3), dtype=np.float32),
        "object": np.full((H, W), -1, dtype=np.int32),
        "prim": np.full((H, W), -1, dtype=np.int32),
        "albedo": np.zeros((H, W, 3), dtype=np.float32),
        "instance": np.full((H, W), -1, dtype=np.int32),
    }


class Session:
    """A scene compiled once (geometry, materials, lights, BVH) that renders many times.

        session = raylume.Session("seed")  # or a Scene, a scene file, a mesh file
        a = session.render(width=300, height=300)
        b = session.render(camera={"position": [0, 1, -2]}, mode="cast", spp=4)

    `accelerate=False` skips the BVH until a ray mode needs it (rasterizing never does)."""

    def __init__(self, scene: SceneLike, *, source: str = "<scene>", accelerate: bool = True):
        """`scene`: a Scene, a path to a scene, glTF or mesh file, or a built-in scene's name
        (as raylume.render takes it)."""
        scene, label = open_scene(scene)
        self.scene = scene
        self.source = label if source == "<scene>" else source
        self.bvh_builds = 0
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
        return session

    def _compile(self, accelerate: bool) -> None:
        self.compiled = compile_scene(self.scene, source=self.source, accelerate=accelerate)
        self._accelerated = accelerate
        self.bvh_builds += int(accelerate)
        self._unreported_build = self.compiled.stats["build_seconds"]

    def render(
        self,
        camera: Camera | dict | None = None,
        *,
        width: int | None = None,
        height: int | None = None,
        spp: int | None = None,
        mode: str | None = None,
        max_depth: int | None = None,
        seed: int | None = None,
        filter: str | None = None,
        exposure: float | None = None,
        denoise: bool | None = None,
        threads: int | None = None,
        aovs: bool = True,
        progress: Callable[[int, int], None] | None = None,
        crop: tuple[int, int, int, int] | None = None,
        status: Callable[[str], None] | None = None,
        cluster: str | Client | None = None,
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
        tiles on its workers, bit-identical to the in-process render (raylume.cluster)."""
        settings = resolve_settings(
            self.scene,
            self.source,
            width=width,
            height=height,
            spp=spp,
            mode=mode,
            max_depth=max_depth,
            seed=seed,
            filter=filter,
            exposure=exposure,
            denoise=denoise,
        )
        warn_about(self.scene, settings.mode)
        cam_model = self._camera(camera)
        W, H = settings.width, settings.height
        window = check_crop(crop, W, H, self.source)
        x0, x1, y0, y1 = window
        lanes = _set_threads(threads)
        check_memory(x1 - x0, y1 - y0, aovs)
        if settings.mode != "raster" and not self._accelerated:
            self._compile(True)
        build_seconds, self._unreported_build = self._unreported_build, 0.0
        clock = _CompileClock(status)
        extra: dict = {}  # mode-specific statistics
        denoising = settings.denoise and settings.mode == "path"
        if cluster is not None:
            from .cluster import render_on_cluster

            part = render_on_cluster(
                cluster, self.compiled, cam_model, settings, window, aovs=aovs or denoising, progress=progress,
                status=clock,
            )  # fmt: skip
            extra["cluster"] = part.cluster
        else:
            part = render_window(
                self.compiled, cam_model, settings, window, aovs=aovs or denoising, lanes=lanes, progress=progress,
                status=clock,
            )  # fmt: skip
        rgb, aov_arrays, kernel_seconds, rays = part.rgb, part.aovs, part.seconds, part.rays
        primary = 0 if settings.mode == "raster" else (x1 - x0) * (y1 - y0) * settings.spp
        if settings.mode != "raster":
            extra["rejected_samples"] = part.rejected
        if denoising:
            from .seen_light import denoise_path_image

            noisy = rgb
            rgb, split = denoise_path_image(
                self.compiled, cam_model, settings, window, lanes, noisy, aov_arrays["albedo"], aov_arrays["normal"]
            )
            rays += split.rays
            extra["denoise_seconds"] = split.seconds
            extra["denoise_edge_pixels"] = split.edge_pixels
            extra["denoise_edge_spp"] = split.edge_spp
            if not aovs:
                aov_arrays = {}
            aov_arrays["noisy"] = noisy
        stats = {
            "width": W,
            "height": H,
            "crop": list(window) if crop is not None else None,
            "spp": settings.spp,
            "mode": settings.mode,
            "threads": lanes,
            **self.compiled.stats,
            "build_seconds": build_seconds,
            "rays": int(rays),
            "primary_rays": int(primary),
            "render_seconds": kernel_seconds,
            "compile_seconds": clock.seconds,
            "mrays_per_second": float(rays / kernel_seconds / 1e6) if kernel_seconds > 0 else 0.0,
            **extra,
        }
        if not aovs:
            aov_arrays = {k: v for k, v in aov_arrays.items() if k == "noisy"}
        return Image(rgb, aov_arrays, stats, settings.encoding, exposure=settings.exposure)

    def add_samples(
        self,
        film: Film,
        spp: int,
        camera: Camera | dict | None = None,
        *,
        mode: str | None = None,
        max_depth: int | None = None,
        seed: int | None = None,
        threads: int | None = None,
        progress: Callable[[int, int], None] | None = None,
    ) -> dict:
        """Add the next `spp` samples per pixel to `film` (cast or trace mode): a progressive
        pass. Passes that add up to film.total_spp give the film the same bits as one render
        of total_spp. Returns {"rays", "render_seconds"}."""
        if film.spp + spp > film.total_spp:
            raise ValueError(
                f"the film takes {film.total_spp} samples per pixel; {film.spp} are in and {spp} more would exceed it"
            )
        settings = resolve_settings(
            self.scene, self.source, width=film.width, height=film.height, mode=mode, max_depth=max_depth, seed=seed
        )
        if settings.mode == "raster":
            raise ValueError("raster mode draws whole images; it adds no samples to a film")
        if not self._accelerated:
            self._compile(True)
        cam_model = self._camera(camera)
        S = self.compiled.for_camera(cam_model.position)
        cam = set_cone_spread(
            camera_of(cam_model, film.width, film.height), film.height, film.total_spp, settings.texture_filter
        )
        seconds, rays = _ray_render(S, cam, film, spp, settings, {}, progress, _set_threads(threads))
        return {"rays": int(rays), "render_seconds": seconds}

    def _camera(self, camera) -> Camera:
        if camera is None:
            return self.scene.camera
        if isinstance(camera, Camera):
            return camera
        try:
            return Camera.model_validate({**self.scene.camera.model_dump(), **dict(camera)})
        except ValidationError as exc:
            raise SceneError(format_validation_error(exc, self.source, Camera, table=("camera",))) from None


@dataclass
class WindowResult:
    """What rendering a window of the image gives: the linear RGB of the window (None while
    passes remain: then `sums` holds the film's running sums), its AOVs, the kernel seconds,
    the rays traced and the samples rejected (path mode). A cluster's tiles are these."""

    window: tuple[int, int, int, int]
    rgb: np.ndarray | None
    aovs: dict = field(default_factory=dict)
    seconds: float = 0.0
    rays: int = 0
    rejected: int = 0
    sums: np.ndarray | None = None
    cluster: dict = field(default_factory=dict)  # statistics of a cluster render


def render_window(
    compiled: CompiledScene,
    camera: Camera,
    settings: RenderSettings,
    window: tuple[int, int, int, int],
    *,
    aovs: bool,
    lanes: int,
    progress: Callable[[int, int], None] | None = None,
    status: Callable | None = None,
    first: int = 0,
    count: int | None = None,
    sums: np.ndarray | None = None,
) -> WindowResult:
    """Render samples first..first+count-1 (default: all of settings.spp) of the pixels in
    `window` = (x0, x1, y0, y1) of the settings' image, continuing from the film `sums` of
    the samples before `first`. Needs no scene model, only the compiled scene and resolved
    settings: this is what a cluster's worker runs for one tile and one pass."""
    W, H = settings.width, settings.height
    x0, x1, y0, y1 = window
    status = status or (lambda what, seconds=0.0: None)
    S = compiled.for_camera(camera.position)
    cam = camera_of(camera, W, H)
    set_cone_spread(cam, H, 1 if settings.mode == "raster" else settings.spp, settings.texture_filter)
    if settings.mode == "raster":
        from .raster import rasterize

        status("compiling")  # rasterize compiles its kernels first, outside its own timing
        rgb, aov_arrays, kernel_seconds, rays = rasterize(
            S, cam, W, H, settings.background, progress=progress, aovs=aovs
        )
        status("rendering", kernel_seconds)
        # the rasterizer draws whole frames (it is fast): a crop is that window of one
        rgb = np.ascontiguousarray(rgb[y0:y1, x0:x1])
        aov_arrays = {k: np.ascontiguousarray(v[y0:y1, x0:x1]) for k, v in aov_arrays.items()}
        return WindowResult(window, rgb, aov_arrays, kernel_seconds, int(rays))
    film = Film(W, H, settings.filter, total_spp=settings.spp, window=window)
    if sums is not None:
        film.sums[...] = sums
        film.spp = first
    count = settings.spp - first if count is None else count
    aov_arrays = allocate_aovs(y1 - y0, x1 - x0) if aovs else {}
    kernel_seconds, rays = _ray_render(S, cam, film, count, settings, aov_arrays, progress, lanes, status=status)
    done = film.spp == film.total_spp
    return WindowResult(
        window,
        film.rgb() if done else None,
        aov_arrays,
        kernel_seconds,
        int(rays),
        film.rejected,
        None if done else film.sums,
    )


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


def resolve_settings(scene: Scene, source: str, **overrides):
    """The scene's [render] table with the given (non-None) values replaced, validated; a bad
    value is a SceneError naming the setting."""
    try:
        return scene.with_render(**overrides).render
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, source, RenderSettings, context="render settings: ")) from None


def check_crop(crop, width: int, height: int, source: str = "<scene>") -> tuple[int, int, int, int]:
    """The window (x0, x1, y0, y1) of a crop (columns x0..x1-1, rows y0..y1-1), the whole image
    for None; a window outside the image or empty is a RaylumeError."""
    if crop is None:
        return 0, width, 0, height
    x0, x1, y0, y1 = (int(c) for c in crop)
    if not (0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height):
        raise RaylumeError(
            f"{source}: crop {x0}:{x1},{y0}:{y1} must be a non-empty window of the {width} x {height} image "
            f"(0 <= X0 < X1 <= {width}, 0 <= Y0 < Y1 <= {height})"
        )
    return x0, x1, y0, y1


def _set_threads(threads: int | None) -> int:
    if threads is not None:
        if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
            raise ValueError(f"threads must be between 1 and {numba.config.NUMBA_NUM_THREADS}")
        numba.set_num_threads(threads)
    else:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return numba.get_num_threads()


PATH_STRATEGIES = {"mis": 0, "light": 1, "bsdf": 2}  # kernels/path.py


def path_strategy() -> int:
    """Path mode's sampling strategy: MIS, unless the environment variable RAYLUME_PATH_STRATEGY
    asks for light sampling or BSDF sampling alone (for tests and debugging: each alone is
    unbiased too, only noisier)."""
    name = os.environ.get("RAYLUME_PATH_STRATEGY", "mis")
    if name not in PATH_STRATEGIES:
        raise RaylumeError(f"RAYLUME_PATH_STRATEGY={name!r}: expected one of {', '.join(PATH_STRATEGIES)}")
    return PATH_STRATEGIES[name]


def _ray_render(S, cam, film: Film, spp: int, settings, aov: dict, progress, lanes: int, status=None):
    """Add the film's next `spp` samples per pixel (and fill the AOVs, of the film's window) on
    `lanes` threads. Returns (kernel seconds, rays traced)."""
    W, H = film.width, film.height
    window = film.kernel_window
    rows = window[3] - window[1]
    rays_per_row = np.zeros(rows, dtype=np.int64)
    # the AOV pass counts apart: a lane still in it and one already in the image pass may add to
    # the same row's count at once, and one of the two additions was lost
    aov_rays_per_row = np.zeros(rows, dtype=np.int64)
    rows_done = np.zeros(lanes * PROGRESS_STRIDE, dtype=np.int64)  # one padded counter per lane
    # control[STOP] = 1 stops every lane before its next row; the lanes claim rows from counters in it
    control = np.zeros(CONTROL_SIZE, dtype=np.int64)
    background = np.asarray(settings.background, dtype=np.float64)
    samples = (film.spp, spp, film.total_spp)  # first, count, total
    X = features(S)  # None: the kernels' variant for spheres and opaque triangles only
    if settings.mode == "path":
        X = path_features(S)  # one variant of the path kernels for every scene (compiled once)
    rejected = np.zeros(lanes * PROGRESS_STRIDE, dtype=np.int64)
    strategy = path_strategy()

    def lane_job(lane: int, window) -> None:
        if aov:
            depth, normal, obj, prim, albedo, instance = (aov[k] for k in AOV_NAMES)
            aov_lane(
                S, X, cam, W, H, window, lane, AOV_ROWS, depth, normal, obj, prim, albedo, instance, aov_rays_per_row,
                rows_done, control,
            )  # fmt: skip
        if settings.mode == "cast":
            cast_lane(S, X, cam, film.filter, W, H, window, lane, PASS_ROWS, samples, settings.seed, background,
                      film.sums, rays_per_row, rows_done, control)  # fmt: skip
        elif settings.mode == "path":
            path_lane(S, X, cam, film.filter, W, H, window, lane, PASS_ROWS, samples, settings.seed, settings.depth,
                      background, film.sums, rays_per_row, rows_done, control, rejected, strategy)  # fmt: skip
        else:
            trace_lane(S, X, cam, film.filter, W, H, window, lane, PASS_ROWS, samples, settings.seed, settings.depth,
                       background, film.sums, rays_per_row, rows_done, control)  # fmt: skip

    status = status or (lambda what: None)
    status("compiling")
    # compile (or load from the cache): no rows; with room on the frame stack (frame_stack.py)
    on_roomy_frame_stack(lane_job, 0, (window[0], window[1], window[2], window[1]))
    control[:] = 0  # (that claimed a row of the empty window)
    status("rendering")
    total = rows * (2 if aov else 1)
    pool = lane_pool(lanes)
    t0 = time.perf_counter()
    futures = [pool.submit(lane_job, lane, window) for lane in range(lanes)]
    try:
        while True:
            finished, pending = wait(futures, timeout=POLL_SECONDS)
            if progress is not None:
                progress(int(rows_done.sum()), total)
            if not pending:
                break
    except KeyboardInterrupt:
        control[STOP] = 1
        wait(futures)
        partial = Image(film.rgb(), aov, {}, settings.encoding, exposure=settings.exposure)
        done = int(rows_done.sum()) - (rows if aov else 0)
        raise RenderInterrupted(partial, max(done, 0)) from None
    kernel_seconds = time.perf_counter() - t0
    for future in futures:
        future.result()  # re-raises a lane's exception
    film.spp += spp
    film.rejected += int(rejected.sum())
    return kernel_seconds, rays_per_row.sum() + aov_rays_per_row.sum()
