"""The cost of the refraction tree: the glass example against the same scene with its glass
made opaque, at 600 x 450 (the example's size), trace mode.

    python benchmarks/bench_glass.py [--repeats 5]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from common import REPO, machine, median_of, run_main, table

import raylume


def opaque(scene: raylume.Scene) -> raylume.Scene:
    doc = scene.model_dump()
    for material in doc["materials"].values():
        material["transparency"] = 0.0
    return raylume.scene_from_dict(doc).with_base_dir(scene.base_dir)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    glass = raylume.load_scene(Path(REPO) / "examples" / "glass.toml")
    rows = []
    base = None
    for name, scene in (("opaque spheres", opaque(glass)), ("glass spheres", glass)):
        raylume.render(scene, width=16, height=12)  # compile outside the timing
        runs = [raylume.render(scene, aovs=False).stats for _ in range(args.repeats)]
        seconds = median_of([r["render_seconds"] for r in runs])
        rays = runs[0]["rays"]
        base = base or seconds
        rows.append(
            [
                name,
                f"{seconds * 1000:.0f} ms",
                f"{rays / 1e6:.2f} M",
                f"{rays / seconds / 1e6:.1f}",
                f"{seconds / base:.2f}x",
            ]
        )
    print(f"examples/glass.toml, 600 x 450, max_depth 8, {runs[0]['threads']} threads; {machine()}\n")
    print(table(["scene", "kernel time (median)", "rays", "Mrays/s", "time vs opaque"], rows))


if __name__ == "__main__":
    run_main(main)
