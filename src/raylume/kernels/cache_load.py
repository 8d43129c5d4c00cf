"""Loading raylume's kernels from Numba's disk cache without Numba's registry refresh.

Before it looks in its disk cache, Numba refreshes the CPU target: it imports every module of
typing and lowering rules it has (numpy's linear algebra, random generators, typed containers,
jitclass, ...) and installs their templates, ~0.45 s of a warm `raylume render`'s ~1.6 s. Code
loaded from the cache needs none of it, only Numba's runtime (reference counting and
allocation, `rtsys.initialize`); a compile, when one comes, refreshes as before. This applies
to raylume's own functions alone (other packages' Numba functions load as Numba loads them),
and only with the Numba internals it was written against (else Numba's own path)."""

from numba.core.caching import FunctionCache
from numba.core.runtime import rtsys

_NUMBA_LOAD = FunctionCache.load_overload
_OURS = __name__.split(".")[0] + "."  # "raylume."
_KNOWN = all(hasattr(FunctionCache, name) for name in ("_load_overload", "_guard_against_spurious_io_errors"))


def _load_overload(self, sig, target_context):
    """FunctionCache.load_overload: the cached overload for `sig`, or None."""
    py_func = getattr(self, "_py_func", None)
    if not (_KNOWN and getattr(py_func, "__module__", "").startswith(_OURS)):
        return _NUMBA_LOAD(self, sig, target_context)
    rtsys.initialize(target_context)  # what cached code calls: NRT's allocation and refcounts
    with self._guard_against_spurious_io_errors():
        return self._load_overload(sig, target_context)


def load_without_refresh() -> None:
    """Install the loading above (idempotent)."""
    FunctionCache.load_overload = _load_overload
