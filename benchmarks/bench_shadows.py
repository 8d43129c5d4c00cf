"""Shadow rays against Embree: `raylume.occluded`'s any-hit queries beside Embree's occlusion.

From every point of a mesh that bench_hits.py's camera sees (1024 x 1024 pixel centres, the hit
moved back along its ray by a millionth of its distance, to the eye's side of the surface) a ray
towards a point light above and to the left of the mesh, ending at the light: about half of them
are blocked (the mesh shadows itself). The rays are in pixel order, as a renderer's are. Traced by
raylume's occlusion kernel (`occluded_rays`, one thread: runs of eight neighbours as packets,
`packet_blocked`), by its single-ray any-hit (`any_hit` ray by ray, the same rays) and by Embree
three ways, single-threaded, all robust: embreex's `run(..., query="OCCLUDED")` (`rtcOccluded1`
ray by ray), `rtcOccluded1` called directly ("Embree 1", embree_direct.py) and
Embree's packets of eight consecutive rays, `rtcOccluded8` ("Embree 8", as raylume's packets take
them). Each is timed in CPU time, alternating in one process, medians. The ratios are Embree's
time over raylume's: above 1, raylume is faster. Last, how many answers agree with Embree's (it is
not watertight, so rays through shared edges may differ).

    python benchmarks/bench_shadows.py [--size 1024] [--repeats 7] [MESH ...]

MESH as bench_hits.py takes them; by default the bunny, Nefertiti and bumpy 10k to 4M.
"""

from __future__ import annotations

import argparse

import numba
import numpy as np
from bench_hits import DEFAULT, _trace, bumpy_size, cpu_seconds, frame_rays, mesh
from common import SHARED_MODELS, cached_entry, growth_table, machine, run_main, table
from embree_direct import EmbreeScene

from raylume.kernels.geometry.query import CHUNK
from raylume.kernels.geometry.traverse import any_hit
from raylume.kernels.geometry.wide_nodes import traversal_stacks
from raylume.kernels.scene import geometry_of
from raylume.kernels.variants import features
from raylume.kernels.vec import kernel_function
from raylume.query_lanes import occluded_rays


def shadow_rays(vertices, faces, size, frame=None):
    """The compiled scene and the shadow rays of its camera's hits: (origins, unit directions,
    distances to the light). `frame`: frame_rays' answer for the mesh, where the caller has it
    (the scene is not compiled again)."""
    compiled, fo, fd, hit = frame if frame is not None else frame_rays(vertices, faces, size)
    t = _trace(compiled, fo[hit], fd[hit])[0]
    points = fo[hit] + fd[hit] * (t * (1 - 1e-6))[:, None]
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    light = (lo + hi) / 2 + np.array([-1.5, 2.0, -1.0]) * np.linalg.norm(hi - lo)
    to_light = light - points
    tmax = np.linalg.norm(to_light, axis=1)
    return compiled, np.ascontiguousarray(points), np.ascontiguousarray(to_light / tmax[:, None]), tmax


def _blocked(compiled, o, d, tmax):
    out = np.empty(len(o), dtype=np.bool_)
    occluded_rays(compiled.kernel, features(compiled.kernel), o, d, np.zeros(len(o)), tmax, out, 1)
    return out


@kernel_function
def _any_hits(S, X, o, d, tmax, out, node_stack, t_stack):
    """occluded_rays' work without packets: any_hit ray by ray."""
    G = geometry_of(S)
    for k in range(o.shape[0]):
        ray_o = (o[k, 0], o[k, 1], o[k, 2])
        ray_d = (d[k, 0], d[k, 1], d[k, 2])
        out[k] = any_hit(G, X, ray_o, ray_d, 0.0, tmax[k], node_stack, t_stack)


any_hits = cached_entry(_any_hits)


