"""Two checkouts of raylume on one query, call for call: hit rays (in packets or ray by ray),
shadow rays or a render of one mesh, timed in two warm worker processes (one a checkout)
that take turns, one call each, so that both see the same minute of this VM's drift. Prints each
checkout's median and the paired ratio B / A (its median, its quartiles, and how often A was
faster).

    python benchmarks/ab_queries.py --a DIR --b DIR [--query hits|singles|shadows|cast|trace|path] [--rounds 40] MESH
    python benchmarks/ab_queries.py --a DIR --b DIR --query scene [--spp 4] SCENE.toml

DIR: a checkout of raylume (its src/ is imported, its benchmarks/ run the query); MESH: as
bench_hits.py takes it (40k, 1M, stanford-bunny, ...). The query is bench_hits.py's packets on
the hit rays of its 1024 x 1024 frame (`_trace`), its single-ray traversal on the same rays
(`singles`: `_trace_singly`, closest_hit ray by ray, as trace and path modes' bounces are traced),
bench_shadows.py's occlusion (`_blocked`), or a whole render of bench_scaling.py's scene with
the mesh (`cast`, `trace`, `path` at 1 sample a pixel: 1024 x 1024, through a Session, so
compiled once); or a scene file rendered as it says (`scene`; or in the mode given) at `--spp`
samples a pixel; one thread, CPU time. Both checkouts must give the same answers (a checksum is
compared first; `--any-answers` times them anyway, for an upper bound of what a change that is
not correct could gain). `--a DIR --b DIR` with one DIR twice is an A / A run: how wide the ratio's
quartiles are when nothing differs.

Fresh processes alternating (bench_builds.py) spread a ~5% change over the VM's 30% drift; here
one round is two calls a few tens of milliseconds apart. An A / A run of the bunny's shadow rays,
40 rounds: median ratio 0.995, quartiles 0.965-1.041; of the Cornell box's path renders (`--query
scene --spp 4`, 60 rounds): 0.984, quartiles 0.938-1.024, so a scene's ratio within 2% of 1 says
nothing; run a small change both ways round (--a OLD --b NEW, then --a NEW --b OLD).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import numpy as np


def is_scene_file(name: str) -> bool:
    """The MESH argument names a scene file rather than a mesh."""
    return name.endswith((".toml", ".json"))


def worker(query: str, name: str, cpu: int) -> None:
    """Set the query up in this process (its checkout's benchmarks/ and src/), print "ready" and
    a checksum of its answers, then time one call for each line read, printing milliseconds."""
    # Both workers on one core: left to the scheduler each keeps to the core it last ran on, and
    # this VM's two cores do not run at one speed (an A / A run of bumpy 40k's hit rays, unpinned:
    # B / A 1.114, A faster in 73% of 30 rounds)
    os.sched_setaffinity(0, {cpu})
    sys.path.insert(0, str(Path.cwd() / "benchmarks"))
    import numba
    from bench_hits import _trace, _trace_singly, cpu_seconds, frame_rays, mesh
    from bench_shadows import _blocked, shadow_rays

    numba.set_num_threads(1)
    if query == "shadows":
        compiled, o, d, tmax = shadow_rays(*mesh(name), 1024)

        def call():
            return _blocked(compiled, o, d, tmax)

        checksum = int(call().sum())
    elif is_scene_file(name):  # a scene file, rendered as it says, `spp` samples a pixel
        import raylume
        from raylume.session import Session

        session = Session(raylume.load_scene(str(Path(name).resolve())))
        spp = int(os.environ.get("AB_SPP", "4"))
        mode = None if query == "scene" else query

        def call():
            return session.render(mode=mode, spp=spp, threads=1, aovs=False).rgb

        checksum = float(call().sum())
    elif query in ("cast", "trace", "path"):
        import tempfile

        import trimesh
        from bench_scaling import scene_for

        from raylume.session import Session

        folder = tempfile.TemporaryDirectory()  # the mesh's file, removed when the worker ends
        path = Path(folder.name) / "mesh.ply"
        trimesh.Trimesh(*mesh(name), process=False).export(path)
        session = Session(scene_for(str(path)))
        spp = 1 if query == "path" else None

        def call():
            return session.render(mode=query, width=1024, height=1024, spp=spp, threads=1, aovs=False).rgb

        checksum = float(call().sum())
    else:
        compiled, fo, fd, hit = frame_rays(*mesh(name), 1024)
        o, d = np.ascontiguousarray(fo[hit]), np.ascontiguousarray(fd[hit])

        if query == "singles":
            from raylume.kernels.geometry.wide_nodes import traversal_stacks

            stacks = traversal_stacks()

            def call():
                return _trace_singly(compiled, o, d, stacks)

        else:

            def call():
                return _trace(compiled, o, d)

        t = call()[0]
        checksum = float(np.sum(t[np.isfinite(t)]))
    call()
    print("ready", checksum, flush=True)
    for _ in sys.stdin:
        print(f"{cpu_seconds(call) * 1e3:.3f}", flush=True)


def start(checkout: Path, query: str, name: str, cpu: int) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(checkout / "src"))
    return subprocess.Popen(
        [sys.executable, __file__, "--worker", query, name, str(cpu)],
        cwd=checkout,
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mesh", help="as bench_hits.py takes it")
    parser.add_argument("--a", type=Path, required=True, help="a raylume checkout")
    parser.add_argument("--b", type=Path, required=True, help="another (or the same, for an A / A run)")
    parser.add_argument(
        "--query", choices=["hits", "singles", "shadows", "cast", "trace", "path", "scene"], default="hits"
    )
    parser.add_argument("--spp", type=int, default=4, help="samples a pixel of a scene file's renders")
    parser.add_argument("--rounds", type=int, default=40)
    parser.add_argument(
        "--any-answers",
        action="store_true",
        help="time checkouts that answer differently (an upper bound of a change that is not correct)",
    )
    parser.add_argument("--cpu", type=int, default=max(os.sched_getaffinity(0)), help="the core both workers run on")
    parser.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    if "--worker" in sys.argv:
        i = sys.argv.index("--worker")
        worker(sys.argv[i + 1], sys.argv[i + 2], int(sys.argv[i + 3]))
        return
    args = parser.parse_args()
    if is_scene_file(args.mesh):
        if args.query not in ("scene", "cast", "trace", "path"):
            parser.error("a scene file takes --query scene (or cast, trace, path: that mode)")
        args.mesh = str(Path(args.mesh).resolve())
        os.environ["AB_SPP"] = str(args.spp)
    workers = [start(c.resolve(), args.query, args.mesh, args.cpu) for c in (args.a, args.b)]
    ready = [w.stdout.readline().split() for w in workers]
    if any(len(r) != 2 or r[0] != "ready" for r in ready):
        sys.exit(f"ab_queries: a worker did not start ({ready})")
    if ready[0][1] != ready[1][1] and not args.any_answers:
        sys.exit(f"ab_queries: the checkouts answer differently (checksums {ready[0][1]} and {ready[1][1]})")
    times: list[list[float]] = [[], []]
    for r in range(args.rounds):
        for k in (0, 1) if r % 2 == 0 else (1, 0):  # each goes first in half the rounds
            workers[k].stdin.write("go\n")
            workers[k].stdin.flush()
            times[k].append(float(workers[k].stdout.readline()))
    for w in workers:
        w.stdin.close()
        w.wait()
    a, b = np.array(times[0]), np.array(times[1])
    ratio = b / a
    q1, q3 = np.percentile(ratio, [25, 75])
    print(
        f"{args.query} {args.mesh}, {args.rounds} rounds: A {np.median(a):.2f} ms, B {np.median(b):.2f} ms; "
        f"B / A median {np.median(ratio):.3f} (quartiles {q1:.3f}-{q3:.3f}), A faster in {np.mean(ratio > 1):.0%}"
    )


if __name__ == "__main__":
    from common import run_main  # (a missing bench-extra module in one line)

    run_main(main)
