"""The threads that run renders' lanes (raylume/lanes.py): kept from one render to the next,
shared by renders running at once, and made anew in a forked child; and the rows the lanes
claim (kernels/integrators/frame.py, claim_row): each row to exactly one lane."""

from __future__ import annotations

import multiprocessing
import threading

import numba
import numpy as np
import pytest

import raylume
from raylume import lanes
from raylume.kernels.integrators.frame import AOV_ROWS, CONTROL_SIZE, PASS_ROWS, STOP, claim_row


def _lane_threads() -> set[int]:
    return {t.ident for t in threading.enumerate() if t.name.startswith("raylume_")}


def test_a_second_render_runs_on_the_first_ones_threads():
    scene = raylume.builtin_scene("seed")
    raylume.render(scene, width=32, height=16, threads=2, aovs=False)
    first = _lane_threads()
    raylume.render(scene, width=32, height=16, threads=2, aovs=False)
    assert first and _lane_threads() == first


def test_renders_at_once_share_the_pool_and_give_their_own_images():
    scene = raylume.builtin_scene("seed")
    alone = {w: raylume.render(scene, width=w, height=24, threads=2, aovs=False).rgb for w in (40, 56, 72)}
    results: dict[int, np.ndarray] = {}

    def render(w: int) -> None:
        results[w] = raylume.render(scene, width=w, height=24, threads=2, aovs=False).rgb

    workers = [threading.Thread(target=render, args=(w,)) for w in alone for _ in range(2)]
    for t in workers:
        t.start()
    for t in workers:
        t.join(timeout=120)
    assert not any(t.is_alive() for t in workers)
    for w, rgb in alone.items():
        np.testing.assert_array_equal(results[w], rgb)


def test_a_larger_render_grows_the_pool():
    pool = lanes.lane_pool(1)
    assert lanes.lane_pool(1) is pool
    bigger = lanes.lane_pool(lanes._size + 1)
    assert bigger is not pool and lanes._size >= 2


def _render_in_child(queue) -> None:
    image = raylume.render(raylume.builtin_scene("seed"), width=24, height=12, threads=2, aovs=False)
    queue.put(float(image.rgb.sum()))


@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="needs the fork start method")
def test_a_forked_child_renders_on_threads_of_its_own():
    """The parent's pool threads do not exist in a child made by fork: it must not wait for them."""
    image = raylume.render(raylume.builtin_scene("seed"), width=24, height=12, threads=2, aovs=False)
    expected = float(image.rgb.sum())
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_render_in_child, args=(queue,), daemon=True)
    child.start()
    child.join(timeout=60)
    if child.exitcode is None:
        child.kill()  # waiting for threads it does not have
        child.join()
    assert child.exitcode == 0
    assert queue.get(timeout=5) == expected


@numba.njit(nogil=True)
def _claim_all(control, counter, seen, n):
    """Claims rows until n are handed out, marking each one claimed in `seen` (per claimer)."""
    while True:
        j = claim_row(control, counter)
        if j >= n:
            return
        seen[j] += 1


def test_every_row_is_claimed_by_exactly_one_lane():
    """Lanes claim rows with an atomic counter: four threads racing over 5 million rows hand out
    each row once (a plain read-increment-write would lose and repeat rows). So many that the
    threads overlap even when a busy machine starts them late."""
    n = 5_000_000
    control = np.zeros(CONTROL_SIZE, dtype=np.int64)
    seen = [np.zeros(n, dtype=np.int8) for _ in range(4)]
    _claim_all(control, PASS_ROWS, np.zeros(n, dtype=np.int8), 0)  # compile (it claims a row)
    control[:] = 0
    workers = [threading.Thread(target=_claim_all, args=(control, PASS_ROWS, s, n)) for s in seen]
    for t in workers:
        t.start()
    for t in workers:
        t.join()
    total = sum(seen)
    assert (total == 1).all()
    assert sum(int(s.sum() > 0) for s in seen) >= 2  # the threads did share the rows
    assert control[STOP] == 0 and control[AOV_ROWS] == 0
