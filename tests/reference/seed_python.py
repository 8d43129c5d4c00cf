"""Independent pure-Python reference ray tracer (the test oracle / "plain Python" peer).

This follows Gabriel Gambetta, *Computer Graphics from Scratch*, chapters
"Basic Raytracing", "Light", "Shadows" and "Reflections", as closely as the
project's scene conventions allow.  It deliberately imports nothing from
``raylume``: it exists to check the fast Numba renderer independently.  Its
per-pixel code is plain Python (``math`` and tuples); numpy is used only to
hand back the finished image.

Interface::

    render_reference(scene, width, height, mode="trace") -> np.ndarray

returns a float64 array of shape ``(height, width, 3)``: linear RGB, *not*
clamped, row 0 at the top.  ``mode`` is ``"trace"`` (lighting, shadows and
reflections) or ``"cast"`` (the colour of the closest hit's material, no
lighting).

``scene`` is a plain dict shaped like the project's TOML scene files; only
spheres and ambient / point / directional lights are supported (anything else
raises rather than being silently ignored, so the oracle never quietly
diverges from the renderer it checks).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["render_reference", "camera_ray_direction", "SEED_SCENE"]

INF = math.inf
PRIMARY_T_MIN = 1e-9  # camera origin is the eye: accept anything in front of it
SECONDARY_T_MIN = 0.001  # shadow and reflection rays, as in the lecture
DEFAULT_FOV = 53.13
DEFAULT_MAX_DEPTH = 3

# The lecture's scene (the end of the "Reflections" chapter).
SEED_SCENE: dict = {
    "render": {"background": [0.0, 0.0, 0.0], "max_depth": 3},
    "camera": {
        "position": [0.0, 0.0, 0.0],
        "look_at": [0.0, 0.0, 1.0],
        "up": [0.0, 1.0, 0.0],
        "fov": 53.13,
    },
    "materials": {
        "red": {"color": [1.0, 0.0, 0.0], "specular": 500, "reflective": 0.2},
        "blue": {"color": [0.0, 0.0, 1.0], "specular": 500, "reflective": 0.3},
        "green": {"color": [0.0, 1.0, 0.0], "specular": 10, "reflective": 0.4},
        "yellow": {"color": [1.0, 1.0, 0.0], "specular": 1000, "reflective": 0.5},
    },
    "lights": [
        {"type": "ambient", "intensity": 0.2},
        {"type": "point", "position": [2.0, 1.0, 0.0], "intensity": 0.6},
        {"type": "directional", "direction": [1.0, 4.0, 4.0], "intensity": 0.2},
    ],
    "objects": [
        {"type": "sphere", "center": [0.0, -1.0, 3.0], "radius": 1.0, "material": "red"},
        {"type": "sphere", "center": [2.0, 0.0, 4.0], "radius": 1.0, "material": "blue"},
        {"type": "sphere", "center": [-2.0, 0.0, 4.0], "radius": 1.0, "material": "green"},
        {"type": "sphere", "center": [0.0, -5001.0, 0.0], "radius": 5000.0, "material": "yellow"},
    ],
}


# --------------------------------------------------------------------------
# Small vector helpers on 3-tuples
# --------------------------------------------------------------------------


def _vec(v) -> tuple[float, float, float]:
    x, y, z = v
    return (float(x), float(y), float(z))


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a, b):
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def _normalize(v):
    n = math.sqrt(_dot(v, v))
    if n == 0.0:
        raise ValueError(f"cannot normalize zero vector {v!r}")
    return (v[0] / n, v[1] / n, v[2] / n)


def _rgb(value) -> tuple[float, float, float]:
    """An intensity: a number (grey) or an [r, g, b] triple."""
    if isinstance(value, (int, float)):
        f = float(value)
        return (f, f, f)
    return _vec(value)


# --------------------------------------------------------------------------
# Scene preparation
# --------------------------------------------------------------------------


def _material(spec, materials: dict) -> tuple:
    """(color, specular_or_None, reflective) from a material name or inline dict."""
    if isinstance(spec, str):
        if spec not in materials:
            raise KeyError(f"unknown material {spec!r}")
        spec = materials[spec]
    color = _vec(spec.get("color", (1.0, 1.0, 1.0)))
    s = spec.get("specular")
    specular = None if s is None or float(s) == -1.0 else float(s)
    reflective = float(spec.get("reflective", 0.0))
    return color, specular, reflective


def _prepare_spheres(scene: dict) -> list[tuple]:
    materials = scene.get("materials", {})
    spheres = []
    for obj in scene.get("objects", []):
        kind = obj.get("type", "sphere")
        if kind != "sphere":
            raise NotImplementedError(f"reference tracer supports spheres only, got {kind!r}")
        center = _vec(obj["center"])
        radius = float(obj["radius"])
        color, specular, reflective = _material(obj.get("material", {}), materials)
        spheres.append((center, radius, color, specular, reflective))
    return spheres


def _prepare_lights(scene: dict) -> list[tuple]:
    lights = []
    for light in scene.get("lights", []):
        kind = light["type"]
        intensity = _rgb(light.get("intensity", 1.0))
        if kind == "ambient":
            lights.append(("ambient", intensity, None))
        elif kind == "point":
            lights.append(("point", intensity, _vec(light["position"])))
        elif kind == "directional":
            lights.append(("directional", intensity, _vec(light["direction"])))
        else:
            raise NotImplementedError(f"reference tracer does not support light type {kind!r}")
    return lights


def _camera(scene: dict):
    cam = scene.get("camera", {})
    position = _vec(cam.get("position", (0.0, 0.0, 0.0)))
    look_at = _vec(cam.get("look_at", (0.0, 0.0, 1.0)))
    up = _vec(cam.get("up", (0.0, 1.0, 0.0)))
    fov = float(cam.get("fov", DEFAULT_FOV))
    f = _normalize(_sub(look_at, position))
    r = _normalize(_cross(up, f))
    u = _cross(f, r)
    return position, f, r, u, fov


def camera_ray_direction(scene: dict, width: int, height: int, i: int, j: int):
    """Unit direction of the primary ray through pixel column ``i``, row ``j`` (row 0 = top)."""
    _, f, r, u, fov = _camera(scene)
    h = math.tan(math.radians(fov) / 2.0)
    w = h * width / height
    a = (i + 0.5) / width * 2.0 - 1.0
    b = 1.0 - (j + 0.5) / height * 2.0
    aw = a * w
    bh = b * h
    return _normalize(
        (
            f[0] + r[0] * aw + u[0] * bh,
            f[1] + r[1] * aw + u[1] * bh,
            f[2] + r[2] * aw + u[2] * bh,
        )
    )


# --------------------------------------------------------------------------
# The lecture's algorithm
# --------------------------------------------------------------------------


def _intersect_ray_sphere(O, D, center, radius):
    """Both roots of |O + tD - C|^2 = r^2 (lecture form), or (inf, inf) on a miss."""
    CO = (O[0] - center[0], O[1] - center[1], O[2] - center[2])
    a = D[0] * D[0] + D[1] * D[1] + D[2] * D[2]
    b = 2.0 * (CO[0] * D[0] + CO[1] * D[1] + CO[2] * D[2])
    c = CO[0] * CO[0] + CO[1] * CO[1] + CO[2] * CO[2] - radius * radius
    discriminant = b * b - 4.0 * a * c
    if discriminant < 0.0:
        return INF, INF
    sq = math.sqrt(discriminant)
    return (-b + sq) / (2.0 * a), (-b - sq) / (2.0 * a)


def _closest_intersection(spheres, O, D, t_min, t_max):
    closest_t = INF
    closest = None
    for sphere in spheres:
        t1, t2 = _intersect_ray_sphere(O, D, sphere[0], sphere[1])
        if t_min <= t1 <= t_max and t1 < closest_t:
            closest_t = t1
            closest = sphere
        if t_min <= t2 <= t_max and t2 < closest_t:
            closest_t = t2
            closest = sphere
    return closest, closest_t


def _compute_lighting(spheres, lights, P, N, V, s):
    """Per-channel light intensity at P (normal N, towards-viewer V, specular exponent s)."""
    ir = ig = ib = 0.0
    n_len = math.sqrt(_dot(N, N))
    v_len = math.sqrt(_dot(V, V))
    for kind, (lr, lg, lb), vec in lights:
        if kind == "ambient":
            ir += lr
            ig += lg
            ib += lb
            continue
        if kind == "point":
            L = (vec[0] - P[0], vec[1] - P[1], vec[2] - P[2])
            t_max = 1.0
        else:  # directional
            L = vec
            t_max = INF

        # Shadow check
        shadow_sphere, _ = _closest_intersection(spheres, P, L, SECONDARY_T_MIN, t_max)
        if shadow_sphere is not None:
            continue

        # Diffuse
        n_dot_l = _dot(N, L)
        l_len = math.sqrt(_dot(L, L))
        if n_dot_l > 0.0:
            k = n_dot_l / (n_len * l_len)
            ir += lr * k
            ig += lg * k
            ib += lb * k

        # Specular
        if s is not None:
            R = (2.0 * N[0] * n_dot_l - L[0], 2.0 * N[1] * n_dot_l - L[1], 2.0 * N[2] * n_dot_l - L[2])
            r_dot_v = _dot(R, V)
            if r_dot_v > 0.0:
                k = (r_dot_v / (math.sqrt(_dot(R, R)) * v_len)) ** s
                ir += lr * k
                ig += lg * k
                ib += lb * k
    return ir, ig, ib


def _trace_ray(spheres, lights, background, cast, O, D, t_min, t_max, depth):
    sphere, t = _closest_intersection(spheres, O, D, t_min, t_max)
    if sphere is None:
        return background
    center, _radius, color, specular, reflective = sphere
    if cast:
        return color

    P = (O[0] + t * D[0], O[1] + t * D[1], O[2] + t * D[2])
    N = _normalize(_sub(P, center))
    V = (-D[0], -D[1], -D[2])
    ir, ig, ib = _compute_lighting(spheres, lights, P, N, V, specular)
    local = (color[0] * ir, color[1] * ig, color[2] * ib)

    r = reflective
    if depth <= 0 or r <= 0.0:
        return local

    # ReflectRay(-D, N) = 2 N dot(N, -D) - (-D)
    n_dot_v = _dot(N, V)
    R = (2.0 * N[0] * n_dot_v - V[0], 2.0 * N[1] * n_dot_v - V[1], 2.0 * N[2] * n_dot_v - V[2])
    refl = _trace_ray(spheres, lights, background, cast, P, R, SECONDARY_T_MIN, INF, depth - 1)
    q = 1.0 - r
    return (local[0] * q + refl[0] * r, local[1] * q + refl[1] * r, local[2] * q + refl[2] * r)


def render_reference(scene: dict, width: int, height: int, mode: str = "trace") -> np.ndarray:
    """Render ``scene`` at ``width`` x ``height``; float64 (height, width, 3), unclamped, row 0 on top."""
    if mode not in ("trace", "cast"):
        raise ValueError(f"mode must be 'trace' or 'cast', got {mode!r}")
    width = int(width)
    height = int(height)
    if width <= 0 or height <= 0:
        raise ValueError("width and height must be positive")

    render = scene.get("render", {})
    background = _vec(render.get("background", (0.0, 0.0, 0.0)))
    max_depth = int(render.get("max_depth", DEFAULT_MAX_DEPTH))
    spheres = _prepare_spheres(scene)
    lights = _prepare_lights(scene)
    O, f, r, u, fov = _camera(scene)
    cast = mode == "cast"

    h = math.tan(math.radians(fov) / 2.0)
    w = h * width / height
    sqrt = math.sqrt

    rows = []
    for j in range(height):
        bh = (1.0 - (j + 0.5) / height * 2.0) * h
        row = []
        for i in range(width):
            aw = ((i + 0.5) / width * 2.0 - 1.0) * w
            dx = f[0] + r[0] * aw + u[0] * bh
            dy = f[1] + r[1] * aw + u[1] * bh
            dz = f[2] + r[2] * aw + u[2] * bh
            n = sqrt(dx * dx + dy * dy + dz * dz)
            D = (dx / n, dy / n, dz / n)
            row.append(_trace_ray(spheres, lights, background, cast, O, D, PRIMARY_T_MIN, INF, max_depth))
        rows.append(row)
    return np.array(rows, dtype=np.float64).reshape(height, width, 3)
