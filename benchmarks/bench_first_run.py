"""The first picture on a fresh machine: `raylume render` (the built-in seed scene, 600 x 600,
trace mode) in a new process, from an empty folder, with an empty Numba cache, as wall-clock and
CPU seconds of the whole command (Python's start, imports, the kernels' compilation, the render,
the PNG) and the compile time it reports.

    python benchmarks/bench_first_run.py [--repeats 3] [--src DIR --src DIR ...] [--python PY] [-- RENDER ARGS]

With --src, each DIR is a checkout of raylume (its src/ is imported): the builds run in turn, A,
B, A, B, so that a shared machine's drift falls on all of them alike. Medians, and every run.
--python: the interpreter that runs `raylume render` (default: this one). A user's first render
runs in what `make render` installs, raylume and its dependencies alone; the dev extras' scipy
adds ~0.3 s (Numba imports it on its first compile): `python3.11 -m venv /tmp/render-env &&
/tmp/render-env/bin/pip install -e .` makes such an interpreter.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import REPO, machine, median_of, run_main, table


def first_run(src: Path, render_args: list[str], python: str = sys.executable) -> tuple[float, float, float]:
    """(wall s, CPU s, compile_seconds) of one cold `raylume render` with src's raylume."""
    with tempfile.TemporaryDirectory() as folder:
        env = {**os.environ, "NUMBA_CACHE_DIR": str(Path(folder) / "cache"), "PYTHONPATH": str(src / "src")}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        subprocess.run(
            [python, "-m", "raylume.cli", "render", "-q", "--stats", "s.json", *render_args],
            cwd=folder, env=env, check=True, capture_output=True,
        )  # fmt: skip
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        stats = json.loads((Path(folder) / "s.json").read_text())
    return wall, cpu, stats["compile_seconds"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--src", action="append", type=Path, help="a raylume checkout to compare (repeatable)")
    parser.add_argument("--python", default=sys.executable, help="the interpreter that runs `raylume render`")
    parser.add_argument("render_args", nargs="*", help="more arguments of `raylume render` (after --)")
    args = parser.parse_args()
    builds = [s.resolve() for s in (args.src or [REPO])]
    runs = {b: [] for b in builds}
    for _ in range(args.repeats):
        for b in builds:
            runs[b].append(first_run(b, args.render_args, args.python))
    print(f"first `raylume render` with an empty cache, medians of {args.repeats} (builds alternating); {machine()}")
    print(f"interpreter: {args.python}\n")

    def cell(k: int, b: Path) -> str:
        values = [r[k] for r in runs[b]]
        return f"{median_of(values):.1f} ({', '.join(f'{v:.1f}' for v in values)})"

    rows = [[str(b), cell(0, b), cell(1, b), cell(2, b)] for b in builds]
    print(table(["build", "wall s", "CPU s", "compile_seconds"], rows))


if __name__ == "__main__":
    run_main(main)
