"""Object transforms applied to analytic shapes when they are packed (Python side)."""

import numpy as np


def object_matrix(transform) -> np.ndarray:
    """4x4 object-to-world matrix of a model Transform (see scene/mesh.py)."""
    from ..scene.mesh import transform_matrix

    return transform_matrix(transform.translate, transform.rotate, transform.scale3)


def transform_point(m: np.ndarray, p) -> np.ndarray:
    return m[:3, :3] @ np.asarray(p, dtype=np.float64) + m[:3, 3]


def transform_vector(m: np.ndarray, v) -> np.ndarray:
    return m[:3, :3] @ np.asarray(v, dtype=np.float64)


def transform_unit_normal(m: np.ndarray, n) -> np.ndarray:
    """A normal maps by the inverse transpose; returned as a unit vector."""
    from ..compile import unit_vector

    return unit_vector(np.linalg.inv(m[:3, :3]).T @ np.asarray(n, dtype=np.float64))


def uniform_scale(m: np.ndarray) -> float:
    """The scale factor of a similarity transform (the model refuses non-uniform scales for
    disks and cylinders, which would make them elliptic)."""
    return float(abs(np.linalg.det(m[:3, :3])) ** (1.0 / 3.0))
