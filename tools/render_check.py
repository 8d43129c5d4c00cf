"""Renders every example and built-in scene into a folder of .npy files, so that two builds can be
compared bit for bit (issue 43: a refactor must not change any image).

    PYTHONPATH=<tree>/src python tools/render_check.py OUT_DIR [--quick]
    python tools/render_check.py --compare DIR_A DIR_B

Each example at its file's settings (animations: frame 0 and a middle frame), then every example
in every mode at a small size with its AOVs, a crop window, and 1 against 2 threads."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
MODES = ("cast", "trace", "path", "raster")


def _save(out: Path, name: str, render, *args, **kwargs) -> None:
    """Saves what render(*args, **kwargs) returns (an Image), or the one-line error it raises
    (a scene that a mode refuses, such as a billion instanced triangles in raster mode)."""
    import raylume

    try:
        image = render(*args, **kwargs)
    except raylume.RaylumeError as exc:
        (out / f"{name}.error.txt").write_text(str(exc))
        np.save(out / f"{name}.npy", np.zeros(0))
        return
    np.save(out / f"{name}.npy", np.asarray(image.rgb))
    for aov, value in (getattr(image, "aovs", None) or {}).items():
        np.save(out / f"{name}.{aov}.npy", np.asarray(value))


def render_all(out: Path, quick: bool) -> None:
    import raylume
    from raylume.animation import camera_at

    warnings.simplefilter("ignore")
    out.mkdir(parents=True, exist_ok=True)
    examples = sorted((ROOT / "examples").glob("*.toml")) + [ROOT / "examples/gltf/room.glb"]
    render = raylume.render
    for path in examples:
        scene = raylume.load_scene(path) if path.suffix == ".toml" else str(path)
        label = path.stem
        if (out / f"{label}.t1.npy").exists():  # rendered by an earlier run into this folder
            continue
        print(label, flush=True)
        if not quick and label == "flight":
            session = raylume.Session(scene)
            for frame in (0, 12):
                _save(out, f"{label}.file.frame{frame}", session.render, camera_at(scene, frame), aovs=False)
        elif not quick:
            _save(out, f"{label}.file", render, scene, aovs=False)
        for mode in MODES:
            _save(out, f"{label}.{mode}", render, scene, mode=mode, width=48, height=32, spp=4, seed=7)
        _save(out, f"{label}.crop", render, scene, mode="path", width=48, height=32, spp=2, crop=(5, 29, 3, 19))
        _save(out, f"{label}.t1", render, scene, mode="trace", width=40, height=24, spp=2, threads=1)
    _save(out, "builtin.seed", render, "seed")
    import trimesh

    mesh = out / "every_light.ply"
    trimesh.creation.icosphere(subdivisions=1, radius=0.12).export(mesh)
    instanced = {"type": "mesh", "file": str(mesh), "material": {"type": "diffuse", "emission": [3, 1, 3]},
                 "instances": [{"translate": [x, 2.8, 2.0]} for x in (-2.0, -1.0, 1.0)]}  # fmt: skip
    every = raylume.Scene.model_validate({**EVERY_LIGHT, "objects": [*EVERY_LIGHT["objects"], instanced]})
    if not (out / "every_light.t1.npy").exists():
        for mode in MODES:
            _save(out, f"every_light.{mode}", render, every, mode=mode, spp=8, seed=3)
        _save(out, "every_light.t1", render, every, mode="trace", spp=2, threads=1)


# Every kind of light and emitter in one scene: spot, point, directional, quad and sphere lights,
# ambient lights before and between the others, emissive shapes of every sampled kind, an
# emissive instanced mesh, an environment, and every material type.
EVERY_LIGHT = {
    "render": {"width": 48, "height": 32, "max_depth": 4},
    "camera": {"position": [0, 1.5, -5], "look_at": [0, 0.5, 0], "fov": 50},
    "environment": {"color": [0.05, 0.07, 0.1]},
    "lights": [
        {"type": "ambient", "intensity": 0.05},
        {"type": "spot", "position": [1, 4, -1], "direction": [-0.2, -1, 0.3], "angle": 30, "inner_angle": 20,
         "intensity": 8.0},
        {"type": "point", "position": [-2, 3, -2], "intensity": [3.0, 2.5, 2.0]},
        {"type": "ambient", "intensity": [0.02, 0.01, 0.03]},
        {"type": "directional", "direction": [1, 2, -1], "intensity": 0.4},
        {"type": "quad", "position": [0, 3.5, 1], "u": [1, 0, 0], "v": [0, 0, 1], "intensity": 2.0, "samples": 4},
        {"type": "sphere", "position": [2.5, 1.5, 1], "radius": 0.3, "intensity": 3.0, "samples": 2},
    ],
    "objects": [
        {"type": "plane", "point": [0, 0, 0], "normal": [0, 1, 0], "material": {"type": "diffuse", "color": "#999999"}},
        {"type": "sphere", "center": [-1.2, 0.6, 0.5], "radius": 0.6,
         "material": {"type": "dielectric", "roughness": 0.1}},
        {"type": "sphere", "center": [0.2, 0.5, 0.2], "radius": 0.5,
         "material": {"type": "conductor", "roughness": 0.2}},
        {"type": "sphere", "center": [1.3, 0.4, -0.3], "radius": 0.4,
         "material": {"type": "plastic", "color": [0.2, 0.4, 0.8]}},
        {"type": "cylinder", "p0": [-2, 0, 1.5], "p1": [-2, 1.2, 1.5], "radius": 0.3, "capped": True,
         "material": {"specular": 50, "reflective": 0.3, "color": [0.9, 0.5, 0.2]}},
        {"type": "sphere", "center": [-0.5, 1.8, 2], "radius": 0.15,
         "material": {"type": "diffuse", "emission": [4, 2, 1]}},
        {"type": "disk", "center": [1.5, 1.0, 2.5], "normal": [0, 0, -1], "radius": 0.3,
         "material": {"type": "diffuse", "emission": [1, 3, 1]}},
        {"type": "quad", "position": [-1.5, 2.2, 2.5], "u": [0.5, 0, 0], "v": [0, 0.5, 0],
         "material": {"type": "diffuse", "emission": [1, 1, 3]}},
        {"type": "triangle", "vertices": [[0.5, 2.5, 3], [1, 2.5, 3], [0.75, 3, 3]],
         "material": {"type": "diffuse", "emission": [2, 2, 2]}},
        {"type": "sphere", "center": [0, 0.8, -1.5], "radius": 0.3,
         "material": {"transparency": 0.7, "ior": 1.3, "color": [0.8, 1, 0.8]}},
    ],
}  # fmt: skip


def compare(a: Path, b: Path) -> int:
    names = sorted(p.name for p in a.glob("*.npy"))
    missing = sorted(set(names) ^ {p.name for p in b.glob("*.npy")})
    bad = 0
    for name in names:
        if not (b / name).exists():
            continue
        x, y = np.load(a / name), np.load(b / name)
        same = x.shape == y.shape and x.dtype == y.dtype and x.tobytes() == y.tobytes()
        if not same:
            bad += 1
            diff = np.abs(x.astype(np.float64) - y.astype(np.float64)) if x.shape == y.shape else None
            print(f"DIFFERENT {name}: max |a-b| {np.nanmax(diff) if diff is not None else 'shape'}")
    print(f"{len(names) - bad} of {len(names)} identical; only in one folder: {missing or 'none'}")
    return 1 if bad or missing else 0


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("out", nargs="?")
    parser.add_argument("--quick", action="store_true", help="skip the renders at the files' own settings")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = parser.parse_args()
    if args.compare:
        return compare(Path(args.compare[0]), Path(args.compare[1]))
    render_all(Path(args.out), args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
