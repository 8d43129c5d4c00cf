"""pbrt-v4 shapes as raylume objects.

A `Shape` directive becomes a Piece in its own object space; `place` turns a piece and its
object-to-world matrix into a scene-model object. Spheres, disks and cylinders stay analytic
where raylume's shapes can hold them (the matrix a similarity, the whole shape; a disk or
cylinder only where pbrt's UVs are not needed, a textured sphere turned so that its UVs are
pbrt's); otherwise they are tessellated along pbrt's own (u, v) parametrisation, so that image
textures land where pbrt puts them. Triangle and bilinear meshes are inline meshes; PLY files
stay where they are, referenced by path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .affine import Z_POLE_SPHERE, turned
from .pbrt_params import Params
from .pbrt_parse import Directive, resolve
from .pbrt_transform import apply_point, apply_vector, rows, similarity_scale

SUPPORTED = ("sphere", "disk", "cylinder", "trianglemesh", "bilinearmesh", "plymesh")
# Grid of a tessellated analytic shape: steps around a full turn, and along its height.
STEPS_AROUND = 64
STEPS_ALONG = 32


@dataclass
class Piece:
    kind: str  # "sphere", "disk", "cylinder" or "mesh"
    table: dict = field(default_factory=dict)  # the shape's parameters, or a mesh's keys
    notes: list[str] = field(default_factory=list)  # why it was tessellated, for a warning


def shape_piece(d: Directive, p: Params) -> Piece:
    """The piece of a Shape directive (kind in SUPPORTED); PbrtError for bad parameters."""
    kind = d.args[0]
    if kind == "sphere":
        r = p.float("radius", 1.0)
        zmin, zmax = p.float("zmin", -r), p.float("zmax", r)
        phimax = p.float("phimax", 360.0)
        _positive(d, "radius", r)
        return Piece("sphere", {"radius": r, "zmin": min(zmin, zmax), "zmax": max(zmin, zmax), "phimax": phimax})
    if kind == "disk":
        r, ri = p.float("radius", 1.0), p.float("innerradius", 0.0)
        _positive(d, "radius", r)
        table = {"height": p.float("height", 0.0), "radius": r, "innerradius": ri, "phimax": p.float("phimax", 360.0)}
        return Piece("disk", table)
    if kind == "cylinder":
        r = p.float("radius", 1.0)
        _positive(d, "radius", r)
        zmin, zmax = p.float("zmin", -1.0), p.float("zmax", 1.0)
        if zmin == zmax:
            raise d.fail("zmin and zmax must differ (the cylinder would have no height)")
        table = {"radius": r, "zmin": min(zmin, zmax), "zmax": max(zmin, zmax), "phimax": p.float("phimax", 360.0)}
        return Piece("cylinder", table)
    if kind == "plymesh":
        name = p.string("filename")
        if name is None:
            raise d.fail('needs "string filename"')
        path = resolve(name, d.search_dir)
        if name.lower().endswith(".gz"):
            raise d.fail(f"{name}: gzip-compressed PLY files are not supported; decompress it first")
        if not path.is_file():
            raise d.fail(f"no such PLY file {str(path)!r}")
        return Piece("mesh", {"file": name})
    return _mesh_piece(d, p, 4 if kind == "bilinearmesh" else 3)


def no_surface(piece: Piece) -> str | None:
    """Why an analytic piece has no surface at all (pbrt draws nothing of it), or None."""
    t = piece.table
    if piece.kind == "mesh":
        return None
    if t["phimax"] <= 0:
        return f"phimax {t['phimax']:g}"
    if piece.kind == "sphere":
        r = t["radius"]
        if min(max(t["zmin"], -r), r) == min(max(t["zmax"], -r), r):
            return f"zmin {t['zmin']:g} and zmax {t['zmax']:g} cut the whole sphere of radius {r:g} away"
    if piece.kind == "disk" and t["innerradius"] >= t["radius"]:
        return f"innerradius {t['innerradius']:g} is not less than radius {t['radius']:g}"
    return None


def _positive(d: Directive, name: str, value: float) -> None:
    if not value > 0:
        raise d.fail(f'"float {name}" must be > 0, got {value:g}')


def _mesh_piece(d: Directive, p: Params, corners: int) -> Piece:
    """A trianglemesh (corners 3) or bilinearmesh (corners 4: two triangles per patch) as an inline mesh."""
    points = p.list("P", "point3", 3)
    if not points:
        raise d.fail('needs "point3 P", the vertex positions')
    n = len(points)
    indices = p.list("indices", "integer")
    if indices is None:
        if n != corners:
            raise d.fail(f'needs "integer indices" (it has {n} vertices, not exactly {corners})')
        indices = list(range(corners))
    if len(indices) % corners:
        raise d.fail(f'"integer indices" holds {len(indices)} numbers, not a multiple of {corners}')
    if min(indices) < 0 or max(indices) >= n:
        raise d.fail(f'"integer indices" refers to vertex {max(indices)}, but "point3 P" has {n} (from 0)')
    normals = p.list("N", "normal3", 3)
    if p.type_of("uv") == "float":  # pbrt-v3 spelling
        flat = p.list("uv", "float")
        uvs = [tuple(flat[k : k + 2]) for k in range(0, len(flat), 2)]
    else:
        uvs = p.list("uv", "point2", 2)
    for key, values in (("N", normals), ("uv", uvs)):
        if values is not None and len(values) != n:
            raise d.fail(f'"{key}" has {len(values)} entries; it needs one per vertex ({n})')
    if corners == 3:
        faces = [indices[k : k + 3] for k in range(0, len(indices), 3)]
    else:  # patch (v00, v10, v01, v11): its two triangles, facing along cross(p10 - p00, p01 - p00)
        faces = []
        for k in range(0, len(indices), 4):
            a, b, c, e = indices[k : k + 4]
            faces += [[a, b, e], [a, e, c]]
    table = {"vertices": [list(v) for v in points], "faces": faces}
    if normals is not None:
        table["normals"] = [list(v) for v in normals]
    if uvs is not None:
        table["uvs"] = [list(v) for v in uvs]
    table["_default_uvs"] = "bilinear" if corners == 4 else "triangle"
    return Piece("mesh", table)


def place(piece: Piece, m: np.ndarray, material, needs_uvs: bool, reverse: bool) -> tuple[dict, str | None]:
    """(the scene-model object of a piece placed by the 4 x 4 matrix m, a note saying how it was
    approximated or None)."""
    if piece.kind == "mesh":
        return _place_mesh(piece.table, m, material, needs_uvs, reverse), None
    analytic, why = _analytic(piece, m, needs_uvs)
    if analytic is not None:
        analytic["material"] = material
        return analytic, None
    table = _tessellate(piece)
    return _place_mesh(table, m, material, needs_uvs, reverse), why


def _place_mesh(table: dict, m: np.ndarray, material, needs_uvs: bool, reverse: bool) -> dict:
    obj = {"type": "mesh", **{k: v for k, v in table.items() if not k.startswith("_")}, "material": material}
    if "vertices" in obj and needs_uvs and "uvs" not in obj:
        obj = _with_default_uvs(obj, table.get("_default_uvs", "triangle"))
    if reverse and "faces" in obj and "normals" not in obj:
        # pbrt turns the geometric normal towards given shading normals, so ReverseOrientation
        # only changes a mesh without them
        obj["faces"] = [list(reversed(f)) for f in obj["faces"]]
    if not np.array_equal(m, np.eye(4)):
        obj["transform"] = {"matrix": rows(m)}
    return obj


def _with_default_uvs(obj: dict, kind: str) -> dict:
    """pbrt's UVs for a mesh without them: each triangle (0,0), (1,0), (1,1); each bilinear
    patch its corners' (u, v). Vertices are unshared so that every corner has its own."""
    v, faces = obj["vertices"], obj["faces"]
    normals = obj.get("normals")
    corner_uvs = ([0, 0], [1, 0], [1, 1]) if kind == "triangle" else None
    new_v, new_n, new_uv, new_f = [], [], [], []
    for k, face in enumerate(faces):
        if corner_uvs is None:  # patches were split into (a, b, e) and (a, e, c)
            corner = ([0, 0], [1, 0], [1, 1]) if k % 2 == 0 else ([0, 0], [1, 1], [0, 1])
        else:
            corner = corner_uvs
        base = len(new_v)
        for i, uv in zip(face, corner):
            new_v.append(v[i])
            new_uv.append(uv)
            if normals is not None:
                new_n.append(normals[i])
        new_f.append([base, base + 1, base + 2])
    out = {**obj, "vertices": new_v, "faces": new_f, "uvs": new_uv}
    if normals is not None:
        out["normals"] = new_n
    return out


