"""Generate the forest example's meshes and placements (examples/forest.toml).

    python examples/forest/make_forest.py [--trees 10000] [--crown 100000]

Writes, next to this script (deterministic, a few seconds):
  crown.ply   a conifer's crown: three stacked, squashed bumpy spheres (raylume.scene.procedural),
              --crown triangles in all (default 100 000)
  trunk.ply   its trunk, a tapered cylinder (a few hundred triangles)
  trees.npy   --trees placement matrices, float32 (N, 3, 4): positions on a jittered grid over a
              square of 240 x 240 units, a random turn about y, a random size (0.6 .. 1.4) and
              a slight non-uniform stretch

With the defaults the forest shows 10 000 x 100 000 = a billion crown triangles, each stored
once: the scene file places both meshes with the same `instances`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
try:
    from raylume.scene.procedural import bumpy_sphere, vertex_normals
except ImportError:  # run from a checkout without installing the package
    sys.path.insert(0, str(HERE.parents[1] / "src"))
    from raylume.scene.procedural import bumpy_sphere, vertex_normals

SIDE = 240.0  # the forest's square, centred on the origin


def crown(triangles: int) -> trimesh.Trimesh:
    """Three bumpy spheres squashed into cones' tiers, widest at the bottom."""
    parts = []
    tiers = ((0.0, 1.0), (0.9, 0.78), (1.7, 0.52))  # (height of the tier's centre, radius)
    for k, (y, r) in enumerate(tiers):
        v, f = bumpy_sphere(triangles // len(tiers), radius=1.0, bumpiness=0.25, seed=11 + k)
        v = v * [r, 0.75 * r, r]
        v[:, 1] += 1.3 + y - 0.45 * r * np.clip(v[:, 1] / (0.75 * r), -1, 1) ** 2  # skirted tiers
        parts.append(trimesh.Trimesh(v, f, process=False))
    mesh = trimesh.util.concatenate(parts)
    mesh.vertex_normals = vertex_normals(mesh.vertices, mesh.faces)
    return mesh


def trunk() -> trimesh.Trimesh:
    mesh = trimesh.creation.cylinder(radius=0.14, height=1.6, sections=24)
    mesh.apply_translation((0, 0, 0.8))
    mesh.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0)))  # z up -> y up
    mesh.vertices[:, [0, 2]] *= 1.0 - 0.4 * mesh.vertices[:, 1:2] / 1.6  # tapered
    return mesh


def placements(n: int, seed: int = 5) -> np.ndarray:
    """n matrices (N, 3, 4): jittered grid positions, turn about y, size, slight stretch."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    cell = SIDE / side
    ij = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)[:n]
    xz = (ij + 0.5 + rng.uniform(-0.4, 0.4, size=(n, 2))) * cell - SIDE / 2
    angle = rng.uniform(0, 2 * np.pi, n)
    size = rng.uniform(0.6, 1.4, n) * cell / 2.4
    stretch = rng.uniform(0.85, 1.3, n)  # taller or squatter: a non-uniform scale
    c, s = np.cos(angle), np.sin(angle)
    m = np.zeros((n, 3, 4))
    m[:, 0, 0], m[:, 0, 2] = c * size, s * size
    m[:, 1, 1] = size * stretch
    m[:, 2, 0], m[:, 2, 2] = -s * size, c * size
    m[:, 0, 3], m[:, 2, 3] = xz[:, 0], xz[:, 1]
    return m.astype(np.float32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trees", type=int, default=10_000)
    parser.add_argument("--crown", type=int, default=100_000, help="crown triangles")
    parser.add_argument("--out", type=Path, default=HERE)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    c = crown(args.crown)
    c.export(args.out / "crown.ply", encoding="binary")
    trunk().export(args.out / "trunk.ply", encoding="binary")
    np.save(args.out / "trees.npy", placements(args.trees))
    print(f"wrote crown.ply ({len(c.faces)} triangles), trunk.ply, trees.npy ({args.trees} trees) in {args.out}")
    print(f"{args.trees} x {len(c.faces)} = {args.trees * len(c.faces):,} crown triangles")


if __name__ == "__main__":
    main()
