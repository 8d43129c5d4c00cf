"""Rendering on a Dask distributed cluster, bit-identical to the in-process render.

    client side                                      each worker
    connect(address) -> Client, versions checked
    scatter(compiled scene, broadcast) ------------> held in worker memory (no scene files)
    _warm(...) pinned to each worker --------------> load/compile kernels, time a probe window
    plan_tiles(): tiles of ~TILE_SECONDS each,
      split into chained sample passes if needed
    submit _render_tile per tile and pass ---------> render_window(window, passes)
    paste each finished tile into the image <------- WindowResult (rgb, AOVs, stats)

Every pixel's value depends only on (scene, camera, settings, seed): the sampler is keyed on
(seed, pixel, sample), so a tile renders the same bits wherever it runs. Passes of one tile are
chained (pass k starts from the film sums of pass k-1), so the samples of a pixel are summed
in sample order, as one in-process pass would; tiles cover disjoint pixels, so the order in
which they finish does not matter. A worker that dies loses only the tasks it held: Dask runs
them again elsewhere, from the same inputs, to the same bits.
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import logging
import math
import os
import pickle
import re
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import CancelledError
from dataclasses import dataclass

import numpy as np

from .compile import CompiledScene
from .errors import RaylumeError
from .image import Image
from .render_window import RenderInterrupted, WindowResult, allocate_aovs, render_window
from .scene.model import Camera, RenderSettings
from .settings import ResolvedSettings, samples_adaptively

CONNECT_TIMEOUT = 4.0  # seconds: an unreachable scheduler is reported well within 10 s
TILE_SECONDS = 1.0  # a task's target run time: long enough to hide its overhead, short enough to balance
MIN_TILE_SIDE = 8  # pixels
TILES_PER_WORKER = 4  # a still is split into at least this many tiles per worker
PROBE_SIDE = 32  # the probe window that measures the cost of a sample on a worker
POLL_SECONDS = 0.05
SCENE_RESENDS = 3  # times tasks may be cancelled (the scene lost) and the scene sent again, in one render
WORKER_WAIT = 60.0  # seconds to wait for a worker to come back when the scene must be sent again
# What must match between the client and every worker for the image to be bit-identical: the
# kernels' source, and the compiler and array library that turn them into machine code.
BIT_KEYS = ("raylume", "kernels", "numba", "llvmlite", "numpy")


class ClusterError(RaylumeError):
    """The cluster cannot render: unreachable, no workers, mismatched versions, tasks lost."""


# --- connecting -----------------------------------------------------------------------------

# Ctrl-C in a terminal signals the whole foreground process group: local worker processes that
# received it died printing a KeyboardInterrupt traceback each (about 67 lines for two) after
# raylume's one line. This process cancels their tasks and stops them; they leave SIGINT to it:
# blocked from their start (_without_sigint) and ignored once set up (this preload, given as its
# text). Their ERROR logs are muted too: one interrupted as it warmed up could outlive the
# scheduler (in this process) by a heartbeat and log its failure; what goes wrong on a worker
# reaches the user as raylume's error.
LOCAL_WORKER_SETUP = (
    "import logging, signal; signal.signal(signal.SIGINT, signal.SIG_IGN); "
    "logging.getLogger('distributed').setLevel(logging.CRITICAL)  # raylume: the client stops this worker"
)

_clients: dict[str, object] = {}  # address or "local:N" -> Client, reused by later renders
_local_clusters: list = []


def parse_address(text: str) -> tuple[str, int | str]:
    """("local", N) for `local` / `local:N`, ("remote", address) for SCHEME://HOST:PORT."""
    text = str(text).strip()
    if text == "local":
        return "local", os.cpu_count() or 1
    match = re.fullmatch(r"local:(\d+)", text)
    if match:
        n = int(match.group(1))
        if not 1 <= n <= 1024:
            raise ClusterError(f"--cluster {text}: the number of local workers must be 1..1024")
        return "local", n
    match = re.fullmatch(r"(tcp|tls|ws|wss)://(\[[0-9A-Fa-f:.]+\]|[^\s/:\[\]]+):(\d{1,5})", text)  # host or [IPv6]
    if match and 1 <= int(match.group(3)) <= 65535:  # (port 99999 had waited for a refusal)
        return "remote", text
    raise ClusterError(
        f"--cluster {text}: expected a Dask scheduler's address tcp://HOST:PORT (as `dask scheduler` prints it), "
        "`local` (a local cluster of one worker process per core) or `local:N` (N worker processes)"
    )


