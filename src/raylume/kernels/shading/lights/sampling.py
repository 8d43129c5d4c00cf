"""What the light kinds share for sampling: the frame about a direction, the solid-angle pdf of a
point sampled on a surface, the cone a sphere subtends, and the last step towards a point."""

import math

from ...film.sampler import concentric_disk, uniform_sphere
from ...geometry.shape_sphere import intersect_sphere
from ...vec import dot, inline_function, kernel_function, length, madd, mul, normalize, sub, turn

INF = math.inf


@kernel_function
def basis(w):
    """Two unit vectors completing the unit w to an orthonormal basis (Duff et al. 2017)."""
    sign = 1.0 if w[2] >= 0.0 else -1.0
    a = -1.0 / (sign + w[2])
    b = w[0] * w[1] * a
    return (1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]), (b, sign + w[1] * w[1] * a, -w[1])


@inline_function
def about(axis, cos_t, sin_t, u):
    """The unit direction at angle t (its cos_t and sin_t) from the unit axis, at the fraction u
    of a turn around it in basis(axis)'s frame."""
    c, s = turn(u)
    e1, e2 = basis(axis)
    return normalize(madd(madd(mul(axis, cos_t), e1, sin_t * c), e2, sin_t * s))


@inline_function
def area_pdf(p, q, n, area):
    """Solid-angle pdf at p of a point q (normal n) sampled uniformly on a surface of `area`."""
    to_q = sub(q, p)
    dist2 = dot(to_q, to_q)
    # dist^2 / (area cos) with cos = |n . to_q| / dist: one division, not two in a chain
    facing = abs(dot(n, to_q)) * area
    if not facing > 0.0:  # edge-on, no area, or q = p
        return 0.0
    return dist2 * math.sqrt(dist2) / facing


@inline_function
def towards_point(p, q, n, area, radiance):
    """A sample of radiance at the point q (normal n) of a surface of `area` sampled uniformly,
    seen from p: (wi, distance, radiance, solid-angle pdf, delta False)."""
    to_q = sub(q, p)
    dist = length(to_q)
    if dist <= 0.0:
        return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, False
    wi = mul(to_q, 1.0 / dist)
    return wi, dist, radiance, area_pdf(p, q, n, area), False


@kernel_function
def sphere_cone(centre, radius, p, u1, u2):
    """A direction towards the sphere, uniform over the cone it subtends from p (pbrt), its
    distance and pdf; from inside, a uniform point on the sphere (pdf converted)."""
    to_c = sub(centre, p)
    dist2 = dot(to_c, to_c)
    if dist2 <= radius * radius * (1.0 + 1e-9):
        n = uniform_sphere(u1, u2)
        q = madd(centre, n, radius)
        to_q = sub(q, p)
        dist = length(to_q)
        if dist <= 0.0:
            return (0.0, 0.0, 1.0), 0.0, 0.0
        return mul(to_q, 1.0 / dist), dist, area_pdf(p, q, n, 4.0 * math.pi * radius * radius)
    dc = math.sqrt(dist2)
    w = mul(to_c, 1.0 / dc)
    sin2_max = radius * radius / dist2
    cos_max = math.sqrt(max(0.0, 1.0 - sin2_max))
    cos_t = 1.0 - u1 * (1.0 - cos_max)
    sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
    wi = about(w, cos_t, sin_t, u2)
    dist = intersect_sphere(p, wi, centre, radius, 0.0, INF)
    if dist == INF:  # a direction on the cone's rim, missed by rounding: the tangent point
        dist = dot(wi, to_c)
    return wi, dist, 1.0 / (2.0 * math.pi * (1.0 - cos_max))


@kernel_function
def sphere_cone_pdf(centre, radius, p, wi, dist):
    """The pdf with which sphere_cone(centre, radius, p) gives wi (meeting the sphere at dist)."""
    to_c = sub(centre, p)
    dist2 = dot(to_c, to_c)
    if dist2 <= radius * radius * (1.0 + 1e-9):
        q = madd(p, wi, dist)
        return area_pdf(p, q, normalize(sub(q, centre)), 4.0 * math.pi * radius * radius)
    cos_max = math.sqrt(max(0.0, 1.0 - radius * radius / dist2))
    return 1.0 / (2.0 * math.pi * (1.0 - cos_max))


# --- emission (bidirectional path tracing's light subpaths: each kind's `emit` / `emit_pdf`) ---


@kernel_function
def cosine_about(n, u1, u2):
    """A direction about the unit n with density cos / pi (cos = its cosine with n)."""
    return about(n, math.sqrt(max(0.0, 1.0 - u1)), math.sqrt(u1), u2)


@kernel_function
def cosine_two_sided(n, u1, u2):
    """A direction leaving a two-sided emitter of unit normal n: either side (u1 < 1/2: n's),
    then cosine-distributed there; density |cos| / (2 pi)."""
    if u1 < 0.5:
        return cosine_about(n, 2.0 * u1, u2)
    return cosine_about(mul(n, -1.0), min(2.0 * u1 - 1.0, 1.0), u2)


@inline_function
def two_sided_pdf(n, w):
    """The density of cosine_two_sided's direction w."""
    return abs(dot(n, w)) * (0.5 / math.pi)


@kernel_function
def disk_origin(B, to_light, u1, u2):
    """The origin of a ray from a light at infinity seen along to_light: a point on the disk of
    the scene's bounding sphere B = (centre x, y, z, radius) that faces the light, outside the
    sphere (pbrt's planar sampling), and its density 1 / (pi R^2)."""
    e1, e2 = basis(to_light)
    a, b = concentric_disk(u1, u2)
    r = B[3]
    c = (B[0], B[1], B[2])
    p = madd(madd(madd(c, to_light, r), e1, a * r), e2, b * r)
    return p, 1.0 / (math.pi * r * r)


@inline_function
def disk_density(B):
    return 1.0 / (math.pi * B[3] * B[3])


NO_EMISSION = ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), 0.0, 0.0, -1)
