"""Bidirectional path tracing against path tracing: error against time on the head lamp
(examples/headlamp.toml) and the Cornell box (examples/cornell.toml), and samples per second.

    python benchmarks/bench_bdpt.py [--size 128x72] [--reference-spp 1024] [--rounds 2]
                                    [--plot docs/images/bdpt_rmse.png] [--pictures docs/images]
                                    [--scene headlamp|cornell|both]

Head lamp: its image at --size (small: the converged reference is long) against a reference made
by bdpt at --reference-spp (cached in benchmarks/.cache; seeds 1000.., none of the runs'). RMSE over
linear RGB, on the whole image and on the beam: the pixels of the reference whose luminance is
above a quarter of its 99.5th percentile, right of the image's left third; and on that left third,
the lamp, where the glints are (the bulb through the lens and the mirror: paths no connection
can make, which bdpt's glint strategy samples and path mode finds by chance). bdpt at 4 ..
50 spp against path at 16 .. 1024 spp, rounds alternating bdpt and path, each render timed (the
render call's wall time, kernels compiled before), new seeds each round. The ratio reported is
path mode's RMSE at bdpt's 50-spp time (interpolated log-log between path's runs) over bdpt's.

Cornell box: 64 x 64 against tests/reference/cornell_mitsuba.npz (Mitsuba's mean over 65536 spp),
the light's pixels left out, bdpt at 2 .. 32 spp and path at 4 .. 256.

--pictures writes the head lamp at 50 spp by bdpt and path mode at the same time
(headlamp_bdpt.png, headlamp_path.png), side by side in headlamp_compare.png.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from common import REPO, machine, run_main, table

sys.path.insert(0, str(REPO / "src"))
import raylume  # noqa: E402

CACHE = REPO / "benchmarks" / ".cache"
HEADLAMP = REPO / "examples" / "headlamp.toml"
CORNELL = REPO / "examples" / "cornell.toml"
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def rmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray) -> float:
    d = (image.astype(np.float64) - reference)[mask]
    return float(np.sqrt(np.mean(d * d)))


def timed(session, integrator: str, spp: int, seed: int, **size) -> tuple[np.ndarray, float]:
    t = time.perf_counter()
    img = session.render(integrator=integrator, spp=spp, seed=seed, aovs=False, **size)
    return img.rgb, time.perf_counter() - t


def headlamp_reference(session, w: int, h: int, spp: int) -> np.ndarray:
    import hashlib

    digest = hashlib.sha256(HEADLAMP.read_bytes() + (HEADLAMP.parent / "headlamp" / "reflector.obj").read_bytes())
    path = CACHE / f"headlamp_{w}x{h}_{spp}_{digest.hexdigest()[:12]}.npy"
    if path.exists():
        return np.load(path)
    CACHE.mkdir(exist_ok=True)
    print(f"rendering the head lamp's reference: bdpt, {spp} spp at {w} x {h} (once; cached in {path})")
    parts = [session.render(integrator="bdpt", spp=spp // 4, seed=1000 + k, width=w, height=h, aovs=False).rgb
             for k in range(4)]  # fmt: skip
    ref = np.mean(np.stack(parts).astype(np.float64), axis=0)
    np.save(path, ref)
    return ref


def curves(session, reference, masks: dict, runs: dict, rounds: int, **size) -> dict:
    """{integrator: [(spp, seconds, {mask: rmse})]} medians over rounds, alternating integrators."""
    results: dict = {name: {spp: [] for spp in spps} for name, spps in runs.items()}
    seed = 0
    for _ in range(rounds):
        for k in range(max(len(s) for s in runs.values())):
            for name, spps in runs.items():
                if k < len(spps):
                    seed += 1
                    rgb, seconds = timed(session, name, spps[k], seed, **size)
                    assert np.isfinite(rgb).all()
                    results[name][spps[k]].append((seconds, {m: rmse(rgb, reference, v) for m, v in masks.items()}))
    out = {}
    for name, by_spp in results.items():
        out[name] = [
            (spp, float(np.median([s for s, _ in rs])), {m: float(np.median([e[m] for _, e in rs])) for m in masks})
            for spp, rs in by_spp.items()
        ]
    return out


def at_time(curve, seconds: float, mask: str) -> float:
    """The curve's RMSE at `seconds`, interpolated log-log (extrapolated from the last two points)."""
    t = np.log([c[1] for c in curve])
    e = np.log([c[2][mask] for c in curve])
    if seconds <= np.exp(t[0]):
        i = 0
    elif seconds >= np.exp(t[-1]):
        i = len(t) - 2
    else:
        i = int(np.searchsorted(t, np.log(seconds))) - 1
    slope = (e[i + 1] - e[i]) / (t[i + 1] - t[i])
    return float(np.exp(e[i] + slope * (np.log(seconds) - t[i])))


