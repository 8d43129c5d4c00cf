"""The viewer's render thread: renders the current camera progressively, pass after pass.

While the camera moves (it changed less than MOVING_SECONDS ago) every frame is one sample per
pixel at a resolution reduced until it renders within MOVE_BUDGET, sent as JPEG. Once it rests,
the full-size film accumulates samples pass after pass, each pass a sweep over row bands
(windowed films, the same pixels as one film) of about REST_PASS_SECONDS each, so that a camera
change waits for one band at most; each pass is sent as a lossless PNG:

* cast and trace mode fill one film of the scene's spp, then stop: the image is then
  bit-identical to `raylume render` of the same camera and size (at spp 1, after one pass);
* path mode has no end: it fills films of max(spp, PATH_FILM_SPP) samples, each with the
  samples after the one before of the same low-discrepancy sequences (`Film.first_sample`), and
  shows all samples so far, the films' sums pooled, up to PATH_MAX_SPP: k films are one render
  of k times as many samples, stratified together (a film's texture filter, the ray cone,
  narrows with the samples up to its end, as that render's; only the first films' is wider);
* raster mode draws the frame once.

With denoising on (`--denoise`, the page's checkbox) path mode's frames are shown denoised: a
moving frame is one sample per pixel at the pixel centres, with its AOVs and the light seen
directly, filtered by SVGF (svgf.py, whose history follows the camera from frame to frame); at
rest the accumulating image is denoised by OIDN (denoise.py) with the albedo and normal AOVs of
the job's first pass, at most every DENOISE_SECONDS and at most a third of the time (a pass
whose turn it is not shows nothing new), until it has DENOISE_UNTIL_SPP samples a pixel; from
there on the accumulation is shown as it is, and converges to `raylume render` as without
denoising. The accumulation itself is the same as without denoising.

A change of camera or mode drops the film. The kernels are nogil and run on the Session's lanes
(all cores by default); this thread only prepares passes and encodes frames. Without watchers
(no open tab) it stops after the first lossless frame of a camera: a closed tab costs nothing.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from ..image import encode_8bit
from ..kernels.film.camera import camera_of
from ..kernels.film.film import Film, sums_image
from ..render_window import allocate_aovs
from ..scene.model import Camera, RenderSettings
from ..session import Session
from ..settings import ResolvedSettings, resolve_settings
from . import camera_control
from .frames import Frame

MODES = ("cast", "trace", "path", "raster")
CAMERA_KEYS = ("position", "look_at", "up", "fov")
MOVING_SECONDS = 0.12  # the camera counts as moving until this long after its last change
MOVE_BUDGET = 0.022  # seconds a frame (pass and encoding) may take while moving: sets the resolution divisor
MOVE_BUDGET_DENOISED = 0.032  # ... with denoising (the AOVs, the light seen directly and SVGF too)
MAX_DIVISOR = 8
DROPS_PER_STEP = 2  # moving frames dropped in a row (the camera moved on meanwhile) that raise the divisor by 1
REST_PASS_SECONDS = 0.05  # a band's pass at rest aims at this long (Ctrl-C and input wait for it)
MAX_BANDS = 64
PATH_FILM_SPP = 16
PATH_MAX_SPP = 4096
FPS_WINDOW = 2.0  # seconds over which fps and Mrays/s are measured
DENOISE_SECONDS = 0.3  # at rest, OIDN denoises a pass's image at most this often ...
DENOISE_SHARE = 3.0  # ... and at most 1 / DENOISE_SHARE of the time
# ... until the image has this many samples a pixel: from there on the accumulation itself is
# shown, which converges to `raylume render` (OIDN's output of a converged image does not: at
# 1024 spp it was ~5x further from an independent render than the raw image, fine detail smoothed)
DENOISE_UNTIL_SPP = 1024


@dataclass
class _Job:
    """The image being rendered for one camera and mode at one resolution."""

    epoch: int
    camera_version: int
    camera: Camera
    mode: str
    divisor: int
    settings: RenderSettings  # the [render] table at the job's size and mode
    batch: int  # total_spp of each film
    bands: list[Film] = field(default_factory=list)  # the film, as windowed films of row bands (none: raster)
    # the completed films pooled: their sums (float64, the whole image's rows) and bdpt's splat
    # sums, added as one film of all their samples would hold them
    done_sums: np.ndarray | None = None
    done_splats: np.ndarray | None = None
    done_spp: int = 0
    rgb: np.ndarray | None = None  # raster mode's image
    finished: bool = False
    sent_lossless: bool = False
    # a moving frame of path mode for SVGF: one sample at the pixel centres (seed seed + seed_offset)
    svgf: bool = False
    seed_offset: int = 0
    aovs: dict | None = None  # path mode: the primary-hit AOVs of the whole image, filled by the first pass
    aovs_filled: bool = False
    emitted: Film | None = None  # svgf: the light seen directly (max_depth 1) at the same camera rays
    denoised_at: float = -math.inf  # when OIDN last denoised this job's image
    shown_denoised: bool | None = None  # whether the last frame sent of this job was denoised

    @property
    def spp(self) -> int:
        if not self.bands:
            return 1 if self.rgb is not None else 0
        return self.done_spp + self.bands[0].spp

    def film_rgb(self) -> np.ndarray:
        """The current film's image: its bands' pixels, which equal those of one whole film."""
        if len(self.bands) == 1:
            return self.bands[0].rgb()
        return np.concatenate([band.rgb() for band in self.bands], axis=0)

    def _film_sums(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The current film's sums over the whole image, and its splat sums (bdpt: one band)."""
        sums = self.bands[0].sums if len(self.bands) == 1 else np.concatenate([b.sums for b in self.bands])
        return sums, self.bands[0].splats

    def pool_film(self) -> None:
        """Add the current, completed film to the pooled films: their sums add (with a filter of
        negative lobes, Mitchell's, the mean of the films' images would not be the image of all
        their samples)."""
        sums, splats = self._film_sums()
        self.done_sums = sums.copy() if self.done_sums is None else self.done_sums + sums
        if splats is not None:
            self.done_splats = splats.copy() if self.done_splats is None else self.done_splats + splats
        self.done_spp += self.bands[0].spp

    def image(self) -> np.ndarray:
        """Linear float32 RGB of every sample so far (one film: exactly its rgb())."""
        if not self.bands:
            return self.rgb
        if self.done_spp == 0:
            return self.film_rgb()
        sums, splats = self._film_sums()
        if splats is not None:
            splats = splats + self.done_splats
        return sums_image(self.done_sums + sums, splats, self.spp)

    def new_film(self, count: int) -> None:
        """Films for rows split into `count` bands (about equal)."""
        s = self.settings
        edges = sorted({round(k * s.height / count) for k in range(count + 1)})
        self.bands = [
            Film(s.width, s.height, s.filter, self.batch, window=(0, s.width, y0, y1), first_sample=self.done_spp)
            for y0, y1 in zip(edges[:-1], edges[1:])
        ]
        self.bands[0].compile_rgb(always=True)  # every frame's image by the kernel, however small


