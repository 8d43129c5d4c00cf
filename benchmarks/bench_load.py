"""A mesh file to its first picture: raylume beside trimesh and Embree, on large meshes.

For each bumpy sphere (a binary PLY file in a temporary folder), alternating rounds in one
process, wall seconds, medians:

* raylume: `raylume.load(path)` (the mesh read by trimesh, its faces checked, the scene framed),
  `Session(scene)` (the triangle tables, the BVH on every core, the primitive table) and a cast
  render at --size x --size on one thread: what `raylume render mesh.ply --mode cast` does
  after its imports.
* trimesh + Embree: `trimesh.load(path, process=False)`, then Embree's first query of the mesh
  (`run` of the same camera's rays, which commits the scene: the BVH build on every core, then
  the rays one by one on one thread). embreex's upload of the mesh (`TriangleMesh`, a Python-side
  copy slower than Embree's build: ~0.8 s at 1M triangles) is timed apart and left out of the
  sum, as bench_bvh.py leaves it out of the build.

raylume does more than Embree's side (a face check, the framing, the shading), so the ratio is
what a user waits for a picture, not a contest of equal work. Kernels are compiled before the
first round. `python benchmarks/bench_load.py [--size 1024] [--repeats 5] [SIZE ...]` (SIZE as
bench_hits.py takes it: 1M, 4M, 10M; default 1M 4M).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh
from bench_hits import bumpy_size
from common import machine, median_of, run_main, table

import raylume
from raylume.scene.procedural import bumpy_sphere
from raylume.session import Session


def raylume_picture(path: Path, size: int) -> dict[str, float]:
    """Seconds of each stage of a cast render of the mesh file."""
    t0 = time.perf_counter()
    scene = raylume.load(path)
    t1 = time.perf_counter()
    session = Session(scene)
    t2 = time.perf_counter()
    session.render(mode="cast", width=size, height=size, threads=1, aovs=False)
    t3 = time.perf_counter()
    return {"load": t1 - t0, "compile": t2 - t1, "render": t3 - t2, "total": t3 - t0}


def embree_picture(path: Path, o: np.ndarray, d: np.ndarray) -> dict[str, float]:
    """Seconds of trimesh's load and Embree's build and first frame of the same rays."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    t0 = time.perf_counter()
    mesh = trimesh.load(path, process=False)
    t1 = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, mesh.vertices.astype(np.float32), mesh.faces.astype(np.int32))
    t2 = time.perf_counter()
    scene.run(o, d, output=1)
    t3 = time.perf_counter()
    return {"load": t1 - t0, "upload": t2 - t1, "build + frame": t3 - t2, "total": (t1 - t0) + (t3 - t2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", nargs="*", default=["1M", "4M"], help="bumpy sphere sizes (1M, 4M, 10M)")
    parser.add_argument("--size", type=int, default=1024, help="image side")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"a mesh file to its first picture, {args.size} x {args.size}, wall seconds, medians of {args.repeats}")
    print(f"alternating raylume and trimesh + Embree; {machine()}\n")
    rows = []
    for name in args.meshes:
        n = bumpy_size(name)
        if n is None:
            raise SystemExit(f"bench_load.py: {name!r} is no bumpy sphere size (1M, 4M, 10M)")
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / f"bumpy_{name}.ply"
            trimesh.Trimesh(*bumpy_sphere(n), process=False).export(path)
            scene = raylume.load(path)
            o, d = raylume.camera_rays(scene.camera, args.size, args.size)
            o32 = np.ascontiguousarray(o.reshape(-1, 3), dtype=np.float32)
            d32 = np.ascontiguousarray(d.reshape(-1, 3), dtype=np.float32)
            raylume_picture(path, 64)  # compiles what the rounds run
            ours: list[dict] = []
            theirs: list[dict] = []
            for _ in range(args.repeats):
                ours.append(raylume_picture(path, args.size))
                theirs.append(embree_picture(path, o32, d32))
        med = {k: median_of([r[k] for r in ours]) for k in ours[0]}
        emb = {k: median_of([r[k] for r in theirs]) for k in theirs[0]}
        rows.append(
            [name, f"{n:,}"]
            + [f"{med[k]:.2f}" for k in ("load", "compile", "render", "total")]
            + [f"{emb[k]:.2f}" for k in ("load", "build + frame", "total", "upload")]
            + [f"{med['total'] / emb['total']:.2f}"]
        )
    headers = ["mesh", "triangles", "raylume load s", "compile s", "cast render s", "raylume total s"]
    headers += ["trimesh load s", "Embree build + frame s", "trimesh + Embree s", "(embreex upload s)"]
    headers += ["raylume / theirs"]
    print(table(headers, rows))


if __name__ == "__main__":
    run_main(main)
