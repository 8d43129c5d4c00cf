"""How long Numba spent compiling during a block of code: the scene build's first use of the
BVH builder compiles it (seconds, once per machine), and that is compilation, not building.

    with JitClock(on_compile=lambda: print("compiling...")) as clock:
        build_bvh(...)
    clock.seconds  # time inside Numba's compilations (or cache loads) on this thread

Numba announces every compilation as a `numba:compile` event; compilations nest (a kernel
compiles its callees inside its own), so only the outermost ones on the clock's thread count."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from numba.core import event

_local = threading.local()


def _clocks() -> list:
    clocks = getattr(_local, "clocks", None)
    if clocks is None:
        clocks = _local.clocks = []
    return clocks


class _Listener(event.Listener):
    def on_start(self, ev) -> None:
        depth = getattr(_local, "depth", 0)
        _local.depth = depth + 1
        if depth == 0:
            _local.started = time.perf_counter()
            for clock in _clocks():
                clock._started()

    def on_end(self, ev) -> None:
        _local.depth = getattr(_local, "depth", 1) - 1
        if _local.depth == 0:
            seconds = time.perf_counter() - _local.started
            for clock in _clocks():
                clock.seconds += seconds


_registered = False
_register_lock = threading.Lock()


class JitClock:
    """Seconds of Numba compilation on this thread while the block runs; `on_compile` is called
    when the first of them starts."""

    def __init__(self, on_compile: Callable[[], None] | None = None):
        self.seconds = 0.0
        self.compiled = False
        self._on_compile = on_compile

    def _started(self) -> None:
        if not self.compiled:
            self.compiled = True
            if self._on_compile is not None:
                self._on_compile()

    def __enter__(self) -> JitClock:
        global _registered
        with _register_lock:
            if not _registered:
                event.register("numba:compile", _Listener())
                _registered = True
        _clocks().append(self)
        return self

    def __exit__(self, *exc) -> bool:
        _clocks().remove(self)
        return False
