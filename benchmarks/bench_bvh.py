"""Primary-ray throughput and BVH build, raylume beside Embree (embreex) and trimesh's ray module.

Same camera rays for every engine (DESIGN.md camera, one ray per pixel through pixel centres),
on the real meshes in ../shared/models and on procedural bumpy spheres of 10k..4M triangles.

    python benchmarks/bench_bvh.py [--size 1024] [--repeats 5] [--quick] [--plot docs/images/bvh_scaling.png]
    python benchmarks/bench_bvh.py --build-only [--repeats 5]   # the BVH build table alone (bumpy 1M, 4M)
    python benchmarks/bench_bvh.py --phases 4e6 [--repeats 5]  # where the build's time goes, beside Embree

Ratios are speeds (Embree's time / raylume's time, one thread each): above 1, raylume is faster.
"on hits" repeats both engines on the rays that hit the mesh alone. The scaling table's "image" columns time
raylume.intersect on one thread with the rays shaped as their image, (size, size, 3), as raylume.camera_rays
gives them: packets of 4 x 2 pixels (issue 13's frame goal: the 4M frame at most 1.8x the 40k one).
The BVH build table times raylume's BVH part of compile (the triangles' boxes, build_bvh, collapse into the
BVH8 that traversal reads) on 1 thread and on all threads against Embree's scene commit (its BVH build, on all
threads; the mesh upload through embreex is excluded: its Python-side copy takes longer than the build),
alternating in one process; with the all-threads build's phases and the CPU time of both (on a loaded VM, the
CPU time is the steadier figure).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import SHARED_MODELS, machine, median_of, run_main, table

import raylume
from raylume.compile import compile_scene
from raylume.kernels.variants import features
from raylume.query_lanes import intersect_rays
from raylume.scene.mesh import load_mesh
from raylume.scene.procedural import bumpy_sphere


def camera_rays(center, radius, size):
    """DESIGN.md camera 2.4 radii in front of the mesh, looking at its centre, pixel centres:
    raylume.camera_rays' rays, as (N, 3) rows in pixel order."""
    position = center - np.array([0.0, 0.0, 2.4 * radius])
    camera = raylume.Camera(position=tuple(position), look_at=tuple(center), fov=53.13)
    o, d = raylume.camera_rays(camera, size, size)
    return o.reshape(-1, 3), d.reshape(-1, 3)


def meshes(quick: bool):
    out = []
    for name in ("stanford-bunny", "nefertiti"):
        path = SHARED_MODELS / f"{name}.obj"
        if path.exists():
            m = load_mesh(path)
            out.append((name, m.vertices, m.faces))
        else:
            print(f"(skipping {name}: {path} not found)")
    sizes = (10_000, 40_000, 100_000, 1_000_000) if quick else (10_000, 40_000, 100_000, 1_000_000, 4_000_000)
    for n in sizes:
        v, f = bumpy_sphere(n)
        out.append((f"bumpy {n // 1000}k" if n < 1_000_000 else f"bumpy {n // 1_000_000}M", v, f))
    return out


def raylume_scene(vertices, faces):
    """A compiled single-mesh scene: the mesh goes through a temporary PLY file, as a user's would."""
    import os
    import tempfile

    import trimesh

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "m.ply")
        trimesh.Trimesh(vertices, faces, process=False).export(path)
        scene = raylume.scene_from_dict({"objects": [{"type": "mesh", "file": path, "smooth": False}]})
        return compile_scene(scene)


def time_raylume(compiled, o, d, threads, repeats):
    import numba

    numba.set_num_threads(threads)
    n = len(o)
    t = np.empty(n)
    obj = np.empty(n, np.int32)
    prim = np.empty(n, np.int32)
    inst = np.empty(n, np.int32)
    intersect_rays(compiled.kernel, features(compiled.kernel), o, d, t, obj, prim, inst, threads)  # compile / warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        intersect_rays(compiled.kernel, features(compiled.kernel), o, d, t, obj, prim, inst, threads)
        times.append(time.perf_counter() - t0)
    return median_of(times), t


def time_image(compiled, o, d, size, repeats):
    """raylume.intersect on one thread with the rays shaped as the camera's image, (size, size,
    3): traced in packets of 4 x 2 pixels (the frame goal's measure) instead of eight along a
    row, directions made unit vectors as it goes, the ids looked up."""
    import numba

    numba.set_num_threads(1)
    o, d = o.reshape(size, size, 3), d.reshape(size, size, 3)
    raylume.intersect(compiled, o, d)  # warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        raylume.intersect(compiled, o, d)
        times.append(time.perf_counter() - t0)
    return median_of(times)