def _analytic(piece: Piece, m: np.ndarray, needs_uvs: bool) -> tuple[dict | None, str | None]:
    """The raylume shape of an analytic piece, or (None, why it must be tessellated)."""
    t = piece.table
    if needs_uvs and piece.kind != "sphere":
        return None, None  # raylume's disks and cylinders have their own UVs; pbrt's need the tessellation
    if t["phimax"] < 360.0:
        return None, f"a partial {piece.kind} (phimax {t['phimax']:g})"
    if piece.kind == "sphere":
        r = t["radius"]
        if t["zmin"] > -r or t["zmax"] < r:
            return None, "a sphere cut by zmin/zmax"
        s = similarity_scale(m)
        if s is None:
            return None, "a sphere under a non-uniform scale or shear (an ellipsoid)"
        centre = _list(apply_point(m, (0, 0, 0)))
        if not needs_uvs:
            return {"type": "sphere", "center": centre, "radius": r * s}, None
        # raylume's sphere turned so that its (u, v) is pbrt's: the object frame as m places it
        frame = m[:3, :3] / s @ Z_POLE_SPHERE
        return {"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": r * s, "transform": turned(frame, centre)}, None
    if piece.kind == "disk":
        if t["innerradius"] > 0:
            return None, "a disk with a hole (innerradius)"
        s = similarity_scale(m, (0, 1))
        if s is None:
            return None, "a disk under a non-uniform scale or shear (an ellipse)"
        normal = np.cross(apply_vector(m, (1, 0, 0)), apply_vector(m, (0, 1, 0)))
        center = apply_point(m, (0, 0, t["height"]))
        return {"type": "disk", "center": _list(center), "normal": _list(normal), "radius": t["radius"] * s}, None
    s = similarity_scale(m, (0, 1))
    axis = apply_vector(m, (0, 0, 1))
    if (
        s is None
        or abs(float(axis @ apply_vector(m, (1, 0, 0)))) > 1e-6 * float(axis @ axis) ** 0.5 * s
        or abs(float(axis @ apply_vector(m, (0, 1, 0)))) > 1e-6 * float(axis @ axis) ** 0.5 * s
    ):
        return None, "a cylinder under a non-uniform scale or shear (an elliptic one)"
    p0, p1 = apply_point(m, (0, 0, t["zmin"])), apply_point(m, (0, 0, t["zmax"]))
    return {"type": "cylinder", "p0": _list(p0), "p1": _list(p1), "radius": t["radius"] * s, "capped": False}, None


