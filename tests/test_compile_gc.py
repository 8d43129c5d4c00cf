"""The garbage collector runs less often while Numba compiles, and the caller's thresholds are
back afterwards (kernels/compile_gc.py)."""

import gc

import numba
import pytest
from numba.core import event

import raylume  # noqa: F401  (importing raylume installs the listener)
from raylume.kernels.compile_gc import COMPILING_THRESHOLD


class _Probe(event.Listener):
    """Records the collector's thresholds as each compilation starts (registered after
    raylume's listener, so it runs after it)."""

    def __init__(self):
        self.seen = []

    def on_start(self, ev):
        self.seen.append(gc.get_threshold())

    def on_end(self, ev):
        pass


@pytest.fixture
def probe():
    listener = _Probe()
    with event.install_listener("numba:compile", listener):
        yield listener


@pytest.fixture
def thresholds():
    saved = gc.get_threshold()
    yield
    gc.set_threshold(*saved)


def test_a_compilation_runs_with_the_raised_threshold_and_restores_the_callers(probe, thresholds):
    gc.set_threshold(1234, 7, 9)

    @numba.njit
    def inner(x):
        return x + 1

    @numba.njit
    def outer(x):
        return inner(x) * 2  # compiles inner inside outer's compilation

    assert outer(3) == 8
    assert len(probe.seen) == 2
    assert all(seen == (COMPILING_THRESHOLD, 7, 9) for seen in probe.seen)
    assert gc.get_threshold() == (1234, 7, 9)


def test_a_failed_compilation_restores_the_thresholds(probe, thresholds):
    gc.set_threshold(900, 10, 10)

    @numba.njit
    def broken(x):
        return x + "a string"

    with pytest.raises(numba.core.errors.TypingError):
        broken(1)
    assert probe.seen == [(COMPILING_THRESHOLD, 10, 10)]
    assert gc.get_threshold() == (900, 10, 10)


def test_a_caller_that_turned_collection_off_by_threshold_keeps_it_off(probe, thresholds):
    gc.set_threshold(0, 10, 10)

    @numba.njit
    def f(x):
        return x - 1

    assert f(1) == 0
    assert probe.seen == [(0, 10, 10)]
    assert gc.get_threshold() == (0, 10, 10)


def test_a_higher_threshold_of_the_callers_is_left_alone(probe, thresholds):
    gc.set_threshold(10 * COMPILING_THRESHOLD, 10, 10)

    @numba.njit
    def f(x):
        return x * 3

    assert f(2) == 6
    assert probe.seen == [(10 * COMPILING_THRESHOLD, 10, 10)]
    assert gc.get_threshold() == (10 * COMPILING_THRESHOLD, 10, 10)
