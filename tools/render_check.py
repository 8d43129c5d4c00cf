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
