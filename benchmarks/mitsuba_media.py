"""Mitsuba 3 references for raylume's participating media (tests/test_media_vs_mitsuba.py), and the
same scenes timed side by side.

    python benchmarks/mitsuba_media.py reference [--seeds 16] [--spp 512]   # writes the .npz
    python benchmarks/mitsuba_media.py bench [--rounds 3]                    # samples per second

Three scenes, each a medium inside a unit sphere or cube with a null boundary, over a grey
floor, lit by a sphere light out of view: `homogeneous` (grey, forward-scattering), `chromatic`
(sigma_a and sigma_s differ per channel, backward-scattering) and `grid` (a smooth noise
density, 12^3 voxels, grey extinction, coloured albedo). Mitsuba renders them with `volpath`
(`volpathmis` for the chromatic one, whose spectral MIS suits it), in scalar_rgb, from the same
numbers: Mitsuba is right-handed, so every x is negated (the grid flipped along x) and Mitsuba's
image is raylume's, not its mirror. The .npz holds the raylume scenes (as JSON), the grid, and
per scene the mean image over seeds and each seed's 8 x 8 block means and image mean, so the
test estimates standard errors from the spread across seeds.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "tests" / "reference" / "media_mitsuba.npz"
WIDTH, HEIGHT, BLOCK = 32, 24, 8
LIGHT = {"type": "sphere", "position": [1.2, 2.6, -0.6], "radius": 0.4, "intensity": [12.0, 12.0, 12.0]}
FLOOR_Y = -1.3


def density_grid() -> np.ndarray:
    from scipy import ndimage

    rng = np.random.default_rng(2026)
    d = ndimage.gaussian_filter(rng.random((12, 12, 12)), 1.6)
    d = (d - d.min()) / (d.max() - d.min())
    return (d**2).astype(np.float32)  # 0 .. 1, mostly thin with dense lumps


def scenes() -> dict[str, dict]:
    """The raylume scene documents (the grid's density file is `density.npy`, the cube `box.obj`)."""
    base = {
        "render": {"width": WIDTH, "height": HEIGHT, "mode": "path", "max_depth": -1},
        "camera": {"position": [0, 0.4, -3.5], "look_at": [0, -0.1, 0], "fov": 40},
        "lights": [LIGHT],
    }
    floor = {"type": "plane", "point": [0, FLOOR_Y, 0], "material": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}}
    sphere = {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": {"type": "null"}, "interior": "m"}
    cube = {"type": "mesh", "file": "box.obj", "material": {"type": "null"}, "interior": "m"}
    albedo = np.array([0.9, 0.6, 0.3])
    return {
        "homogeneous": {
            **base,
            "media": {"m": {"type": "homogeneous", "sigma_a": 0.3, "sigma_s": 2.7, "g": 0.5}},
            "objects": [floor, sphere],
        },
        "chromatic": {
            **base,
            "media": {"m": {"type": "homogeneous", "sigma_a": [0.6, 0.2, 0.05], "sigma_s": [0.5, 1.5, 4.0], "g": -0.3}},
            "objects": [floor, sphere],
        },
        "grid": {
            **base,
            "media": {
                "m": {
                    "type": "grid",
                    "density": "density.npy",
                    "bounds_min": [-1, -1, -1],
                    "bounds_max": [1, 1, 1],
                    "sigma_a": (6.0 * (1 - albedo)).tolist(),
                    "sigma_s": (6.0 * albedo).tolist(),
                    "g": 0.2,
                }
            },
            "objects": [floor, cube],
        },
    }


def mitsuba_scene(name: str, doc: dict, grid: np.ndarray):
    import mitsuba as mi

    T = mi.ScalarTransform4f
    cam = doc["camera"]
    flip = np.array([-1.0, 1.0, 1.0])
    medium = doc["media"]["m"]
    sigma_a, sigma_s = (np.broadcast_to(np.asarray(medium[k], float), 3) for k in ("sigma_a", "sigma_s"))
    sigma_t = sigma_a + sigma_s
    phase = {"type": "hg", "g": float(medium["g"])}
    if medium["type"] == "grid":
        m = {
            "type": "heterogeneous",
            "sigma_t": {
                "type": "gridvolume",
                "grid": mi.VolumeGrid(np.ascontiguousarray(grid[:, :, ::-1, None])),
                "to_world": T().translate([-1, -1, -1]).scale([2, 2, 2]),
            },
            "scale": float(sigma_t[0]),
            "albedo": {"type": "rgb", "value": (sigma_s / sigma_t).tolist()},
            "phase": phase,
        }
        boundary = {"type": "cube"}
    else:
        m = {  # sigma_t as a colour in [0, 1] times a scale (Mitsuba reads an RGB as a reflectance)
            "type": "homogeneous",
            "sigma_t": {"type": "rgb", "value": (sigma_t / sigma_t.max()).tolist()},
            "scale": float(sigma_t.max()),
            "albedo": {"type": "rgb", "value": (sigma_s / sigma_t).tolist()},
            "phase": phase,
        }
        boundary = {"type": "sphere", "center": [0, 0, 0], "radius": 1.0}
    light = doc["lights"][0]
    return {
        "type": "scene",
        "integrator": {"type": "volpathmis" if name == "chromatic" else "volpath", "max_depth": -1, "rr_depth": 5},
        "sensor": {
            "type": "perspective",
            "fov": float(cam["fov"]),
            "fov_axis": "y",
            "to_world": T().look_at(
                origin=(np.asarray(cam["position"]) * flip).tolist(),
                target=(np.asarray(cam["look_at"]) * flip).tolist(),
                up=[0, 1, 0],
            ),
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {
                "type": "hdrfilm",
                "width": WIDTH,
                "height": HEIGHT,
                "pixel_format": "rgb",
                "component_format": "float32",
                "rfilter": {"type": "box"},
            },
        },
        "floor": {
            "type": "rectangle",
            "to_world": T().translate([0, FLOOR_Y, 0]).rotate([1, 0, 0], -90).scale([50, 50, 1]),
            "bsdf": {
                "type": "twosided",
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5] * 3}},
            },
        },
        "medium_boundary": {**boundary, "bsdf": {"type": "null"}, "interior": m},
        "light": {
            "type": "sphere",
            "center": (np.asarray(light["position"]) * flip).tolist(),
            "radius": float(light["radius"]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": light["intensity"]}},
        },
    }


