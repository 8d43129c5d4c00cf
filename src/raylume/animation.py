"""Camera animation: the camera of frame K from the `[animation]` keyframes.

Each of `position`, `look_at`, `up` and `fov` is its own track: interpolated between the
keyframes that give it, held before the first and after the last of them, and taken from
`[camera]` where no keyframe gives it. `interpolation = "linear"` joins keyframes by straight
lines; `"catmull-rom"` by the cubic Hermite curve through them whose tangent at a keyframe is
the slope between its neighbours, (p[i+1] - p[i-1]) / (t[i+1] - t[i-1]) (one-sided at the
ends), so the camera moves smoothly through every keyframe. A frame is a pure function of
the scene and K: frame K of a video is the still `--frame K`.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING

from pydantic import ValidationError

from .errors import SceneError
from .scene.model import Animation, Camera, Scene
from .scene.validation_errors import format_validation_error
from .settings import OVERRIDES, ResolvedSettings, settings_of_call

if TYPE_CHECKING:
    from .image import Image

TRACKS = ("position", "look_at", "up", "fov")


def animation_of(scene: Scene, source: str = "<scene>") -> Animation:
    if scene.animation is None:
        raise SceneError(
            f"{source}: has no [animation] table; add one with `frames` and [[animation.camera]] keyframes "
            "to render a video, a sequence or --frame K"
        )
    return scene.animation


def camera_at(scene: Scene, frame: int, source: str = "<scene>") -> Camera:
    """The camera of frame `frame` (0-based) of the scene's animation."""
    animation = animation_of(scene, source)
    if not 0 <= frame < animation.frames:
        raise SceneError(f"{source}: frame {frame} is outside the animation's frames 0..{animation.frames - 1}")
    values = scene.camera.model_dump()
    keys = sorted(animation.camera, key=lambda key: key.frame)
    for track in TRACKS:
        points = [(key.frame, getattr(key, track)) for key in keys if getattr(key, track) is not None]
        if points:
            values[track] = interpolate(points, frame, animation.interpolation)
    try:
        return Camera.model_validate(values)
    except ValidationError as exc:
        context = f"animation frame {frame}: the interpolated camera is invalid: "
        raise SceneError(format_validation_error(exc, source, Camera, table=("camera",), context=context)) from None


def interpolate(points: list[tuple[int, object]], t: float, method: str = "catmull-rom"):
    """The value at time t of the track through `points` (time, value): value a number or a
    sequence of numbers, times increasing."""
    times = [p[0] for p in points]
    values = [_vector(p[1]) for p in points]
    scalar = not isinstance(points[0][1], (tuple, list))
    if t <= times[0]:
        out = values[0]
    elif t >= times[-1]:
        out = values[-1]
    else:
        i = bisect_right(times, t) - 1  # times[i] <= t < times[i + 1]
        t0, t1 = times[i], times[i + 1]
        h = t1 - t0
        s = (t - t0) / h
        p0, p1 = values[i], values[i + 1]
        if method == "linear":
            out = [a + (b - a) * s for a, b in zip(p0, p1)]
        else:
            m0 = _slope(times, values, i)
            m1 = _slope(times, values, i + 1)
            h00 = 2 * s**3 - 3 * s**2 + 1
            h10 = s**3 - 2 * s**2 + s
            h01 = -2 * s**3 + 3 * s**2
            h11 = s**3 - s**2
            out = [h00 * a + h10 * h * ma + h01 * b + h11 * h * mb for a, b, ma, mb in zip(p0, p1, m0, m1)]
    return float(out[0]) if scalar else tuple(float(v) for v in out)


def _vector(value) -> list[float]:
    return [float(v) for v in value] if isinstance(value, (tuple, list)) else [float(value)]


def _slope(times, values, i) -> list[float]:
    """Catmull-Rom's tangent at keyframe i: the slope between its neighbours (one-sided at the ends)."""
    lo, hi = max(i - 1, 0), min(i + 1, len(times) - 1)
    return [(b - a) / (times[hi] - times[lo]) for a, b in zip(values[lo], values[hi])]


def parse_frames(text: str, frames: int) -> range:
    """`A:B` -> frames A..B-1 (either side may be left out: `:B`, `A:`), checked against the
    animation's frame count."""
    start, sep, stop = text.partition(":")
    try:
        a = int(start) if start.strip() else 0
        b = int(stop) if stop.strip() else frames
    except ValueError:
        a = b = -1
    if not sep or not 0 <= a < b <= frames:
        raise SceneError(
            f"--frames {text}: expected A:B with 0 <= A < B <= {frames} (frames A to B-1 of the {frames} frames)"
        )
    return range(a, b)


def render_animation(
    session,
    frames: Iterable[int] | None = None,
    *,
    cluster=None,
    progress: Callable[[int, int], None] | None = None,
    settings: ResolvedSettings | None = None,
    status: Callable[[str], None] | None = None,
    **arguments,
) -> Iterator[tuple[int, Image]]:
    """Render frames of the session's scene animation (default: all) and yield (frame, Image)
    in order. `settings` (raylume.settings.resolve_settings), or `arguments` as Session.render
    takes them (width, height, spp, mode, seed, ..., threads, crop), override the [render]
    table. With `cluster`, frames render in parallel on its workers (several frames in flight,
    each in tiles); frame K is bit-identical to the still of frame K. `progress(done, total)`
    counts frames in-process and tasks (tiles, passes) on a cluster. `status` hears each
    in-process frame's "compiling" and "rendering" (Session.render): the first frame's kernels
    compile (or load from the cache) there, and each frame's stats hold its `compile_seconds`."""
    unknown = sorted(set(arguments) - {*OVERRIDES, "threads", "crop"})
    if unknown:
        raise TypeError(f"render_animation: unexpected keyword arguments {', '.join(unknown)}")
    scene, source = session.scene, session.source
    settings = settings_of_call(scene, arguments, settings, source)
    animation = animation_of(scene, source)
    frames = list(range(animation.frames) if frames is None else frames)
    cameras = [(k, camera_at(scene, k, source)) for k in frames]  # every camera checked before rendering
    if cluster is None:
        for done, (k, camera) in enumerate(cameras):
            if progress is not None:
                progress(done, len(cameras))
            yield k, session.render(camera, aovs=False, settings=settings, status=status)
        if progress is not None:
            progress(len(cameras), len(cameras))
        return
    from .cluster import FrameRenderer
    from .image import Image

    table = settings.render
    denoising = table.denoise and table.mode == "path"
    renderer = FrameRenderer(
        cluster, session.compiled, settings, aovs=denoising, progress=progress, frames=len(cameras)
    )
    for k, result in renderer.frames(cameras):
        rgb = result.rgb
        if denoising:
            from .denoise import denoise

            rgb = denoise(rgb, result.aovs["albedo"], result.aovs["normal"])
        stats = {"width": table.width, "height": table.height, "spp": table.spp, "mode": table.mode, "frame": k,
                 "rays": result.rays, "render_seconds": result.seconds}  # fmt: skip
        yield k, Image(rgb, {}, stats, table.encoding, exposure=table.exposure)
    session.last_cluster_stats = renderer.stats()
