"""The threads that run a render's lanes (and raylume.intersect's), kept from one call to the
next.

A lane is a nogil kernel on a Python thread. A pool made for each render started its threads
anew every time, and a new thread often began on the busy core, beside the lane already
running, and shared it for milliseconds before the scheduler moved it: the seed's two lanes took
9-10 ms instead of 5-6 in half of the renders on this project's 2-core machine. Threads kept
waiting between renders wake where they last ran.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None
_size = 0


def lane_pool(workers: int) -> ThreadPoolExecutor:
    """A pool of at least `workers` threads, shared by every render in the process. Jobs of
    renders running at once (from several threads) queue in it; a lane never waits on another
    job, so they only wait their turn."""
    global _pool, _size
    with _lock:
        if _pool is None or _size < workers:
            # A render still holding the smaller pool submits its lanes to it; once no render
            # holds it, it is collected and its idle threads end.
            _size = max(workers, os.cpu_count() or 1)
            _pool = ThreadPoolExecutor(max_workers=_size, thread_name_prefix="raylume")
        return _pool


def _forget_pool() -> None:
    """In a forked child the pool's threads do not exist: start a new pool there."""
    global _pool, _size, _lock
    _pool, _size = None, 0
    _lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)