def report(title: str, result: dict, masks: list[str], pixels: int) -> None:
    print(f"\n{title}")
    rows = []
    for name, curve in result.items():
        for spp, seconds, errors in curve:
            rows.append([name, spp, f"{seconds:.2f}", f"{pixels * spp / seconds / 1e3:.0f}",
                         *[f"{errors[m]:.4f}" for m in masks]])  # fmt: skip
    print(table(["integrator", "spp", "seconds", "k samples/s", *[f"RMSE {m}" for m in masks]], rows))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", default="128x72")
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--scene", default="both", choices=["headlamp", "cornell", "both"])
    parser.add_argument("--plot", type=Path)
    parser.add_argument("--pictures", type=Path)
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    print(machine())
    plots = []
    if args.scene in ("headlamp", "both"):
        session = raylume.Session(raylume.load_scene(HEADLAMP))
        for name in ("bdpt", "path"):  # compile (or load) the kernels first
            session.render(integrator=name, spp=1, width=8, height=8, aovs=False)
        reference = headlamp_reference(session, w, h, args.reference_spp)
        lum = reference @ LUMINANCE
        beam = lum > 0.25 * np.percentile(lum, 99.5)
        beam[:, : w // 3] = False
        lamp = np.zeros((h, w), bool)
        lamp[:, : w // 3] = True  # the lamp's glints: paths through its lens and mirror (bdpt_glint.py)
        masks = {"image": np.ones((h, w), bool), "beam": beam, "lamp": lamp}
        runs = {"bdpt": [4, 8, 16, 32, 50], "path": [16, 64, 256, 1024]}
        result = curves(session, reference, {k: v[..., None].repeat(3, 2) for k, v in masks.items()}, runs,
                        args.rounds, width=w, height=h)  # fmt: skip
        report(f"Head lamp, {w} x {h} (beam: {int(beam.sum())} pixels)", result, list(masks), w * h)
        spp50 = next(c for c in result["bdpt"] if c[0] == 50)
        for m in masks:
            ratio = at_time(result["path"], spp50[1], m) / spp50[2][m]
            print(f"at bdpt's 50-spp time ({spp50[1]:.2f} s), path mode's RMSE / bdpt's on the {m}: {ratio:.1f}x")
        plots.append(("head lamp", result, ["image", "beam"]))
        if args.pictures is not None:
            pictures(session, w, h, spp50[1], args.pictures)
    if args.scene in ("cornell", "both"):
        from test_path_vs_mitsuba import load_reference

        ref = load_reference()
        session = raylume.Session(raylume.load_scene(CORNELL))
        for name in ("bdpt", "path"):
            session.render(integrator=name, spp=1, width=8, height=8, aovs=False)
        keep = (ref.light_coverage == 0)[..., None].repeat(3, 2)
        runs = {"bdpt": [2, 4, 8, 16, 32], "path": [4, 16, 64, 256]}
        result = curves(session, ref.mean, {"image": keep}, runs, args.rounds, width=64, height=64)
        report("Cornell box, 64 x 64, against Mitsuba's reference", result, ["image"], 64 * 64)
        plots.append(("Cornell box", result, ["image"]))
    if args.plot is not None:
        plot(plots, args.plot)


def pictures(session, w: int, h: int, seconds: float, folder: Path) -> None:
    """The head lamp by bdpt at 50 spp and by path mode in about the same time, side by side."""
    bdpt = session.render(integrator="bdpt", spp=50, seed=7, width=w, height=h, aovs=False)
    per_spp = timed(session, "path", 64, 8, width=w, height=h)[1] / 64
    spp = max(1, int(seconds / per_spp))
    path = session.render(integrator="path", spp=spp, seed=9, width=w, height=h, aovs=False)
    folder.mkdir(parents=True, exist_ok=True)
    bdpt.save(folder / "headlamp_bdpt.png")
    path.save(folder / "headlamp_path.png")
    gap = np.ones((h, 4, 3), np.float32)
    both = raylume.Image(np.concatenate([bdpt.rgb, gap * 0, path.rgb], axis=1), {}, {}, "srgb")
    both.save(folder / "headlamp_compare.png")
    print(f"pictures: bdpt 50 spp ({bdpt.stats['render_seconds']:.2f} s) and path {spp} spp "
          f"({path.stats['render_seconds']:.2f} s) in {folder}")  # fmt: skip


def plot(plots, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(plots), figsize=(5 * len(plots), 3.6))
    axes = np.atleast_1d(axes)
    for ax, (title, result, masks) in zip(axes, plots):
        for name, curve in result.items():
            for m, style in zip(masks, ("-o", "--s")):
                ax.loglog([c[1] for c in curve], [c[2][m] for c in curve], style, label=f"{name}, {m}")
        ax.set_title(title)
        ax.set_xlabel("render time (s)")
        ax.set_ylabel("RMSE (linear RGB)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"plot: {path}")


if __name__ == "__main__":
    sys.path.insert(0, str(REPO / "tests"))
    run_main(main)
