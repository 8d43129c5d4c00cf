"""Mouse gestures as camera moves: orbit around look_at, pan in the image plane, dolly along
the viewing direction. Plain math on (position, look_at, up, fov); the camera frame is
DESIGN.md section 3's (left-handed): f = normalize(L - P), r = normalize(cross(U, f)),
u = cross(f, r). Gestures move the camera so the scene follows the cursor, as if grabbed."""

from __future__ import annotations

import math

Vec = tuple[float, float, float]

# A drag across the image's full height turns the camera by this angle (radians).
ORBIT_PER_HEIGHT = math.pi
# The orbit's polar angle (from `up`) stays this far from the poles: `up` must never become
# parallel to the viewing direction.
POLE_MARGIN = math.radians(1.0)
# Wheel: one notch (deltaY 100 in browsers) moves the camera 10 % closer or farther.
DOLLY_PER_UNIT = math.log(1.1) / 100.0
MIN_DISTANCE = 1e-4  # how close dolly may bring the camera to look_at (scene units)


def _sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _scale(a: Vec, s: float) -> Vec:
    return (a[0] * s, a[1] * s, a[2] * s)


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a: Vec) -> float:
    return math.sqrt(_dot(a, a))


def _unit(a: Vec) -> Vec:
    return _scale(a, 1.0 / _norm(a))


def rotate(v: Vec, axis: Vec, angle: float) -> Vec:
    """v turned by `angle` radians about the unit vector `axis` (Rodrigues' formula)."""
    c, s = math.cos(angle), math.sin(angle)
    kv = _cross(axis, v)
    kd = _dot(axis, v) * (1.0 - c)
    return (
        v[0] * c + kv[0] * s + axis[0] * kd,
        v[1] * c + kv[1] * s + axis[1] * kd,
        v[2] * c + kv[2] * s + axis[2] * kd,
    )


def camera_frame(position: Vec, look_at: Vec, up: Vec) -> tuple[Vec, Vec, Vec]:
    """(f, r, u): forward, right and up unit vectors of the camera, as DESIGN.md defines them."""
    f = _unit(_sub(look_at, position))
    r = _unit(_cross(up, f))
    return f, r, _cross(f, r)


def orbit(position: Vec, look_at: Vec, up: Vec, dx: float, dy: float, height: int) -> Vec:
    """The new position after a drag of (dx, dy) image pixels (x to the right, y down): the
    camera turns about look_at, around `up` for dx (drag right: the camera goes left, so the
    scene turns right with the cursor) and around its right axis for dy (drag down: the camera
    rises), keeping its distance. The polar angle is clamped POLE_MARGIN short of `up`'s poles."""
    rate = ORBIT_PER_HEIGHT / max(height, 1)
    k = _unit(up)
    v = _sub(position, look_at)
    v = rotate(v, k, dx * rate)
    _, r, _ = camera_frame(_add(look_at, v), look_at, up)
    polar = math.acos(max(-1.0, min(1.0, _dot(v, k) / _norm(v))))
    # turning about r by +a moves v towards +up, i.e. lowers the polar angle by a
    target = min(max(polar - dy * rate, POLE_MARGIN), math.pi - POLE_MARGIN)
    v = rotate(v, r, polar - target)
    return _add(look_at, v)


def pan(position: Vec, look_at: Vec, up: Vec, fov: float, dx: float, dy: float, height: int) -> tuple[Vec, Vec]:
    """(position, look_at) after a pan drag of (dx, dy) image pixels: both move in the image
    plane so that a point at look_at's distance stays under the cursor."""
    _, r, u = camera_frame(position, look_at, up)
    distance = _norm(_sub(look_at, position))
    per_pixel = 2.0 * distance * math.tan(math.radians(fov) / 2.0) / max(height, 1)
    shift = _add(_scale(r, -dx * per_pixel), _scale(u, dy * per_pixel))
    return _add(position, shift), _add(look_at, shift)


def dolly(position: Vec, look_at: Vec, delta: float) -> Vec:
    """The new position after a wheel turn of `delta` (the browser's deltaY: positive away
    from the user, i.e. zoom out): the distance to look_at is multiplied by
    exp(delta * DOLLY_PER_UNIT), never below MIN_DISTANCE."""
    v = _sub(position, look_at)
    distance = _norm(v)
    # (the exponent held to +-100, e^100 ~ 1e43: a wheel turn of any size stays a finite number,
    # and a camera pushed past the scene's range is refused as a camera value)
    new = max(distance * math.exp(max(-100.0, min(100.0, delta * DOLLY_PER_UNIT))), MIN_DISTANCE)
    return _add(look_at, _scale(v, new / distance))
