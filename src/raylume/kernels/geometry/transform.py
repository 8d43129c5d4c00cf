"""Object transforms applied to analytic shapes and lights when they are packed (numpy, the
host side of the kernels' modules): `pack` functions receive the object's 4x4 object-to-world
matrix (compile/objects.py makes it from the model's `transform`)."""

import numpy as np


def unit_vector(v) -> np.ndarray:
    """v / |v|, scaled first so that tiny but non-zero vectors (1e-200) do not underflow."""
    v = np.asarray(v, dtype=np.float64)
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def transform_point(m: np.ndarray, p) -> np.ndarray:
    return m[:3, :3] @ np.asarray(p, dtype=np.float64) + m[:3, 3]


def transform_vector(m: np.ndarray, v) -> np.ndarray:
    return m[:3, :3] @ np.asarray(v, dtype=np.float64)


def transform_unit_normal(m: np.ndarray, n) -> np.ndarray:
    """A normal maps by the inverse transpose; returned as a unit vector."""
    return unit_vector(np.linalg.inv(m[:3, :3]).T @ np.asarray(n, dtype=np.float64))


def uniform_scale(m: np.ndarray) -> float:
    """The scale factor of a similarity transform (the model refuses non-uniform scales for
    disks and cylinders, which would make them elliptic)."""
    return float(abs(np.linalg.det(m[:3, :3])) ** (1.0 / 3.0))
