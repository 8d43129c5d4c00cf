"""What a bidirectional pass needs beside the scene, made on the host: the scene's bounding
sphere (lights at infinity send their light subpaths from its disk), the splat sums and filter,
the strategy counts, and the strategy switch for tests."""

import os
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..film.film import FILTER_NEGATIVE
from ..film.splat import splat_filter
from ..shading.lights.registry import visible_bounds
from ..shading.media import grid
from ..shading.media.table import MED_BOX_MAX, MED_BOX_MIN, MED_KIND
from .bdpt import GLINT_ONLY, MAX_SEGMENTS, NO_GLINT
from .bdpt_glint import GLINT_COUNT

STRATEGY_VARIABLE = "RAYLUME_BDPT_STRATEGY"


class BdptPass(NamedTuple):
    """bdpt_lane's extra argument."""

    bounds: np.ndarray  # float64 (4,): the bounding sphere's centre and radius
    splats: np.ndarray  # int64, the film window's splat sums (splat.py)
    filter: np.ndarray  # the splat filter (splat.splat_filter)
    counts: np.ndarray  # int64 (lanes, n, n): samples with a nonzero contribution per (s, t)
    strategy: tuple  # (s, t, mis): s = -1 for every strategy, GLINT_ONLY the glint strategy alone
    glint: np.ndarray  # the glint strategy's cdf over the image's pixels; (1,) without it (bdpt_glint.py)


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
    unweighted (the whole image of paths of s + t - 1 segments, where it can make them);
    "glint" the glint strategy alone, weighted (GLINT_ONLY); "noglint" every strategy but the
    glint strategy (NO_GLINT: bdpt as Veach's, for comparisons)."""
    text = os.environ.get(STRATEGY_VARIABLE, "")
    if not text:
        return -1, -1, 1
    if text.strip() == "glint":
        return GLINT_ONLY, GLINT_ONLY, 1
    if text.strip() == "noglint":
        return NO_GLINT, NO_GLINT, 1
    parts = text.split(",")
    try:
        s, t = int(parts[0]), int(parts[1])
    except (ValueError, IndexError):
        raise ValueError(f"{STRATEGY_VARIABLE}={text!r}: expected 's,t' or 's,t,nomis'") from None
    mis = not (len(parts) > 2 and parts[2].strip() == "nomis")
    return s, t, int(mis)


def bdpt_pass(S, film, lanes: int) -> BdptPass:
    """The extra argument of a bidirectional pass that adds to `film` (its splat sums), the glint
    strategy's cdf the film's if made, else none yet (glint_cdf makes it)."""
    n = MAX_SEGMENTS + 2
    return BdptPass(
        bounding_sphere(S),
        film.enable_splats(),
        splat_filter(film.filter_name),
        np.zeros((lanes, n, n), dtype=np.int64),
        strategy_switch(),
        film.glint if film.glint is not None else np.zeros(1),
    )


def glint_cdf(S, film, strategy: tuple, guide_of: Callable[[np.ndarray], None]) -> np.ndarray:
    """The glint strategy's cdf over the image's pixels (row-major, a leading 0), made once per
    film (every pass of an image samples the same guide); (1,) where the strategy takes no part:
    scenes with media or null boundaries, images of 1 sample per pixel (the pixel's centre, not
    its filter's area), filters with negative lobes, the switch's "noglint" and unweighted
    strategies, or nothing found."""
    if film.glint is None:
        off = S.media_present or S.pass_through or film.pixel_centres
        off = off or np.isfinite(film.filter[FILTER_NEGATIVE]) or strategy[0] == NO_GLINT or strategy[2] == 0
        cdf = np.zeros(1)
        if not off:
            guide = np.zeros((film.height, film.width))
            guide_of(guide)
            guide = _spread(guide)
            sums = np.concatenate([[0.0], np.cumsum(guide.ravel())])  # in order: the same bits anywhere
            if sums[-1] > 0.0 and np.isfinite(sums[-1]):
                cdf = sums
        film.glint = cdf
    return film.glint


def _spread(guide: np.ndarray) -> np.ndarray:
    """The guide summed over each pixel's 3 x 3 neighbourhood: a glint's image straddles pixels
    that its pilot samples may all have missed (any guide keeps the image unbiased). On the head
    lamp at 128 x 72 (6 seeds), bdpt's whole-image RMSE against path mode's at the same time:
    0.82x unspread (a glint pixel without guide), 8.1x over 3 x 3, 6.7x over 5 x 5 (fewer of
    the strategy's samples where the glint is)."""
    padded = np.pad(guide, 1)
    h, w = guide.shape
    rows = padded[0:h, :] + padded[1 : h + 1, :] + padded[2 : h + 2, :]
    return rows[:, 0:w] + rows[:, 1 : w + 1] + rows[:, 2 : w + 2]


def strategy_counts(counts: np.ndarray) -> dict[str, int]:
    """{"s,t": samples} of the strategies that contributed ("glint": the glint strategy's)."""
    total = counts.sum(axis=0)
    names = {GLINT_COUNT: "glint"}
    return {names.get((s, t), f"{s},{t}"): int(total[s, t]) for s, t in zip(*np.nonzero(total))}
