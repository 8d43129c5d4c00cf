"""Instancing: frame time and peak memory against the number of instances of one mesh.

N copies (1, 10, ..., 10 000) of a 100k-triangle bumpy sphere on a square grid that fills the
same view whatever N (each copy scaled by 1/sqrt(N)), cast mode (one primary ray per pixel).
Beside them, where it fits in memory, the same copies flattened into one plain mesh (raylume
and Embree through embreex, one thread each: embreex's run() is single-threaded).

    python benchmarks/bench_instances.py [--width 1024 --height 768] [--repeats 3]
                                         [--counts 1,10,100,1000,10000] [--flat-max 100]
                                         [--rotate] [--rounds 1] [--plot docs/images/instances.png]

Every configuration runs in a process of its own, so that its peak resident memory (VmHWM, what
/usr/bin/time -v reports as maximum resident set size) is its own: build + render, with the
kernels loaded from Numba's cache.
"Frame" is the kernel time of one frame (stats render_seconds), median of --repeats; "CPU" the
process's CPU time for the frame (time.process_time), which other work on the machine disturbs
less. With --rounds R every configuration runs R times, the counts alternating (1, 10000, 1,
10000, ...), and the table gives the medians over the rounds.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from common import machine, run_main, table

MESH_TRIANGLES = 100_000


def grid_matrices(n: int, rotate: bool = False) -> np.ndarray:
    """(n, 3, 4): copies of a unit-radius mesh on a side x side grid covering [-1, 1]^2 at z = 0;
    with `rotate`, each copy turned by its own random rotation (seeded)."""
    side = math.ceil(math.sqrt(n))
    scale = 0.95 / side
    ij = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)[:n]
    m = np.zeros((n, 3, 4))
    m[:, 0, 0] = m[:, 1, 1] = m[:, 2, 2] = scale
    if rotate:
        from scipy.spatial.transform import Rotation

        m[:, :, :3] = scale * Rotation.random(n, random_state=11).as_matrix()
    m[:, 0, 3] = (ij[:, 0] + 0.5) * 2 / side - 1
    m[:, 1, 3] = 1 - (ij[:, 1] + 0.5) * 2 / side
    return m


CHILD = r"""
import json, sys, time
import numpy as np
import raylume
mode, folder = sys.argv[1], sys.argv[2]
n, width, height, repeats = (int(x) for x in sys.argv[3:7])
camera = {"position": [0, 0, -2.4], "look_at": [0, 0, 0], "fov": 53.13}
obj = {"type": "mesh", "file": f"{folder}/mesh.ply", "smooth": False}
if mode == "instanced":
    obj["instances"] = f"{folder}/m{n}.npy"
else:
    obj["file"] = f"{folder}/flat{n}.ply"
out = {}
if mode == "embree":
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    import trimesh
    from raylume.kernels.film.camera import camera_frame
    mesh = trimesh.load(f"{folder}/flat{n}.ply", process=False)
    t0 = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32))
    cam = camera_frame(np.array([0, 0, -2.4]), np.zeros(3), (0, 1, 0), 53.13, width, height)
    i, j = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    a = (i / width * 2 - 1).reshape(-1, 1); b = (1 - j / height * 2).reshape(-1, 1)
    d = cam[3:6] + a * cam[6:9] + b * cam[9:12]
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    o = np.broadcast_to(np.float32([0, 0, -2.4]), d.shape).copy()
    scene.run(o[:1], d[:1], output=1)
    out["build_seconds"] = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter(); scene.run(o, d, output=1); times.append(time.perf_counter() - t0)
    out["frame"] = float(np.median(times))
else:
    lights = [{"type": "ambient", "intensity": 1}]
    scene = raylume.scene_from_dict({"camera": camera, "objects": [obj], "lights": lights})
    session = raylume.Session(scene)
    times, cpu = [], []
    for _ in range(repeats + 1):  # the first loads the kernels
        c0 = time.process_time()
        img = session.render(mode="cast", width=width, height=height, threads=1, aovs=False)
        cpu.append(time.process_time() - c0)
        times.append(img.stats["render_seconds"])
    out["frame"] = float(np.median(times[1:]))
    out["frame_cpu"] = float(np.median(cpu[1:]))  # this process's CPU time: steadier under load
    out["build_seconds"] = session.compiled.stats["build_seconds"]
    out["bytes_per_instance"] = session.compiled.stats.get("bytes_per_instance")
    out["bvh_bytes"] = session.compiled.stats["bvh_bytes"]
