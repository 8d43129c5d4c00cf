"""Adaptive sampling (`noise_threshold`) against uniform sampling at equal error: for each
threshold, an adaptive render (--spp at most), then uniform renders; each is measured against a
reference (the mean of two 4096-spp renders of other seeds) by the threshold's own measure
(Cycles': per pixel, |error| of r + g + b over 1e-4 + sqrt(r + g + b)), averaged over each
16 x 16 tile. The figure compared is the worst error over the tiles that the adaptive render
stopped before --spp, the error adaptive sampling bounds (a tile that reaches --spp is as noisy
as its samples leave it, and where the reference's own noise is near a tile's, as around
caustics, that tile measures the reference). Uniform sampling's spp for that error is found
from a uniform render at the adaptive render's mean spp by the 1 / sqrt(spp) law, then by the
rate the error fell between that render and a render at that spp (the sampler's
low-discrepancy points converge faster than 1 / sqrt(spp)); its time is the last uniform
render's. The adaptive render's mean error over its stopped tiles and its image's MSE times
its mean spp (lower: less error for the samples) compare versions of adaptive sampling: run
the script with PYTHONPATH at another checkout's src. Rounds alternate adaptive, uniform
(--rounds), medians printed. Mitsuba 3 and pbrt-v4 have no adaptive sampler; the peer here is
raylume's own uniform sampling.

    python benchmarks/bench_adaptive.py [--scene examples/cornell.toml ...] [--size 128] [--spp 1024]
                                        [--thresholds 0.08 0.04 0.02] [--rounds 3] [--threads N]
                                        [--picture docs/images/adaptive_spp.png]

--picture writes the first scene's render at the middle threshold beside the samples each of its
pixels took (the `spp` AOV).
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from common import REPO, machine, median_of, run_main, table


def tile_error(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Each tile's mean error, by the threshold's measure."""
    from raylume.adaptive import tile_errors

    ref = reference.astype(np.float64)
    error = np.abs(image.astype(np.float64) - ref).sum(axis=2) / (1e-4 + np.sqrt(np.maximum(ref.sum(axis=2), 0)))
    return tile_errors(error)


