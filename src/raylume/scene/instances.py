"""A mesh object's `instances`: the placement matrices of its copies, read and checked.

Each matrix maps the object (after its own `transform`) to world space, column-vector
convention: p' = M @ [p, 1]. They come from a `.npy` file of shape (N, 4, 4) or (N, 3, 4)
(relative to the scene file) or from inline transform tables (scale, rotate, translate as for
every object). The compiler (compile/instances.py) stores the mesh once and each copy as its inverse
matrix; problems are InstanceError, reported by the caller with the object's key path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .generated import generator_hint
from .mesh import object_matrix_of
from .model import Mesh

# Beyond this many instances the top-level BVH's build (float64 boxes, sort keys) needs more
# than a few GB; a guard against a mistaken array rather than a limit anyone should meet.
MAX_INSTANCES = 1 << 25
# A matrix whose linear part has |det| below this fraction of the product of its column lengths
# is singular for all practical purposes (its inverse would amplify rounding by 1e12).
SINGULAR = 1e-12


class InstanceError(ValueError):
    """The instances of a mesh object cannot be used (missing file, wrong shape, NaN, singular)."""


def instance_path(obj: Mesh, base_dir: Path) -> Path:
    path = Path(str(obj.instances))
    return path if path.is_absolute() else Path(base_dir) / path


def instance_matrices(obj: Mesh, base_dir: Path) -> np.ndarray | None:
    """float64 (N, 3, 4) object-to-world matrices of the object's instances, or None when it has
    none (the mesh is placed once, by its transform alone). Raises InstanceError."""
    if obj.instances is None:
        return None
    if isinstance(obj.instances, list):
        m = np.stack([object_matrix_of(t)[:3] for t in obj.instances])
        return check_matrices(m, "inline instances")
    path = instance_path(obj, base_dir)
    what = f"instances file {path}"
    if not path.is_file():
        if path.exists():
            raise InstanceError(f"{what} is not a file")
        raise InstanceError(f"{what} does not exist{generator_hint(path)}")
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise InstanceError(f"cannot read {what} as a .npy array: {exc}") from None
    if not isinstance(array, np.ndarray) or not (
        np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)
    ):
        raise InstanceError(f"{what} must hold a float array of shape (N, 4, 4) or (N, 3, 4), not {array.dtype}")
    if array.ndim != 3 or array.shape[1:] not in ((4, 4), (3, 4)):
        raise InstanceError(f"{what} has shape {array.shape}; expected (N, 4, 4) or (N, 3, 4) matrices")
    return check_matrices(array, what)


def check_matrices(m: np.ndarray, what: str) -> np.ndarray:
    """The (N, 3, 4) affine part of (N, 4, 4) or (N, 3, 4) matrices (of any number type) after
    checking that every one is finite, affine and invertible, in float64."""
    n = len(m)
    if n == 0:
        raise InstanceError(f"{what} holds no matrices; give at least one (or leave instances out)")
    if n > MAX_INSTANCES:  # before the float64 copy (a 400 MB int8 file had taken 3.7 GB to refuse)
        raise InstanceError(f"{what} holds {n} matrices, more than the {MAX_INSTANCES} supported")
    m = np.asarray(m, dtype=np.float64)
    finite = np.isfinite(m).all(axis=(1, 2))
    if not finite.all():
        raise InstanceError(f"{what}: matrix {int(np.argmin(finite))} has NaN or infinite entries")
    if m.shape[1] == 4:
        bottom = m[:, 3, :]
        affine = (bottom == (0.0, 0.0, 0.0, 1.0)).all(axis=1)
        if not affine.all():
            k = int(np.argmin(affine))
            raise InstanceError(
                f"{what}: matrix {k} has bottom row {bottom[k].tolist()}; an affine transform's is [0, 0, 0, 1]"
            )
        m = m[:, :3, :]
    a = m[:, :, :3]
    det = np.linalg.det(a)
    scale = np.prod(np.linalg.norm(a, axis=1), axis=1)
    singular = ~(np.abs(det) > SINGULAR * scale)
    if singular.any():
        k = int(np.argmax(singular))
        raise InstanceError(f"{what}: matrix {k} is singular (it flattens the mesh; determinant {det[k]:.3g})")
    # float32 holds the world-to-object matrices (inverse_rows): a scale below ~1e-38 (1e-40:
    # well conditioned, but its inverse 1e40) would be inf there, and the instance drawn only
    # by the rasterizer, which takes the matrix itself. The inverse's entries are cofactors (two
    # products, each <= largest^2) over det, so exact inverses are taken only where that bound
    # leaves a doubt (all of them cost ~0.8 s per million matrices).
    with np.errstate(over="ignore"):
        largest = np.abs(m).max(axis=(1, 2))
        doubt = np.flatnonzero(~(2 * largest**2 / np.abs(det) * (1 + 3 * largest) < FLOAT32_LIMIT))
        inverse_largest = np.zeros(n)
        inverse_largest[doubt] = np.abs(_inverses(m[doubt])).max(axis=(1, 2))
    beyond = ~(inverse_largest < FLOAT32_LIMIT) | ~(largest < FLOAT32_LIMIT)
    if beyond.any():
        k = int(np.argmax(beyond))
        raise InstanceError(
            f"{what}: matrix {k} (entries up to {largest[k]:.3g}) or its inverse (up to {inverse_largest[k]:.3g}) "
            "is beyond float32's range, which holds instances' matrices: scale by between 1e-30 and 1e30"
        )
    return np.ascontiguousarray(m, dtype=np.float64)


FLOAT32_LIMIT = 1e38  # below float32's largest, 3.4e38


def _inverses(m: np.ndarray) -> np.ndarray:
    """float64 (N, 3, 4): each (3, 4) affine matrix's inverse (world to object)."""
    inv = np.linalg.inv(m[:, :, :3])
    t = -np.einsum("nij,nj->ni", inv, m[:, :, 3])
    return np.concatenate([inv, t[:, :, None]], axis=2)


def inverse_rows(m: np.ndarray) -> np.ndarray:
    """float32 (N, 12): each (3, 4) matrix's inverse (world to object), row-major, computed in
    float64 and rounded once."""
    return np.ascontiguousarray(_inverses(m).reshape(len(m), 12), dtype=np.float32)
