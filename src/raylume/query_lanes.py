"""Batch ray queries on the lanes' threads (the host side of kernels/geometry/query.py): the rays'
chunks shared among threads, each running a nogil lane kernel."""

from __future__ import annotations

import numpy as np

from .kernels.geometry.query import chunk_layout, intersect_lane, occluded_lane
from .lanes import lane_pool


def _run_lanes(kernel, args, shares: int, lanes: int, unit: bool) -> int:
    """kernel(*args, lane, lanes, unit, bad) on `lanes` threads (the calling one and the kept
    pool's, as a render runs its lanes: a parfor (prange) did the same and cost ~1.7 s of cold
    compile), at most one per share of the work (a chunk, or an image's band); returns the rays
    the lanes refused (bad's sum)."""
    bad = np.zeros(max(1, lanes), dtype=np.int64)
    lanes = max(1, min(lanes, shares))
    if lanes == 1:
        kernel(*args, 0, 1, unit, bad)
        return int(bad.sum())
    pool = lane_pool(lanes - 1)
    futures = [pool.submit(kernel, *args, lane, lanes, unit, bad) for lane in range(1, lanes)]
    kernel(*args, 0, lanes, unit, bad)
    for f in futures:
        f.result()
    return int(bad.sum())


def ray_spans(tmin, tmax, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """tmin (at least 0) and tmax (numbers, or arrays that broadcast to the rays' leading shape) as the
    kernels read them (span_of): arrays of one value where both are one number (no array the
    size of the rays), else C-contiguous 1-D arrays of one per ray, in the rays' order."""
    for name, v in (("tmin", tmin), ("tmax", tmax)):
        if v is None:  # (numpy would read it as NaN, and every ray would miss)
            raise ValueError(f"{name} must be a number or an array of numbers, not None")
    tmin, tmax = (np.asarray(v, dtype=np.float64) for v in (tmin, tmax))
    if np.isnan(tmin).any() or np.isnan(tmax).any():
        raise ValueError("tmin and tmax must not be NaN (tmax may be inf: no limit)")
    # A ray starts at its origin: the box test keeps no part of a box behind it (as Embree
    # asks tnear >= 0), so a negative tmin would find only what its leaves hold behind it.
    if not (tmin >= 0).all():
        raise ValueError("tmin must be at least 0: rays start at their origin (move it back to find hits behind it)")
    if tmin.size == 1 and tmax.size == 1:
        return tmin.reshape(1), tmax.reshape(1)
    try:
        return tuple(np.ascontiguousarray(np.broadcast_to(v, shape).reshape(-1)) for v in (tmin, tmax))
    except ValueError:
        raise ValueError(f"tmin and tmax must broadcast to the rays' shape {shape}") from None


def intersect_rays(
    S,
    X,
    origins,
    directions,
    t_out,
    object_out,
    prim_out,
    instance_out,
    lanes: int,
    unit: bool = False,
    tmin=0.0,
    tmax=np.inf,
    width: int = 0,
) -> int:
    """Closest hit of each ray between tmin and tmax (numbers, or arrays of one per ray) into
    the outputs: t = inf, object = prim = instance = -1 for misses; instance is the instance's
    index within its object, 0 off instances. X: the scene's `features(S)` (kernels/variants.py).
    Directions are unit vectors, or with `unit` of any length: each lane then divides its
    chunk's directions by their lengths as it reaches them (raylume.intersect: in numpy, before
    the kernel, that had taken ~80% of the kernel's own time), and the count of rays with a
    component that is not finite or a zero direction is returned (0 without `unit`). width:
    the rays' row length where they form an image (grid_width), traced then in packets of
    4 x 2 neighbours where the lanes copy their chunks anyway (`unit`) and one tmin and one
    tmax serve every ray; 0: the rays in their own order. The rays' chunks are shared among
    `lanes` threads, each running the nogil intersect_lane."""
    tmin, tmax = ray_spans(tmin, tmax, origins.shape[:1])
    if not unit or tmin.shape[0] > 1 or tmax.shape[0] > 1:
        width = 0
    layout = chunk_layout(origins.shape[0], width)
    args = (S, X, origins, directions, (tmin, tmax), (t_out, object_out, prim_out, instance_out), width, layout)
    return _run_lanes(intersect_lane, args, layout[0], lanes, unit)


def occluded_rays(S, X, origins, directions, tmin, tmax, out, lanes: int, unit: bool = False) -> int:
    """Whether anything lies along each ray between tmin and tmax (numbers, or arrays of one
    per ray) into `out` (bool): shadow and visibility rays, each stopping at the first blocker
    found. Directions, `unit` and the returned count as intersect_rays says."""
    args = (S, X, origins, directions, *ray_spans(tmin, tmax, origins.shape[:1]), out)
    return _run_lanes(occluded_lane, args, chunk_layout(origins.shape[0], 0)[0], lanes, unit)
