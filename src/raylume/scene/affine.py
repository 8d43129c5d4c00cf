"""A 4 x 4 affine matrix as the `transform` table raylume's scene files take: scale (per axis,
applied first), rotate (degrees about x, then y, then z), translate; the inverse of
scene.mesh.transform_matrix. Matrices that shear have no such table: a ValueError (the caller
then gives the whole `matrix`).
"""

from __future__ import annotations

import math

import numpy as np

ORTHOGONAL = 1e-6  # how far R^T R may be from the identity before the matrix counts as a shear


def decompose(m: np.ndarray) -> dict:
    """{"translate", "rotate", "scale"} with transform_matrix(**it) == m to rounding."""
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (4, 4) or not np.allclose(m[3], (0, 0, 0, 1)):
        raise ValueError("not an affine transformation (its last row must be 0, 0, 0, 1)")
    a = m[:3, :3]
    scale = np.linalg.norm(a, axis=0)
    if np.any(scale == 0):
        raise ValueError("it collapses an axis (a zero scale)")
    r = a / scale
    if np.linalg.det(r) < 0:  # a mirror: carried by a negative x scale, the rest is a rotation
        scale[0], r[:, 0] = -scale[0], -r[:, 0]
    if np.abs(r.T @ r - np.eye(3)).max() > ORTHOGONAL:
        raise ValueError("it shears (a non-uniform scale applied after a rotation)")
    return {"translate": _floats(m[:3, 3]), "rotate": _floats(euler_xyz(r)), "scale": _floats(scale)}


# raylume's sphere has its poles on its object y axis and u = 0.5 at -z (compile: shape_sphere.uv);
# pbrt's and Mitsuba's on z, u = phi / 2pi with phi = atan2(y, x). The columns are raylume's object
# axes x, y, z in their object space: x' = -y, y' = z, z' = x, with which raylume's (u, v) at a point
# is pbrt's (u, v) and Mitsuba's (u, 1 - v) (Mitsuba's v runs from the image's top, raylume's up).
Z_POLE_SPHERE = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def turned(frame: np.ndarray, translate) -> dict:
    """A sphere's transform table placing its object axes on `frame` (3 x 3, orthonormal up to
    rounding, a mirror allowed) at `translate`: the nearest orthonormal frame, as rotate and a
    scale of exactly 1 (or [-1, 1, 1] for a mirror), which the scene model's sphere accepts."""
    u, _, vt = np.linalg.svd(np.asarray(frame, dtype=np.float64))
    r = u @ vt
    scale: float | list[float] = 1.0
    if np.linalg.det(r) < 0:  # a mirror: carried by the x scale, the rest is a rotation
        r[:, 0], scale = -r[:, 0], [-1.0, 1.0, 1.0]
    return {"translate": _floats(translate), "rotate": _floats(euler_xyz(r)), "scale": scale}


def euler_xyz(r: np.ndarray) -> tuple[float, float, float]:
    """Degrees (x, y, z) with Rz @ Ry @ Rx == r, for a rotation matrix r."""
    sy = -r[2, 0]
    if abs(sy) < 1 - 1e-12:
        ax = math.atan2(r[2, 1], r[2, 2])
        ay = math.asin(sy)
        az = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock (y = +-90): only x - z or x + z is fixed; put it all in x
        ay = math.copysign(math.pi / 2, sy)
        ax = math.atan2(math.copysign(1.0, sy) * r[0, 1], r[1, 1])
        az = 0.0
    return tuple(math.degrees(v) for v in (ax, ay, az))  # type: ignore[return-value]


def _floats(values) -> list[float]:
    return [float(v) + 0.0 for v in values]  # + 0.0: no -0.0 in scene files


def is_identity(t: dict) -> bool:
    return t["translate"] == [0.0] * 3 and t["rotate"] == [0.0] * 3 and t["scale"] == [1.0] * 3
