"""Numba kernels, in rooms: geometry, shading, integrators, film, raster (docs/architecture.md).
Importing this package points Numba's on-disk cache at a folder named after a hash of the
kernel sources, every room's: Numba checks only the timestamp of the file holding a cached
entry point, so an edit to a function it calls (in another module) would otherwise run stale
machine code. Kernels import only kernels (tests/test_architecture.py), so everything compiled
into a kernel, constants included, is in this hash. It also makes Python's garbage collector
run less often while Numba compiles (compile_gc.py), and loads raylume's kernels from the cache
without Numba's registry refresh (cache_load.py)."""

import hashlib
import os
from pathlib import Path

import numba

from .cache_load import load_without_refresh
from .compile_gc import collect_less_while_compiling


def _kernel_source_hash(root: Path = Path(__file__).parent) -> str:
    """A hash of every kernel module's path and source, in every room below `root`."""
    digest = hashlib.sha1()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def _configure_cache() -> None:
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "raylume"
    )
    numba.config.CACHE_DIR = os.path.join(base, f"kernels-{_kernel_source_hash()}")


_configure_cache()
collect_less_while_compiling()
load_without_refresh()
