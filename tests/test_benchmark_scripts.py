"""The benchmark scripts as a user runs them (benchmarks/README.md): `--help` answers without
running anything, and a script that needs a module of the bench extra that is not installed says
so in one line instead of a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


def _run(tmp_path, *args, missing: tuple[str, ...] = ()):
    """A script run with the modules `missing` made uninstalled (a folder earlier on the path
    whose module of that name raises ModuleNotFoundError, as a missing one does)."""
    shim = tmp_path / "shim"
    shim.mkdir(exist_ok=True)
    for name in missing:
        message = f"No module named {name!r}"
        (shim / f"{name}.py").write_text(f"raise ModuleNotFoundError({message!r}, name={name!r})\n")
    env = {**os.environ, "PYTHONPATH": str(shim)}
    return subprocess.run(
        [sys.executable, str(BENCH / args[0]), *args[1:]], capture_output=True, text=True, timeout=300, env=env
    )


def test_run_all_answers_help_and_refuses_what_it_does_not_take(tmp_path):
    """--help had started the full half-hour run (only --quick was looked for)."""
    result = _run(tmp_path, "run_all.py", "--help")
    assert result.returncode == 0 and "--quick" in result.stdout and "## " not in result.stdout
    refused = _run(tmp_path, "run_all.py", "--bogus")
    assert refused.returncode == 2 and "unrecognized arguments: --bogus" in refused.stderr


@pytest.mark.parametrize(
    "args, module",
    [
        (("bench_hits.py", "--help"), "embreex"),  # Embree is bound when the module loads
        (("mitsuba_scene.py", "compare", "--width", "16", "--height", "8", "--spp", "1"), "mitsuba"),
    ],
)
def test_a_missing_bench_extra_is_one_line(tmp_path, args, module):
    result = _run(tmp_path, *args, missing=(module,))
    assert "Traceback" not in result.stderr, result.stderr
    if args[-1] == "--help":
        assert result.returncode == 0 and "usage:" in result.stdout
    else:
        assert result.returncode == 1
        assert result.stderr.strip() == (
            f"{args[0]}: needs {module}, which raylume's bench extra installs: make bench (pip install -e '.[bench]')"
        )
