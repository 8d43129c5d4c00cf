"""The camera of frame K of a scene's `[animation]`, from its keyframes (raylume/animation.py
renders the frames; compile/media.py checks where the frames' cameras sit).

Each of `position`, `look_at`, `up` and `fov` is its own track: interpolated between the
keyframes that give it, held before the first and after the last of them, and taken from
`[camera]` where no keyframe gives it. `interpolation = "linear"` joins keyframes by straight
lines; `"catmull-rom"` by the cubic Hermite curve through them whose tangent at a keyframe is
the slope between its neighbours, (p[i+1] - p[i-1]) / (t[i+1] - t[i-1]) (one-sided at the
ends), so the camera moves smoothly through every keyframe.
"""

from __future__ import annotations

from bisect import bisect_right

from pydantic import ValidationError

from ..errors import SceneError
from .model import Animation, Camera, Scene
from .validation_errors import format_validation_error

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
