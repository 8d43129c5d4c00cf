"""Helpers shared by the benchmark scripts: medians, tables, machine description."""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_MODELS = REPO.parent / "shared" / "models"
sys.path.insert(0, str(REPO / "tests"))  # the pure-Python reference lives with the tests


# Python modules of raylume's bench extra (pyproject.toml): a script that needs a missing one says so
BENCH_EXTRA = {"embreex": "embreex", "mitsuba": "mitsuba", "drjit": "mitsuba", "rtree": "rtree"}


def missing_extra(exc: ModuleNotFoundError) -> str | None:
    """The one-line answer for a bench-extra module that is not installed, else None."""
    root = (exc.name or "").split(".")[0]
    if root not in BENCH_EXTRA:
        return None
    script = Path(sys.argv[0]).name
    extra = BENCH_EXTRA[root]
    return f"{script}: needs {extra}, which raylume's bench extra installs: make bench (pip install -e '.[bench]')"


def run_main(main) -> None:
    """main() as a script's entry: a missing bench-extra module is one line and exit status 1,
    not a traceback."""
    try:
        result = main()
    except ModuleNotFoundError as exc:
        if (line := missing_extra(exc)) is None:
            raise
        raise SystemExit(line) from None
    sys.exit(result)


def machine() -> str:
    """The CPU, its core count, its widest vectors and Python's version: a line for a benchmark's
    header. The vectors matter beside Mitsuba's llvm variant, which compiles for the widest the
    machine has (16 float32 lanes on AVX-512, 8 on AVX2)."""
    cpu = platform.processor() or platform.machine()
    first: dict[str, str] = {}  # the first processor's fields
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if not line.strip():
                break
            key, _, value = line.partition(":")
            first[key.strip()] = value.strip()
    except OSError:
        pass
    cpu = first.get("model name", cpu)
    flags = set(first.get("flags", "").split())
    about = (
        [f"family {first['cpu family']} model {first['model']}"] if "cpu family" in first and "model" in first else []
    )
    about += ["AVX-512"] if "avx512f" in flags else ["AVX2"] if "avx2" in flags else []
    if about:
        cpu += f" ({', '.join(about)})"
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def cached_entry(function):
    """A KernelFunction that a benchmark calls from Python (a ray-by-ray loop), compiled with its
    options into Numba's disk cache, as the query kernels are: its own Python entry compiles
    afresh in every process, and tools/profile_kernels.py --count finds a kernel's code only as
    loaded from the cache (a compile under valgrind would take many minutes)."""
    from raylume.kernels.vec import python_entry

    return python_entry(function, cache=True)


def median_time(fn, repeats: int = 5) -> float:
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def median_of(values) -> float:
    return statistics.median(values)


def run_python(code: str, env: dict | None = None) -> tuple[float, str]:
    """Wall time of `python -c code` in a new process, and its stdout."""
    t0 = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env={**os.environ, **(env or {})}
    )
    return time.perf_counter() - t0, out.stdout


def child_probe(code: str, what: str, timeout: int = 300) -> str:
    """Why `python -c code` fails in a new process ("" when the last line it prints starts with
    "ok"): for libraries that abort the process on failure, past any except (Mitsuba's
    llvm_ad_rgb under an LLVM that cannot compile its kernels). `what` names the work in the
    reason."""
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"{what} did not finish in {timeout} s"
    printed = out.stdout.strip().splitlines()
    if out.returncode == 0 and printed and printed[-1].startswith("ok"):
        return ""
    lines = [ln.strip() for ln in (out.stderr + out.stdout).splitlines() if ln.strip() and not ln.startswith(" ")]
    first = next((ln for ln in lines if "ERROR" in ln or "Error" in ln), lines[-1] if lines else "")
    return f"{what} exited with status {out.returncode}: {first[:160]}"


def table(headers: list[str], rows: list[list]) -> str:
    """A GitHub-flavoured markdown table."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(row[k]) for row in cells) for k in range(len(headers))]
    lines = ["| " + " | ".join(c.ljust(w) for c, w in zip(row, widths)) + " |" for row in cells]
    lines.insert(1, "| " + " | ".join("-" * w for w in widths) + " |")
    return "\n".join(lines)


def growth_table(seconds: dict[str, dict[str, float]], rays: dict[str, int], base: str = "40k") -> str:
    """How each engine's time grows from the `base` mesh (issue 49's scaling goal): for every other
    mesh, time / base time per engine, and the time a ray added, in ns (the ratio weighs an engine's
    growth against its own small-mesh speed; the added time compares the growth itself). Empty
    without the base mesh."""
    if base not in seconds:
        return ""
    engines = list(seconds[base])
    headers = ["mesh"] + [f"{e}: time / {base}" for e in engines] + [f"{e}: ns a ray more" for e in engines]
    rows = []
    for name, times in seconds.items():
        if name == base:
            continue
        ratios = [f"{times[e] / seconds[base][e]:.2f}" for e in engines]
        added = [f"{(times[e] / rays[name] - seconds[base][e] / rays[base]) * 1e9:+.0f}" for e in engines]
        rows.append([name, *ratios, *added])
    return table(headers, rows) if rows else ""