def tile_worst(image: np.ndarray, reference: np.ndarray, tiles: np.ndarray) -> float:
    """The largest mean error of the flagged tiles."""
    return float(tile_error(image, reference)[tiles].max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", nargs="+", default=[str(REPO / "examples" / "cornell.toml")])
    parser.add_argument("--size", type=int, default=128, help="image width; the height keeps the scene's aspect")
    parser.add_argument("--spp", type=int, default=1024, help="the most samples a pixel takes")
    parser.add_argument("--thresholds", type=float, nargs="+", default=[0.08, 0.04, 0.02])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--picture", default=None, help="a PNG of the render beside its samples a pixel")
    args = parser.parse_args()

    import raylume
    from raylume.adaptive import tile_errors
    from raylume.scene.model import MAX_SPP

    print(f"{machine()}\n")
    for path in args.scene:
        scene = raylume.load_scene(path)
        W = args.size
        H = max(1, round(W * scene.render.height / scene.render.width))
        size = dict(width=W, height=H, threads=args.threads, mode="path")
        raylume.render(scene, **{**size, "width": 8, "height": 8}, spp=64, noise_threshold=0.1)  # compile
        reference = (
            sum(raylume.render(scene, **size, spp=4096, seed=s, aovs=False).rgb.astype(np.float64) for s in (90, 91))
            / 2
        )
        rows = []
        for threshold in args.thresholds:
            a_time, a_spp, a_err, u_spp, u_time, u_err, stopped_share = [], [], [], [], [], [], []
            a_mean, a_mse = [], []
            for r in range(args.rounds):
                adaptive = raylume.render(scene, **size, spp=args.spp, noise_threshold=threshold, seed=r, aovs=False)
                stopped = tile_errors(adaptive.aovs["spp"].astype(np.float64)) < args.spp
                if not stopped.any():
                    continue
                stopped_share.append(stopped.mean())
                a_time.append(adaptive.stats["render_seconds"])
                a_spp.append(adaptive.stats["adaptive"]["mean_spp"])
                a_err.append(tile_worst(adaptive.rgb, reference, stopped))
                a_mean.append(float(tile_error(adaptive.rgb, reference)[stopped].mean()))
                a_mse.append(float(np.mean((adaptive.rgb.astype(np.float64) - reference) ** 2)) * a_spp[-1])
                same = max(2, round(a_spp[-1]))
                probe = raylume.render(scene, **size, spp=same, seed=r, aovs=False)
                e_same = tile_worst(probe.rgb, reference, stopped)
                ratio = e_same / a_err[-1]
                need = min(MAX_SPP, max(2, math.ceil(same * ratio**2)))
                uniform = raylume.render(scene, **size, spp=need, seed=r, aovs=False)
                e_need = tile_worst(uniform.rgb, reference, stopped)
                if need != same and e_need > 0 and e_same > e_need:
                    # the error's own rate between the two (low-discrepancy samples converge faster
                    # than 1 / sqrt(spp)), and a uniform render at the spp it gives
                    rate = math.log(e_same / e_need) / math.log(need / same)
                    better = min(MAX_SPP, max(2, math.ceil(same * ratio ** (1.0 / rate))))
                    if better != need:
                        need = better
                        uniform = raylume.render(scene, **size, spp=need, seed=r, aovs=False)
                u_spp.append(need)
                u_time.append(uniform.stats["render_seconds"])
                u_err.append(tile_worst(uniform.rgb, reference, stopped))
            if not a_time:
                rows.append([threshold, "no tile stopped", "", "", "", "", "", "", "", "", ""])
                continue
            rows.append(
                [
                    threshold,
                    f"{100 * median_of(stopped_share):.0f}%",
                    f"{median_of(a_spp):.0f}",
                    f"{median_of(a_err):.4f}",
                    f"{median_of(a_mean):.4f}",
                    f"{median_of(a_mse):.4f}",
                    f"{median_of(a_time):.2f} s",
                    f"{median_of(u_spp):.0f}",
                    f"{median_of(u_err):.4f}",
                    f"{median_of(u_time):.2f} s",
                    f"{median_of([u / a for u, a in zip(u_time, a_time, strict=True)]):.2f}x",
                ]
            )
        print(f"{path} at {W} x {H}, path mode, spp at most {args.spp}, median of {args.rounds} rounds\n")
        print(
            table(
                [
                    "threshold",
                    "tiles stopped",
                    "adaptive: mean spp",
                    "worst tile error",
                    "mean tile error",
                    "image MSE x mean spp",
                    "time",
                    "uniform: spp for that error",
                    "worst tile error",
                    "time",
                    "uniform time / adaptive",
                ],
                rows,
            )
        )
        print()
        if args.picture and path == args.scene[0]:
            threshold = args.thresholds[len(args.thresholds) // 2]
            shown = raylume.render(scene, **size, spp=args.spp, noise_threshold=threshold)
            write_picture(args.picture, shown, threshold)
            print(f"wrote {args.picture}")


def write_picture(path: str, image, threshold: float) -> None:
    """The render (sRGB) beside its samples a pixel, with a colour bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from raylume.image import encode_levels

    stats = image.stats["adaptive"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(8.4, 3.8), layout="constrained")
    left.imshow(encode_levels(image.rgb, "srgb"))
    left.set_title(f"noise_threshold {threshold}: {stats['mean_spp']:.0f} spp a pixel on average", fontsize=9)
    shown = right.imshow(image.aovs["spp"], cmap="magma")
    right.set_title(f"samples each pixel took ({stats['min_spp']}-{stats['max_spp']})", fontsize=9)
    fig.colorbar(shown, ax=right, shrink=0.85)
    for axes in (left, right):
        axes.set_axis_off()
    fig.savefig(path, dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    run_main(main)
