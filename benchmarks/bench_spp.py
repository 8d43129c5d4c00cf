"""Cost of samples per pixel: the quality example (examples/quality.toml: area lights, image
textures, depth of field, Gaussian filter) at 1, 4, 16 and 64 spp. Prints a markdown table of
medians: rays, kernel time, wall time of the whole render call, rays per second, and time per
sample normalised to 1 spp. Linear cost means a flat 'per sample' column: no overhead per
sample beyond its rays.

    python benchmarks/bench_spp.py [--width 320 --height 200] [--repeats 3] [--threads N]
"""

from __future__ import annotations

import argparse
import time

from common import REPO, machine, median_of, run_main, table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default=str(REPO / "examples" / "quality.toml"))
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=200)
    parser.add_argument("--spp", type=int, nargs="+", default=[1, 4, 16, 64])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=None)
    args = parser.parse_args()

    import raylume

    scene = raylume.load_scene(args.scene)
    size = dict(width=args.width, height=args.height, threads=args.threads, aovs=False)
    raylume.render(scene, width=8, height=8, spp=2, threads=args.threads)  # JIT once, outside the timings

    rows = []
    base = None
    for spp in args.spp:
        kernel, wall, stats = [], [], None
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            img = raylume.render(scene, spp=spp, **size)
            wall.append(time.perf_counter() - t0)
            kernel.append(img.stats["render_seconds"])
            stats = img.stats
        k, w = median_of(kernel), median_of(wall)
        per_sample = k / spp
        base = base or per_sample
        rows.append(
            [
                spp,
                f"{stats['rays'] / 1e6:.2f} M",
                f"{stats['rays'] / (args.width * args.height * spp):.2f}",
                f"{k:.3f} s",
                f"{w:.3f} s",
                f"{stats['rays'] / k / 1e6:.2f}",
                f"{per_sample * 1e3:.1f} ms ({per_sample / base:.2f}x)",
            ]
        )
    print(
        f"{args.scene} at {args.width} x {args.height}, {stats['threads']} threads, median of {args.repeats}; "
        f"{machine()}\n"
    )
    print(
        table(
            [
                "spp",
                "rays",
                "rays per sample",
                "kernel time",
                "wall time (render call)",
                "Mrays/s",
                "kernel time per spp (vs 1 spp)",
            ],
            rows,
        )
    )


if __name__ == "__main__":
    run_main(main)
