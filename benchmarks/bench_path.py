"""raylume's path tracer against Mitsuba 3: speed on the Cornell box (examples/cornell.toml) and on
the material showcase (examples/materials.toml), and error against time on the Cornell box.

    python benchmarks/bench_path.py [--rounds 3] [--scene cornell|materials|both] [--quick]
                                    [--plot docs/images/path_rmse.png] [--speed-only]
                                    [--no-denoise-goal | --denoise-goal-only] [--no-cold]

1. Speed, on each scene --scene names (default both): raylume's `mode = "path"` against Mitsuba
   3's `path` integrator in variant scalar_rgb, and llvm_ad_rgb where it runs (it is probed in a
   child process first: a broken LLVM aborts the process). 64 spp, max_depth 8 (the TOMLs').
   - Cornell box: 256 x 256 (--size), built for Mitsuba from the same TOML and OBJ files by
     benchmarks/mitsuba_reference.py.
   - Materials: the TOML's 640 x 320 (times --materials-scale), built for Mitsuba by
     benchmarks/mitsuba_scene.py: a checkered plane (a large rectangle), six spheres (smooth and
     rough gold, glass, frosted glass, rough plastic, diffuse), the HDR sky as an envmap. One
     approximation: Mitsuba's `path` has no media, so its glass does not absorb (raylume's
     Beer-Lambert costs one exp per channel per segment inside). Both look the sky up
     bilinearly (`python benchmarks/mitsuba_scene.py compare` shows both images).
   All in this process, alternating raylume, Mitsuba, raylume, Mitsuba, ... for --rounds rounds,
   each round on all cores and on 1 thread. Times are the wall time of the render call (raylume's
   kernel time beside it, and its rays per sample; then each round's own ratio, median and
   range), after a warm-up render: raylume's Numba compilation (or cache load) is reported apart,
   and at the very end a cold compile in a new process with an empty Numba cache (--no-cold
   skips it).
2. Error against time (Cornell box only): 64 x 64 against tests/reference/cornell_mitsuba.npz
   (Mitsuba's mean over 65536 spp), the pixels that see any of the light left out, RMSE over
   linear RGB. raylume and Mitsuba scalar_rgb at 4 .. 1024 spp, Mitsuba with its independent
   sampler (the speed benchmark's and the reference's) and with its low-discrepancy `ldsampler`
   (raylume's sampler is low-discrepancy too), and raylume's 16 spp denoised by Intel OIDN (its
   time includes the denoiser). New seeds every round, none of the reference's. The reference's
   own noise adds about 1/64 of an independent 1024-spp render's variance to its squared error
   (~0.8 % RMSE), more of a low-discrepancy one's.
3. The denoising goal (Cornell box only) at the speed benchmark's size (256 x 256): raw 256 spp
   against 16 spp denoised, RMSE against raylume's own 4096-spp render (cached in
   benchmarks/.cache, minutes to make the first time; --no-denoise-goal skips it), over all
   pixels, over the pixels that see none of the light, and over those less a 2-pixel ring. The
   denoised image's time includes what `--denoise` adds (raylume/seen_light.py): the light seen
   directly rendered apart, the light's edge pixels path-traced at 16x the samples, and OIDN.

--speed-only runs part 1 alone (no error, denoising or cold-start runs).

Mitsuba is optional (pip install 'raylume[bench]'); without it raylume's figures are printed alone.
Its llvm_ad_rgb variant also needs the LLVM shared library, which pip does not install: on Debian
`make bench` installs libllvm19 where apt-get can (Dr.Jit finds libLLVM.so by itself; elsewhere set
DRJIT_LIBLLVM_PATH to it; an older libLLVM, as Debian 12's default 14 or 15, fails to compile its
kernels). Without it the probe says why and llvm_ad_rgb is left out.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from common import REPO, child_probe, machine, median_of, run_main, run_python, table
from mitsuba_reference import REFERENCE, SCENE, load_toml, mitsuba_dict

import raylume

COLD_CODE = """
import time, raylume
t = time.perf_counter()
img = raylume.render(raylume.load_scene({scene!r}), width=16, height=16, spp=1, mode="path", aovs=False)
print(time.perf_counter() - t, img.stats["compile_seconds"])
"""

LLVM_PROBE = """
import sys
sys.path.insert(0, {bench!r})
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
from mitsuba_reference import load_toml, mitsuba_dict
import numpy as np
img = np.array(mi.render(mi.load_dict(mitsuba_dict(load_toml(), 16, 16)), spp=2))
print("ok", img.shape)
"""


def load() -> str:
    """The 1-minute load average (this benchmark alone brings it near its thread count; more means
    other work on the machine, which skews every time here)."""
    return f"1-min load average {os.getloadavg()[0]:.2f}"


# --------------------------------------------------------------------------- renderers


MATERIALS = REPO / "examples" / "materials.toml"


@dataclass
class BenchScene:
    """A scene of part 1: its TOML (raylume), its size and depth, and its Mitsuba dictionary."""

    label: str
    path: Path
    width: int
    height: int
    max_depth: int
    mitsuba: Callable[[], dict]  # called after mi.set_variant: the load_dict dictionary
    notes: list = field(default_factory=list)  # what Mitsuba's scene approximates (filled by `mitsuba`)


def cornell_bench(doc: dict, size: int) -> BenchScene:
    return BenchScene(
        "Cornell box", SCENE, size, size, int(doc["render"]["max_depth"]), lambda: mitsuba_dict(doc, size, size)
    )


def materials_bench(scale: float) -> BenchScene:
    from mitsuba_scene import mitsuba_scene_dict

    scene = raylume.load_scene(MATERIALS)
    W, H = max(1, round(scene.render.width * scale)), max(1, round(scene.render.height * scale))
    notes: list = []

    def build() -> dict:
        notes.clear()
        return mitsuba_scene_dict(scene, W, H, notes=notes)

    return BenchScene("materials (examples/materials.toml)", MATERIALS, W, H, scene.render.depth, build, notes)


class Raylume:
    name = "raylume"

    def __init__(self, width: int, height: int, max_depth: int, path: Path = SCENE):
        t = time.perf_counter()
        self.session = raylume.Session(raylume.load_scene(path))
        self.setup_seconds = time.perf_counter() - t
        self.size = dict(width=width, height=height, mode="path", max_depth=max_depth, aovs=False)
        t = time.perf_counter()
        warm = self.session.render(**{**self.size, "width": 16, "height": 16}, spp=1)
        self.warmup_seconds = time.perf_counter() - t
        self.compile_seconds = warm.stats["compile_seconds"]

    def render(self, spp: int, seed: int, threads: int, denoise: bool = False):
        """(linear RGB float64 (H, W, 3), wall seconds of the call, its stats)."""
        t = time.perf_counter()
        img = self.session.render(spp=spp, seed=seed, threads=threads, denoise=denoise, **self.size)
        seconds = time.perf_counter() - t
        return np.asarray(img.rgb, dtype=np.float64), seconds, img.stats


class Mitsuba:
    def __init__(self, variant: str, build: Callable[[], dict], threads=None, sampler: str | None = None):
        """`build` makes the scene's load_dict dictionary (called once the variant is set); the
        warm-up renders once on each thread count of `threads` (default: all cores). `sampler`:
        the sensor's sampler instead of the dictionary's (independent)."""
        import drjit as dr
        import mitsuba as mi

        self.mi, self.dr, self.variant = mi, dr, variant
        self.name = f"Mitsuba {variant}" + (f" {sampler}" if sampler else "")
        mi.set_variant(variant)
        d = build()
        if sampler:
            d["sensor"]["sampler"]["type"] = sampler
        t = time.perf_counter()
        self.scene = mi.load_dict(d)
        self.setup_seconds = time.perf_counter() - t
        t = time.perf_counter()
        # first renders: the LLVM variant compiles its kernels here (or loads them from its disk
        # cache), for each thread count: a first 1-thread render once took 10x a later one
        for n in threads or [os.cpu_count() or 1]:
            self.render(4, 1, n)
        self.warmup_seconds = time.perf_counter() - t

    def render(self, spp: int, seed: int, threads: int, denoise: bool = False):
        self.mi.set_variant(self.variant)
        self.dr.set_thread_count(threads)
        t = time.perf_counter()
        rgb = np.array(self.mi.render(self.scene, seed=seed, spp=spp), dtype=np.float64)[:, :, :3]
        return rgb, time.perf_counter() - t, {}


def mitsuba_version() -> str | None:
    try:
        import mitsuba
    except ImportError:
        return None
    return mitsuba.__version__


def llvm_probe() -> tuple[bool, str]:
    """Whether Mitsuba's llvm_ad_rgb renders here (in a child process: an LLVM failure aborts)."""
    why = child_probe(LLVM_PROBE.format(bench=str(Path(__file__).resolve().parent)), "a 16 x 16 probe render")
    return not why, why


