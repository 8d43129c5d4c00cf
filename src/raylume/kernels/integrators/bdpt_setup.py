"""What a bidirectional pass needs beside the scene, made on the host: the scene's bounding
sphere (lights at infinity send their light subpaths from its disk), the splat sums and filter,
the strategy counts, and the strategy switch for tests."""

import os
from typing import NamedTuple

import numpy as np

from ..film.splat import splat_filter
from ..shading.lights.registry import visible_bounds
from ..shading.media import grid
from ..shading.media.table import MED_BOX_MAX, MED_BOX_MIN, MED_KIND
from .bdpt import MAX_SEGMENTS

STRATEGY_VARIABLE = "RAYLUME_BDPT_STRATEGY"


class BdptPass(NamedTuple):
    """bdpt_lane's extra argument."""

    bounds: np.ndarray  # float64 (4,): the bounding sphere's centre and radius
    splats: np.ndarray  # int64, the film window's splat sums (splat.py)
    filter: np.ndarray  # the splat filter (splat.splat_filter)
    counts: np.ndarray  # int64 (lanes, n, n): samples with a nonzero contribution per (s, t)
    strategy: tuple  # (s, t, mis): s = -1 for every strategy


def _box_of_nodes(nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    if nodes.shape[0] == 0:
        return None
    lo = nodes[0, 0:3].astype(np.float64).min(axis=1)
    hi = nodes[0, 3:6].astype(np.float64).max(axis=1)
    return (lo, hi) if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo <= hi) else None


def bounding_sphere(S) -> np.ndarray:
    """(centre x, y, z, radius) of a sphere around the scene's bounded geometry, area lights and
    grid media's boxes (a little larger, so that the disk lies outside everything)."""
    boxes = []
    if S.media_present:
        for row in S.medium_data:
            if int(row[MED_KIND]) == grid.KIND:
                boxes.append((row[MED_BOX_MIN : MED_BOX_MIN + 3].copy(), row[MED_BOX_MAX : MED_BOX_MAX + 3].copy()))
    if S.n_bounded > 0:
        boxes.append(_box_of_nodes(S.node_bounds))
    if S.instance_inverse.shape[0] > 0:
        boxes.append(_box_of_nodes(S.inst_node_bounds))
    for e in range(S.n_area_lights):
        boxes.append(visible_bounds(int(S.light_kind[e]), S.light_data[e]))
    boxes = [b for b in boxes if b is not None]
    if not boxes:
        return np.array([0.0, 0.0, 0.0, 1.0])
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    centre = 0.5 * (lo + hi)
    radius = max(float(np.linalg.norm(hi - lo)) * 0.5 * 1.01, 1e-6 * max(1.0, float(np.abs(centre).max())))
    return np.array([*centre, radius])


def strategy_switch() -> tuple[int, int, int]:
    """(s, t, mis) from RAYLUME_BDPT_STRATEGY: unset, every strategy with MIS (-1, -1, 1);
    "s,t" that strategy alone with its MIS weight (its share of the image); "s,t,nomis" alone,
    unweighted (the whole image of paths of s + t - 1 segments, where it can make them)."""
    text = os.environ.get(STRATEGY_VARIABLE, "")
    if not text:
        return -1, -1, 1
    parts = text.split(",")
    try:
        s, t = int(parts[0]), int(parts[1])
    except (ValueError, IndexError):
        raise ValueError(f"{STRATEGY_VARIABLE}={text!r}: expected 's,t' or 's,t,nomis'") from None
    mis = not (len(parts) > 2 and parts[2].strip() == "nomis")
    return s, t, int(mis)


def bdpt_pass(S, film, lanes: int) -> BdptPass:
    """The extra argument of a bidirectional pass that adds to `film` (its splat sums)."""
    n = MAX_SEGMENTS + 2
    return BdptPass(
        bounding_sphere(S),
        film.enable_splats(),
        splat_filter(film.filter_name),
        np.zeros((lanes, n, n), dtype=np.int64),
        strategy_switch(),
    )


def strategy_counts(counts: np.ndarray) -> dict[str, int]:
    """{"s,t": samples} of the strategies that contributed."""
    total = counts.sum(axis=0)
    return {f"{s},{t}": int(total[s, t]) for s, t in zip(*np.nonzero(total))}