# this process's high-water mark (VmHWM: ru_maxrss would carry over the parent's across exec)
hwm = [line for line in open("/proc/self/status") if line.startswith("VmHWM:")][0]
out["peak_bytes"] = int(hwm.split()[1]) * 1024
print(json.dumps(out))
"""


def run(mode: str, folder: Path, n: int, args) -> dict:
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, mode, str(folder), str(n), str(args.width), str(args.height), str(args.repeats)],
        capture_output=True,
        text=True,
        check=False,
    )
    if proc.returncode != 0:
        print(proc.stderr[-2000:], file=sys.stderr)
        return {}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def prepare(folder: Path, counts: list[int], flat_max: int, rotate: bool = False) -> None:
    import trimesh

    from raylume.scene.procedural import bumpy_sphere

    v, f = bumpy_sphere(MESH_TRIANGLES, radius=1.0, bumpiness=0.2, seed=7)
    trimesh.Trimesh(v, f, process=False).export(folder / "mesh.ply")
    for n in counts:
        m = grid_matrices(n, rotate)
        np.save(folder / f"m{n}.npy", m)
        if n <= flat_max:
            verts = np.concatenate([v @ a[:, :3].T + a[:, 3] for a in m])
            faces = np.concatenate([f + k * len(v) for k in range(n)])
            trimesh.Trimesh(verts, faces, process=False).export(folder / f"flat{n}.ply")


def _median_run(runs: list[dict]) -> dict:
    """One configuration's runs: the medians of its times, the rest from the first run."""
    runs = [r for r in runs if r]
    if not runs:
        return {}
    out = dict(runs[0])
    for key in ("frame", "frame_cpu"):
        if key in out:
            out[key] = float(np.median([r[key] for r in runs]))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=int, default=1024)
    parser.add_argument("--height", type=int, default=768)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--counts", default="1,10,100,1000,10000")
    parser.add_argument("--flat-max", type=int, default=100, help="largest N also flattened (N x 100k triangles)")
    parser.add_argument("--rotate", action="store_true", help="each copy randomly rotated (looser world boxes)")
    parser.add_argument("--rounds", type=int, default=1, help="runs of every configuration, alternating")
    parser.add_argument("--plot", default=None)
    args = parser.parse_args()
    counts = [int(c) for c in args.counts.split(",")]
    print(
        f"{args.width} x {args.height} primary rays (cast), 1 thread, medians of {args.repeats} frames"
        f" x {args.rounds} alternating rounds; {machine()}"
    )
    turned = ", each randomly rotated" if args.rotate else ""
    print(f"mesh: bumpy sphere of {MESH_TRIANGLES} triangles; N copies fill the same view{turned}\n")
    results: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        prepare(folder, counts, args.flat_max, args.rotate)
        runs: dict = {n: {} for n in counts}
        for _ in range(args.rounds):
            for n in counts:
                modes = ["instanced"] + (["flat", "embree"] if n <= args.flat_max else [])
                for mode in modes:
                    runs[n].setdefault(mode, []).append(run(mode, folder, n, args))
                print(f"N = {n}: {json.dumps({m: r[-1] for m, r in runs[n].items()})}", flush=True)
        for n in counts:
            results[n] = {mode: _median_run(r) for mode, r in runs[n].items()}
    base = results[counts[0]]["instanced"]["frame"]
    base_cpu = results[counts[0]]["instanced"].get("frame_cpu")
    rows = []
    for n in counts:
        r = results[n]
        inst, flat, emb = r["instanced"], r.get("flat", {}), r.get("embree", {})

        def ms(x):
            return f"{1e3 * x['frame']:.0f}" if x else "-"

        cpu = f"{1e3 * inst['frame_cpu']:.0f}" if inst.get("frame_cpu") else "-"
        cpu_vs = f"{inst['frame_cpu'] / base_cpu:.2f}x" if inst.get("frame_cpu") and base_cpu else "-"

        def gb(x):
            return f"{x['peak_bytes'] / 2**30:.2f}" if x else "-"

        rows.append(
            [
                n,
                f"{n * MESH_TRIANGLES / 1e6:g} M",
                ms(inst),
                f"{inst['frame'] / base:.2f}x",
                cpu,
                cpu_vs,
                gb(inst),
                f"{inst['bytes_per_instance']:.0f}" if inst.get("bytes_per_instance") else "-",
                ms(flat),
                gb(flat),
                ms(emb),
                gb(emb),
                f"{emb['frame'] / inst['frame']:.2f}" if emb else "-",
            ]
        )
    print()
    print(
        table(
            [
                "instances",
                "triangles",
                "frame ms",
                "vs 1",
                "CPU ms",
                "CPU vs 1",
                "peak GB",
                "B/instance",
                "flat ms",
                "flat GB",
                "Embree ms (flat)",
                "Embree GB",
                "Embree / instanced",
            ],
            rows,
        )
    )
    if args.plot:
        plot(results, counts, args)


def plot(results: dict, counts: list[int], args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(9, 3.4))
    for key, label, style in (
        ("instanced", "raylume, instanced", "o-"),
        ("flat", "raylume, flattened", "s--"),
        ("embree", "Embree, flattened", "^:"),
    ):
        ns = [n for n in counts if results[n].get(key)]
        ax.plot(ns, [1e3 * results[n][key]["frame"] for n in ns], style, label=label)
        bx.plot(ns, [results[n][key]["peak_bytes"] / 2**30 for n in ns], style, label=label)
    for a, title in ((ax, "frame time (ms, 1 thread)"), (bx, "peak memory (GB)")):
        a.set_xscale("log")
        a.set_xlabel(f"copies of a {MESH_TRIANGLES // 1000}k-triangle mesh")
        a.set_title(title, fontsize=10)
        a.grid(alpha=0.3)
    ax.set_ylim(bottom=0)
    bx.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    fig.suptitle(f"{args.width} x {args.height} primary rays, copies filling the same view", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.plot, dpi=110)
    print(f"plot: {args.plot}")


if __name__ == "__main__":
    run_main(main)
