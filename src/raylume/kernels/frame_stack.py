"""Room on CPython's frame stack for Numba's compiler.

CPython (3.11 to 3.13 at least) keeps a thread's frames in 16 KiB chunks. It maps a new chunk
when a call does not fit in the current one, and unmaps it as soon as that call returns. A loop
whose callee's frame lands just past a chunk's end therefore maps and unmaps a chunk on every
call: ~11 us a call instead of 40 ns. Numba's compiler recurses deeply (each function it
compiles inside its caller's typing), and where its hot loops fall against the chunk boundaries
depends on every frame below them. A cold compile of raylume.intersect unmapped 9,850 chunks
at issue 13's filing and 298,975 after, ~3 s of ~16 (docs/performance.md, "Cold compile").

A chunk is as large as the frame that opens it needs, rounded up to a power of two. The call
below reserves a value stack of ROOMY_SLOTS slots: its frame opens a 1 MiB chunk of its own,
and about half of it is left for the frames above it, more than Numba's compiler uses
(`strace`: 380 chunks unmapped instead of 316,453 for that compile). A larger co_stacksize
than a function needs only reserves space, so this is safe on any Python; where frames are
kept otherwise, it costs one larger frame a call."""

from __future__ import annotations

import functools
import types
from collections.abc import Callable
from typing import Any, TypeVar

from numba.core.registry import CPUDispatcher

from .vector_width import ENTRY_PIPELINE

# Value-stack slots (8 bytes each) reserved by the frame that calls in: ~528 KB, a 1 MiB chunk.
ROOMY_SLOTS = 66_000

T = TypeVar("T")


def _call(function, args, kwargs):
    return function(*args, **kwargs)


_roomy_call = types.FunctionType(
    _call.__code__.replace(co_stacksize=_call.__code__.co_stacksize + ROOMY_SLOTS), _call.__globals__, "_roomy_call"
)


def on_roomy_frame_stack(function: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
    """function(*args, **kwargs), called from a frame that opens a frame-stack chunk large
    enough for the calls it makes, Numba's compilations included."""
    return _roomy_call(function, args, kwargs)


def roomy_frame_stack(function: Callable[..., T]) -> Callable[..., T]:
    """Decorator: every call of `function` runs as on_roomy_frame_stack runs it."""

    @functools.wraps(function)
    def wrapper(*args: Any, **kwargs: Any) -> T:
        return _roomy_call(function, args, kwargs)

    return wrapper


class _CompilesOnRoomyStack(CPUDispatcher):
    """A Numba entry point whose compilations (and loads from the disk cache) run from a roomy
    frame. Numba calls _compile_for_args only when no compiled version matches the arguments,
    so the calls that find one, every call of a kernel called often, pay nothing for it (a
    roomy frame maps and unmaps 1 MiB: ~14 us, half again a 4-ray raylume.intersect)."""

    def _compile_for_args(self, *args, **kws):
        return _roomy_call(super()._compile_for_args, args, kws)


def roomy_njit(*, cache: bool = False, **options: Any) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """numba.njit(cache=cache, **options) for a kernel that Python calls often: it compiles on a
    roomy frame stack whenever it compiles, for the vector width the CPU prefers
    (vector_width.py)."""

    def decorate(py_func: Callable[..., T]) -> Callable[..., T]:
        dispatcher = _CompilesOnRoomyStack(
            py_func=py_func, locals={}, targetoptions=dict(options, nopython=True), pipeline_class=ENTRY_PIPELINE
        )
        if cache:
            dispatcher.enable_caching()
        return dispatcher

    return decorate