# --------------------------------------------------------------------------- part 1: speed


def speed(args, bench: BenchScene, have_mitsuba: bool, llvm_ok: bool) -> dict:
    W, H, spp, depth = bench.width, bench.height, args.spp, bench.max_depth
    all_cores = os.cpu_count() or 1
    configs = [all_cores, 1] if all_cores > 1 else [1]
    print(f"\n{bench.label}: {W} x {H}, {spp} spp, max_depth {depth}", flush=True)
    engines = [Raylume(W, H, depth, bench.path)]
    if have_mitsuba:
        engines.append(Mitsuba("scalar_rgb", bench.mitsuba, configs))
        if llvm_ok:
            engines.append(Mitsuba("llvm_ad_rgb", bench.mitsuba, configs))
    times = {(e.name, t): [] for e in engines for t in configs}
    kernel = {t: [] for t in configs}
    rays = {}
    for r in range(args.rounds):
        for threads in configs:
            for e in engines:  # raylume, Mitsuba, raylume, Mitsuba, ...
                _, seconds, stats = e.render(spp, 100 + r, threads)
                times[e.name, threads].append(seconds)
                if stats:
                    kernel[threads].append(stats["render_seconds"])
                    rays[threads] = stats["rays"]
                print(f"  round {r + 1}/{args.rounds}, {threads} thread(s), {e.name}: {seconds:.2f} s", flush=True)
    samples = W * H * spp
    rows = []
    for threads in configs:
        base = median_of(times["raylume", threads])
        for e in engines:
            s = median_of(times[e.name, threads])
            extra = (
                f"kernel {median_of(kernel[threads]):.2f} s, {rays[threads] / samples:.2f} rays/sample"
                if e.name == "raylume"
                else ""
            )
            rows.append(
                [
                    e.name,
                    threads,
                    f"{s:.2f} s",
                    f"{samples / s / 1e6:.3f}",
                    "" if e.name == "raylume" else f"{base / s:.2f}",
                    extra,
                ]
            )
    print(
        f"\n### 1. Speed: {bench.label} {W} x {H}, {spp} spp, max_depth {depth}, "
        f"median of {args.rounds} alternating rounds; {machine()}; {load()} at the end\n"
    )
    print(
        table(
            ["renderer", "threads", "seconds (median)", "M samples/s", "time ratio raylume / this", "notes"],
            rows,
        )
    )
    # the VM's speed drifts between rounds: each round's own ratio (raylume's time over the other
    # renderer's in the same round, a few seconds apart) is the steadier measure; their median and range
    for threads in configs:
        for e in engines[1:]:
            ratios = [r / o for r, o in zip(times["raylume", threads], times[e.name, threads], strict=True)]
            print(
                f"per-round ratio raylume / {e.name}, {threads} thread(s): median {median_of(ratios):.3f}, "
                f"range {min(ratios):.3f}-{max(ratios):.3f} over {len(ratios)} rounds"
            )
    if bench.notes and have_mitsuba:
        print("\nMitsuba's scene approximates raylume's: " + "; ".join(bench.notes) + ".")
    setup = [
        [e.name, f"{e.setup_seconds:.3f} s", f"{e.warmup_seconds:.2f} s"]
        + ([f"{e.compile_seconds:.2f} s"] if e.name == "raylume" else ["-"])
        for e in engines
    ]
    print(
        "\n"
        + table(
            [
                "renderer",
                "scene setup (Session / load_dict)",
                "warm-up render(s) (wall)",
                "of which compiling / cache load",
            ],
            setup,
        )
    )
    return {
        t: (median_of(times["raylume", t]), {e.name: median_of(times[e.name, t]) for e in engines}) for t in configs
    }


