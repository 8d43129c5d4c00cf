"""Rasterization against ray casting as the triangle count grows: the seed's contrast, measured.

The same scene for both modes: a bumpy sphere (raylume.scene.procedural.bumpy_sphere) of
about 1k .. 4M triangles, smooth-shaded, seen from 3 radii away (it fills about 40% of
the frame), the same lights, the same camera, the same thread count. For each size it times
`raylume.render(..., mode="raster")` (the Z-buffer rasterizer with lighting, no shadows) and
`mode="cast"` (one primary ray per pixel through the BVH), using each image's
stats["render_seconds"]: the kernels alone, without loading the mesh, building the BVH or
compiling. Medians of --repeats frames. Prints a table and the crossover, the triangle count
beyond which ray casting is faster than rasterization, and draws a log-log plot (the README's
with the default sizes; with --sizes or --quick only where --plot says).

    python benchmarks/bench_scaling.py [--sizes 1000,10000,...] [--quick] [--width 1024]
        [--height 1024] [--repeats 5] [--threads N] [--threading-layer workqueue]
        [--plot docs/images/scaling.png]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh
from common import REPO, machine, median_of, run_main, table

import raylume
from raylume.scene.procedural import bumpy_sphere

DEFAULT_SIZES = (1_000, 10_000, 70_000, 100_000, 1_000_000, 4_000_000)
QUICK_SIZES = (1_000, 10_000, 70_000, 100_000)


def scene_for(mesh_path: str):
    return raylume.scene_from_dict(
        {
            "camera": {"position": [0, 0, -3], "look_at": [0, 0, 0], "fov": 53.13},
            "lights": [
                {"type": "ambient", "intensity": 0.2},
                {"type": "point", "position": [2, 2, -3], "intensity": 0.6},
                {"type": "directional", "direction": [1, 4, -4], "intensity": 0.2},
            ],
            "objects": [
                {
                    "type": "mesh",
                    "file": mesh_path,
                    "smooth": True,
                    "material": {"color": [0.8, 0.7, 0.5], "specular": 50},
                }
            ],
        }
    )


def time_modes(sc, args) -> dict:
    """Kernel seconds per frame of each mode over args.repeats renders, the modes alternating
    frame by frame so that both see the same machine (other processes, clock, caches)."""
    times = {"raster": [], "cast": []}
    build = []
    for _ in range(args.repeats):
        for mode in times:
            img = raylume.render(sc, mode=mode, width=args.width, height=args.height, threads=args.threads, aovs=False)
            times[mode].append(img.stats["render_seconds"])
            build.append(img.stats["build_seconds"])
    return times, median_of(build)


def crossover(ns, raster, cast):
    """Triangle count where the two curves meet, by log-log interpolation between measured
    sizes; otherwise an extrapolation from the power laws through the two largest sizes."""
    logn = np.log(ns)
    diff = np.log(raster) - np.log(cast)  # > 0 where ray casting is faster
    for k in range(len(ns) - 1):
        if diff[k] <= 0 < diff[k + 1]:
            s = -diff[k] / (diff[k + 1] - diff[k])
            return float(np.exp(logn[k] + s * (logn[k + 1] - logn[k]))), "measured"
    if diff[0] > 0:
        return None, "ray casting is faster at every measured size"
    if len(ns) < 2:
        return None, "one size only"
    slope_r = (math.log(raster[-1]) - math.log(raster[-2])) / (logn[-1] - logn[-2])
    slope_c = (math.log(cast[-1]) - math.log(cast[-2])) / (logn[-1] - logn[-2])
    if slope_r <= slope_c:
        return None, "rasterization is faster at every measured size and does not grow faster"
    # log r + slope_r x = log c + slope_c x, x = log n - log n_last
    x = -diff[-1] / (slope_r - slope_c)
    return float(np.exp(logn[-1] + x)), "extrapolated"


def plot(path: Path, ns, raster, cast, cross, args, threads) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    ns = np.asarray(ns, float)
    raster_ms, cast_ms = np.asarray(raster) * 1e3, np.asarray(cast) * 1e3
    fig, ax = plt.subplots(figsize=(5.6, 3.8), dpi=100)
    (l1,) = ax.loglog(ns, raster_ms, "o-", label="rasterization (Z-buffer)")
    (l2,) = ax.loglog(ns, cast_ms, "s-", label="ray casting (BVH)")
    where, how = cross
    if where is not None:
        if how == "extrapolated":  # the power laws through the two largest sizes, dashed
            xs = np.array([ns[-1], where])
            for ms, line in ((raster_ms, l1), (cast_ms, l2)):
                slope = math.log(ms[-1] / ms[-2]) / math.log(ns[-1] / ns[-2])
                ax.loglog(xs, ms[-1] * (xs / ns[-1]) ** slope, "--", color=line.get_color(), lw=1)
        y = (
            float(np.exp(np.interp(math.log(where), np.log(ns), np.log(raster_ms))))
            if how == "measured"
            else raster_ms[-1]
            * (where / ns[-1]) ** (math.log(raster_ms[-1] / raster_ms[-2]) / math.log(ns[-1] / ns[-2]))
        )
        ax.plot([where], [y], "k*", ms=9)
        ax.annotate(
            f"crossover ~{where / 1e6:.1f}M\n({how})",
            (where, y),
            xytext=(-6, -62),
            textcoords="offset points",
            ha="right",
            fontsize=8,
        )
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}" if str(int(v))[0] in "235" else ""))
    ax.set_xlabel("triangles")
    ax.set_ylabel("ms per frame (kernels)")
    ax.set_title(f"{args.width}x{args.height}, {threads} thread{'s' if threads != 1 else ''}", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", default=None, help="comma-separated triangle counts (default 1k..4M)")
    parser.add_argument("--quick", action="store_true", help=f"sizes {QUICK_SIZES} only")
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--height", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=None, help="Numba threads (default: all)")
    parser.add_argument(
        "--threading-layer",
        default=None,
        choices=["workqueue", "omp", "tbb"],
        help="Numba threading layer (default: Numba's choice). On a machine shared with "
        "other busy processes, OpenMP's spinning barriers can stall a frame by a "
        "time slice; 'workqueue' does not",
    )
    parser.add_argument(
        "--plot",
        default=None,
        help="PNG path (default: docs/images/scaling.png, the README's, for the default sizes only: "
        "a run of chosen sizes does not replace it)",
    )
    args = parser.parse_args()
    if args.plot is None and not (args.sizes or args.quick):
        args.plot = str(REPO / "docs" / "images" / "scaling.png")
    if args.threading_layer:
        import numba

        numba.config.THREADING_LAYER = args.threading_layer
    sizes = (
        [int(s) for s in args.sizes.split(",")] if args.sizes else list(QUICK_SIZES if args.quick else DEFAULT_SIZES)
    )

    rows, ns, raster, cast = [], [], [], []
    threads = None
    print(f"{args.width} x {args.height}, medians of {args.repeats} frames; {machine()}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            t0 = time.perf_counter()
            v, f = bumpy_sphere(n)
            path = str(Path(tmp) / f"bumpy_{n}.ply")
            trimesh.Trimesh(v, f, process=False).export(path)
            del v
            sc = scene_for(path)
            # a first frame of each mode compiles (or loads) the kernels, outside the medians
            warm = raylume.render(sc, mode="raster", width=32, height=32, threads=args.threads)
            raylume.render(sc, mode="cast", width=32, height=32, threads=args.threads)
            if threads is None:
                import numba

                threads = warm.stats["threads"]
                print(f"{threads} threads, threading layer {numba.threading_layer()}\n", flush=True)
            times, build = time_modes(sc, args)
            r, c = median_of(times["raster"]), median_of(times["cast"])
            ns.append(len(f))
            raster.append(r)
            cast.append(c)
            rows.append(
                [
                    f"{len(f):,}",
                    f"{r * 1e3:.1f}",
                    f"{c * 1e3:.1f}",
                    f"{c / r:.2f}",
                    f"{min(times['raster']) * 1e3:.1f}",
                    f"{min(times['cast']) * 1e3:.1f}",
                    f"{len(f) / r / 1e6:.1f}",
                    f"{build:.2f}",
                ]
            )
            print(
                f"  {len(f):>9,} triangles: raster {r * 1e3:8.1f} ms, cast {c * 1e3:8.1f} ms "
                f"({time.perf_counter() - t0:.0f} s)",
                flush=True,
            )
            Path(path).unlink()

    print(
        f"\nPer-frame kernel time (median and best of {args.repeats}), {args.width}x{args.height}, "
        f"{threads} thread(s) (raster: Z-buffer + local lighting; cast: one BVH ray per pixel, "
        "material colour)\n"
    )
    print(
        table(
            [
                "triangles",
                "raster ms",
                "cast ms",
                "cast / raster",
                "raster best",
                "cast best",
                "raster Mtri/s",
                "scene build s",
            ],
            rows,
        )
    )
    cross = crossover(np.asarray(ns, float), raster, cast)
    if cross[0] is None:
        print(f"\nno crossover: {cross[1]}")
    else:
        print(f"\nray casting overtakes rasterization at about {cross[0]:,.0f} triangles ({cross[1]})")
    if args.plot:
        plot(Path(args.plot), ns, raster, cast, cross, args, threads)
        print(f"plot written to {args.plot} ({Path(args.plot).stat().st_size // 1024} KB)")


if __name__ == "__main__":
    run_main(main)