def connect(cluster) -> object:
    """A distributed.Client for `cluster`: an address, `local`, `local:N`, or a Client (returned
    as it is). Clients of addresses are kept for later renders; local clusters started here are
    closed when the program exits. A scheduler that does not answer within CONNECT_TIMEOUT, or
    has no worker, is a ClusterError."""
    from distributed import Client

    # distributed registered its own exit handlers as it was imported (just now, the first
    # time), and they run before those registered earlier: _close_all, registered again, runs
    # first, muting the scheduler's "lose scattered data" ERROR as the local workers stop.
    atexit.unregister(_close_all)
    atexit.register(_close_all)
    if isinstance(cluster, Client):
        return cluster
    kind, value = parse_address(cluster)
    key = f"local:{value}" if kind == "local" else str(value)
    client = _clients.get(key)
    if client is not None and client.status == "running":
        return client
    if kind == "local":
        from distributed import LocalCluster

        try:
            local = _without_sigint(
                lambda: LocalCluster(
                    n_workers=int(value),
                    threads_per_worker=1,  # one tile at a time per process: the kernels use one core each
                    processes=True,
                    dashboard_address=":0",  # a free port: 8787 may be taken by another cluster
                    silence_logs=logging.ERROR,
                    preload=[LOCAL_WORKER_SETUP],
                )
            )
        except BaseException:  # Ctrl-C while the workers start: leave quietly, exit 130
            _abandon_half_started_clusters()
            raise
        _local_clusters.append(local)
        client = Client(local, set_as_default=False)
    else:
        _probe(value)  # a scheduler answers there, or a ClusterError now, within CONNECT_TIMEOUT + 1 s
        try:
            client = Client(value, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except Exception as exc:  # it stopped answering since the probe
            raise ClusterError(
                f"--cluster {value}: no Dask scheduler answered there within {CONNECT_TIMEOUT:g} s ({exc}); "
                f"start one with `dask scheduler` and workers with `dask worker {value}`, or use --cluster local"
            ) from None
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
        except Exception:
            client.close()
            raise ClusterError(
                f"--cluster {value}: the scheduler has no workers; start some with `dask worker {value}`"
            ) from None
    _clients[key] = client
    return client


def _without_sigint(start: Callable[[], object]) -> object:
    """start() on a thread of its own that blocks SIGINT, waited for here, where Ctrl-C still
    raises KeyboardInterrupt. What it starts inherits the mask: the local cluster's event loop
    thread, and through it the worker processes its nannies spawn, now and when they restart one
    (a blocked signal stays blocked across fork and exec), so a Ctrl-C while they start up, before
    LOCAL_WORKER_SETUP runs in them, does not kill them mid-import either. multiprocessing's
    resource tracker, launched with the first process, unblocks SIGINT in the thread launching it:
    it is launched from here first."""
    import signal
    import threading

    if not hasattr(signal, "pthread_sigmask"):  # Windows: no signal masks, no process groups
        return start()
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    outcome: dict = {}

    def run():
        try:
            outcome["value"] = start()
        except BaseException as exc:  # noqa: BLE001 - raised again on the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=run, name="raylume-local-cluster", daemon=True)
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        thread.start()  # a new thread inherits its creator's signal mask
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
    while thread.is_alive():
        thread.join(0.1)  # short waits: a KeyboardInterrupt is raised between them
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


HANDSHAKE_GRACE = 1.0  # seconds past CONNECT_TIMEOUT that a connected listener has to answer


def _probe(address: str) -> None:
    """Connect to `address`, say hello as Dask does and ask who answers, all within
    CONNECT_TIMEOUT + HANDSHAKE_GRACE seconds; a ClusterError unless a Dask scheduler answers.

    distributed's Client bounds its connection attempts but not the handshake after them: a
    listener that accepts and stays silent (any other server waiting for its client to speak)
    would hang it forever, and one that answers other bytes fails it with a misleading error
    (their first 8 bytes read as a length: "Unable to allocate 3 EiB") and a Client left half
    started. This probe runs on a loop and thread of its own, so that it can be abandoned."""
    import asyncio
    import threading

    from distributed.comm import connect as dask_connect

    outcome: dict = {}

    async def hello():
        comm = await dask_connect(address, timeout=CONNECT_TIMEOUT)  # retried until CONNECT_TIMEOUT
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    def run():
        try:
            outcome["answer"] = asyncio.run(asyncio.wait_for(hello(), CONNECT_TIMEOUT + HANDSHAKE_GRACE))
        except BaseException as exc:  # noqa: BLE001 - classified below, on the caller's thread
            outcome["error"] = exc

    thread = threading.Thread(target=run, name="raylume-probe", daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT + HANDSHAKE_GRACE + 1.0)  # the loop ends itself by then
    waited = f"{CONNECT_TIMEOUT + HANDSHAKE_GRACE:g} s"
    start_one = f"start one with `dask scheduler` and workers with `dask worker {address}`, or use --cluster local"
    error = outcome.get("error")
    answer = outcome.get("answer")
    if error is None and answer is None:  # the thread did not even end: treat as silent
        error = TimeoutError()
    if isinstance(error, (TimeoutError, asyncio.TimeoutError)):
        # connect() itself gives up on connecting after CONNECT_TIMEOUT with an OSError: a
        # timeout here is a connection accepted and a handshake never answered
        raise ClusterError(
            f"--cluster {address}: no Dask scheduler answered there within {waited}: something else is "
            "listening there (it accepted the connection but never answered as Dask does); "
            f"check the address and port, or {start_one}"
        )
    if type(error) is OSError and str(error).startswith("Timed out trying to connect"):
        cause = _root_cause(error)
        reason = f": {_reason(cause)}" if cause is not error else ""
        raise ClusterError(
            f"--cluster {address}: no Dask scheduler answered there within {CONNECT_TIMEOUT:g} s "
            f"(nothing accepted the connection{reason}); {start_one}"
        )
    if error is not None:
        raise ClusterError(
            f"--cluster {address}: something else than a Dask scheduler is listening there: it answered with "
            f"what is not Dask's protocol ({type(error).__name__}); check the address and port, or {start_one}"
        )
    kind = answer.get("type") if isinstance(answer, dict) else None
    if kind != "Scheduler":
        what = f"a Dask {kind}" if isinstance(kind, str) else "something other than a Dask scheduler"
        raise ClusterError(
            f"--cluster {address}: {what} answered there, not a scheduler; give the scheduler's address "
            "(as `dask scheduler` prints it)"
        )


def _root_cause(error: BaseException) -> BaseException:
    """The exception at the end of `error`'s chain of causes: distributed wraps the socket's error
    (a refused connection, a reset) in its own, whose text names internal objects."""
    while error.__cause__ is not None:
        error = error.__cause__
    return error


def _reason(error: BaseException) -> str:
    """An OSError's reason (its strerror: 'Connection refused'), else the exception's text."""
    if isinstance(error, OSError) and error.strerror:
        return error.strerror
    return str(error) or type(error).__name__


class _ReconnectLog(logging.Filter):
    """Drops distributed.client's report that it failed to reconnect to its scheduler, while a
    render runs (installed by FrameRenderer): the render raises an error that says so itself,
    and the log line, from the client's own thread, could come before or after that error."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("Failed to reconnect to scheduler")


_reconnect_log = _ReconnectLog()


@contextlib.contextmanager
def _no_reconnect_log():
    log = logging.getLogger("distributed.client")
    log.addFilter(_reconnect_log)
    try:
        yield
    finally:
        log.removeFilter(_reconnect_log)


def _abandon(client) -> None:
    """Close a client whose scheduler is gone, and forget it. Its reconnection loop, stopped by
    the close, logs "Failed to reconnect to scheduler" as an ERROR (with a traceback when cut
    short): the error raised says it already, so the client's log is muted while it closes."""
    for key, cached in list(_clients.items()):
        if cached is client:
            del _clients[key]
    log = logging.getLogger("distributed.client")
    level = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        client.close(timeout=2)
    except BaseException:  # noqa: BLE001 - whatever the close meets, the client is dropped
        pass
    finally:
        log.setLevel(level)


def _abandon_half_started_clusters() -> None:
    """Close the local clusters whose start was interrupted. Distributed closes them again at
    exit, and one interrupted mid-start fails an assertion there with a traceback on stderr;
    marked closed, it is skipped."""
    from distributed.core import Status
    from distributed.deploy.spec import SpecCluster

    for cluster in list(SpecCluster._instances):
        if cluster not in _local_clusters and getattr(cluster, "status", Status.closed) != Status.closed:
            try:
                cluster.close(timeout=2)
            except BaseException:
                pass
            cluster.status = Status.closed


@atexit.register
def _close_all() -> None:
    # At exit nothing is wanted any more, and raylume has said what it had to; but a client whose
    # close timed out (a loaded machine) still holds its scattered scene, and a local cluster's
    # scheduler, in this process, would log the scene's loss as an ERROR on stderr as its workers
    # stop, after a render that succeeded. After Ctrl-C, the client's last cancellations race its
    # close: the scheduler logged "Closed comm ... while trying to write" (CRITICAL), an
    # AssertionError handling them, and asyncio its "Task exception was never retrieved".
    logging.getLogger("distributed.scheduler").setLevel(logging.CRITICAL)
    if _clients or _local_clusters:
        muted = [name for name in logging.root.manager.loggerDict if name.startswith("distributed.")]
        for name in ("distributed", "asyncio", *muted):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    for client in _clients.values():
        try:
            client.close(timeout=2)
        except Exception:
            pass
    for local in _local_clusters:
        try:
            local.close(timeout=2)
        except Exception:
            pass
    _clients.clear()
    _local_clusters.clear()


@functools.cache
def versions() -> dict[str, str]:
    """This process's versions of what decides the image's bits (BIT_KEYS)."""
    import llvmlite
    import numba

    from ._version import __version__
    from .kernels import _kernel_source_hash

    return {
        "raylume": __version__,
        "kernels": _kernel_source_hash(),
        "numba": numba.__version__,
        "llvmlite": llvmlite.__version__,
        "numpy": np.__version__,
    }


def _mismatch(expected: dict, found: dict) -> list[str]:
    return [
        f"{key} {found.get(key)} (the client has {expected.get(key)})"
        for key in BIT_KEYS
        if found.get(key) != expected.get(key)
    ]


def _refusal(worker: str, differences: list[str]) -> str:
    return (
        f"worker {worker} is refused: {', '.join(differences)}. A different Numba, llvmlite, NumPy or raylume "
        "can compile the kernels into other machine code and the image would not be bit-identical to a local "
        "render; install the client's versions on every worker"
    )


def _failed_check(worker: str, error: BaseException) -> str:
    """A worker on which the version check itself failed: most often, raylume (or the Numba or
    NumPy it needs) cannot be imported there. distributed hands the worker's exception back as
    Exception("ImportError('No module named raylume')"): its text is what there is to go on."""
    text = str(error) or type(error).__name__
    if isinstance(error, ImportError) or "ImportError" in text or "ModuleNotFoundError" in text:
        return (
            f"worker {worker} is refused: raylume cannot be imported there ({text}); install the client's "
            "raylume, numba, llvmlite and numpy on every worker (the same versions, for bit-identical images)"
        )
    return f"worker {worker} is refused: the version check failed there ({text})"


def check_versions(client, expected: dict | None = None) -> None:
    """Refuse (ClusterError) a cluster any of whose workers runs other versions of BIT_KEYS."""
    expected = expected or versions()
    found = client.run(versions, on_error="return")  # a worker's failure is its entry, not a raise
    for worker, theirs in sorted(found.items()):
        if isinstance(theirs, BaseException):
            raise ClusterError(_failed_check(worker, theirs))
        differences = _mismatch(expected, theirs)
        if differences:
            raise ClusterError(_refusal(worker, differences))


def _check_here(expected: dict) -> str:
    """On a worker, before any work: refuse if this worker's versions differ (a worker may
    join after check_versions ran). Returns the worker's address."""
    differences = _mismatch(expected, versions())
    address = _worker_address()
    if differences:
        raise ClusterError(_refusal(address, differences))
    return address


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except ValueError:  # not on a worker (tests call the task functions directly)
        return "local"


# --- tasks that run on the workers ----------------------------------------------------------


def probe_window(settings: RenderSettings) -> tuple[int, int, int, int]:
    """The centre square (at most PROBE_SIDE pixels a side) whose render times a sample."""
    W, H = settings.width, settings.height
    w, h = min(W, PROBE_SIDE), min(H, PROBE_SIDE)
    x0, y0 = (W - w) // 2, (H - h) // 2
    return x0, x0 + w, y0, y0 + h


def _warm(compiled: CompiledScene, camera: Camera, settings: RenderSettings, expected: dict) -> dict:
    """A worker's first task: load (or compile) the kernels this render needs, then time one
    sample of the probe window. Returns the seconds per pixel-sample, and the compile time."""
    worker = _check_here(expected)
    marks: list[float] = []
    started = time.perf_counter()
    window = probe_window(settings)
    count = None if settings.mode == "raster" else 1
    result = render_window(
        compiled, camera, settings, window, aovs=False, lanes=1, count=count,
        status=lambda what, seconds=0.0: marks.append(time.perf_counter()),
    )  # fmt: skip
    compile_seconds = (marks[1] - marks[0]) if len(marks) >= 2 else 0.0
    x0, x1, y0, y1 = window
    pixels = (x1 - x0) * (y1 - y0)
    return {
        "worker": worker,
        "compile_seconds": compile_seconds,
        "warm_seconds": time.perf_counter() - started,
        "sample_seconds": max(result.seconds, 1e-9) / pixels,
    }


def _render_tile(
    compiled: CompiledScene,
    camera: Camera,
    settings: RenderSettings,
    window: tuple[int, int, int, int],
    first: int,
    count: int | None,
    previous: WindowResult | None,
    aovs: bool,
    expected: dict,
) -> WindowResult:
    """One pass (samples first..first+count-1) of one tile, continuing `previous`, the tile's
    pass before it (None for the first). AOVs are made in the first pass and carried on. With a
    noise threshold (adaptive sampling) the tile is one task that samples adaptively, its
    16 x 16 tiles on the whole image's grid, as in-process."""
    worker = _check_here(expected)
    if settings.noise_threshold is not None:
        from .adaptive import render_adaptive

        result = render_adaptive(compiled, camera, settings, window, aovs=aovs, lanes=1, quiet=True)
        result.cluster = {"passes": [(worker, result.seconds, result.rays)]}
        return result
    result = render_window(
        compiled, camera, settings, window, aovs=aovs and previous is None, lanes=1, first=first, count=count,
        sums=None if previous is None else previous.sums, splats=None if previous is None else previous.splats,
    )  # fmt: skip
    record = (worker, result.seconds, result.rays)
    if previous is not None:
        result.aovs = previous.aovs
        result.seconds += previous.seconds
        result.rays += previous.rays
        result.rejected += previous.rejected
    result.cluster = {"passes": [*(previous.cluster["passes"] if previous is not None else []), record]}
    return result


# --- planning -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Tile:
    window: tuple[int, int, int, int]  # x0, x1, y0, y1
    passes: tuple[tuple[int, int | None], ...]  # (first, count) of each pass, in sample order


def plan_tiles(
    window: tuple[int, int, int, int],
    settings: RenderSettings,
    sample_seconds: float,
    min_tiles: int = 1,
    tile_seconds: float | None = None,
) -> list[Tile]:
    """Split `window` into square tiles of about `tile_seconds` of work each (at the measured
    seconds per pixel-sample), at least `min_tiles` of them, and a tile's samples into passes
    when even a MIN_TILE_SIDE tile would take longer. Raster mode is one task: the rasterizer
    draws whole frames. With a noise threshold (adaptive sampling) a tile is one task whose edges
    lie on adaptive sampling's grid of the whole image, so that no grid tile is sampled twice."""
    tile_seconds = TILE_SECONDS if tile_seconds is None else tile_seconds
    if settings.mode == "raster":
        return [Tile(window, ((0, None),))]
    x0, x1, y0, y1 = window
    w, h = x1 - x0, y1 - y0
    spp = settings.spp
    total = w * h * spp * sample_seconds
    n_tiles = max(min_tiles, math.ceil(total / tile_seconds), 1)
    side = max(MIN_TILE_SIDE, int(math.sqrt(w * h / n_tiles)))
    if settings.noise_threshold is not None:
        return _grid_tiles(window, settings, side)
    side_x, side_y = min(side, w), min(side, h)
    tile_cost = side_x * side_y * spp * sample_seconds
    n_passes = min(spp, max(1, math.ceil(tile_cost / tile_seconds)))
    counts = [spp // n_passes + (1 if k < spp % n_passes else 0) for k in range(n_passes)]
    firsts = np.cumsum([0, *counts[:-1]])
    passes = tuple((int(f), int(c)) for f, c in zip(firsts, counts))
    tiles = []
    for ty in range(y0, y1, side_y):
        for tx in range(x0, x1, side_x):
            tiles.append(Tile((tx, min(tx + side_x, x1), ty, min(ty + side_y, y1)), passes))
    return tiles


def _grid_tiles(window: tuple[int, int, int, int], settings: RenderSettings, side: int) -> list[Tile]:
    """Tiles of about `side` pixels covering `window`, their edges on adaptive sampling's tile
    grid of the whole image (adaptive.tile_edges), each one adaptive task."""
    from .adaptive import TILE, tile_edges

    x0, x1, y0, y1 = window
    step = max(1, round(side / TILE))  # grid tiles a side

    def cuts(lo: int, hi: int, size: int) -> list[int]:
        inside = [int(e) for e in tile_edges(size)[::step] if lo < e < hi]
        return [lo, *inside, hi]

    xs, ys = cuts(x0, x1, settings.width), cuts(y0, y1, settings.height)
    return [
        Tile((xa, xb, ya, yb), ((0, None),))
        for ya, yb in zip(ys[:-1], ys[1:], strict=True)
        for xa, xb in zip(xs[:-1], xs[1:], strict=True)
    ]


# --- the client side ------------------------------------------------------------------------


@dataclass
class _Frame:
    key: object
    camera: Camera
    tiles: list[Tile]
    finals: dict  # future key -> (future, Tile), until the tile's last pass is in
    results: list  # (Tile, WindowResult) of the tiles done


class FrameRenderer:
    """Distributed renders of one or more frames (cameras) of one scene and settings: the
    scene scattered once, the workers warmed once, then each frame planned into tiles and
    passes. `frames(cameras)` yields (key, WindowResult) in the order given, rendering several
    frames at once; `partial()` is the first unfinished frame's tiles done so far (after
    Ctrl-C); `stats()` the cluster's statistics, per worker too."""

    def __init__(
        self,
        cluster,
        compiled: CompiledScene,
        settings: ResolvedSettings,
        *,
        aovs: bool = False,
        progress: Callable[[int, int], None] | None = None,
        min_tiles: int = 1,
        ahead: int | None = None,
        shuffle=None,
        frames: int = 1,
    ):
        self.client = connect(cluster)
        # how the user named the cluster, for errors: the address given, or the scheduler's
        self.label = cluster if isinstance(cluster, str) else getattr(self.client.scheduler, "address", "")
        try:
            with _no_reconnect_log():
                self._start(compiled, settings, aovs, progress, min_tiles, ahead, shuffle, frames)
        except OSError as exc:  # the scheduler gone: CommClosedError, a connection timed out
            raise self._scheduler_lost(exc) from None

    def _start(self, compiled, settings, aovs, progress, min_tiles, ahead, shuffle, frames) -> None:
        self.frames_expected = frames  # for the progress bar's total before all are submitted
        # what the workers get: the [render] table, with a noise threshold where the tiles sample
        # adaptively (not raster mode nor bdpt), and no time limit (its tiles share no clock)
        table = settings.render
        adaptive = samples_adaptively(table, on_cluster=True)
        self.adaptive = adaptive
        self.settings = table.model_copy(
            update={"time_limit": None, "noise_threshold": table.noise_threshold if adaptive else None}
        )
        if adaptive:  # once, here: the workers' tasks are quiet
            from .adaptive import warn_about_rounds

            warn_about_rounds(self.settings)
        self.window = settings.window
        self.aovs = aovs
        self.progress = progress
        self.min_tiles = min_tiles
        self.shuffle = shuffle  # a random.Random: tiles start in a shuffled order (tests)
        self.threads = max(1, int(sum(self.client.nthreads().values())))
        self.ahead = ahead or max(2, 2 * self.threads)
        self.started = time.perf_counter()
        self.expected = versions()
        check_versions(self.client, self.expected)
        self.scene_bytes = len(pickle.dumps(compiled, protocol=5))
        # Shipped to every worker once, now; tasks name it, so no tile carries the scene.
        self.compiled = compiled
        [self.scene] = self.client.scatter([compiled], broadcast=True, hash=False)
        self.scene_resends = 0
        self.pending: set = set()  # every submitted, unfinished future (passes too)
        self.warm_futures: list = []
        self.warm_workers: dict = {}  # warm-up task's key -> the worker it is pinned to
        self.warm_up_retries = 0
        self.warm: dict = {}
        self.sample_seconds: float | None = None
        self.first_tile_seconds: float | None = None
        self.tasks_done = 0
        self.tasks_total = 0
        self.frames_submitted = 0
        self.tiles = 0
        self.finish_order: list[tuple[object, tuple]] = []  # (frame, tile window) as they finished
        self.records: list = []  # (worker, seconds, rays) of every pass
        self.in_flight: list[_Frame] = []

    def frames(self, cameras: Iterable[tuple[object, Camera]]) -> Iterator[tuple[object, WindowResult]]:
        cameras = iter(cameras)
        try:
            with _no_reconnect_log():
                yield from self._frames(cameras)
        except OSError as exc:  # the scheduler gone: CommClosedError, a connection timed out
            raise self._scheduler_lost(exc) from None
        finally:
            self.cancel()

    def _frames(self, cameras: Iterator[tuple[object, Camera]]) -> Iterator[tuple[object, WindowResult]]:
        exhausted = False
        while True:
            while not exhausted and len(self.in_flight) < self.ahead:
                item = next(cameras, None)
                if item is None:
                    exhausted = True
                    break
                if self.sample_seconds is None:
                    self.sample_seconds = self._warm_up(item[1])
                self.in_flight.append(self._submit(*item))
                self._report()
            if not self.in_flight:
                return
            self._poll()
            while self.in_flight and not self.in_flight[0].finals:
                frame = self.in_flight.pop(0)
                yield frame.key, self._combine(frame)

    def _warm_up(self, camera: Camera) -> float:
        """Warm every worker's kernels (a task pinned to it, before its tiles); wait for the
        first and return its seconds per pixel-sample."""
        self._submit_warm_ups(camera)
        checked = time.monotonic()
        while True:
            for future in self.warm_futures:
                if future.status == "finished":
                    try:
                        info = future.result()
                    except CancelledError:  # lost with the scene since
                        continue
                    self.warm[info["worker"]] = info
                    return info["sample_seconds"]
                if future.status == "error":
                    future.result()  # raises the worker's error (a refused version, ...)
            if time.monotonic() - checked > 10 * POLL_SECONDS:  # asks the scheduler: not every poll
                checked = time.monotonic()
                self._require_scheduler()
                if self._warm_ups_stranded():
                    self._warm_up_again(camera)
            time.sleep(POLL_SECONDS / 5)

    def _submit_warm_ups(self, camera: Camera) -> None:
        for address in self.client.nthreads():
            future = self.client.submit(
                _warm, self.scene, camera, self.settings, self.expected,
                workers=[address], allow_other_workers=False, pure=False, priority=100,
            )  # fmt: skip
            self.warm_futures.append(future)
            self.warm_workers[future.key] = address

    def _warm_ups_stranded(self) -> bool:
        """Whether no warm-up task can finish any more: each one cancelled (the scene lost) or
        pinned to a worker that has left (a restarted worker comes back at another address).
        Also true when there were no workers to warm."""
        workers = self.client.nthreads()
        return all(
            f.status == "cancelled" or (f.status != "finished" and self.warm_workers[f.key] not in workers)
            for f in self.warm_futures
        )

    def _warm_up_again(self, camera: Camera) -> None:
        """The workers left (or the scene went with them) during the warm-up: send the scene
        again if it was lost, and warm the workers there are now."""
        scene_lost = any(f.status == "cancelled" for f in self.warm_futures)
        self.client.cancel(self.warm_futures, force=True)
        self.warm_futures.clear()
        if scene_lost:
            self._resend_scene()  # counts against SCENE_RESENDS, waits for a worker
        else:
            self.warm_up_retries += 1
            if self.warm_up_retries > SCENE_RESENDS:
                raise ClusterError(
                    f"the workers left during the warm-up {SCENE_RESENDS} times in this render; "
                    "the cluster's workers keep dying"
                )
            self._wait_for_a_worker("the workers left during the warm-up")
        self._submit_warm_ups(camera)

    def _submit(self, key, camera: Camera) -> _Frame:
        tiles = plan_tiles(self.window, self.settings, self.sample_seconds, self.min_tiles)
        order = list(range(len(tiles)))
        if self.shuffle is not None:
            self.shuffle.shuffle(order)
        finals = {}
        for rank, index in enumerate(order):
            final = self._submit_tile(camera, tiles[index], -rank if self.shuffle is not None else 0)
            finals[final.key] = (final, tiles[index])
        self.tiles += len(tiles)
        self.frames_submitted += 1
        return _Frame(key, camera, tiles, finals, [])

    def _submit_tile(self, camera: Camera, tile: Tile, priority: int):
        """Submit the tile's passes, each taking the previous one's result; returns the last."""
        previous = None
        for first, count in tile.passes:
            previous = self.client.submit(
                _render_tile, self.scene, camera, self.settings, tile.window, first, count, previous, self.aovs,
                self.expected, pure=False, priority=priority,
            )  # fmt: skip
            self.pending.add(previous)
            self.tasks_total += 1
        return previous

    def _poll(self) -> None:
        """Wait a moment, then collect the finished tasks (a failed one raises its error)."""
        time.sleep(POLL_SECONDS)
        if self.client.status in ("closing", "closed"):  # the scheduler gone, reconnection given up
            raise self._scheduler_lost()
        # "lost" (its worker died) is not an end: Dask computes it again elsewhere
        for future in [f for f in self.warm_futures if f.status == "finished"]:
            self.warm_futures.remove(future)
            try:
                info = future.result()  # the other workers' warm-ups, for the statistics
            except CancelledError:  # lost with the scene since: only statistics
                continue
            self.warm[info["worker"]] = info
        settled = [f for f in self.pending if f.status in ("finished", "error", "cancelled")]
        # A task is cancelled when something it needs can no longer be computed: the scene,
        # when the last worker holding it dies (Dask's memory manager keeps one copy of a
        # broadcast value once no task waits for it), or when the scheduler restarted. Then the
        # scene is sent again and the tiles not done resubmitted.
        lost = False
        for future in settled:
            self.pending.discard(future)
            if future.status == "cancelled":
                lost = True
                continue
            if future.status == "error":
                self._raise(future)
            self.tasks_done += 1
            for frame in self.in_flight:
                entry = frame.finals.get(future.key)
                if entry is not None:
                    try:
                        result = future.result()  # waits if it was lost again since
                    except CancelledError:
                        lost = True
                        continue
                    del frame.finals[future.key]
                    frame.results.append((entry[1], result))
                    self.records.extend(result.cluster["passes"])
                    self.finish_order.append((frame.key, entry[1].window))
                    if self.first_tile_seconds is None:
                        self.first_tile_seconds = time.perf_counter() - self.started
        if lost:
            self._resend_scene()
        self._report()

    def _resend_scene(self) -> None:
        """Scatter the scene again and resubmit every tile not done, each from its first pass."""
        self._require_scheduler()  # tasks are cancelled too when the client loses its scheduler
        self.scene_resends += 1
        if self.scene_resends > SCENE_RESENDS:
            raise ClusterError(
                f"the cluster cancelled tiles' tasks {SCENE_RESENDS} times in this render (the scene lost with "
                "the workers holding it, or the scheduler restarted); the scene was sent again each time"
            )
        self.client.cancel([*self.pending, self.scene], force=True)
        self.pending.clear()
        self._wait_for_a_worker("the scene was lost with its workers")
        [self.scene] = self.client.scatter([self.compiled], broadcast=True, hash=False)
        for frame in self.in_flight:
            finals = {}
            for _, tile in frame.finals.values():
                final = self._submit_tile(frame.camera, tile, 0)
                finals[final.key] = (final, tile)
            frame.finals = finals

    def _scheduler_lost(self, error: BaseException | None = None) -> ClusterError:
        """The error for a scheduler that went away mid-render (killed, its machine gone, the
        network cut): the client is closed and forgotten, its reconnection attempts silenced."""
        if error is not None:
            reason = _reason(_root_cause(error))
        else:
            reason = f"it did not answer again within {CONNECT_TIMEOUT:g} s"
        _abandon(self.client)
        return ClusterError(
            f"--cluster {self.label}: the scheduler was lost during the render ({reason}); check that it "
            "still runs (if not, start it and its workers again), then render again"
        )

    def _require_scheduler(self) -> None:
        """Return once the client is connected; raise _scheduler_lost if it cannot be. A client
        that lost its scheduler tries to reconnect for CONNECT_TIMEOUT ("connecting"), cancelling
        every task; a scheduler restarted within that time is used again (the scene resent)."""
        deadline = time.monotonic() + CONNECT_TIMEOUT + 2.0
        while self.client.status == "connecting" and time.monotonic() < deadline:
            time.sleep(POLL_SECONDS)
        if self.client.status != "running":
            raise self._scheduler_lost()

    def _wait_for_a_worker(self, what: str) -> None:
        try:
            self.client.wait_for_workers(1, timeout=WORKER_WAIT)
        except TimeoutError:
            raise ClusterError(f"{what} and none came back within {WORKER_WAIT:.0f} s") from None

    def _report(self) -> None:
        if self.progress is not None:
            total = self.tasks_total
            if 0 < self.frames_submitted < self.frames_expected:
                total = round(total * self.frames_expected / self.frames_submitted)
            self.progress(self.tasks_done, total)

    @staticmethod
    def _raise(future) -> None:
        """A failed task's error: the worker's own (a refused version, ...), or in words."""
        from distributed import KilledWorker

        try:
            future.result()
        except KilledWorker:
            raise ClusterError(
                "a tile's task was lost with its worker several times in a row; the cluster's workers keep dying"
            ) from None

    def _combine(self, frame: _Frame) -> WindowResult:
        """The window's image from the frame's tiles: disjoint pixels, so any order of
        finishing gives the same array."""
        x0, x1, y0, y1 = self.window
        rgb = np.zeros((y1 - y0, x1 - x0, 3), dtype=np.float32)
        aov_arrays = allocate_aovs(y1 - y0, x1 - x0) if self.aovs else {}
        if self.adaptive:
            aov_arrays["spp"] = np.zeros((y1 - y0, x1 - x0), dtype=np.float32)
        for tile, result in frame.results:
            tx0, tx1, ty0, ty1 = tile.window
            rows, cols = slice(ty0 - y0, ty1 - y0), slice(tx0 - x0, tx1 - x0)
            rgb[rows, cols] = result.rgb
            for name, array in result.aovs.items():
                aov_arrays[name][rows, cols] = array
        results = [r for _, r in frame.results]
        adaptive = {}
        if self.adaptive and results:  # (none yet: Ctrl-C before the first tile)
            from .adaptive import adaptive_stats

            tasks = [r.adaptive for r in results]
            rounds = max(t["rounds"] for t in tasks)
            tiles, converged = sum(t["tiles"] for t in tasks), sum(t["tiles_converged"] for t in tasks)
            adaptive = adaptive_stats(self.settings, aov_arrays["spp"], rounds, tiles, converged)
        return WindowResult(
            self.window,
            rgb,
            aov_arrays,
            seconds=sum(r.seconds for r in results),
            rays=sum(r.rays for r in results),
            rejected=sum(r.rejected for r in results),
            adaptive=adaptive,
        )

    def partial(self) -> tuple[WindowResult, int, int] | None:
        """(the first unfinished frame with its finished tiles, tiles done, tiles), or None."""
        if not self.in_flight:
            return None
        frame = self.in_flight[0]
        return self._combine(frame), len(frame.results), len(frame.tiles)

    def cancel(self) -> None:
        """Cancel the cluster's outstanding work and release the scattered scene."""
        futures = [*self.pending, *self.warm_futures, self.scene]
        self.pending.clear()
        self.warm_futures.clear()
        try:
            self.client.cancel(futures, force=True)
        except Exception:
            pass

    def stats(self) -> dict:
        workers: dict[str, dict] = {}
        for worker, seconds, rays in self.records:
            entry = workers.setdefault(worker, {"tasks": 0, "render_seconds": 0.0, "rays": 0})
            entry["tasks"] += 1
            entry["render_seconds"] += seconds
            entry["rays"] += int(rays)
        for worker, info in self.warm.items():
            workers.setdefault(worker, {"tasks": 0, "render_seconds": 0.0, "rays": 0})
            workers[worker]["compile_seconds"] = info["compile_seconds"]
        for entry in workers.values():
            seconds = entry["render_seconds"]
            entry["mrays_per_second"] = entry["rays"] / seconds / 1e6 if seconds else 0.0
        nthreads = self.client.nthreads()
        compiles = [info["compile_seconds"] for info in self.warm.values()]
        return {
            "workers": len(nthreads),
            "threads": int(sum(nthreads.values())),
            "tiles": self.tiles,
            "tasks": self.tasks_done,
            "scene_bytes": self.scene_bytes,
            "wall_seconds": time.perf_counter() - self.started,
            "first_tile_seconds": self.first_tile_seconds,
            # the workers compile (or load) the kernels side by side: the longest of them
            "compile_seconds": max(compiles, default=0.0),
            "per_worker": workers,
        }


def render_on_cluster(
    cluster,
    compiled: CompiledScene,
    camera: Camera,
    settings: ResolvedSettings,
    *,
    aovs: bool = False,
    progress: Callable[[int, int], None] | None = None,
    status: Callable | None = None,
    shuffle=None,
) -> WindowResult:
    """One image (the window of `settings`: the crop, or the whole image) rendered in tiles on
    the cluster: what Session.render does with `cluster=`. `seconds` of the result is the time
    in the kernels, summed over the tiles (also .cluster["kernel_seconds"]), as an in-process
    render's is its kernels' alone: no warm-up, scheduling or transfers. The wall time of the
    distributed render is .cluster["wall_seconds"]; the workers' compile time
    .cluster["compile_seconds"]. Ctrl-C raises RenderInterrupted with the tiles done so far."""
    client = connect(cluster)
    threads = max(1, int(sum(client.nthreads().values())))
    renderer = FrameRenderer(
        client, compiled, settings, aovs=aovs, progress=progress, min_tiles=TILES_PER_WORKER * threads,
        shuffle=shuffle,
    )  # fmt: skip
    if status is not None:
        status("rendering")
    try:
        [(_, result)] = list(renderer.frames([(0, camera)]))
    except KeyboardInterrupt:
        raise _interrupted(renderer.partial(), settings) from None
    result.cluster = renderer.stats()
    result.cluster["kernel_seconds"] = result.seconds
    result.cluster["finish_order"] = [list(w) for _, w in renderer.finish_order]
    return result


def _interrupted(partial, settings: ResolvedSettings) -> RenderInterrupted:
    x0, x1, y0, y1 = settings.window
    if partial is None:
        rgb, done, total = np.zeros((y1 - y0, x1 - x0, 3), dtype=np.float32), 0, 0
    else:
        result, done, total = partial
        rgb = result.rgb
    image = Image(
        rgb, {}, {}, settings.render.encoding, exposure=settings.render.exposure, tonemap=settings.render.tonemap
    )
    return RenderInterrupted(image, 0, done=f"{done} of {total} tiles")
