"""The cost of rendering on a Dask cluster: the same render in-process (2 threads) and on a
local cluster of 2 single-threaded worker processes, for a short and a long render.

The scene is the Cornell box in path mode (examples/cornell.toml), at 256 x 256 and an spp
chosen so that the in-process render takes about --short and --long seconds on this machine
(measured from a calibration render). Both sides are warm (kernels compiled or loaded, the
cluster started) before the timed rounds, which alternate; each row is the median of
--repeats rounds. Cluster times are end to end as a user sees them: scattering the scene,
the per-worker warm-up task, every tile, and assembling the image. Also measured: the time to
the first tile (warm workers, and a fresh cluster whose workers load the kernels from the disk
cache), tiles, the kernel seconds of a tile and the bytes a tile sends back. The last table
estimates a 4K (3840 x 2160), 1024 spp frame of the same scene on 16 and 64 machines from
these measurements (see docs/guide/cluster.md).

    python benchmarks/bench_cluster.py [--short 2] [--long 20] [--repeats 3] [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from common import REPO, machine, run_main, table

import raylume
from raylume import cluster as C

WIDTH = HEIGHT = 256


def timed(fn, **kwargs):
    t0 = time.perf_counter()
    out = fn(**kwargs)
    return time.perf_counter() - t0, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--short", type=float, default=2.0, help="seconds of the short in-process render")
    parser.add_argument("--long", type=float, default=20.0, help="seconds of the long in-process render")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="a 1 s and a 4 s render, 1 round")
    args = parser.parse_args()
    if args.quick:
        args.short, args.long, args.repeats = 1.0, 4.0, 1
    from distributed import Client, LocalCluster

    print(f"machine: {machine()}\n")
    scene = raylume.load_scene(REPO / "examples" / "cornell.toml")
    session = raylume.Session(scene)
    session.render(width=WIDTH, height=HEIGHT, spp=1, threads=2)  # compile (or load) the kernels
    seconds, _ = timed(lambda: session.render(width=WIDTH, height=HEIGHT, spp=8, threads=2))
    per_spp = seconds / 8

    started = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=40)  # fmt: skip
    client = Client(cluster, set_as_default=False)
    cluster_start = time.perf_counter() - started
    _, cold = timed(lambda: session.render(width=WIDTH, height=HEIGHT, spp=1, cluster=client))
    cold_first_tile = cold.stats["cluster"]["first_tile_seconds"]

    rows, details = [], {}
    for label, target in (("short", args.short), ("long", args.long)):
        spp = max(1, round(target / per_spp))
        local_times, cluster_times, first_tiles, stats = [], [], [], None
        for _ in range(args.repeats):
            t_local, reference = timed(session.render, width=WIDTH, height=HEIGHT, spp=spp, threads=2)
            t_cluster, image = timed(session.render, width=WIDTH, height=HEIGHT, spp=spp, cluster=client)
            assert np.array_equal(reference.rgb, image.rgb), "the cluster's image differs"
            local_times.append(t_local)
            cluster_times.append(t_cluster)
            first_tiles.append(image.stats["cluster"]["first_tile_seconds"])
            stats = image.stats["cluster"]
        t_local, t_cluster = statistics.median(local_times), statistics.median(cluster_times)
        tile_px = (WIDTH * HEIGHT) / stats["tiles"]
        tile_kernel = stats["kernel_seconds"] / stats["tasks"]
        rows.append([
            f"{label} ({spp} spp)", f"{t_local:.2f}", f"{t_cluster:.2f}", f"{(t_cluster / t_local - 1) * 100:+.1f}%",
            f"{statistics.median(first_tiles):.2f}", stats["tiles"], stats["tasks"], f"{tile_kernel:.2f}",
            f"{tile_px * 48 / 1024:.0f}",
        ])  # fmt: skip
        details[label] = dict(spp=spp, local=t_local, cluster=t_cluster, stats=stats, tile_kernel=tile_kernel)
    print(f"Cornell box, path mode, {WIDTH} x {HEIGHT}; in-process: 2 threads; cluster: 2 worker processes x 1 thread")
    print(f"(local cluster started in {cluster_start:.1f} s; first tile of a fresh cluster {cold_first_tile:.2f} s;")
    print(f" compiled scene shipped once per worker: {stats['scene_bytes'] / 1024:.0f} KiB)\n")
    print(table(
        ["render", "in-process s", "cluster s", "overhead", "first tile s", "tiles", "tasks", "kernel s/task",
         "KiB back/tile"],
        rows,
    ))  # fmt: skip

    # The cost of a task itself: many tiny tiles of almost no work (8 x 8 pixels, cast mode),
    # the cluster's busy time less the kernels', per task, after the first tile.
    saved = C.TILE_SECONDS
    C.TILE_SECONDS = 1e-9
    overheads = []
    for _ in range(3):
        t_tiny, tiny = timed(session.render, width=128, height=128, spp=1, mode="cast", cluster=client, aovs=False)
        c = tiny.stats["cluster"]
        overheads.append(max((t_tiny - c["first_tile_seconds"]) * 2 - c["kernel_seconds"], 0.0) / c["tasks"])
    C.TILE_SECONDS = saved
    overhead_per_task = statistics.median(overheads)
    print(f"\nper-task overhead ({c['tasks']} tasks of 8 x 8 pixels, cast): {overhead_per_task * 1000:.1f} ms")

    # Estimate: a 4K frame at 1024 spp of this scene on N machines of `cores` cores each.
    long = details["long"]
    sample_seconds = long["stats"]["kernel_seconds"] / (WIDTH * HEIGHT * long["spp"])  # per core
    pixels, spp = 3840 * 2160, 1024
    work = pixels * spp * sample_seconds  # core-seconds
    tasks = work / C.TILE_SECONDS
    image_bytes = pixels * 12  # float32 RGB back to the client (no AOVs)
    est = []
    for machines in (1, 16, 64):
        for cores in (16,):
            n = machines * cores
            compute = (work + tasks * overhead_per_task) / n
            tail = C.TILE_SECONDS  # the last tiles: at most one tile's time with some cores idle
            transfer = image_bytes / 117e6  # through the client's 1 Gb/s link
            startup = 5.0 + cold_first_tile  # workers warm (kernels from a shared cache), scene scattered
            total = compute + tail + transfer + startup
            est.append([machines, n, f"{work / n:.0f}", f"{compute:.0f}", f"{transfer:.1f}", f"{startup:.1f}",
                        f"{total:.0f}", f"{(work / cores) / total / machines * 100:.0f}%"])  # fmt: skip
    print(f"\nEstimate, 3840 x 2160 x {spp} spp of this scene: {work / 3600:.1f} core-hours of kernels "
          f"({sample_seconds * 1e6:.2f} us per sample per core), {tasks:.0f} tasks of {C.TILE_SECONDS:g} s, "
          f"{overhead_per_task * 1000:.1f} ms overhead per task, 1 s tail, 1 Gb/s to the client\n")  # fmt: skip
    print(table(["machines", "cores", "ideal s", "compute s", "image transfer s", "startup s", "total s",
                 "efficiency"], est))  # fmt: skip
    client.close()
    cluster.close()


if __name__ == "__main__":  # the local cluster's worker processes import this module
    run_main(main)