class Renderer:
    """Renders `session`'s scene with `settings` (size, spp, mode, threads; default: the scene's
    [render] table on every core) from its camera, following camera and mode changes;
    `on_frame(frame)` is called (on the render thread) for each new frame."""

    def __init__(
        self,
        session: Session,
        settings: ResolvedSettings | None = None,
        *,
        on_frame: Callable[[Frame], None] | None = None,
    ):
        self.session = session
        self.settings = settings or resolve_settings(session.scene, source=session.source)
        table = self.settings.render
        self.width, self.height = table.width, table.height
        self.threads = self.settings.threads
        self.on_frame = on_frame
        self.home = session.scene.camera
        self._camera = self.home
        self._mode = table.mode
        self._denoise = bool(table.denoise)
        self.integrator = str(getattr(table, "integrator", "path"))  # path mode's integrator
        self._svgf = None  # the filter of moving frames (made on first use), its history
        self._svgf_frames = 0  # moving frames filtered: each takes the next seed
        self._svgf_reset = False
        self._oidn_seconds = 0.0  # the last OIDN call's duration
        self._svgf_seconds = 0.0  # the last moving frame's filtering, per pixel
        self._dropped = 0  # moving frames dropped in a row
        self._cond = threading.Condition()
        self._epoch = 0
        self.camera_version = 0
        self._last_change = -math.inf
        self._stop = False
        self._thread: threading.Thread | None = None
        self._watchers = 0
        self.latest: Frame | None = None
        self.frames = 0
        self._frame_times: deque[float] = deque()
        self._rays: deque[tuple[float, int, float]] = deque()  # (time, rays, kernel seconds)
        # (mode, moving) -> seconds per sample per pixel of a frame; (mode, "svgf") for denoised moving frames
        self._cost: dict[tuple[str, bool | str], float] = {}
        self._warm: set[str] = set()  # modes whose kernels are loaded
        self._job: _Job | None = None  # the image being rendered (for tests)
        self.status = "starting"
        self.error: str | None = None
        self.started = time.monotonic()

    # --- state the server reads and changes -------------------------------------------------

    @property
    def camera(self) -> Camera:
        return self._camera

    @property
    def mode(self) -> str:
        return self._mode

    @property
    def denoise(self) -> bool:
        return self._denoise

    def set_camera(self, updates: dict) -> int:
        """Move the camera to `updates` (any of position, look_at, up, fov), as a drag would.
        Returns the new camera_version; a bad value is a SceneError naming the key."""
        unknown = sorted(set(updates) - set(CAMERA_KEYS))
        if unknown:
            raise SceneError(f"camera: unknown key {', '.join(unknown)}; allowed: {', '.join(CAMERA_KEYS)}")
        camera = self.session._camera({**self._camera.model_dump(), **updates})
        with self._cond:
            self._camera = camera
            self.camera_version += 1
            self._epoch += 1
            self._last_change = time.monotonic()
            self._cond.notify_all()
            return self.camera_version

    def gesture(self, kind: str, dx: float = 0.0, dy: float = 0.0, delta: float = 0.0) -> int:
        """Apply a mouse gesture: 'orbit' or 'pan' by (dx, dy) image pixels, 'dolly' by a wheel
        delta (camera_control.py)."""
        c = self._camera
        if kind == "orbit":
            updates = {"position": camera_control.orbit(c.position, c.look_at, c.up, dx, dy, self.height)}
        elif kind == "pan":
            position, look_at = camera_control.pan(c.position, c.look_at, c.up, c.fov, dx, dy, self.height)
            updates = {"position": position, "look_at": look_at}
        elif kind == "dolly":
            updates = {"position": camera_control.dolly(c.position, c.look_at, delta)}
        else:
            raise SceneError(f"unknown gesture {kind!r}; expected orbit, pan or dolly")
        return self.set_camera(updates)

    def reset_camera(self) -> int:
        return self.set_camera({k: getattr(self.home, k) for k in CAMERA_KEYS})

    def set_mode(self, mode: str) -> None:
        if mode not in MODES:
            raise SceneError(f"mode {mode!r}: expected one of {', '.join(MODES)}")
        resolve_settings(self.settings.render, {"mode": mode}, source=self.session.source)  # e.g. max_depth -1
        with self._cond:
            if mode != self._mode:
                self._mode = mode
                self._epoch += 1
                self._cond.notify_all()

    def set_denoise(self, on: bool) -> None:
        """Show path mode's frames denoised (or not). The accumulation goes on: a resting image is
        shown again at once, denoised or not. A RaylumeError when OIDN cannot run here."""
        on = bool(on)
        if on:
            from ..denoise import require_denoiser

            require_denoiser()
        with self._cond:
            if on != self._denoise:
                self._denoise = on
                self._svgf_reset = on  # a history from before is stale
                self._cond.notify_all()

    def add_watcher(self, count: int = 1) -> None:
        """A tab opened (count 1) or closed (-1): frames beyond the first lossless one are only
        rendered while someone watches."""
        with self._cond:
            self._watchers += count
            self._cond.notify_all()

    def stats(self) -> dict:
        now = time.monotonic()
        with self._cond:
            self._trim(now)
            span = min(FPS_WINDOW, now - self.started)
            rays = sum(r for _, r, _ in self._rays)
            seconds = sum(s for _, _, s in self._rays)
            frame = self.latest
            c = self._camera
            return {
                "frames": self.frames,
                "fps": len(self._frame_times) / span if span > 0 else 0.0,
                "spp": frame.spp if frame else 0,
                "width": self.width,
                "height": self.height,
                "mode": self._mode,
                "denoise": self._denoise,
                "integrator": self.integrator,
                "camera": {"position": list(c.position), "look_at": list(c.look_at), "up": list(c.up), "fov": c.fov},
                "camera_version": self.camera_version,
                "mrays_per_second": rays / seconds / 1e6 if seconds > 0 else 0.0,
                "frame_width": frame.width if frame else 0,
                "frame_height": frame.height if frame else 0,
                "converged": bool(frame and frame.converged),
                "denoised": bool(frame and frame.denoised),
                "status": self.status,
                "error": self.error,
                "watchers": self._watchers,
            }

    def _trim(self, now: float) -> None:
        while self._frame_times and self._frame_times[0] < now - FPS_WINDOW:
            self._frame_times.popleft()
        while self._rays and self._rays[0][0] < now - FPS_WINDOW:
            self._rays.popleft()

    # --- the thread -------------------------------------------------------------------------

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="raylume-view-render", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 1.0) -> bool:
        """Ask the thread to stop after the pass in flight; True if it ended within `timeout`."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
            return not self._thread.is_alive()
        return True

    def _run(self) -> None:
        job: _Job | None = None
        failed_epoch = -1
        while True:
            with self._cond:
                if self._stop:
                    return
                now = time.monotonic()
                epoch, version, camera, mode = self._epoch, self.camera_version, self._camera, self._mode
                rest_in = self._last_change + MOVING_SECONDS - now
                moving = rest_in > 0
                fresh = job is None or job.epoch != epoch
                republish = False
                if epoch == failed_epoch:
                    self._cond.wait()
                    continue
                if not fresh:
                    if moving:  # a frame of this camera is out; wait for the next move or for rest
                        self._cond.wait(rest_in)
                        continue
                    if job.divisor > 1 or job.svgf:
                        fresh = True  # at rest: start again at full size (and with its own samples)
                    elif job.sent_lossless and job.shown_denoised != self._shows_denoised(job):
                        republish = True  # denoising was turned on or off: show the image as asked
                    elif job.sent_lossless and (job.finished or self._watchers == 0):
                        self.status = "converged" if job.finished else "paused (no viewer)"
                        self._cond.wait()
                        continue
            try:
                if fresh:
                    job = self._job = self._new_job(epoch, version, camera, mode, moving)
                started = time.perf_counter()
                samples = self._step(job, moving) if not (job.finished or republish) else 0
                denoising = 0.0
                if job.epoch == self._epoch and samples >= 0:  # else the camera moved: render the new one at once
                    denoising = self._publish(job, moving)
                    self._dropped = 0
                elif moving:
                    # Dropped. Moves that come faster than frames would drop every frame: a few
                    # in a row lower the resolution (_divisor) until frames come through.
                    self._dropped += 1
                    if job.svgf:  # dropped before filtering: count the filter as it took last time
                        denoising = -self._svgf_seconds * job.settings.width * job.settings.height
                if samples > 0:
                    self._learn_cost(job, moving, samples, time.perf_counter() - started - denoising)
            except Exception as exc:  # a failed pass must not kill the view: report it, wait for a change
                self.error = str(exc) or type(exc).__name__
                self.status = "error"
                failed_epoch = epoch
                job = None

    def _divisor(self, mode: str, svgf: bool = False) -> int:
        cost = self._cost.get((mode, True), self._cost.get((mode, False)))
        if svgf:
            cost = self._cost.get((mode, "svgf"), cost)
        if cost is None:
            return 1
        budget = MOVE_BUDGET_DENOISED if svgf else MOVE_BUDGET
        divisor = math.ceil(math.sqrt(cost * self.width * self.height / budget)) + self._dropped // DROPS_PER_STEP
        return max(1, min(MAX_DIVISOR, divisor))

    def _shows_denoised(self, job: _Job) -> bool:
        return self._denoise and job.mode == "path" and (job.svgf or job.spp < DENOISE_UNTIL_SPP)

    def _new_job(self, epoch: int, version: int, camera: Camera, mode: str, moving: bool) -> _Job:
        svgf = moving and mode == "path" and self._denoise
        divisor = self._divisor(mode, svgf) if moving else 1
        w, h = -(-self.width // divisor), -(-self.height // divisor)
        size_and_mode = {"width": w, "height": h, "mode": mode}
        settings = resolve_settings(self.settings.render, size_and_mode, source=self.session.source).render
        batch = settings.spp if divisor == 1 else 1
        if mode == "path" and divisor == 1:
            batch = max(settings.spp, PATH_FILM_SPP)
        if svgf:
            batch = 1  # one sample at the pixel centres, where the AOVs are
        job = _Job(epoch, version, camera, mode, divisor, settings, batch, svgf=svgf)
        if mode != "raster":
            job.new_film(1 if moving else self._band_count(mode, w, h))  # moving: fits MOVE_BUDGET whole
        if mode == "path" and (svgf or divisor == 1):  # SVGF's guides, or OIDN's if it comes to rest
            job.aovs = allocate_aovs(h, w)
        if svgf:
            job.emitted = Film(w, h, settings.filter, total_spp=1)
            self._svgf_frames += 1
            job.seed_offset = self._svgf_frames  # each frame new noise, which the filter averages over time
        self.error = None
        return job

    def _band_count(self, mode: str, w: int, h: int) -> int:
        """Bands for a full-size film at rest: a pass over one band should take about
        REST_PASS_SECONDS, so that a camera change waits for no more (a pass is not interrupted)."""
        cost = self._cost.get((mode, False), self._cost.get((mode, True)))
        if cost is None or (mode == "path" and self.integrator == "bdpt"):
            return 1  # bdpt: every band would trace the whole image's light subpaths (its splats)
        return max(1, min(h, MAX_BANDS, math.ceil(cost * w * h / REST_PASS_SECONDS)))

    def _step(self, job: _Job, moving: bool) -> int:
        """One pass over the image, band after band: 1 spp while moving, about REST_PASS_SECONDS
        of samples per band at rest. Returns the samples per pixel it added (0 for a first pass,
        whose time is no measure; -1 when a camera change or stop cut it short)."""
        s = job.settings
        compiling = f"compiling the {job.mode}-mode kernels (once per mode and kind of scene)"
        self.status = "rendering" if job.mode in self._warm else compiling
        first = job.mode not in self._warm
        rays, seconds, count = 0, 0.0, 1
        if not job.bands:
            image = self.session.render(job.camera, width=s.width, height=s.height, mode="raster", aovs=False)
            job.rgb, job.finished = image.rgb, True
            seconds = image.stats["render_seconds"]
        else:
            count = 1 if moving else self._pass_spp(job)
            seed = s.seed + job.seed_offset
            fill = job.aovs is not None and not job.aovs_filled
            for band in job.bands:
                if job.epoch != self._epoch or self._stop:
                    return -1  # the job is dropped: its bands now hold different sample counts
                _, _, y0, y1 = band.window
                aovs = {name: array[y0:y1] for name, array in job.aovs.items()} if fill else None
                info = self.session.add_samples(
                    band, count, job.camera, mode=job.mode, seed=seed, threads=self.threads, aovs=aovs,
                    integrator=self.integrator if job.mode == "path" else None,
                )  # fmt: skip
                rays, seconds = rays + info["rays"], seconds + info["render_seconds"]
                self._warm.add(job.mode)
            job.aovs_filled = job.aovs is not None
            if job.emitted is not None:  # the light seen directly: the same camera rays, max_depth 1
                info = self.session.add_samples(
                    job.emitted, 1, job.camera, mode="path", max_depth=1, seed=seed, threads=self.threads
                )
                rays, seconds = rays + info["rays"], seconds + info["render_seconds"]
            if job.svgf:
                job.finished = True  # one frame; at rest a new job accumulates
            elif job.bands[0].spp == job.batch:
                if job.mode == "path" and job.spp < PATH_MAX_SPP:
                    job.pool_film()
                    job.new_film(len(job.bands))
                else:
                    job.finished = True
        self._warm.add(job.mode)
        self.status = "rendering"
        with self._cond:
            self._rays.append((time.monotonic(), int(rays), float(seconds)))
        return 0 if first else count  # a first pass's time includes compiling

    def _learn_cost(self, job: _Job, moving: bool, samples: int, seconds: float) -> None:
        """Seconds per sample per pixel of a whole frame (pass, read-out, encoding), apart for
        moving frames (1 spp: the encoding weighs more) and resting passes: what the resolution
        while moving and the size of passes at rest are chosen by."""
        per_sample = seconds / (samples * job.settings.width * job.settings.height)
        key = (job.mode, "svgf") if job.svgf else (job.mode, moving)
        old = self._cost.get(key)
        self._cost[key] = per_sample if old is None else 0.7 * old + 0.3 * per_sample

    def _pass_spp(self, job: _Job) -> int:
        """Samples per pixel of a pass at rest: about REST_PASS_SECONDS per band."""
        cost = self._cost.get((job.mode, False), self._cost.get((job.mode, True)))
        left = job.batch - job.bands[0].spp
        if cost is None:
            return 1
        band_pixels = job.settings.width * job.settings.height / len(job.bands)
        return max(1, min(left, int(REST_PASS_SECONDS / (cost * band_pixels))))

    def _publish(self, job: _Job, moving: bool) -> float:
        """Send the job's image (denoised if asked). Returns the seconds OIDN took (no part of
        a pass's cost; SVGF's is part of a moving frame's); a resting pass whose turn for OIDN it
        is not sends nothing."""
        s = job.settings
        image = job.image()
        denoised = self._shows_denoised(job) and (job.svgf or not moving) and job.aovs_filled
        seconds = 0.0
        if denoised and job.svgf:
            image = self._filter_moving(job, image)
        elif denoised:
            interval = max(DENOISE_SECONDS, DENOISE_SHARE * self._oidn_seconds)
            due = job.finished or not job.shown_denoised or time.monotonic() - job.denoised_at >= interval
            if not due:
                return 0.0  # the last denoised frame stays shown
            from ..denoise import denoise

            started = time.perf_counter()
            image = denoise(image, job.aovs["albedo"], job.aovs["normal"])
            seconds = self._oidn_seconds = time.perf_counter() - started
            job.denoised_at = time.monotonic()
            if job.epoch != self._epoch:
                return seconds  # the camera moved meanwhile: drop it
        rgb8 = encode_8bit(image, s.encoding, s.exposure, s.tonemap)  # as Image.save encodes a PNG
        lossless = not moving
        frame = Frame(
            number=0,
            rgb8=rgb8,
            format="png" if lossless else "jpeg",
            spp=job.spp,
            mode=job.mode,
            camera_version=job.camera_version,
            converged=job.finished and job.divisor == 1 and not job.svgf,
            denoised=denoised,
        )
        with self._cond:
            self.frames += 1
            frame.number = self.frames
            self.latest = frame
            self._frame_times.append(frame.time)
            self._trim(frame.time)
        job.sent_lossless = job.sent_lossless or lossless
        job.shown_denoised = denoised
        if self.on_frame is not None:
            self.on_frame(frame)
        return seconds

    def _filter_moving(self, job: _Job, image: np.ndarray) -> np.ndarray:
        """A moving frame through SVGF, whose history is the frames before (any size)."""
        from ..svgf import Svgf

        if self._svgf is None:
            self.status = "compiling the denoiser (once)"
            self._svgf = Svgf(threads=self.threads)
        if self._svgf_reset:
            self._svgf_reset = False
            self._svgf.reset()
        s, aovs = job.settings, job.aovs
        camera = camera_of(job.camera, s.width, s.height)
        started = time.perf_counter()
        out = self._svgf.filter(image, aovs["albedo"], aovs["normal"], aovs["depth"], camera, job.emitted.rgb())
        self._svgf_seconds = (time.perf_counter() - started) / (s.width * s.height)
        self.status = "rendering"
        return out
