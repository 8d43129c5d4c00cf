"""raylume's kernels load from Numba's disk cache without Numba's registry refresh (its typing
and lowering rules: a third of a warm render), and draw the same image; other packages' Numba
functions load as Numba loads them."""

from __future__ import annotations

import subprocess
import sys

from numba.core.caching import FunctionCache

from raylume.kernels import cache_load

RENDER = """
import hashlib
import sys
from numba.core import base
refreshes = []
refresh = base.BaseContext.refresh
base.BaseContext.refresh = lambda self: (refreshes.append(1), refresh(self))[1]
import raylume
image = raylume.render(raylume.builtin_scene("seed").with_render(width=64, height=48), aovs=False)
sys.stdout.write(f"{len(refreshes)} {hashlib.sha256(image.rgb.tobytes()).hexdigest()}")
"""


def _render_in_a_new_process() -> tuple[int, str]:
    out = subprocess.run([sys.executable, "-c", RENDER], capture_output=True, text=True, check=True).stdout
    refreshes, *image = out.split()
    return int(refreshes), " ".join(image)


def test_a_cached_kernel_loads_without_a_refresh_and_draws_the_same():
    _, first = _render_in_a_new_process()  # compiles the seed's kernel, or loads it
    refreshes, again = _render_in_a_new_process()
    assert refreshes == 0
    assert again == first


def test_other_packages_functions_load_as_numba_loads_them(monkeypatch):
    calls = []
    monkeypatch.setattr(cache_load, "_NUMBA_LOAD", lambda self, sig, ctx: calls.append(self) or "numba's")

    def elsewhere(x):
        return x

    elsewhere.__module__ = "someone_else.kernels"
    cache = FunctionCache.__new__(FunctionCache)
    cache._py_func = elsewhere
    assert cache_load._load_overload(cache, None, None) == "numba's"
    assert calls == [cache]
