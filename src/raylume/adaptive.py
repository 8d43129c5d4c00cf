"""Adaptive sampling: the image in tiles, each rendered in rounds of samples until its noise is
below `noise_threshold`, its pixels have `spp` samples, or `time_limit` seconds have passed.

A round renders the tiles still open with a few samples per pixel (`round_sizes`: the first
four ceil(spp / 256) each, at least 2, then a quarter more each round), split between two
streams: each pixel's samples are two low-discrepancy sequences of their own seeds
(`stream_seed`), A taking the round's first half and B the rest, and each round continues both
where the round before stopped (`render_window`'s `first` and `sums`). Any prefix of a
sequence is an unbiased, stratified estimate, so a pixel that stops after any round holds an
unbiased mean, with the stratification of its two sequences over all its rounds. (Rounds that
each began a sequence of their own, as the first version's did, were stratified within a
round only: that lost most of the low-discrepancy sampler's gain.)

The two streams are independent estimates of the pixel, so their difference measures its
noise, as Cycles' half buffer does: with n_A and n_B samples and means m_A and m_B, the mean of
all N has the variance var(m_A - m_B) n_A n_B / N^2 (the sequences' own convergence included,
whatever its rate), and |m_A - m_B| sqrt(pi / 2) estimates the standard deviation of the
difference. A pixel's error is Cycles' measure with that standard error: the errors of r, g and
b summed, over 1e-4 + the square root of the pixel's summed mean (noise in the dark counts
more). One pixel's estimate is one absolute difference; a tile stops when the mean error of its
pixels falls below the threshold, judged from its `FIRST_CHECK`-th round on and once it has
`least_spp` samples (Cycles' minimum: a tile whose first samples found no rare bright path
shows no difference for it). Dammertz et al., "A hierarchical automatic stopping condition for
Monte Carlo global illumination" (WSCG 2010), stop in blocks as well, for the same reason.

Stopping on an estimate of the noise is biased where a tile's first samples miss rare bright
paths (caustics seen by path tracing: a tile that found none stops dark); `min_spp` raises the
samples every tile takes first.

The decisions depend only on the streams' sums, which depend on neither threads nor tiles:
the image depends on the scene, seed, spp, min_spp and threshold. A `time_limit` is checked between
windows (after the first round, a tile row each) against the render time spent, so with one
the image depends on the machine's speed too; it stays unbiased, as every tile holds whole
rounds."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from .compile import CompiledScene
from .image import Image
from .kernels.film.film import film_rgb_numpy
from .render_window import RenderInterrupted, WindowResult, allocate_aovs, render_window
from .scene.checks import warn
from .scene.model import Camera, RenderSettings

TILE = 16  # side of a tile in pixels: what stops as one (tile_edges: a sliver at the end joins its neighbour)
FIRST_SHARE = 256  # the first rounds take ceil(spp / 256) samples a pixel each (at least 2)
FIRST_CHECK = 4  # rounds a tile takes before its noise is judged
GROWTH = 4  # a later round adds a quarter of the samples taken so far
ERROR_FLOOR = 1e-4  # Cycles' epsilon under the square root of the pixel's brightness

STREAMS = 2  # sequences a pixel: their difference is its noise
_GOLDEN = 0x9E3779B97F4A7C15
_MASK64 = (1 << 64) - 1


def stream_seed(seed: int, stream: int) -> int:
    """The seed of stream `stream` (the first keeps the render's own)."""
    if stream == 0:
        return seed
    x = (seed * _GOLDEN + stream) & _MASK64  # splitmix64's finaliser
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & _MASK64
    return (x ^ (x >> 31)) & 0xFFFFFFFF


def stream_sizes(size: int) -> tuple[int, int]:
    """A round's samples per pixel for streams A and B: A the larger half."""
    return (size + 1) // 2, size // 2


def least_spp(settings: RenderSettings) -> int:
    """The samples every pixel takes before its tile may stop: `min_spp`, or else Cycles' rule
    of thumb, ceil(16 / threshold^0.3) and at least 4 (32 at 0.1, 40 at 0.05, 64 at 0.01): a
    tile that has seen no rare bright path in its first samples has no spread to show for it,
    and would stop dark."""
    if settings.min_spp is not None:
        return min(settings.min_spp, settings.spp)
    if settings.noise_threshold is None:
        return settings.spp
    return min(max(4, math.ceil(16.0 / settings.noise_threshold**0.3)), settings.spp)


def round_sizes(spp: int) -> list[int]:
    """Samples per pixel of each round, adding up to spp: FIRST_CHECK rounds of
    ceil(spp / FIRST_SHARE) samples, at least 2, then each round a quarter of the samples taken
    so far (so a tile takes at most a quarter more than it needed), the last what is left. No
    round takes one sample while spp > 1: both streams take a sample of every round."""
    if spp == 1:
        return [1]
    first = max(2, -(-spp // FIRST_SHARE))
    sizes: list[int] = []
    taken = 0
    while taken < spp:
        size = first if len(sizes) < FIRST_CHECK else max(first, -(-taken // GROWTH))
        size = min(size, spp - taken)
        if spp - taken - size == 1:
            size += 1  # no round of one left over
        sizes.append(size)
        taken += size
    return sizes


class _Streams:
    """A window's two streams: each one's film sums (as render_window continues them) and the
    samples it holds per pixel."""

    def __init__(self, h: int, w: int):
        self.sums: list[np.ndarray | None] = [None] * STREAMS  # made by the first round
        self.taken = np.zeros((STREAMS, h, w), dtype=np.int64)

    @property
    def samples(self) -> np.ndarray:
        """(h, w): the samples each pixel holds."""
        return self.taken.sum(axis=0)

    def window_sums(self, stream: int, rows: slice, cols: slice) -> np.ndarray | None:
        """The stream's sums of a window, for render_window to continue (None before any)."""
        sums = self.sums[stream]
        return None if sums is None else np.ascontiguousarray(sums[rows, cols])

    def add(self, stream: int, rows: slice, cols: slice, sums: np.ndarray, n: int) -> None:
        """The window's sums after n more samples of the stream."""
        if self.sums[stream] is None:
            h, w = self.taken.shape[1:]
            self.sums[stream] = np.zeros((h, w, sums.shape[2]))
        self.sums[stream][rows, cols] = sums
        self.taken[stream, rows, cols] += n

    def mean(self) -> np.ndarray:
        """(h, w, 3) float32: every sample's filter-weighted mean, as one film of them all."""
        held = [sums for sums in self.sums if sums is not None]
        return film_rgb_numpy(held[0] if len(held) == 1 else held[0] + held[1])

    def standard_error(self) -> np.ndarray:
        """(h, w, 3): each pixel's standard error of its mean from the streams' difference,
        |m_A - m_B| sqrt(pi / 2) sqrt(n_A n_B) / N (module docstring); inf where a stream holds
        no sample."""
        h, w = self.taken.shape[1:]
        if any(sums is None for sums in self.sums):
            return np.full((h, w, 3), np.inf)
        a, b = (film_rgb_numpy(sums).astype(np.float64) for sums in self.sums)
        n_a, n_b = self.taken.astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(n_a * n_b > 0, math.sqrt(math.pi / 2) * np.sqrt(n_a * n_b) / (n_a + n_b), np.inf)
        return np.abs(a - b) * scale[..., None]

    def pixel_error(self) -> np.ndarray:
        """Each pixel's error (module docstring): its standard errors of r, g and b summed,
        over 1e-4 + the square root of its summed mean."""
        noise = self.standard_error().sum(axis=2)
        brightness = np.maximum(self.mean().astype(np.float64).sum(axis=2), 0.0)
        return noise / (ERROR_FLOOR + np.sqrt(brightness))


def tile_edges(size: int) -> np.ndarray:
    """The tiles' edges along one side of `size` pixels, from 0: every TILE, except that a last
    tile of less than TILE / 2 joins the one before (a tile a pixel or two wide has too few
    pixels for its mean error: a QA run found such slivers stopping above the threshold in 14%
    of cases, against none of the whole tiles)."""
    edges = [*range(0, size, TILE), size]
    if len(edges) > 2 and edges[-1] - edges[-2] < TILE // 2:
        del edges[-2]
    return np.array(edges)


def tile_areas(h: int, w: int) -> np.ndarray:
    """The pixels in each tile of an h x w window."""
    return np.diff(tile_edges(h))[:, None] * np.diff(tile_edges(w))[None, :]


def tile_errors(pixel_error: np.ndarray) -> np.ndarray:
    """The mean pixel error of each tile of the window (tile_edges)."""
    h, w = pixel_error.shape
    rows = np.add.reduceat(pixel_error, tile_edges(h)[:-1], axis=0)
    return np.add.reduceat(rows, tile_edges(w)[:-1], axis=1) / tile_areas(h, w)


def open_windows(
    open_tiles: np.ndarray, window: tuple[int, int, int, int], join_rows: bool = True
) -> list[tuple[int, int, int, int]]:
    """The windows (x0, x1, y0, y1) that cover the open tiles: each tile row's runs of open
    tiles, runs repeated in consecutive tile rows joined into one taller window when
    `join_rows` (every tile open: one window, the whole)."""
    x0, x1, y0, y1 = window
    xs, ys = x0 + tile_edges(x1 - x0), y0 + tile_edges(y1 - y0)
    rows = []
    for row in open_tiles:
        edges = np.flatnonzero(np.diff(np.concatenate(([0], row.astype(np.int8), [0]))))
        rows.append(tuple(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True)))
    windows = []
    start = 0
    for ty in range(1, len(rows) + 1):
        if join_rows and ty < len(rows) and rows[ty] == rows[start]:
            continue
        for a, b in rows[start]:
            windows.append((int(xs[a]), int(xs[b]), int(ys[start]), int(ys[ty])))
        start = ty
    return windows


def render_adaptive(
    compiled: CompiledScene,
    camera: Camera,
    settings: RenderSettings,
    window: tuple[int, int, int, int],
    *,
    aovs: bool,
    lanes: int,
    progress: Callable[[int, int], None] | None = None,
    status: Callable | None = None,
    quiet: bool = False,
) -> WindowResult:
    """Render `window` = (x0, x1, y0, y1) adaptively (module docstring). The result's `aovs`
    hold `spp`, the samples each pixel took (float32; with the others when `aovs`), and its
    `adaptive` the statistics. `quiet`: no warnings about the rounds (a cluster's tasks: the
    client gives them once).

    The tiles lie on the whole image's grid, so a crop renders the tiles its window touches
    whole and keeps its window: each tile stops as it does in the whole image, and the crop is
    that window of the whole adaptive render (as a crop of a plain render is)."""
    x0, x1, y0, y1 = window
    xs, ys = tile_edges(settings.width), tile_edges(settings.height)  # the whole image's grid
    grid = (int(xs[xs <= x0].max()), int(xs[xs >= x1].min()), int(ys[ys <= y0].max()), int(ys[ys >= y1].min()))
    part = _render_tiles(
        compiled, camera, settings, grid, aovs=aovs, lanes=lanes, progress=progress, status=status, quiet=quiet
    )
    if grid == window:
        return part
    rows, cols = slice(y0 - grid[2], y1 - grid[2]), slice(x0 - grid[0], x1 - grid[0])
    crop_aovs = {name: np.ascontiguousarray(array[rows, cols]) for name, array in part.aovs.items()}
    stats = {**part.adaptive, **samples_taken(crop_aovs["spp"])}
    rgb = np.ascontiguousarray(part.rgb[rows, cols])
    return WindowResult(window, rgb, crop_aovs, part.seconds, part.rays, part.rejected, adaptive=stats)


def _judged_rounds(settings: RenderSettings) -> set[int]:
    """The rounds after which a tile may stop: from the FIRST_CHECK-th, once it has least_spp."""
    taken = np.cumsum(round_sizes(settings.spp))
    least = least_spp(settings)
    return {r for r in range(FIRST_CHECK - 1, len(taken)) if taken[r] >= least}


def warn_about_rounds(settings: RenderSettings) -> None:
    """A SceneWarning where the settings leave adaptive sampling nothing to do: no tile can stop
    before its last round, or a time limit with one round."""
    sizes = round_sizes(settings.spp)
    if settings.noise_threshold is not None and not _judged_rounds(settings) - {len(sizes) - 1}:
        rounds = f"{len(sizes)} round{'s' if len(sizes) > 1 else ''}"
        warn(
            f"noise_threshold judges a tile from its {FIRST_CHECK}th round and {least_spp(settings)} samples a pixel "
            f"on; spp {settings.spp} is {rounds}, so every pixel takes them all (spp is the most a pixel takes: give "
            "it more)"
        )
    if settings.time_limit is not None and len(sizes) == 1:
        warn(
            f"time_limit with spp {settings.spp}: one round renders the whole image (spp is the most samples a "
            "pixel takes: give it 1024 or more)"
        )


def _render_tiles(
    compiled: CompiledScene,
    camera: Camera,
    settings: RenderSettings,
    window: tuple[int, int, int, int],
    *,
    aovs: bool,
    lanes: int,
    progress: Callable[[int, int], None] | None,
    status: Callable | None,
    quiet: bool,
) -> WindowResult:
    """render_adaptive on a window whose corner lies on the tile grid."""
    x0, x1, y0, y1 = window
    h, w = y1 - y0, x1 - x0
    sizes = round_sizes(settings.spp)
    threshold, time_limit = settings.noise_threshold, settings.time_limit
    taken = np.cumsum(sizes)  # samples a pixel has after each round
    judged = _judged_rounds(settings)
    if not quiet:
        warn_about_rounds(settings)
    streams = _Streams(h, w)
    # each stream a sequence of its own seed, of spp samples at most
    tables = [settings.model_copy(update={"seed": stream_seed(settings.seed, k)}) for k in range(STREAMS)]
    per_round = np.array([stream_sizes(n) for n in sizes]).T  # (stream, round): samples a pixel
    stream_first = np.cumsum(per_round, axis=1) - per_round  # where each round starts in each sequence
    th, tw = len(tile_edges(h)) - 1, len(tile_edges(w)) - 1
    open_tiles = np.ones((th, tw), dtype=bool)
    aov_arrays = allocate_aovs(h, w) if aovs else {}
    seconds = 0.0  # the kernels' (render_seconds)
    spent = 0.0  # what a time limit counts: the kernels and the noise checks
    rays = rejected = 0
    planned = h * w * settings.spp
    done = 0
    stopped_by = "spp"
    rounds_done = 0

    window_started = time.perf_counter()
    shown = 0  # progress only moves on

    def report(extra: int = 0) -> None:
        """Progress in pixel samples; with a time limit, the time spent if it is further on."""
        nonlocal shown
        if progress is None:
            return
        reached = done + extra
        if time_limit is not None:
            reached = max(reached, int(planned * (spent + time.perf_counter() - window_started) / time_limit))
        shown = max(shown, min(reached, planned))
        progress(shown, planned)

    def out_of_time(r: int) -> bool:
        return r > 0 and time_limit is not None and spent >= time_limit

    try:
        for r, n in enumerate(sizes):
            if not open_tiles.any():
                break
            if out_of_time(r):
                stopped_by = "time"
                break
            # a time limit is checked between windows: after the first round (one window, the
            # whole), a tile row each, so that it stops within one's time
            for win in open_windows(open_tiles, window, join_rows=time_limit is None or r == 0):
                if out_of_time(r):
                    stopped_by = "time"
                    break  # the tiles left keep the rounds they have
                area = (win[1] - win[0]) * (win[3] - win[2])
                rows, cols = slice(win[2] - y0, win[3] - y0), slice(win[0] - x0, win[1] - x0)
                before = 0  # the round's samples a pixel of the window already has
                for k, count in enumerate(stream_sizes(n)):
                    if count == 0:
                        continue  # spp 1: one sample, at the pixel's centre

                    def window_progress(done_rows: int, total: int, area=area, count=count, before=before) -> None:
                        report(area * (before + count * done_rows // max(total, 1)))

                    window_started = time.perf_counter()
                    part = render_window(
                        compiled, camera, tables[k], win, aovs=aovs and r == 0 and k == 0, lanes=lanes,
                        progress=window_progress, status=status, first=int(stream_first[k, r]), count=count,
                        sums=streams.window_sums(k, rows, cols), cone_spp=settings.spp, keep_sums=True,
                    )  # fmt: skip
                    window_started = time.perf_counter()
                    streams.add(k, rows, cols, part.sums, count)
                    for name, array in part.aovs.items():
                        aov_arrays[name][rows, cols] = array
                    seconds += part.seconds
                    spent += part.seconds
                    rays += part.rays
                    rejected += part.rejected
                    before += count
                done += area * n
                report()
            if stopped_by == "time":
                break
            rounds_done = r + 1
            if threshold is not None and r in judged:
                started = time.perf_counter()
                closing = open_tiles & (tile_errors(streams.pixel_error()) < threshold)
                open_tiles &= ~closing
                done += int(tile_areas(h, w)[closing].sum()) * (settings.spp - int(taken[r]))
                spent += time.perf_counter() - started
                report()
    except KeyboardInterrupt as exc:
        least = int(streams.samples.min())
        if least == 0:
            raise  # in the first round, one window: its rows done, as a plain render's
        whole = int(np.searchsorted(taken, least, side="right"))  # rounds every pixel has (the last may have ended)
        done_aovs = {**aov_arrays, "spp": streams.samples.astype(np.float32)}
        partial = Image(
            streams.mean(), done_aovs, {}, settings.encoding, exposure=settings.exposure, tonemap=settings.tonemap
        )
        raise RenderInterrupted(partial, h, f"{whole} rounds, {least} or more samples in every pixel") from exc
    samples = streams.samples
    aov_arrays["spp"] = samples.astype(np.float32)  # asked for or not: it costs nothing
    converged = int((~open_tiles).sum())
    stats = adaptive_stats(settings, samples, rounds_done, th * tw, converged, out_of_time=stopped_by == "time")
    return WindowResult(window, streams.mean(), aov_arrays, seconds, rays, rejected, adaptive=stats)


def adaptive_stats(
    settings: RenderSettings, spp: np.ndarray, rounds: int, tiles: int, converged: int, out_of_time: bool = False
) -> dict:
    """An adaptive render's statistics (a cluster's: its tasks' together), from the samples each
    pixel took, the rounds, the tiles and those that converged: stopped by the time limit, by
    noise where every tile converged and some pixel took fewer than spp (tiles below the
    threshold only once they took every sample stopped by spp), else by spp."""
    if out_of_time:
        stopped_by = "time"
    elif settings.noise_threshold is not None and converged == tiles and int(spp.min()) < settings.spp:
        stopped_by = "noise"
    else:
        stopped_by = "spp"
    return {
        "noise_threshold": settings.noise_threshold,
        "time_limit": settings.time_limit,
        "tile": TILE,
        "round_spp": round_sizes(settings.spp)[0],
        "rounds": rounds,
        **samples_taken(spp),
        "tiles": tiles,
        "tiles_converged": converged,
        "stopped_by": stopped_by,
    }


def samples_taken(spp: np.ndarray) -> dict:
    """The statistics of the samples each pixel took: their sum, mean, least and most."""
    return {
        "samples": int(spp.sum()),
        "mean_spp": float(spp.mean(dtype=np.float64)),
        "min_spp": int(spp.min()),
        "max_spp": int(spp.max()),
    }


__all__ = [
    "FIRST_CHECK",
    "TILE",
    "adaptive_stats",
    "render_adaptive",
    "round_sizes",
    "stream_seed",
    "stream_sizes",
    "tile_errors",
]