# --------------------------------------------------------------------------- part 2: error against time


def cold_start() -> None:
    with tempfile.TemporaryDirectory() as cache:
        wall, out = run_python(COLD_CODE.format(scene=str(SCENE)), env={"NUMBA_CACHE_DIR": cache})
    first, compile_s = (float(x) for x in out.split())
    print(
        f"\nraylume cold start, new process, empty Numba cache: {wall:.1f} s wall "
        f"(first path render call {first:.1f} s, of which compiling {compile_s:.1f} s); {load()} at the end"
    )


def error_vs_time(args, doc, have_mitsuba: bool) -> dict:
    with np.load(REFERENCE) as f:
        ref = f["mean"].astype(np.float64)
        keep = ~(f["light_coverage"] > 0)
    H, W = keep.shape
    depth = int(doc["render"]["max_depth"])
    threads = os.cpu_count() or 1
    engines = [Raylume(W, H, depth)]
    if have_mitsuba:
        engines.append(Mitsuba("scalar_rgb", lambda: mitsuba_dict(doc, W, H)))
        # raylume's sampler is low-discrepancy (scrambled Sobol points per pixel): its peer is
        # Mitsuba's low-discrepancy sampler (scrambled (0, 2)-sequences, padded), beside the
        # independent one its speed and the references use
        engines.append(Mitsuba("scalar_rgb", lambda: mitsuba_dict(doc, W, H), sampler="ldsampler"))

    def rmse(img):
        return float(np.sqrt(np.mean((img[keep] - ref[keep]) ** 2)))

    runs = {}  # (engine, spp, denoised) -> [(rmse, seconds)]
    for r in range(args.rounds):
        for spp in args.spp_list:
            for e in engines:
                img, seconds, _ = e.render(spp, 2000 + r, threads)
                runs.setdefault((e.name, spp, False), []).append((rmse(img), seconds))
        img, seconds, stats = engines[0].render(16, 3000 + r, threads, denoise=True)
        runs.setdefault(("raylume", 16, True), []).append((rmse(img), seconds, stats.get("denoise_seconds", 0.0)))
        print(f"  error round {r + 1}/{args.rounds} done", flush=True)
    result = {}
    rows = []
    for (name, spp, denoised), vals in runs.items():
        e = median_of([v[0] for v in vals])
        s = median_of([v[1] for v in vals])
        result[name, spp, denoised] = (e, s)
        label = f"{spp} + OIDN" if denoised else str(spp)
        note = f"denoiser {median_of([v[2] for v in vals]):.2f} s of it" if denoised else ""
        rows.append(
            [name, label, f"{e:.5f}", f"{s:.3f} s", f"{W * H * spp / s / 1e6:.3f}", f"{e * e * s * 1e6:.1f}", note]
        )
    rows.sort(key=lambda row: (row[0] != "raylume", int(row[1].split()[0]), "OIDN" in row[1]))
    ref_rms = float(np.sqrt(np.mean(ref[keep] ** 2)))
    print(
        f"\n### 2. Error against time: {W} x {H}, RMSE (linear RGB, {int((~keep).sum())} light pixels left out; "
        f"the reference's RMS value is {ref_rms:.4f}) against {REFERENCE.relative_to(REPO)}, "
        f"{threads} threads, median of {args.rounds} rounds; {load()} at the end\n"
    )
    headers = ["renderer", "spp", "RMSE (median)", "seconds (median)", "M samples/s", "RMSE^2 x s (1e-6)", "notes"]
    print(table(headers, rows))
    print("\nRMSE^2 x seconds: error variance times time, the inverse of Monte Carlo efficiency (lower is better).")
    return result


