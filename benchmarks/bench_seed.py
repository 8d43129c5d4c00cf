"""The seed scene at 600 x 600 in trace mode: raylume (cold, warm, kernel) beside the
pure-Python implementation of the seed's pseudocode (tests/reference/seed_python.py).

    python benchmarks/bench_seed.py [--repeats 15] [--python-size 600]

The kernel time is shown as the median and the best of the repeats: on a shared virtual machine
the same build's frames vary by half from one minute to the next.
"""

from __future__ import annotations

import argparse
import tempfile

from common import machine, median_of, median_time, run_main, run_python, table

RENDER_CODE = """
import time, raylume
t0 = time.perf_counter()
img = raylume.render(raylume.builtin_scene("seed"), aovs=False)
print(img.stats["render_seconds"], time.perf_counter() - t0)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument(
        "--python-size", type=int, default=600, help="render the pure-Python peer at this size and scale to 600 x 600"
    )
    args = parser.parse_args()

    from reference.seed_python import SEED_SCENE, render_reference

    import raylume

    scene = raylume.builtin_scene("seed")
    raylume.render(scene, width=8, height=8)  # compile once in this process
    kernels = [raylume.render(scene, aovs=False).stats["render_seconds"] for _ in range(args.repeats)]
    kernel = median_of(kernels)
    stats = raylume.render(scene, aovs=False).stats
    one_thread = median_of(
        [raylume.render(scene, aovs=False, threads=1).stats["render_seconds"] for _ in range(args.repeats)]
    )

    with tempfile.TemporaryDirectory() as cache:
        cold_wall, _ = run_python(RENDER_CODE, env={"NUMBA_CACHE_DIR": cache})
        warm = [run_python(RENDER_CODE, env={"NUMBA_CACHE_DIR": cache})[0] for _ in range(args.repeats)]
    warm_wall = median_of(warm)

    n = args.python_size
    python_seconds = median_time(lambda: render_reference(SEED_SCENE, n, n), repeats=1) * (600 * 600) / (n * n)
    scaled = "" if n == 600 else f" (measured at {n} x {n}, scaled by pixel count)"

    print(f"seed scene, 600 x 600, trace mode, {stats['threads']} threads; {machine()}")
    print(f"rays per frame: {stats['rays']:,} ({stats['primary_rays']:,} primary)\n")
    rows = [
        ["pure Python (seed pseudocode)" + scaled, f"{python_seconds:.2f} s", "1x"],
        ["raylume kernel time", f"{kernel * 1000:.1f} ms", f"{python_seconds / kernel:.0f}x"],
        ["raylume kernel time, best run", f"{min(kernels) * 1000:.1f} ms", f"{python_seconds / min(kernels):.0f}x"],
        ["raylume kernel time, 1 thread", f"{one_thread * 1000:.1f} ms", f"{python_seconds / one_thread:.0f}x"],
        ["raylume warm render, new process (wall)", f"{warm_wall:.2f} s", f"{python_seconds / warm_wall:.1f}x"],
        ["raylume cold render, empty cache (wall)", f"{cold_wall:.2f} s", f"{python_seconds / cold_wall:.1f}x"],
    ]
    print(table(["what", "median time", "speed-up vs pure Python"], rows))
    print(f"\nraylume: {stats['rays'] / kernel / 1e6:.1f} Mrays/s")


if __name__ == "__main__":
    run_main(main)
