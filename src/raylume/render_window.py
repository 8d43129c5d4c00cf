"""A window of the image rendered from a compiled scene and resolved [render] settings: what
a Session runs for a whole image (or a crop), the cluster's workers for a tile and a pass, and
the path-mode denoiser (seen_light.py) for its extra passes. It needs no scene model.

Ray modes run one *lane* per thread over the window (kernels/integrators/frame.py: each lane claims the
next row left, so a lane slowed by the machine takes fewer; lanes.py keeps the threads from one
render to the next). The calling thread only waits and watches: it polls the lanes' row
counters for the progress bar, and on Ctrl-C raises a flag that every lane checks before each
row, so the render stops within a row's time and keeps the rows that are done.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import wait
from dataclasses import dataclass, field

import numpy as np

from .compile import CompiledScene
from .errors import RaylumeError
from .image import Image
from .kernels.film.camera import CAM_LENS_RADIUS, camera_of, set_cone_spread
from .kernels.film.film import FILM_WIDTH, Film
from .kernels.film.image_pass import Aovs, ImagePass
from .kernels.frame_stack import on_roomy_frame_stack
from .kernels.integrators.bdpt_setup import bdpt_pass, glint_cdf, strategy_counts
from .kernels.integrators.frame import (
    AOV_ROWS,
    CONTROL_SIZE,
    PASS_ROWS,
    PROGRESS_STRIDE,
    STOP,
    LaneControl,
    aov_lane,
    bdpt_glint_guide,
    bdpt_lane,
    cast_lane,
    path_lane,
    path_wave_lane,
    trace_lane,
)
from .kernels.integrators.wavefront import wavefront_rows, wavefront_tables
from .kernels.scene import trace_views
from .kernels.variants import features, path_features, trace_features
from .lanes import lane_pool
from .scene.model import Camera, RenderSettings

AOV_NAMES = ("depth", "normal", "object", "prim", "albedo", "instance")  # of the primary hit
# AOVs of the render itself: the image before --denoise, the samples an adaptive render took
RENDER_AOVS = ("noisy", "spp")
POLL_SECONDS = 0.05  # how often the waiting thread updates progress and notices Ctrl-C


class RenderInterrupted(KeyboardInterrupt):
    """Ctrl-C during a render. `image` holds the rows finished so far (the rest is black)."""

    def __init__(self, image: Image, rows_done: int, done: str | None = None):
        self.done = done or f"{rows_done} of {image.height} rows"  # what was finished, in words
        super().__init__(f"interrupted after {self.done}")
        self.image = image
        self.rows_done = rows_done


def allocate_aovs(H: int, W: int) -> dict:
    return {
        "depth": np.full((H, W), np.inf, dtype=np.float32),
        "normal": np.zeros((H, W, 3), dtype=np.float32),
        "object": np.full((H, W), -1, dtype=np.int32),
        "prim": np.full((H, W), -1, dtype=np.int32),
        "albedo": np.zeros((H, W, 3), dtype=np.float32),
        "instance": np.full((H, W), -1, dtype=np.int32),
    }


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
    strategies: dict = field(default_factory=dict)  # bdpt: samples per strategy "s,t"
    splats: np.ndarray | None = None  # bdpt, while passes remain: the film's splat sums
    adaptive: dict = field(default_factory=dict)  # statistics of an adaptive render (adaptive.py)


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
    splats: np.ndarray | None = None,
    cone_spp: int | None = None,
    keep_sums: bool = False,
) -> WindowResult:
    """Render samples first..first+count-1 (default: all of settings.spp) of the pixels in
    `window` = (x0, x1, y0, y1) of the settings' image, continuing from the film `sums` of
    the samples before `first`. Needs no scene model, only the compiled scene and resolved
    settings: this is what a cluster's worker runs for one tile and one pass. `cone_spp`: the
    samples a pixel takes in all (default settings.spp), which narrow the texture filter's ray
    cone (an adaptive render's rounds are renders of a few samples each). `keep_sums`: the
    result holds the film's sums even once its samples are all in (adaptive sampling's streams
    go on from them)."""
    W, H = settings.width, settings.height
    x0, x1, y0, y1 = window
    status = status or (lambda what, seconds=0.0: None)
    S = compiled.for_camera(camera.position)
    cam = camera_of(camera, W, H)
    spp = cone_spp or settings.spp
    set_cone_spread(cam, H, 1 if settings.mode == "raster" else spp, settings.texture_filter)
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
        if splats is not None:
            film.enable_splats()[...] = splats
    count = settings.spp - first if count is None else count
    aov_arrays = allocate_aovs(y1 - y0, x1 - x0) if aovs else {}
    kernel_seconds, rays = add_samples_to_film(
        S, cam, film, count, settings, aov_arrays, progress, lanes, status=status
    )
    done = film.spp == film.total_spp
    return WindowResult(
        window,
        film.rgb() if done else None,
        aov_arrays,
        kernel_seconds,
        int(rays),
        film.rejected,
        film.sums if keep_sums or not done else None,
        strategies=film.strategies,
        splats=None if done else film.splats,
    )


PATH_STRATEGIES = {"mis": 0, "light": 1, "bsdf": 2}  # kernels/integrators/path.py


def path_strategy() -> int:
    """Path mode's sampling strategy: MIS, unless the environment variable RAYLUME_PATH_STRATEGY
    asks for light sampling or BSDF sampling alone (for tests and debugging: each alone is
    unbiased too, only noisier)."""
    name = os.environ.get("RAYLUME_PATH_STRATEGY", "mis")
    if name not in PATH_STRATEGIES:
        raise RaylumeError(f"RAYLUME_PATH_STRATEGY={name!r}: expected one of {', '.join(PATH_STRATEGIES)}")
    return PATH_STRATEGIES[name]


def path_kernel():
    """Path mode's kernel: the wavefront (path_wavefront.py), unless the environment variable
    RAYLUME_PATH_KERNEL asks for the scalar one, a path at a time (path.py; for tests, which
    compare the two, and debugging). Both give the same images in expectation."""
    name = os.environ.get("RAYLUME_PATH_KERNEL", "wavefront")
    if name not in ("wavefront", "scalar"):
        raise RaylumeError(f"RAYLUME_PATH_KERNEL={name!r}: expected wavefront or scalar")
    return path_wave_lane if name == "wavefront" else path_lane


def _centres_only(cam: np.ndarray, film: Film) -> bool:
    """Whether the film's samples are one at each pixel's centre, through a pinhole, into sums
    without the unsigned half (variants.trace_features)."""
    return film.pixel_centres and not cam[CAM_LENS_RADIUS] > 0.0 and film.sums.shape[2] == FILM_WIDTH


def add_samples_to_film(S, cam, film: Film, spp: int, settings, aov: dict, progress, lanes: int, status=None):
    """Add the film's next `spp` samples per pixel (and fill the AOVs, of the film's window) on
    `lanes` threads. Returns (kernel seconds, rays traced)."""
    W, H = film.width, film.height
    window = film.kernel_window
    rows = window[3] - window[1]
    bidirectional = settings.mode == "path" and settings.integrator == "bdpt"
    # bdpt's lanes go over every row of the image: light subpaths of any pixel may reach the window
    image_rows = H if bidirectional else rows
    rays_per_row = np.zeros(image_rows, dtype=np.int64)
    # the AOV pass counts apart: a lane still in it and one already in the image pass may add to
    # the same row's count at once, and one of the two additions was lost
    aov_rays_per_row = np.zeros(rows, dtype=np.int64)
    rows_done = np.zeros(lanes * PROGRESS_STRIDE, dtype=np.int64)  # one padded counter per lane
    # control[STOP] = 1 stops every lane before its next row; the lanes claim rows from counters in it
    control = np.zeros(CONTROL_SIZE, dtype=np.int64)
    background = tuple(float(c) for c in settings.background)
    # first, count, total: the kernels take total 1 as the pixel centre, so a film of one sample
    # after others counts the samples before it
    samples = (film.first_sample + film.spp, spp, film.first_sample + film.total_spp)
    X = features(S)  # None: the kernels' variant for spheres and opaque triangles only
    if settings.mode == "path":
        X = path_features(S)  # one variant of the path kernels for every scene (compiled once)
    B = 0  # trace mode's variant of a basic scene (X None): None for the seed's picture
    if settings.mode == "trace" and X is None:
        B = trace_features(S, _centres_only(cam, film))
    rejected = np.zeros(lanes * PROGRESS_STRIDE, dtype=np.int64)
    views = trace_views(S, B) if settings.mode == "trace" else None
    tables = wavefront_tables(S) if settings.mode == "trace" else None  # read by every lane
    strategy = path_strategy()
    path_kernel_lane = path_kernel() if settings.mode == "path" else None
    bd = bdpt_pass(S, film, lanes) if bidirectional else None
    image_pass = ImagePass(cam, film.filter, W, H, window, samples, settings.seed, settings.depth, background)

    pilot_rays = 0  # the glint guide's, counted in the render's rays

    def glint_guide(guide: np.ndarray) -> None:
        """bdpt's glint guide, its rows in bands on the lanes (each pixel's score its own: the
        same bits on any number of lanes)."""
        nonlocal pilot_rays
        bands = np.linspace(0, H, lanes + 1).astype(int)
        rows = [(int(a), int(b)) for a, b in zip(bands[:-1], bands[1:], strict=True)]
        args = (S, X, image_pass, bd.bounds, guide)
        for job in [lane_pool(lanes).submit(bdpt_glint_guide, *args, band) for band in rows]:
            pilot_rays += int(job.result())

    aovs = Aovs(**{name: aov[name] for name in Aovs._fields}) if aov else None

    def lane_job(lane: int, window) -> None:
        P = ImagePass(cam, film.filter, W, H, window, samples, settings.seed, settings.depth, background)
        if aovs is not None:
            aov_lane(S, X, P, aovs, LaneControl(lane, AOV_ROWS, rows_done, control, aov_rays_per_row, rejected))
        C = LaneControl(lane, PASS_ROWS, rows_done, control, rays_per_row, rejected)
        if settings.mode == "cast":
            cast_lane(S, X, P, film.sums, C)
        elif bidirectional:
            bdpt_lane(S, X, P, film.sums, C, bd)
        elif settings.mode == "path":
            path_kernel_lane(S, X, P, film.sums, C, strategy)
        else:
            trace_lane(*views, X, P, film.sums, C, B, (*wavefront_rows(), *tables))

    status = status or (lambda what: None)
    status("compiling")
    # compile (or load from the cache): no rows; with room on the frame stack (frame_stack.py)
    control[STOP] = 1  # (bdpt's lanes go over the image's rows, not the window's: no row at all)
    on_roomy_frame_stack(lane_job, 0, (window[0], window[1], window[2], window[1]))
    if bidirectional:  # the glint guide's kernel, on no rows
        on_roomy_frame_stack(bdpt_glint_guide, S, X, image_pass, bd.bounds, np.zeros((1, 1)), (0, 0))
    film.compile_rgb()
    control[:] = 0  # (that claimed a row of the empty window)
    status("rendering")
    total = rows * (1 if aov else 0) + image_rows
    pool = lane_pool(lanes)
    t0 = time.perf_counter()
    if bidirectional:  # made by the film's first pass, in the render's time
        bd = bd._replace(glint=glint_cdf(S, film, bd.strategy, glint_guide))
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
        partial = Image(film.rgb(), aov, {}, settings.encoding, exposure=settings.exposure, tonemap=settings.tonemap)
        done = int(rows_done.sum()) - (rows if aov else 0)
        raise RenderInterrupted(partial, max(min(done, rows), 0)) from None
    kernel_seconds = time.perf_counter() - t0
    for future in futures:
        future.result()  # re-raises a lane's exception
    film.spp += spp
    film.rejected += int(rejected.sum())
    if bd is not None:
        counts = strategy_counts(bd.counts)
        for key, n in counts.items():
            film.strategies[key] = film.strategies.get(key, 0) + n
    return kernel_seconds, rays_per_row.sum() + aov_rays_per_row.sum() + pilot_rays
