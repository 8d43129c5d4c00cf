"""Shared fixtures: small scenes built in code, the shared real meshes (skipped when absent)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_MODELS = REPO.parent / "shared" / "models"


@pytest.fixture
def shared_models() -> Path:
    if not SHARED_MODELS.is_dir():
        pytest.skip(f"real meshes not available: {SHARED_MODELS} is absent (CI and developers have ../shared)")
    return SHARED_MODELS


def _say(line: str) -> None:
    """A line on the terminal itself, before pytest prints anything (a first run waits minutes
    for the warm-up below): sys.__stderr__, which pytest's capture of sys.stderr leaves alone."""
    if sys.__stderr__ is not None:
        sys.__stderr__.write(line + "\n")
        sys.__stderr__.flush()


def pytest_configure(config) -> None:
    """With pytest-xdist workers (make test: -n 2), compile every kernel variant first, in as many
    processes side by side (python -m raylume.warmup --part I/N), into Numba's disk cache. The
    workers then load kernels instead of compiling them, and never compile one kernel twice at
    the same time, each for its own first test (a cold run: 9 min 22 s before this)."""
    if hasattr(config, "workerinput"):
        return  # a worker: the controller has warmed the cache
    workers = config.getoption("numprocesses", default=None)
    if not isinstance(workers, int) or workers < 2:
        return  # one process: kernels compile as the tests reach them
    _say("compiling raylume's kernels before the tests (a few minutes on a first run; loaded from the cache after)...")
    started = time.perf_counter()
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "raylume.warmup", "--part", f"{i}/{workers}", "--quiet"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for i in range(workers)
    ]
    for proc in procs:
        out, _ = proc.communicate()
        if proc.returncode != 0:  # not fatal here: the tests that need the kernel will fail and say why
            sys.stderr.write(f"kernel warm-up failed ({' '.join(proc.args[1:])}):\n{out}\n")
    _say(f"kernels ready in {time.perf_counter() - started:.0f} s")
