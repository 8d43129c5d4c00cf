"""Write the head lamp's parabolic reflector (examples/headlamp.toml) as an OBJ mesh with exact
vertex normals:

    python examples/headlamp_reflector.py          # -> examples/headlamp/reflector.obj

The paraboloid z = (x^2 + y^2) / (4 f) opens along +z, its focus at (0, 0, f): light leaving
the focus leaves the mirror parallel to the axis. Rings of constant radius from the hole at the
vertex (where the bulb's socket would be) to the rim, each a circle of SEGMENTS vertices."""

from __future__ import annotations

import math
from pathlib import Path

FOCAL = 0.05  # focal length (m): the bulb sits at the focus
RIM = 0.18  # rim radius (m)
HOLE = 0.016  # radius of the hole at the vertex
RINGS = 24
SEGMENTS = 64


def paraboloid(
    focal: float = FOCAL, rim: float = RIM, hole: float = HOLE, rings: int = RINGS, segments: int = SEGMENTS
):
    """(vertices, normals, triangles): the paraboloid's surface between radii `hole` and `rim`;
    normals are the surface's, facing the focus (inside)."""
    vertices, normals, triangles = [], [], []
    for i in range(rings + 1):
        r = hole + (rim - hole) * i / rings
        for k in range(segments):
            a = 2 * math.pi * k / segments
            x, y = r * math.cos(a), r * math.sin(a)
            vertices.append((x, y, r * r / (4 * focal)))
            gx, gy, gz = -x / (2 * focal), -y / (2 * focal), 1.0
            n = math.sqrt(gx * gx + gy * gy + gz * gz)
            normals.append((gx / n, gy / n, gz / n))
    for i in range(rings):
        for k in range(segments):
            a, b = i * segments + k, i * segments + (k + 1) % segments
            c, d = a + segments, b + segments
            triangles += [(a, b, d), (a, d, c)]
    return vertices, normals, triangles


def write_obj(path: Path) -> None:
    vertices, normals, triangles = paraboloid()
    lines = [f"# parabolic reflector: focal length {FOCAL} m, rim radius {RIM} m (headlamp_reflector.py)"]
    lines += [f"v {x:.7f} {y:.7f} {z:.7f}" for x, y, z in vertices]
    lines += [f"vn {x:.7f} {y:.7f} {z:.7f}" for x, y, z in normals]
    lines += [f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}" for a, b, c in triangles]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    write_obj(Path(__file__).resolve().parent / "headlamp" / "reflector.obj")