def block_means(images: np.ndarray) -> np.ndarray:
    s, h, w, c = images.shape
    return images.reshape(s, h // BLOCK, BLOCK, w // BLOCK, BLOCK, c).mean(axis=(2, 4))


def make_reference(args) -> None:
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    grid = density_grid()
    out: dict[str, np.ndarray] = {"density": grid}
    docs = scenes()
    for name, doc in docs.items():
        scene = mi.load_dict(mitsuba_scene(name, doc, grid))
        start = time.perf_counter()
        images = []
        for seed in range(args.seeds):
            images.append(np.array(mi.render(scene, seed=seed, spp=args.spp), dtype=np.float64)[:, :, :3])
            print(f"  {name}: seed {seed + 1}/{args.seeds}, {time.perf_counter() - start:.0f} s", flush=True)
        images = np.stack(images)
        out[f"{name}_mean"] = images.mean(axis=0)
        out[f"{name}_blocks"] = block_means(images)
        out[f"{name}_global"] = images.mean(axis=(1, 2))
    meta = {"scenes": docs, "seeds": args.seeds, "spp": args.spp, "block": BLOCK, "mitsuba": mi.__version__}
    np.savez_compressed(OUT, meta=json.dumps(meta), **out)
    print(f"wrote {OUT}")


LLVM_PROBE = """
import sys
sys.path.insert(0, {bench!r})
import mitsuba as mi
import numpy as np
from mitsuba_media import density_grid, mitsuba_scene, scenes
mi.set_variant("llvm_ad_rgb")
for name, doc in scenes().items():
    md = mitsuba_scene(name, doc, density_grid())
    md["sensor"]["film"].update(width=8, height=6)
    np.asarray(mi.render(mi.load_dict(md), spp=1))
print("ok")
"""


def llvm_probe() -> str:
    """Why Mitsuba's llvm_ad_rgb does not render the three scenes here ("" if it does), found in a
    child process: an LLVM that fails to compile a kernel aborts the process, past any except."""
    from common import child_probe

    return child_probe(LLVM_PROBE.format(bench=str(Path(__file__).resolve().parent)), "8 x 6 probe renders")


def bench(args) -> None:
    """Samples per second, raylume against Mitsuba (scalar_rgb, llvm_ad_rgb where it runs), alternating."""
    import tempfile

    import mitsuba as mi
    import trimesh

    import raylume
    from raylume.scene.document import scene_from_dict

    grid = density_grid()
    folder = Path(tempfile.mkdtemp())
    np.save(folder / "density.npy", grid)
    trimesh.creation.box(extents=(2, 2, 2)).export(folder / "box.obj")
    size, spp = (args.size, args.size * HEIGHT // WIDTH), args.spp
    llvm_why = llvm_probe()
    print(f"{size[0]} x {size[1]}, {spp} spp, 2 threads; median of {args.rounds} alternating rounds")
    if llvm_why:
        print(f"Mitsuba llvm_ad_rgb skipped: {llvm_why}")
    print("| scene | raylume | Mitsuba scalar_rgb | Mitsuba llvm_ad_rgb | raylume / scalar | raylume / llvm |")
    print("| --- | --- | --- | --- | --- | --- |")
    docs = scenes()
    # the grid's cost against a homogeneous medium of the same mean density (raylume only)
    mean_density = float(grid.mean())
    same_mean = json.loads(json.dumps(docs["grid"]))
    medium = same_mean["media"]["m"]
    same_mean["media"]["m"] = {
        "type": "homogeneous",
        "sigma_a": [a * mean_density for a in medium["sigma_a"]],
        "sigma_s": [x * mean_density for x in medium["sigma_s"]],
        "g": medium["g"],
    }
    docs["grid's mean, homogeneous"] = same_mean
    for name, doc in docs.items():
        doc = json.loads(json.dumps(doc))
        doc["render"].update(width=size[0], height=size[1], spp=spp)
        s = raylume.Session(scene_from_dict(doc).with_base_dir(folder))
        s.render(width=8, height=6, spp=1)
        variants = {}
        in_mitsuba = name in ("homogeneous", "chromatic", "grid")
        for variant in (("scalar_rgb",) if llvm_why else ("scalar_rgb", "llvm_ad_rgb")) if in_mitsuba else ():
            try:
                mi.set_variant(variant)
                md = mitsuba_scene(name, doc, grid)
                md["sensor"]["film"].update(width=size[0], height=size[1])
                variants[variant] = (mi.load_dict(md), mi.render, mi)
                mi.render(variants[variant][0], spp=1)
            except Exception as exc:  # noqa: BLE001 - a variant that does not run is reported, not fatal
                print(f"  {variant}: {exc}", file=sys.stderr)
        times = {"raylume": [], **{v: [] for v in variants}}
        for _ in range(args.rounds):
            t = time.perf_counter()
            s.render(spp=spp, aovs=False)
            times["raylume"].append(time.perf_counter() - t)
            for v, (scene, render, mi_mod) in variants.items():
                mi_mod.set_variant(v)
                t = time.perf_counter()
                img = render(scene, spp=spp)
                np.asarray(img)
                times[v].append(time.perf_counter() - t)
        med = {k: float(np.median(v)) for k, v in times.items()}
        samples = size[0] * size[1] * spp
        cells = [
            f"{med[v]:.2f} s ({samples / med[v] / 1e6:.2f} M samples/s)" if v in med else "-"
            for v in ("raylume", "scalar_rgb", "llvm_ad_rgb")
        ]
        ratios = [f"{med['raylume'] / med[v]:.2f}" if v in med else "-" for v in ("scalar_rgb", "llvm_ad_rgb")]
        print(f"| {name} | " + " | ".join(cells + ratios) + " |", flush=True)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    ref = sub.add_parser("reference")
    ref.add_argument("--seeds", type=int, default=16)
    ref.add_argument("--spp", type=int, default=512)
    b = sub.add_parser("bench")
    b.add_argument("--rounds", type=int, default=3)
    b.add_argument("--size", type=int, default=128)
    b.add_argument("--spp", type=int, default=32)
    args = parser.parse_args(argv)
    {"reference": make_reference, "bench": bench}[args.command](args)


if __name__ == "__main__":
    from common import run_main  # (here: tests import this module for its scene conversion)

    run_main(main)