def time_embree(vertices, faces, o, d, repeats):
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    t0 = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, vertices.astype(np.float32), faces.astype(np.int32))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    scene.run(o32[:1], d32[:1], output=1)  # Embree builds lazily on the first query
    build = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = scene.run(o32, d32, output=1)
        times.append(time.perf_counter() - t0)
    tfar = np.where(res["geomID"] >= 0, res["tfar"], np.inf)
    return median_of(times), build, tfar


def time_builds(vertices, faces, repeats):
    """Medians of the BVH build alone, alternating: raylume on 1 thread and on all threads (what
    compile/geometry.py does: the triangles' boxes from the float32 triangle table, build_bvh, collapse into
    the BVH8), and Embree's commit. Returns (1T s, all s, Embree s, SAH, the all-threads build's
    phases (boxes, build_bvh, collapse) s, CPU s of the all-threads build and of Embree's)."""
    import numba
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    from raylume.accel.bvh import build_bvh, sah_cost, triangle_bounds
    from raylume.accel.wide import collapse
    from raylume.compile import BVH_LEAF_BLOCK, BVH_OPTIONS, BVH_TRAVERSAL_COST

    tri = vertices.astype(np.float32)[faces].reshape(-1, 9)
    v32, f32 = vertices.astype(np.float32), faces.astype(np.int32)
    o, d = np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32)
    everything = numba.config.NUMBA_NUM_THREADS

    def ours(threads):
        numba.set_num_threads(threads)
        c0, t0 = time.process_time(), time.perf_counter()
        lo, hi = np.empty((len(tri), 3)), np.empty((len(tri), 3))
        triangle_bounds(tri, lo, hi)
        t1 = time.perf_counter()
        bvh = build_bvh(lo, hi, **BVH_OPTIONS)
        t2 = time.perf_counter()
        collapse(bvh)
        t3 = time.perf_counter()
        return t3 - t0, (t1 - t0, t2 - t1, t3 - t2), time.process_time() - c0, bvh

    def embree():
        scene = rtcs.EmbreeScene()
        TriangleMesh(scene, v32, f32)  # the upload: not timed
        c0, t0 = time.process_time(), time.perf_counter()
        scene.run(o, d, output=1)  # Embree builds lazily on the first query
        return time.perf_counter() - t0, time.process_time() - c0

    ours(1)  # compile
    t1, ta, te, phases, cpu, cpu_e = [], [], [], [], [], []
    for _ in range(repeats):
        t1.append(ours(1)[0])
        dt, ph, c, bvh = ours(everything)
        ta.append(dt)
        phases.append(ph)
        cpu.append(c)
        e, ce = embree()
        te.append(e)
        cpu_e.append(ce)
    numba.set_num_threads(everything)
    phase = tuple(median_of([p[k] for p in phases]) for k in range(3))
    return (
        median_of(t1),
        median_of(ta),
        median_of(te),
        sah_cost(bvh, BVH_TRAVERSAL_COST, leaf_block=BVH_LEAF_BLOCK),
        phase,
        (median_of(cpu), median_of(cpu_e)),
    )


def build_table(repeats):
    """The build table on its own: bumpy 1M and 4M."""
    import numba

    rows = []
    for n in (1_000_000, 4_000_000):
        v, f = bumpy_sphere(n)
        t1, ta, te, sah, (boxes, build, coll), (cpu, cpu_e) = time_builds(v, f, repeats)
        rows.append(
            [
                f"bumpy {n // 1_000_000}M",
                f"{len(f):,}",
                f"{t1:.2f}",
                f"{ta:.2f}",
                f"{boxes:.2f} / {build:.2f} / {coll:.2f}",
            ]
            + [f"{te:.2f}", f"{t1 / te:.2f}", f"{ta / te:.2f}", f"{cpu:.2f} / {cpu_e:.2f}", f"{sah:.1f}"]
        )
        print(" | ".join(rows[-1]), flush=True)
    all_t = numba.config.NUMBA_NUM_THREADS
    headers = ["mesh", "triangles", "raylume build 1T s", f"raylume build {all_t}T s"]
    headers += [f"boxes / build_bvh / collapse {all_t}T s", "Embree build s", "raylume/Embree (1T)"]
    headers += [f"raylume/Embree ({all_t}T)", f"CPU s raylume {all_t}T / Embree", "SAH"]
    print("\n" + table(headers, rows))


