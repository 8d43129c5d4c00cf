"""pbrt-v4's transform directives as 4 x 4 matrices (column vectors, p' = M @ [p, 1]), built as
pbrt builds them (src/pbrt/util/transform.cpp): each directive post-multiplies the current
transformation matrix, so the last one written applies first to a shape's points."""

from __future__ import annotations

import math

import numpy as np

IDENTITY = np.eye(4)


def translate(dx: float, dy: float, dz: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (dx, dy, dz)
    return m


def scale(sx: float, sy: float, sz: float) -> np.ndarray:
    return np.diag([sx, sy, sz, 1.0])


def rotate(degrees: float, axis) -> np.ndarray:
    """A rotation by `degrees` about `axis` (not normalised), pbrt's Rotate: positive angles turn
    clockwise looking down the axis towards the origin, in a left-handed frame."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    theta = math.radians(degrees)
    c, s = math.cos(theta), math.sin(theta)
    x, y, z = a
    m = np.eye(4)
    m[:3, :3] = [
        [x * x + (1 - x * x) * c, x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
        [x * y * (1 - c) + z * s, y * y + (1 - y * y) * c, y * z * (1 - c) - x * s],
        [x * z * (1 - c) - y * s, y * z * (1 - c) + x * s, z * z + (1 - z * z) * c],
    ]
    return m


def look_at(eye, target, up) -> np.ndarray:
    """pbrt's LookAt: the camera-from-world matrix of a camera at `eye` looking at `target`, its
    +y as near `up` as can be, +x = normalize(cross(up, dir)) (pbrt's screen +x: the image's right).
    Raises ValueError when eye == target or up is parallel to the view direction."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    d = target - eye
    if not np.linalg.norm(d) > 0:
        raise ValueError("the eye and the look-at point are the same")
    d = d / np.linalg.norm(d)
    if not np.linalg.norm(up) > 0:
        raise ValueError("the up vector is zero")
    right = np.cross(up / np.linalg.norm(up), d)
    if not np.linalg.norm(right) > 1e-12:
        raise ValueError("the up vector is parallel to the viewing direction")
    right = right / np.linalg.norm(right)
    new_up = np.cross(d, right)
    world_from_camera = np.eye(4)
    world_from_camera[:3, 0], world_from_camera[:3, 1], world_from_camera[:3, 2] = right, new_up, d
    world_from_camera[:3, 3] = eye
    return np.linalg.inv(world_from_camera)


def from_pbrt_numbers(values) -> np.ndarray:
    """Transform / ConcatTransform's 16 numbers, which pbrt lists column by column."""
    return np.array(values, dtype=np.float64).reshape(4, 4).T


def apply_point(m: np.ndarray, p) -> np.ndarray:
    return m[:3, :3] @ np.asarray(p, dtype=np.float64) + m[:3, 3]


def apply_vector(m: np.ndarray, v) -> np.ndarray:
    return m[:3, :3] @ np.asarray(v, dtype=np.float64)


def similarity_scale(m: np.ndarray, columns=(0, 1, 2), tol: float = 1e-6) -> float | None:
    """The common length of the linear part's given columns when they are mutually orthogonal and
    equally long (the transform is a similarity on their span), else None."""
    cols = [m[:3, k] for k in columns]
    lengths = [float(np.linalg.norm(c)) for c in cols]
    top = max(lengths)
    if not top > 0 or max(lengths) - min(lengths) > tol * top:
        return None
    for i in range(len(cols)):
        for j in range(i + 1, len(cols)):
            if abs(float(cols[i] @ cols[j])) > tol * top * top:
                return None
    return lengths[0]


def rows(m: np.ndarray) -> list[list[float]]:
    """A matrix as the scene model's `matrix` (rows of plain floats)."""
    return [[float(x) for x in row] for row in m]
