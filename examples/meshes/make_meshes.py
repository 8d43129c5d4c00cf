"""Regenerate the procedural example mesh(es) in this folder.

    python examples/meshes/make_meshes.py

Writes lens.ply (a smooth icosphere that examples/glass.toml squashes into a lens) and
bumpy_sphere.ply: raylume's benchmark surface (a sphere displaced by a
smooth random field) at a size fit for examples, as binary PLY with
area-weighted vertex normals so it renders smooth by default. Deterministic.
"""

from pathlib import Path

import trimesh

try:
    from raylume.scene.procedural import bumpy_sphere, vertex_normals
except ImportError:  # run from a checkout without installing the package
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))
    from raylume.scene.procedural import bumpy_sphere, vertex_normals

HERE = Path(__file__).resolve().parent


def main() -> None:
    vertices, faces = bumpy_sphere(6000, radius=1.0, bumpiness=0.2, seed=7)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.vertex_normals = vertex_normals(vertices, faces)  # cached normals are exported
    out = HERE / "bumpy_sphere.ply"
    mesh.export(out, encoding="binary")
    print(f"wrote {out.name}: {len(vertices)} vertices, {len(faces)} triangles, {out.stat().st_size} bytes")

    # A smooth unit sphere, squashed by a scene transform into a lens (examples/glass.toml).
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    sphere.vertex_normals = sphere.vertices / (sphere.vertices ** 2).sum(axis=1, keepdims=True) ** 0.5
    out = HERE / "lens.ply"
    sphere.export(out, encoding="binary")
    print(f"wrote {out.name}: {len(sphere.vertices)} vertices, {len(sphere.faces)} triangles, {out.stat().st_size} bytes")


if __name__ == "__main__":
    main()
