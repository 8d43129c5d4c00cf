"""Fewer garbage collections while Numba compiles.

Compiling a kernel makes millions of short-lived Python objects (Numba IR, types, llvmlite IR)
and keeps hundreds of thousands alive, so Python's collector, run every 700 allocations, walked
the same live objects again and again: ~1.3 s of a 15 s cold compile of raylume.intersect
(`gc.callbacks`, 1,150 collections). While any Numba compilation runs, the youngest
generation's threshold is raised; the garbage is still collected, in fewer and larger passes,
and the caller's thresholds are back as soon as the outermost compilation ends, even one that
fails. Numba compiles under one global lock, so compilations nest but never overlap."""

import gc

from numba.core import event

# Objects allocated (less those freed) between collections of the youngest generation while
# compiling; Python's default is 700.
COMPILING_THRESHOLD = 100_000


class _FewerCollections(event.Listener):
    def __init__(self) -> None:
        self.depth = 0
        self.saved = gc.get_threshold()

    def on_start(self, ev) -> None:
        if self.depth == 0:
            self.saved = gc.get_threshold()
            if 0 < self.saved[0] < COMPILING_THRESHOLD:
                gc.set_threshold(COMPILING_THRESHOLD, *self.saved[1:])
        self.depth += 1

    def on_end(self, ev) -> None:
        self.depth -= 1
        if self.depth == 0:
            gc.set_threshold(*self.saved)


_listener = _FewerCollections()
_registered = False


def collect_less_while_compiling() -> None:
    """Raise the collector's threshold during every Numba compilation from now on (once)."""
    global _registered
    if not _registered:
        event.register("numba:compile", _listener)
        _registered = True