def _list(v) -> list[float]:
    return [float(x) for x in v]


def _tessellate(piece: Piece) -> dict:
    """An analytic piece as a grid of triangles over pbrt's (u, v), with its UVs and normals."""
    t = piece.table
    phimax = math.radians(min(max(t["phimax"], 0.0), 360.0))
    nu = max(4, math.ceil(STEPS_AROUND * phimax / (2 * math.pi)))
    nv = STEPS_ALONG if piece.kind != "disk" else 4
    u, v = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    phi = u * phimax
    if piece.kind == "sphere":
        r = t["radius"]
        th0 = math.acos(min(max(t["zmin"] / r, -1.0), 1.0))
        th1 = math.acos(min(max(t["zmax"] / r, -1.0), 1.0))
        theta = th0 + v * (th1 - th0)
        p = np.stack([r * np.sin(theta) * np.cos(phi), r * np.sin(theta) * np.sin(phi), r * np.cos(theta)], -1)
        n = p / r
    elif piece.kind == "cylinder":
        r = t["radius"]
        z = t["zmin"] + v * (t["zmax"] - t["zmin"])
        p = np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)
        n = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(z)], -1)
    else:
        rad = (1 - v) * t["radius"] + v * t["innerradius"]
        p = np.stack([rad * np.cos(phi), rad * np.sin(phi), np.full_like(rad, t["height"])], -1)
        n = np.broadcast_to(np.array([0.0, 0.0, 1.0]), p.shape)
    index = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, e = index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, e], -1).reshape(-1, 3)])
    verts, normals = p.reshape(-1, 3), n.reshape(-1, 3)
    # wound so that each face's front is the shape's outside (pbrt's normal, before any flip)
    fn = np.cross(verts[faces[:, 1]] - verts[faces[:, 0]], verts[faces[:, 2]] - verts[faces[:, 0]])
    if float(np.einsum("ij,ij->", fn, normals[faces[:, 0]] + normals[faces[:, 1]] + normals[faces[:, 2]])) < 0:
        faces = faces[:, ::-1]
    # drop the zero-area triangles at a sphere's poles and a disk's centre
    area = np.linalg.norm(fn, axis=1)
    faces = faces[area > 1e-12 * max(float(area.max()), 1e-300)]
    uvs = np.stack([u, v], -1).reshape(-1, 2)
    return {
        "vertices": verts.tolist(),
        "faces": faces.tolist(),
        "normals": normals.tolist(),
        "uvs": uvs.tolist(),
    }
