"""Cold compile: the first use of each kind of work on a machine, in a new process with an empty
Numba cache, as CPU seconds (raylume's import, the scene's build and the kernels' compilation,
numpy's and trimesh's imports left out; the renders are tiny).

    python benchmarks/bench_compile.py [--repeats 3] [--src DIR --src DIR ...] [WORK ...]

WORK: intersect, occluded, cast, cast-full, seed, glass, path, raster (default: all). With --src, each DIR
is a checkout of raylume (its src/ is imported instead of this one's): the builds run in turn,
A, B, A, B, so that the machine's drift is shared among them (an older build must understand
the same calls: `raylume.load_scene`, `raylume.scene_from_dict`, `raylume.intersect`). Issue 13's
goal: no longer than the build of its filing (f6d3e37).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from common import REPO, machine, median_of, run_main, table

EXAMPLES = REPO / "examples"
MESH = "import trimesh; trimesh.creation.icosphere(3).export(mesh)"  # 1,280 triangles
MESH_SCENE = 'raylume.scene_from_dict({"objects": [{"type": "mesh", "file": mesh}]})'
WORK = {
    "intersect": (
        f"{MESH}; from raylume.compile import compile_scene; import numpy as np; "
        f"raylume.intersect(compile_scene({MESH_SCENE}), np.zeros((4, 3)) + [0, 0, -5], np.tile([0, 0, 1.0], (4, 1)))",
        "raylume.intersect on a 1,280-triangle mesh",
    ),
    "occluded": (
        f"{MESH}; from raylume.compile import compile_scene; import numpy as np; "
        f"raylume.occluded(compile_scene({MESH_SCENE}), np.zeros((4, 3)) + [0, 0, -5], np.tile([0, 0, 1.0], (4, 1)))",
        "raylume.occluded on that mesh (a build without it fails)",
    ),
    "cast": (
        f"{MESH}; raylume.render({MESH_SCENE}, width=32, height=32, mode='cast', aovs=False)",
        "cast render of that mesh, 32 x 32 (the basic kernel variant)",
    ),
    "cast-full": (
        f"raylume.render(raylume.load_scene('{EXAMPLES}/meshes.toml'), width=32, height=32, mode='cast', aovs=False)",
        "cast render of examples/meshes.toml (a plane: the full variant)",
    ),
    "seed": ("raylume.render(raylume.builtin_scene('seed'), width=32, height=32)", "the seed, trace mode with AOVs"),
    "glass": (f"raylume.render(raylume.load_scene('{EXAMPLES}/glass.toml'), width=32, height=32)", "glass, trace"),
    "path": (
        f"raylume.render(raylume.load_scene('{EXAMPLES}/cornell.toml'), width=32, height=32, mode='path', spp=1)",
        "cornell, path mode",
    ),
    "raster": (
        f"raylume.render(raylume.load_scene('{EXAMPLES}/glass.toml'), width=32, height=32, mode='raster')",
        "glass, raster mode",
    ),
}


def cold_seconds(src: Path, work: str) -> float:
    """CPU seconds of `work` in a new process importing raylume from src, with an empty cache."""
    code = (
        "import time, os, tempfile, warnings, numpy, trimesh; warnings.simplefilter('ignore'); "
        "t0 = time.process_time(); "
        "import raylume; mesh = os.path.join(tempfile.mkdtemp(), 'm.ply'); "
        f"{WORK[work][0]}; print(time.process_time() - t0)"
    )
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(src / "src")}
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    return float(out.stdout.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("work", nargs="*", help=f"any of {', '.join(WORK)} (default: all)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--src", action="append", type=Path, help="a raylume checkout to compare (repeatable)")
    args = parser.parse_args()
    args.work = args.work or list(WORK)
    if unknown := set(args.work) - set(WORK):
        parser.error(f"unknown work {', '.join(sorted(unknown))}; choose from {', '.join(WORK)}")
    builds = [s.resolve() for s in (args.src or [REPO])]
    seconds = {(b, w): [] for b in builds for w in args.work}
    for _ in range(args.repeats):
        for w in args.work:
            for b in builds:
                seconds[b, w].append(cold_seconds(b, w))
    print(f"cold compile, CPU seconds, medians of {args.repeats} (builds alternating); {machine()}\n")

    def cell(runs: list[float]) -> str:
        return f"{median_of(runs):.1f} ({', '.join(f'{s:.1f}' for s in runs)})"

    rows = [[WORK[w][1]] + [cell(seconds[b, w]) for b in builds] for w in args.work]
    print(table(["first use of"] + [str(b) for b in builds], rows))


if __name__ == "__main__":
    run_main(main)
