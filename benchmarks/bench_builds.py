"""Two (or more) builds of raylume side by side on the figures a refactor must keep: the seed
scene's trace kernel, hit rays (`raylume.intersect`) on a bumpy sphere, and path mode on the
Cornell box and on examples/materials.toml, each in a fresh process per build and round, the
builds alternating (A, B, A, B, ...) so that the machine's drift is shared among them. Medians
over the rounds, and each build's ratio to the first. Cold compiles are bench_compile.py's
(`--src` there too).

    python benchmarks/bench_builds.py --src OLD --src NEW [--rounds 4] [WORK ...]

DIR: a checkout of raylume (its src/ is imported); WORK: seed, hits, cornell, cornell-1t,
materials (default: all). Every figure is the render's own kernel time (`render_seconds`) or,
for hits, the CPU time of the call, after a warm-up in the same process.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from common import REPO, machine, median_of, run_main, table

EXAMPLES = REPO / "examples"
WORK = {
    # the seed at 600 x 600, trace mode, all cores: the median of 7 frames
    "seed": """
import statistics, raylume
scene = raylume.builtin_scene("seed")
raylume.render(scene, aovs=False)
print(statistics.median(raylume.render(scene, aovs=False).stats["render_seconds"] for _ in range(7)))
""",
    # 1024 x 1024 camera rays at a 1M-triangle bumpy sphere, one thread, CPU time, median of 5
    "hits": """
import statistics, time, numba, numpy as np, raylume
from raylume.scene.procedural import bumpy_sphere
numba.set_num_threads(1)
v, f = bumpy_sphere(1_000_000)
import tempfile, trimesh, os
path = os.path.join(tempfile.mkdtemp(), "b.ply"); trimesh.Trimesh(v, f, process=False).export(path)
scene = raylume.scene_from_dict({"camera": {"position": [0, 0, -3], "look_at": [0, 0, 0], "fov": 40},
                                 "objects": [{"type": "mesh", "file": path}]})
o, d = raylume.camera_rays(scene, 1024, 1024)
from raylume.compile import compile_scene
compiled = compile_scene(scene)
raylume.intersect(compiled, o, d)
times = []
for _ in range(5):
    t = time.process_time(); raylume.intersect(compiled, o, d); times.append(time.process_time() - t)
print(statistics.median(times))
""",
    # the Cornell box, 256 x 256, 64 spp, max_depth 8 (bench_path.py's speed run), all cores
    "cornell": """
import statistics, raylume
scene = raylume.load_scene("{examples}/cornell.toml")
raylume.render(scene, width=64, height=64, spp=4, aovs=False)
print(statistics.median(raylume.render(scene, aovs=False).stats["render_seconds"] for _ in range(3)))
""",
    "cornell-1t": """
import statistics, raylume
scene = raylume.load_scene("{examples}/cornell.toml")
raylume.render(scene, width=64, height=64, spp=4, aovs=False, threads=1)
print(statistics.median(raylume.render(scene, aovs=False, threads=1).stats["render_seconds"] for _ in range(3)))
""",
    # metals, glass, plastic and an HDR environment, 320 x 200 at 16 spp, all cores
    "materials": """
import statistics, raylume
scene = raylume.load_scene("{examples}/materials.toml")
raylume.render(scene, width=32, height=20, spp=2, aovs=False)
print(statistics.median(
    raylume.render(scene, width=320, height=200, spp=16, aovs=False).stats["render_seconds"] for _ in range(3)))
""",
}


def run(src: Path, code: str) -> float:
    env = dict(os.environ, PYTHONPATH=str(src / "src"))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=src)
    if out.returncode != 0:
        raise SystemExit(f"{src}: {out.stderr.strip().splitlines()[-1]}")
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("work", nargs="*", help=f"any of {', '.join(WORK)} (default: all)")
    parser.add_argument("--src", action="append", type=Path, required=True, help="a raylume checkout (repeatable)")
    parser.add_argument("--rounds", type=int, default=4)
    args = parser.parse_args()
    works = args.work or list(WORK)
    print(machine())
    rows = []
    for work in works:
        code = WORK[work].replace("{examples}", str(EXAMPLES))
        times = {src: [] for src in args.src}
        for _ in range(args.rounds):
            for src in args.src:
                times[src].append(run(src.resolve(), code))
        medians = [median_of(times[src]) for src in args.src]
        for src, m in zip(args.src, medians):
            spread = ", ".join(f"{t * 1e3:.1f}" for t in times[src])
            rows.append([work, str(src), f"{m * 1e3:.1f}", f"{m / medians[0]:.3f}", spread])
        print(table(["work", "build", "median ms", "/ first", "rounds (ms)"], rows[-len(args.src) :]), flush=True)
    print()
    print(table(["work", "build", "median ms", "/ first", "rounds (ms)"], rows))


if __name__ == "__main__":
    run_main(main)
