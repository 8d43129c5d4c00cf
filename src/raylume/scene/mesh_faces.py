"""A loaded mesh's faces checked in one compiled pass: which are degenerate (zero area up to
float64 rounding), and whether every index names a vertex; and the box of the vertices they use.

In numpy the test took ~0.85 s of a 4M-triangle mesh's 1.0 s load_mesh (warm; more on a first
load, whose temporaries' pages fault in): the three vertex gathers, np.cross and the dot
products each made (F, 3) float64 temporaries of ~100 MB. Here a face is read once and nothing
is allocated but the answer. Imported by scene/mesh.py only when a mesh is placed, so that the
command line's --help and scene files without meshes do not load Numba for it.
"""

from __future__ import annotations

import numba as nb
import numpy as np


def _kernel_arrays(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' inputs: C-contiguous float64 vertices, faces as int32 or int64 (one compiled
    signature each)."""
    f = np.ascontiguousarray(faces)
    if f.dtype not in (np.int32, np.int64):
        f = f.astype(np.int64)
    return np.ascontiguousarray(vertices, dtype=np.float64), f


@nb.njit(cache=True, nogil=True)
def _nondegenerate(v, f, sin2, good):
    """good[i]: face i's area^2 above sin2 times the product of its two edges' squared lengths
    from vertex 0, the numpy expression in place_mesh's comment operation for operation (no
    FMA: Numba contracts nothing without fastmath). Returns the number of faces with an index
    outside 0 .. len(v) - 1 (their `good` is False)."""
    n = v.shape[0]
    bad = 0
    for i in range(f.shape[0]):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        if a < 0 or b < 0 or c < 0 or a >= n or b >= n or c >= n:
            good[i] = False
            bad += 1
            continue
        e1x, e1y, e1z = v[b, 0] - v[a, 0], v[b, 1] - v[a, 1], v[b, 2] - v[a, 2]
        e2x, e2y, e2z = v[c, 0] - v[a, 0], v[c, 1] - v[a, 1], v[c, 2] - v[a, 2]
        # np.cross's components: a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0
        cx = e1y * e2z - e1z * e2y
        cy = e1z * e2x - e1x * e2z
        cz = e1x * e2y - e1y * e2x
        area2 = cx * cx + cy * cy + cz * cz
        scale2 = (e1x * e1x + e1y * e1y + e1z * e1z) * (e2x * e2x + e2y * e2y + e2z * e2z)
        good[i] = area2 > sin2 * scale2
    return bad


def nondegenerate_faces(vertices: np.ndarray, faces: np.ndarray, sin2: float) -> tuple[np.ndarray, int]:
    """(good, bad): for float64 (V, 3) vertices and integer (F, 3) faces, bool (F,) True where a
    face's squared area exceeds sin2 times |e1|^2 |e2|^2 (e1, e2 its edges from its first
    vertex), as np.einsum of np.cross would find it; and how many faces index no vertex."""
    v, f = _kernel_arrays(vertices, faces)
    good = np.empty(len(f), dtype=bool)
    bad = _nondegenerate(v, f, float(sin2), good)
    return good, int(bad)


@nb.njit(cache=True, nogil=True)
def _used_bounds(v, f, lo, hi):
    for k in range(3):
        lo[k] = np.inf
        hi[k] = -np.inf
    for i in range(f.shape[0]):
        for j in range(3):
            a = f[i, j]
            for k in range(3):
                x = v[a, k]
                if x < lo[k]:
                    lo[k] = x
                if x > hi[k]:
                    hi[k] = x


def used_bounds(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): the bounding box of the vertices that faces use (faces index vertices, none
    outside; at least one face). As a mask of the used vertices and their copy, 0.2 s at 4M
    triangles."""
    v, f = _kernel_arrays(vertices, faces)
    lo, hi = np.empty(3), np.empty(3)
    _used_bounds(v, f, lo, hi)
    return lo, hi