def plot(result: dict, path: str) -> None:
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for name, style in (("raylume", "o-"), ("Mitsuba scalar_rgb", "s--"), ("Mitsuba scalar_rgb ldsampler", "^:")):
        pts = sorted((s, e, spp) for (n, spp, d), (e, s) in result.items() if n == name and not d)
        if not pts:
            continue
        xs, ys, spps = zip(*pts)
        ax.plot(xs, ys, style, label=name)
        for x, y, spp in pts:
            ax.annotate(str(spp), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    if ("raylume", 16, True) in result:
        e, s = result["raylume", 16, True]
        ax.plot([s], [e], "*", markersize=14, color="C2", label="raylume 16 spp + OIDN denoiser")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlabel("seconds per render (wall, 2 threads)")
    ax.set_ylabel("RMSE against Mitsuba 65536 spp")
    ax.set_title("Cornell box 64 x 64: error against time (labels: spp)", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    print(f"\nwrote {path} ({Path(path).stat().st_size / 1024:.0f} KiB)")


# --------------------------------------------------------------------------- part 3: the denoising goal at full size

CACHE = REPO / "benchmarks" / ".cache"  # git-ignored: raylume's long reference renders


def raylume_reference(doc, width: int, spp: int = 4096, seed: int = 99) -> np.ndarray:
    """raylume's own render of the Cornell box at width x width and `spp`, cached under
    benchmarks/.cache by the scene file's contents (minutes on two cores when not cached)."""
    import hashlib

    key = hashlib.sha1(
        SCENE.read_bytes() + b"".join(p.read_bytes() for p in sorted(SCENE.parent.glob("cornell/*.obj")))
    )
    path = CACHE / f"cornell_{width}_{spp}spp_seed{seed}_{key.hexdigest()[:10]}.npy"
    if path.exists():
        return np.load(path)
    print(f"  rendering the {spp}-spp reference at {width} x {width} (cached in {path.relative_to(REPO)})", flush=True)
    t = time.perf_counter()
    session = raylume.Session(raylume.load_scene(SCENE))
    img = session.render(width=width, height=width, spp=spp, seed=seed, mode="path", aovs=False)
    ref = np.asarray(img.rgb, dtype=np.float64)
    CACHE.mkdir(exist_ok=True)
    np.save(path, ref)
    print(f"  reference done in {time.perf_counter() - t:.0f} s", flush=True)
    return ref


def denoise_goal(args, doc) -> dict:
    """Denoised 16 spp against raw 256 spp, both against raylume's 4096-spp reference, at the
    speed benchmark's size: RMSE over all pixels, over the pixels that see none of the light
    (exact coverage, mitsuba_reference.light_coverage) and over those less a 2-pixel ring."""
    from mitsuba_reference import light_coverage

    W = args.size
    ref = raylume_reference(doc, W)
    sees_light = light_coverage(doc, W, W)[0] > 0
    ring = sees_light.copy()
    for dy in range(-2, 3):
        for dx in range(-2, 3):
            ring |= np.roll(np.roll(sees_light, dy, 0), dx, 1)
    masks = {"all pixels": None, "pixels that see none of the light": sees_light, "... less a 2-pixel ring": ring}
    engine = Raylume(W, W, int(doc["render"]["max_depth"]))
    threads = os.cpu_count() or 1
    errors: dict = {}
    for r in range(args.rounds):
        for label, spp, denoise in (("256", 256, False), ("16 + OIDN", 16, True)):
            img, seconds, _ = engine.render(spp, 4000 + 10 * r + spp, threads, denoise=denoise)
            for name, leave_out in masks.items():
                err = ((img - ref) ** 2).mean(axis=2)
                keep = err if leave_out is None else err[~leave_out]
                errors.setdefault((label, name), []).append(float(np.sqrt(keep.mean())))
            errors.setdefault((label, "seconds"), []).append(seconds)
        print(f"  denoising round {r + 1}/{args.rounds} done", flush=True)
    rows = [
        [name, f"{median_of(errors['256', name]):.5f}", f"{median_of(errors['16 + OIDN', name]):.5f}"] for name in masks
    ]
    rows.append(
        [
            "seconds per render",
            f"{median_of(errors['256', 'seconds']):.2f}",
            f"{median_of(errors['16 + OIDN', 'seconds']):.2f}",
        ]
    )
    print(
        f"\n### 3. Denoising at {W} x {W}: RMSE against raylume's 4096 spp (seed 99), {threads} threads, "
        f"median of {args.rounds} rounds; {load()} at the end\n"
    )
    print(table(["pixels", "raw 256 spp", "16 spp + OIDN"], rows))
    return {name: (median_of(errors["16 + OIDN", name]), median_of(errors["256", name])) for name in masks}


# --------------------------------------------------------------------------- main


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds (medians over them)")
    parser.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: 8 spp, the Cornell box at 64 x 64, materials at 1/4 size, spp up to 64, no cold start",
    )
    parser.add_argument(
        "--scene", choices=["cornell", "materials", "both"], default="both", help="the scene(s) of part 1 (speed)"
    )
    parser.add_argument("--size", type=int, help="the Cornell box's side in parts 1 and 3 (default 256, --quick 64)")
    parser.add_argument(
        "--materials-scale",
        type=float,
        help="examples/materials.toml's 640 x 320 times this in part 1 (default 1, --quick 0.25)",
    )
    parser.add_argument("--speed-only", action="store_true", help="part 1 alone (no error, denoising or cold start)")
    parser.add_argument("--plot", metavar="PATH", help="write the RMSE-against-time plot (PNG) here")
    parser.add_argument("--no-cold", dest="cold", action="store_false", help="skip the cold-compile process")
    parser.add_argument("--skip-mitsuba", action="store_true", help="raylume's figures alone")
    parser.add_argument(
        "--no-denoise-goal", dest="denoise_goal", action="store_false", help="skip part 3 (its reference takes minutes)"
    )
    parser.add_argument("--denoise-goal-only", action="store_true", help="part 3 alone")
    args = parser.parse_args()
    if args.speed_only and args.denoise_goal_only:
        parser.error("--speed-only and --denoise-goal-only exclude each other")
    size, args.spp = (64, 8) if args.quick else (256, 64)
    args.size = args.size or size
    args.materials_scale = args.materials_scale or (0.25 if args.quick else 1.0)
    args.spp_list = [4, 16, 64] if args.quick else [4, 16, 64, 256, 1024]
    args.cold = args.cold and not args.quick and not args.speed_only
    args.denoise_goal = args.denoise_goal and not args.quick and not args.speed_only

    doc = load_toml()
    version = None if args.skip_mitsuba else mitsuba_version()
    have_mitsuba = version is not None
    llvm_ok, llvm_why = llvm_probe() if have_mitsuba else (False, "")
    print(f"raylume path mode; {machine()}; {load()}")
    if not have_mitsuba:
        why = "--skip-mitsuba" if args.skip_mitsuba else "not importable (pip install 'raylume[bench]')"
        print(f"Mitsuba skipped: {why}")
    else:
        print(f"Mitsuba {version}: scalar_rgb; llvm_ad_rgb " + ("runs here" if llvm_ok else f"skipped: {llvm_why}"))

    only3 = args.denoise_goal_only
    benches = []
    if not only3 and args.scene in ("cornell", "both"):
        benches.append(cornell_bench(doc, args.size))
    if not only3 and args.scene in ("materials", "both"):
        benches.append(materials_bench(args.materials_scale))
    speeds = {bench.label: speed(args, bench, have_mitsuba, llvm_ok) for bench in benches}
    errors = {} if only3 or args.speed_only else error_vs_time(args, doc, have_mitsuba)
    denoising = denoise_goal(args, doc) if args.denoise_goal else {}
    if args.plot and errors:
        plot(errors, args.plot)
    if args.cold and not only3:  # last: it takes a minute or more and the figures above matter more
        cold_start()

    print("\n### Goals\n")
    for name, (d, raw) in denoising.items():
        verdict = "holds" if d < raw else "does not hold"
        print(
            f"- {args.size} x {args.size}, {name}: denoised 16 spp closer to the 4096-spp reference than raw 256 spp: "
            f"{verdict} (RMSE {d:.5f} against {raw:.5f})"
        )
    if ("raylume", 16, True) in errors and ("raylume", 256, False) in errors:
        d, raw = errors["raylume", 16, True][0], errors["raylume", 256, False][0]
        verdict = "holds" if d < raw else "does not hold"
        print(
            f"- 64 x 64 against Mitsuba, light pixels left out: denoised 16 spp closer than raw 256 spp: {verdict} "
            f"(RMSE {d:.5f} against {raw:.5f}, ratio {d / raw:.2f})"
        )
    if have_mitsuba:
        for label, by_threads in speeds.items():
            for threads, (ours, theirs) in by_threads.items():
                for variant in ("scalar_rgb", "llvm_ad_rgb"):
                    if f"Mitsuba {variant}" not in theirs:
                        continue
                    m = theirs[f"Mitsuba {variant}"]
                    verdict = "holds" if ours <= m else "does not hold"
                    print(
                        f"- {label}: raylume at least as fast per sample as Mitsuba {variant}, {threads} thread(s): "
                        f"{verdict} (raylume / Mitsuba time {ours / m:.2f})"
                    )
        top = max(args.spp_list)
        if ("Mitsuba scalar_rgb", top, False) in errors:
            (e1, s1), (e2, s2) = errors["raylume", top, False], errors["Mitsuba scalar_rgb", top, False]
            print(
                f"- (not a goal) error for the time, {top} spp: raylume's RMSE^2 x seconds is "
                f"{e1 * e1 * s1 / (e2 * e2 * s2):.2f} x Mitsuba's (below 1: raylume reaches an error sooner)"
            )
    else:
        print("- speed against Mitsuba: not measured (Mitsuba skipped)")


if __name__ == "__main__":
    run_main(main)
