"""Instructions a ray, raylume against Embree, counted: each engine's query run once under
valgrind's callgrind, which counts every instruction executed and simulates the branches'
prediction. Exact and repeatable where this VM's timings drift by a third, and it splits a
speed gap into "more instructions" and "slower instructions" (time / instructions).

For each mesh and engine a child process builds the scene and the rays (bench_hits.py's hit
rays of a 1024 x 1024 frame, or bench_shadows.py's shadow rays), makes the query once to warm
up, then switches callgrind's counting on (`callgrind_control -i on`), makes the query once more
and switches it off: the counts are the whole call's, Python's few instructions around it
included, for raylume's batch query (`intersect_rays` / `occluded_rays`, packets), raylume's
single rays ("raylume 1": closest_hit or any_hit ray by ray, bench_hits.py's and
bench_shadows.py's loops, as path mode's bounces are traced) and for Embree's packets of eight
and its single rays (embree_direct.py, robust, the loops that call it
compiled by Numba). Printed: instructions and mispredicted conditional branches a ray (callgrind's
model: a counter per branch, no history), and each engine's instructions over raylume's.
Embree's counts hold its driver's: the loop that fills its ray structures and the float32 copy
of the rays (about 100 instructions a ray on Nefertiti's shadow rays, 85 of them the loop).

Valgrind runs no AVX-512: Embree picks its AVX2 code under it, and raylume's kernels are
compiled for x86-64-v3 (AVX2, FMA; tools/profile_kernels.py COUNT_CPU) in a process of their
own first, so that the child under valgrind loads them from Numba's cache. On an AVX-512
machine both engines run other instructions natively; the counts compare the engines' work at
one instruction set, not what either takes there. A diagnostic beside bench_hits.py and
bench_shadows.py, which time the same queries.

    python benchmarks/count_instructions.py [--query shadows|hits] [--size 1024] [MESH ...]

Needs valgrind (Debian's `valgrind`, which `make bench` installs where apt-get can); without it
the script says so and does nothing.

tools/profile_kernels.py --hits MESH [--shadows] --count says where raylume's instructions go.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ENGINES = ("raylume", "raylume 1", "Embree 8", "Embree 1")
DEFAULT = ["stanford-bunny", "nefertiti", "40k"]
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tools"))
from profile_kernels import COUNT_CPU, COUNT_FEATURES, callgrind_command, count_calls  # noqa: E402


def child(engine: str, query: str, name: str, size: int) -> None:
    """Set the query up, warm it up, count one call (counting switched on and off around it by
    callgrind_control on this process), print the rays."""
    import numba
    import numpy as np
    from bench_hits import _trace, _trace_singly, frame_rays, mesh
    from bench_shadows import _blocked, _blocked_singly, shadow_rays
    from embree_direct import EmbreeScene

    from raylume.kernels.geometry.wide_nodes import traversal_stacks

    numba.set_num_threads(1)
    vertices, faces = mesh(name)
    frame = compiled, fo, fd, hit = frame_rays(vertices, faces, size)
    if query == "shadows":
        _, o, d, tmax = shadow_rays(vertices, faces, size, frame)
    else:
        o, d = np.ascontiguousarray(fo[hit]), np.ascontiguousarray(fd[hit])
    stacks = traversal_stacks()

    def ours(singly: bool):  # raylume's query in packets, or ray by ray ("raylume 1")
        if query == "shadows":
            if singly:
                return lambda: _blocked_singly(compiled, o, d, tmax, stacks)
            return lambda: _blocked(compiled, o, d, tmax)
        return (lambda: _trace_singly(compiled, o, d, stacks)) if singly else (lambda: _trace(compiled, o, d))

    if engine.startswith("raylume"):
        call = ours(engine == "raylume 1")
    else:
        scene, packets = EmbreeScene(vertices, faces), engine == "Embree 8"
        if query == "shadows":
            call = lambda: scene.occluded(o, d, tmax, packets=packets)  # noqa: E731
        else:
            call = lambda: scene.intersect(o, d, packets=packets)  # noqa: E731
    call()
    if os.environ.get("COUNT_WARM_ONLY"):
        ours(True)()  # both of raylume's kernels into the cache from one warm-up child
        return
    count_calls(call)
    print("rays", len(o), flush=True)


def totals(path: Path) -> dict[str, int]:
    """The `totals:` line of a callgrind output, by event."""
    text = path.read_text().splitlines()
    events = next(line.split()[1:] for line in text if line.startswith("events:"))
    values = next(line.split()[1:] for line in text if line.startswith("totals:"))
    return dict(zip(events, map(int, values), strict=False))


def count(engine: str, query: str, name: str, size: int, env: dict) -> tuple[float, float]:
    """(instructions a ray, mispredicted conditional branches a ray) of one engine's query."""
    with tempfile.TemporaryDirectory() as folder:
        grind = callgrind_command(Path(folder))
        me = [sys.executable, __file__, "--child", engine, "--query", query, "--size", str(size), name]
        run = subprocess.run([*grind, *me], env=env, capture_output=True, text=True, check=True)
        rays = int(next(line.split()[1] for line in run.stdout.splitlines() if line.startswith("rays")))
        counted = totals(Path(folder) / "callgrind.out")
    return counted["Ir"] / rays, counted["Bcm"] / rays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", nargs="*", default=DEFAULT)
    parser.add_argument("--query", choices=("shadows", "hits"), default="shadows")
    parser.add_argument("--size", type=int, default=1024, help="image side: size x size camera rays")
    parser.add_argument("--child", choices=ENGINES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    if args.child:
        child(args.child, args.query, args.meshes[0], args.size)
        return
    missing = [tool for tool in ("valgrind", "callgrind_control") if shutil.which(tool) is None]
    if missing:
        print(f"count_instructions: skipped, no {' or '.join(missing)} on the PATH (Debian's valgrind)")
        return
    from common import machine, table

    env = {**os.environ, "NUMBA_CPU_NAME": COUNT_CPU, "NUMBA_CPU_FEATURES": COUNT_FEATURES}
    rows = []
    from bench_hits import SHARED_MODELS, bumpy_size

    for name in args.meshes:
        if bumpy_size(name) is None and not (SHARED_MODELS / f"{name}.obj").exists():
            print(f"(skipping {name}: no {SHARED_MODELS / name}.obj)")
            continue
        # raylume's kernels compiled into Numba's cache natively (minutes under valgrind)
        warm = [sys.executable, __file__, "--child", "raylume", "--query", args.query, "--size", str(args.size), name]
        subprocess.run(warm, env={**env, "COUNT_WARM_ONLY": "1"}, check=True)
        counted = {engine: count(engine, args.query, name, args.size, env) for engine in ENGINES}
        ours = counted["raylume"][0]
        for engine, (instructions, mispredicted) in counted.items():
            rows.append([name, engine, f"{instructions:.0f}", f"{mispredicted:.2f}", f"{instructions / ours:.2f}"])
    print(machine())
    print(f"{args.query} rays of a {args.size} x {args.size} frame, counted under callgrind (x86-64-v3 code):\n")
    headers = ["mesh", "engine", "instructions a ray", "mispredicted a ray", "instructions / raylume's"]
    print(table(headers, rows))


if __name__ == "__main__":
    from common import run_main  # (a missing bench-extra module in one line)

    run_main(main)
