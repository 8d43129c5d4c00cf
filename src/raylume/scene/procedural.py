"""Procedural triangle meshes built with numpy alone.

Tests, examples and benchmarks use these so that they never depend on mesh
files outside the repository. Every generator is fully vectorised (no Python
loop over triangles), so millions of triangles take a second or two.

Conventions shared with :mod:`raylume.scene.mesh`: vertices are float64
``(V, 3)``, faces int32 ``(F, 3)`` wound counter-clockwise seen from the front,
i.e. ``cross(v1 - v0, v2 - v0)`` points outward (up for the plane). +y is up.
"""

from __future__ import annotations

import numpy as np

__all__ = ["uv_sphere", "bumpy_sphere", "grid_plane", "vertex_normals"]


def _sphere_grid(n_triangles: int) -> tuple[int, int]:
    """Pick (stacks, segments) so that a UV sphere has about n triangles.

    With pole fans the count is exactly 2 * segments * (stacks - 1). Segments
    ~ 2 * stacks keeps the quads near the equator roughly square; trying a few
    stack counts around that keeps the error well under 2% from 1k triangles up.
    """
    n = max(int(n_triangles), 1)
    guess = max(2, round((n / 4) ** 0.5) + 1)
    best = None
    for stacks in range(max(2, guess - 3), guess + 4):
        segments = max(3, round(n / (2 * (stacks - 1))))
        err = abs(2 * segments * (stacks - 1) - n)
        if best is None or err < best[0]:
            best = (err, stacks, segments)
    return best[1], best[2]


def _unit_sphere(n_triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit UV sphere around the y axis: poles are single vertices joined by
    triangle fans (quads collapsing at a pole would give zero-area triangles),
    and the seam shares its vertices, so the mesh is closed and watertight."""
    stacks, k = _sphere_grid(n_triangles)
    theta = np.pi * np.arange(1, stacks) / stacks  # ring polar angles, poles excluded
    phi = 2.0 * np.pi * np.arange(k) / k
    st = np.sin(theta)[:, None]
    rings = np.stack(
        [st * np.cos(phi), np.broadcast_to(np.cos(theta)[:, None], (stacks - 1, k)), st * np.sin(phi)],
        axis=-1,
    ).reshape(-1, 3)
    vertices = np.concatenate([[[0.0, 1.0, 0.0]], rings, [[0.0, -1.0, 0.0]]])
    top, bottom = 0, len(vertices) - 1

    i = np.arange(k)
    ring = lambda r, seg: 1 + r * k + seg % k  # noqa: E731 - vertex index of ring r, segment seg
    # Windings chosen so cross(v1 - v0, v2 - v0) points away from the centre.
    top_fan = np.stack([np.full(k, top), ring(0, i + 1), ring(0, i)], axis=1)
    r = np.arange(stacks - 2)[:, None]
    a, b, c, d = ring(r, i), ring(r, i + 1), ring(r + 1, i), ring(r + 1, i + 1)
    bands = np.stack([a, b, c, b, d, c], axis=-1).reshape(-1, 3)
    last = stacks - 2
    bottom_fan = np.stack([np.full(k, bottom), ring(last, i), ring(last, i + 1)], axis=1)
    faces = np.concatenate([top_fan, bands, bottom_fan]).astype(np.int32)
    return vertices, faces


def uv_sphere(n_triangles: int, radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Closed UV sphere (poles on the y axis) with about ``n_triangles`` faces (at least 6)."""
    vertices, faces = _unit_sphere(n_triangles)
    return vertices * float(radius) + np.asarray(center, dtype=np.float64), faces


def bumpy_sphere(
    n_triangles: int, radius: float = 1.0, bumpiness: float = 0.15, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """The benchmark mesh: a UV sphere displaced radially by a smooth random field.

    The displacement is a normalised sum of a few plane waves evaluated at the
    unit direction of each vertex, so it is continuous across the seam and the
    poles (the mesh stays watertight), lies in [-1, 1], and the radius stays in
    ``radius * [1 - bumpiness, 1 + bumpiness]``. Being a radial graph over the
    sphere, the surface cannot self-intersect and every face keeps its outward
    winding. Deterministic for a given ``seed``.
    """
    if not 0.0 <= bumpiness < 1.0:
        raise ValueError(f"bumpiness must be in [0, 1), got {bumpiness}")
    dirs, faces = _unit_sphere(n_triangles)
    rng = np.random.default_rng(seed)
    n_waves = 6
    waves = rng.normal(size=(n_waves, 3))
    # Frequencies 2..6 rad per unit length: a handful of lumps, smooth at any resolution.
    waves *= (rng.uniform(2.0, 6.0, n_waves) / np.linalg.norm(waves, axis=1))[:, None]
    phase = rng.uniform(0.0, 2.0 * np.pi, n_waves)
    amp = rng.uniform(0.5, 1.0, n_waves)
    field = np.sin(dirs @ waves.T + phase) @ (amp / amp.sum())
    vertices = dirs * (float(radius) * (1.0 + bumpiness * field))[:, None]
    return vertices, faces


def grid_plane(nx: int, nz: int, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Flat ``size`` x ``size`` square in the y = 0 plane, centred on the origin,
    split into nx by nz cells of two triangles each; the front faces +y."""
    if nx < 1 or nz < 1:
        raise ValueError(f"grid_plane needs nx >= 1 and nz >= 1, got {nx}, {nz}")
    half = 0.5 * float(size)
    x, z = np.meshgrid(np.linspace(-half, half, nx + 1), np.linspace(-half, half, nz + 1))
    vertices = np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(nx), np.arange(nz))
    a = (j * (nx + 1) + i).ravel()
    b, c = a + 1, a + nx + 1
    d = c + 1
    faces = np.stack([a, c, b, b, c, d], axis=1).reshape(-1, 3).astype(np.int32)
    return vertices, faces


def vertex_normals(vertices, faces) -> np.ndarray:
    """Area-weighted unit vertex normals, float32 (V, 3).

    Each face adds its unnormalised cross product (length = twice its area) to
    its three corners. Vertices that no face with area touches get +y rather
    than NaN, so the result is always unit length.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    weighted = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    # bincount per (corner, axis) is much faster than np.add.at on millions of faces.
    acc = np.zeros((len(v), 3))
    for corner in range(3):
        for axis in range(3):
            acc[:, axis] += np.bincount(f[:, corner], weights=weighted[:, axis], minlength=len(v))
    length = np.linalg.norm(acc, axis=1)
    out = np.zeros_like(acc)
    out[:, 1] = 1.0
    ok = length > 0
    out[ok] = acc[ok] / length[ok, None]
    return out.astype(np.float32)