def _blocked_singly(compiled, o, d, tmax, stacks):
    out = np.empty(len(o), dtype=np.bool_)
    any_hits(compiled.kernel, features(compiled.kernel), o, d, tmax, out, *stacks)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("meshes", nargs="*", default=DEFAULT)
    parser.add_argument("--size", type=int, default=1024, help="image side: size x size camera rays")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    numba.set_num_threads(1)
    stacks = traversal_stacks()
    print(f"shadow rays of a {args.size} x {args.size} frame's hits, 1 thread, CPU time, medians of {args.repeats}")
    print(f"alternating raylume and Embree; chunks of {CHUNK} rays; {machine()}\n")
    rows = []
    seconds, rays = {}, {}  # per bumpy sphere: each engine's seconds; the shadow rays
    for name in args.meshes:
        vf = mesh(name)
        if vf is None:
            print(f"(skipping {name}: not found in {SHARED_MODELS})")
            continue
        v, f = vf
        compiled, o, d, tmax = shadow_rays(v, f, args.size)
        embree = rtcs.EmbreeScene()
        TriangleMesh(embree, v.astype(np.float32), f.astype(np.int32))
        o32, d32, tmax32 = o.astype(np.float32), d.astype(np.float32), tmax.astype(np.float32)
        theirs_blocked = embree.run(o32, d32, dists=tmax32, query="OCCLUDED") != -1  # Embree builds here
        direct = EmbreeScene(v, f)
        assert np.array_equal(direct.occluded(o32, d32, tmax32), theirs_blocked)
        assert np.array_equal(direct.occluded(o32, d32, tmax32, packets=True), theirs_blocked)
        ours_blocked = _blocked(compiled, o, d, tmax)
        assert np.array_equal(ours_blocked, _blocked_singly(compiled, o, d, tmax, stacks))
        ours, singly, theirs, ones, eights = [], [], [], [], []
        for _ in range(args.repeats):
            ours.append(cpu_seconds(lambda: _blocked(compiled, o, d, tmax)))  # noqa: B023 (called at once)
            theirs.append(cpu_seconds(lambda: embree.run(o32, d32, dists=tmax32, query="OCCLUDED")))  # noqa: B023
            ones.append(cpu_seconds(lambda: direct.occluded(o32, d32, tmax32)))  # noqa: B023
            eights.append(cpu_seconds(lambda: direct.occluded(o32, d32, tmax32, packets=True)))  # noqa: B023
            singly.append(cpu_seconds(lambda: _blocked_singly(compiled, o, d, tmax, stacks)))  # noqa: B023
        r, e, r1 = np.median(ours), np.median(theirs), np.median(singly)
        e1, e8 = np.median(ones), np.median(eights)
        pairs = np.array(theirs) / np.array(ours)
        if bumpy_size(name) is not None:
            seconds[name] = {"packets": r, "single rays": r1, "Embree": e, "Embree 1": e1, "Embree 8": e8}
            rays[name] = len(o)
        rows.append(
            [name, f"{len(f):,}", f"{len(o):,}", f"{ours_blocked.mean():.0%}", f"{r * 1e3:.1f}", f"{r1 * 1e3:.1f}"]
            + [f"{e * 1e3:.1f}", f"{e / r:.2f}", f"{pairs.min():.2f}-{pairs.max():.2f}", f"{e / r1:.2f}"]
            + [f"{e1 * 1e3:.1f}", f"{e8 * 1e3:.1f}", f"{e1 / r:.2f}", f"{e8 / r:.2f}"]
            + [f"{np.mean(ours_blocked == theirs_blocked):.4%}"]
        )
        print(" | ".join(rows[-1]), flush=True)
    headers = ["mesh", "triangles", "shadow rays", "blocked", "raylume ms", "single-ray ms", "Embree ms"]
    headers += ["Embree / raylume", "per pair", "Embree / single-ray", "Embree 1 ms", "Embree 8 ms"]
    headers += ["Embree 1 / raylume", "Embree 8 / raylume", "answers as Embree's"]
    print("\n" + table(headers, rows))
    if grown := growth_table(seconds, rays):
        print("\nshadow rays, growth from bumpy 40k:\n" + grown)


if __name__ == "__main__":
    run_main(main)
