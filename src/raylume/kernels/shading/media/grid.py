"""The `grid` medium [Mitsuba 3: heterogeneous with a gridvolume; pbrt-v4: uniformgrid]: a density
array (nz, ny, nx) over a box, interpolated trilinearly between the voxels' centres (clamped to
the outermost centres inside the box, 0 outside it), scaling sigma_a and sigma_s. Tracking
(tracking.py) walks a coarse grid of majorants over the box, so empty space costs one step per
majorant cell, not one tentative collision per unit of the densest voxel's optical depth."""

import math

import numpy as np

from ...vec import inline_function
from .table import (
    MED_BOX_MAX,
    MED_BOX_MIN,
    MED_CELLS,
    MED_DENSITY,
    MED_G,
    MED_MX,
    MED_MY,
    MED_MZ,
    MED_NX,
    MED_NY,
    MED_NZ,
    MED_SIGMA_A,
    MED_SIGMA_S,
    MED_SIGMA_T_MAX,
)

NAME = "grid"
KIND = 1
MAJORANT_CELLS = 16  # majorant cells along each axis (fewer where the grid has fewer voxels)


def pack(medium, row: np.ndarray, density: np.ndarray, density_offset: int, cells_offset: int) -> np.ndarray:
    """Fill the medium's row; returns its majorant cells (mz, my, mx) of sigma_t's largest
    channel times the largest density that trilinear interpolation can give in each cell."""
    row[MED_SIGMA_A : MED_SIGMA_A + 3] = medium.sigma_a
    row[MED_SIGMA_S : MED_SIGMA_S + 3] = medium.sigma_s
    row[MED_G] = medium.g
    row[MED_SIGMA_T_MAX] = max(a + s for a, s in zip(medium.sigma_a, medium.sigma_s))
    row[MED_BOX_MIN : MED_BOX_MIN + 3] = medium.bounds_min
    row[MED_BOX_MAX : MED_BOX_MAX + 3] = medium.bounds_max
    nz, ny, nx = density.shape
    row[MED_DENSITY] = density_offset
    row[MED_NX], row[MED_NY], row[MED_NZ] = nx, ny, nz
    cells = majorant_cells(density)
    row[MED_CELLS] = cells_offset
    row[MED_MZ], row[MED_MY], row[MED_MX] = cells.shape
    return cells * row[MED_SIGMA_T_MAX]


def majorant_cells(density: np.ndarray) -> np.ndarray:
    """Per majorant cell, the largest density a trilinear lookup can return inside it: the
    maximum over the voxels whose centres lie in the cell or one voxel beyond it."""
    shape = density.shape
    m = [min(MAJORANT_CELLS, n) for n in shape]
    out = np.zeros(m, dtype=np.float64)
    edges = [np.linspace(0, n, c + 1) for n, c in zip(shape, m)]  # cell boundaries in voxel units
    for a in range(m[0]):
        z0, z1 = _voxel_range(edges[0], a, shape[0])
        for b in range(m[1]):
            y0, y1 = _voxel_range(edges[1], b, shape[1])
            for c in range(m[2]):
                x0, x1 = _voxel_range(edges[2], c, shape[2])
                out[a, b, c] = density[z0:z1, y0:y1, x0:x1].max()
    return out


def _voxel_range(edges: np.ndarray, cell: int, n: int) -> tuple[int, int]:
    # voxel i's centre is at i + 0.5 (voxel units): a lookup in [e0, e1] blends voxels
    # floor(e0 - 0.5) .. floor(e1 - 0.5) + 1, clamped to the grid
    lo = max(0, math.floor(edges[cell] - 0.5))
    hi = min(n, math.floor(edges[cell + 1] - 0.5) + 2)
    return lo, hi


@inline_function
def density_at(data, density, k, p):
    """The grid's density at the point p (trilinear; 0 outside the box)."""
    nx, ny, nz = int(data[k, MED_NX]), int(data[k, MED_NY]), int(data[k, MED_NZ])
    gx = _grid_coordinate(data, k, p, 0, nx)
    gy = _grid_coordinate(data, k, p, 1, ny)
    gz = _grid_coordinate(data, k, p, 2, nz)
    if gx < -0.5 or gy < -0.5 or gz < -0.5 or gx > nx - 0.5 or gy > ny - 0.5 or gz > nz - 0.5:
        return 0.0
    gx = min(max(gx, 0.0), nx - 1.0)
    gy = min(max(gy, 0.0), ny - 1.0)
    gz = min(max(gz, 0.0), nz - 1.0)
    i0, j0, k0 = (
        min(int(gx), nx - 2 if nx > 1 else 0),
        min(int(gy), ny - 2 if ny > 1 else 0),
        min(int(gz), nz - 2 if nz > 1 else 0),
    )
    fx, fy, fz = gx - i0, gy - j0, gz - k0
    i1, j1, k1 = min(i0 + 1, nx - 1), min(j0 + 1, ny - 1), min(k0 + 1, nz - 1)
    base = int(data[k, MED_DENSITY])
    c000 = density[base + (k0 * ny + j0) * nx + i0]
    c001 = density[base + (k0 * ny + j0) * nx + i1]
    c010 = density[base + (k0 * ny + j1) * nx + i0]
    c011 = density[base + (k0 * ny + j1) * nx + i1]
    c100 = density[base + (k1 * ny + j0) * nx + i0]
    c101 = density[base + (k1 * ny + j0) * nx + i1]
    c110 = density[base + (k1 * ny + j1) * nx + i0]
    c111 = density[base + (k1 * ny + j1) * nx + i1]
    c00 = c000 + (c001 - c000) * fx
    c01 = c010 + (c011 - c010) * fx
    c10 = c100 + (c101 - c100) * fx
    c11 = c110 + (c111 - c110) * fx
    c0 = c00 + (c01 - c00) * fy
    c1 = c10 + (c11 - c10) * fy
    return max(0.0, c0 + (c1 - c0) * fz)


@inline_function
def _grid_coordinate(data, k, p, axis, n):
    """p's coordinate along `axis` in voxel units, voxel centres at integers."""
    lo, hi = data[k, MED_BOX_MIN + axis], data[k, MED_BOX_MAX + axis]
    return (p[axis] - lo) / (hi - lo) * n - 0.5