def phase_table(n, repeats):
    """Where the build's time goes at n triangles (bumpy sphere), on all threads, alternating with
    Embree's commit: wall seconds of each pass the builder runs on its thread pool (wrapped here),
    the rest of build_bvh, the boxes and the collapse; medians."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    from raylume.accel import bvh as bvh_module
    from raylume.accel.wide import collapse
    from raylume.compile import BVH_OPTIONS

    v, f = bumpy_sphere(n)
    tri = v.astype(np.float32)[f].reshape(-1, 9)
    v32, f32 = v.astype(np.float32), f.astype(np.int32)
    spent: dict[str, float] = {}
    plain_map = bvh_module._Runner.map

    def timed_map(self, fn, argsets):
        t0 = time.perf_counter()
        out = plain_map(self, fn, argsets)
        spent[fn.__name__] = spent.get(fn.__name__, 0.0) + time.perf_counter() - t0
        return out

    def ours():
        c0, t0 = time.process_time(), time.perf_counter()
        lo, hi = np.empty((len(tri), 3)), np.empty((len(tri), 3))
        bvh_module.triangle_bounds(tri, lo, hi)
        t1 = time.perf_counter()
        spent.clear()
        bvh = bvh_module.build_bvh(lo, hi, **BVH_OPTIONS)
        t2 = time.perf_counter()
        collapse(bvh)
        t3 = time.perf_counter()
        row = {"boxes (triangle_bounds)": t1 - t0, **{f"build_bvh: {k}": t for k, t in spent.items()}}
        row["build_bvh: the rest (Python, numpy)"] = (t2 - t1) - sum(spent.values())
        row["collapse"] = t3 - t2
        row["total"] = t3 - t0
        row["total CPU"] = time.process_time() - c0
        return row

    def embree():
        scene = rtcs.EmbreeScene()
        TriangleMesh(scene, v32, f32)
        c0, t0 = time.process_time(), time.perf_counter()
        scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
        return {"Embree commit": time.perf_counter() - t0, "Embree CPU": time.process_time() - c0}

    bvh_module._Runner.map = timed_map
    try:
        ours()  # compile
        rows = []
        for _ in range(repeats):
            rows.append({**ours(), **embree()})
    finally:
        bvh_module._Runner.map = plain_map
    keys = list(rows[0])
    print(table(["phase", "s"], [[k, f"{median_of([r.get(k, 0.0) for r in rows]):.3f}"] for k in keys]))


def time_trimesh(vertices, faces, o, d, n_rays):
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    sel = np.linspace(0, len(o) - 1, n_rays).astype(int)
    t0 = time.perf_counter()
    mesh.ray.intersects_first(o[sel], d[sel])
    return (time.perf_counter() - t0) / n_rays * len(o)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--size", type=int, default=1024, help="image side: size x size camera rays")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--quick", action="store_true", help="skip the 4M mesh and trimesh")
    parser.add_argument("--trimesh-rays", type=int, default=20_000)
    parser.add_argument("--plot", default=None, help="write the scaling plot (PNG) here")
    parser.add_argument("--build-only", action="store_true", help="only the BVH build table (bumpy 1M and 4M)")
    parser.add_argument("--phases", type=float, default=None, help="the build's phases at this many triangles")
    args = parser.parse_args()
    if args.phases:
        print(f"BVH build phases, bumpy {args.phases:g} triangles, medians of {args.repeats}; {machine()}\n")
        phase_table(int(args.phases), args.repeats)
        return
    if args.build_only:
        print(f"BVH build, medians of {args.repeats}, alternating; {machine()}\n")
        build_table(args.repeats)
        return

    try:
        import embreex  # noqa: F401  (only probing that it is installed)

        have_embree = True
    except ImportError:
        have_embree = False
        print("embreex not installed: pip install 'raylume[bench]' for the Embree column")

    print(f"{args.size} x {args.size} primary rays, medians of {args.repeats}; {machine()}")
    print("embreex's run() traces on one thread, so raylume is shown on 1 thread and on all cores.\n")
    rows, build_rows, scaling = [], [], []
    for name, v, f in meshes(args.quick):
        compiled = raylume_scene(v, f)
        o, d = camera_rays(
            v.mean(axis=0) * 0 + (v.min(0) + v.max(0)) / 2, np.linalg.norm(v.max(0) - v.min(0)) / 2, args.size
        )
        n = len(o)
        r1, t_ours = time_raylume(compiled, o, d, 1, args.repeats)
        import numba

        r2, _ = time_raylume(compiled, o, d, numba.config.NUMBA_NUM_THREADS, args.repeats)
        row = [name, f"{len(f):,}", f"{n / r1 / 1e6:.2f}", f"{n / r2 / 1e6:.2f}"]
        if have_embree:
            e, e_build, t_embree = time_embree(v, f, o, d, args.repeats)
            agree = np.mean(np.isclose(t_ours, t_embree, rtol=1e-4) | (np.isinf(t_ours) & np.isinf(t_embree)))
            # The rays that hit alone: most of a loosely framed frame misses, and a miss costs
            # Embree more per ray than it costs raylume, which flatters the full-frame ratio.
            hit = np.isfinite(t_ours)
            h1, _ = time_raylume(compiled, o[hit], d[hit], 1, args.repeats)
            eh, _, _ = time_embree(v, f, o[hit], d[hit], args.repeats)
            row += [f"{n / e / 1e6:.2f}", f"{e / r1:.2f}", f"{hit.mean() * 100:.0f}%", f"{eh / h1:.2f}"]
            row += [f"{agree * 100:.2f}%"]
            b1, ba, e_build, *_ = time_builds(v, f, args.repeats)
        else:
            b1 = ba = e_build = float("nan")
        if not args.quick and len(f) <= 1_000_000:
            row.append(f"{n / time_trimesh(v, f, o, d, args.trimesh_rays) / 1e6:.3f}")
        else:
            row.append("-")
        rows.append(row)
        s = compiled.stats
        build_rows.append(
            [
                name,
                f"{len(f):,}",
                f"{s['build_seconds']:.2f}",
                f"{b1:.2f}",
                f"{ba:.2f}",
                f"{e_build:.2f}",
                f"{ba / e_build:.2f}",
                f"{s['bvh_bytes'] / len(f):.1f}",
                f"{s['bvh_nodes']:,}",
            ]
        )
        if name.startswith("bumpy"):
            scaling.append((len(f), r1, r2, time_image(compiled, o, d, args.size, args.repeats)))
        print(" | ".join(row), flush=True)

    headers = ["mesh", "triangles", "raylume 1T Mrays/s", "raylume all Mrays/s"]
    if have_embree:
        headers += ["Embree 1T Mrays/s", "raylume/Embree (1T)", "rays hit", "on hits: raylume/Embree", "same hits"]
    headers += ["trimesh Mrays/s"]
    print("\n" + table(headers, rows))
    print(
        "\nBVH build (raylume compile: the whole compile_scene, mesh file included; build: boxes + build_bvh +"
        " collapse on 1 thread and all; Embree: its scene commit on all threads)\n"
    )
    headers = ["mesh", "triangles", "raylume compile s", "raylume build 1T s", "raylume build all s"]
    headers += ["Embree build s", "build all/Embree", "raylume BVH bytes/tri", "BVH nodes"]
    print(table(headers, build_rows))
    # One thread as well: on a shared VM the second core's speed varies most.
    print("\nScaling of primary-ray time with triangle count (1 thread and all threads)\n")
    base = next((row for row in scaling if row[0] == 40_000), scaling[0])
    print(
        table(
            [
                "triangles",
                "1T time ms",
                "1T / 1T(40k)",
                "all time ms",
                "all / all(40k)",
                "image 1T ms",
                "image / image(40k)",
            ],
            [
                [
                    f"{n:,}",
                    f"{t1 * 1000:.1f}",
                    f"{t1 / base[1]:.2f}",
                    f"{t2 * 1000:.1f}",
                    f"{t2 / base[2]:.2f}",
                    f"{ti * 1000:.1f}",
                    f"{ti / base[3]:.2f}",
                ]
                for n, t1, t2, ti in scaling
            ],
        )
    )
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5.5, 3.6), dpi=110)
        ns, _, ts, _ = zip(*scaling)
        ax.loglog(ns, [t * 1000 for t in ts], "o-", label="raylume ray casting (BVH)")
        ax.loglog(ns, [ts[0] * 1000 * n / ns[0] for n in ns], ":", color="grey", label="linear in N")
        ax.set_xlabel("triangles")
        ax.set_ylabel(f"ms per {args.size}x{args.size} frame")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot)
        print(f"\nplot written to {args.plot}")


if __name__ == "__main__":
    run_main(main)
