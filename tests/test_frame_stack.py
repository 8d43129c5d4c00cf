"""A call through frame_stack.on_roomy_frame_stack gives the calls above it room on CPython's
frame stack: a loop whose callee's frame would open a new 16 KiB chunk on every call (mapped,
touched, unmapped) opens none (raylume/frame_stack.py). Counted in minor page faults, which a
freshly mapped chunk costs at least once."""

import sys
import types

import pytest

from raylume.kernels.frame_stack import on_roomy_frame_stack, roomy_frame_stack

resource = pytest.importorskip("resource")

CALLS = 200  # calls of the loop's callee at each frame size
CHUNK_SLOTS = 16 * 1024 // 8  # a frame-stack chunk, in 8-byte slots


def _leaf():
    return 1


def _loop():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(CALLS):
        _leaf()
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def _loop_reserving(extra):
    """_loop with a frame `extra` slots larger."""
    code = _loop.__code__
    return types.FunctionType(code.replace(co_stacksize=code.co_stacksize + extra), _loop.__globals__)


def _most_faults():
    """The most page faults of CALLS calls of _leaf from _loop frames of every size over a
    chunk's length, in steps smaller than _leaf's frame: at one size at least, _loop's frame
    ends too close to its chunk's end for _leaf's, which opens a chunk on every call."""
    return max(_loop_reserving(extra)() for extra in range(0, CHUNK_SLOTS + 8, 4))


def test_calls_pass_their_arguments_results_and_exceptions():
    assert on_roomy_frame_stack(lambda a, b=2: (a, b), 1, b=5) == (1, 5)

    @roomy_frame_stack
    def fails(x):
        raise KeyError(x)

    with pytest.raises(KeyError):
        fails(3)
    assert fails.__name__ == "fails"


def test_a_loop_that_opens_a_frame_chunk_per_call_opens_none_above_a_roomy_frame():
    plain = _most_faults()
    if plain < CALLS:
        pytest.skip(f"Python {sys.version.split()[0]} opened no frame-stack chunk per call here")
    assert on_roomy_frame_stack(_most_faults) < CALLS // 10
