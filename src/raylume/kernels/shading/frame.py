"""The shading frame at a surface point, as every integrator that samples BSDFs makes it (path
mode, and bidirectional path tracing's walks and connections), so that they agree on which
side a material sees and on its local directions.

A two-sided material acts on whichever side a ray meets, so its frame turns to face that side;
a dielectric's stays outward (its inside is the medium). A shading normal that points below the
geometric surface is replaced by the geometric normal."""

from ..vec import dot, inline_function, mul
from .lights.sampling import basis


@inline_function
def facing_normals(two_sided, behind, ng, ns):
    """(ng, ns) of shading_frame, without the frame's other two axes."""
    if two_sided and behind:
        ng = mul(ng, -1.0)
        ns = mul(ns, -1.0)
    if dot(ns, ng) <= 0.0:
        ns = ng
    return ng, ns


@inline_function
def shading_frame(two_sided, behind, ng, ns):
    """(ng, ns, s, t) for outward normals ng (geometric) and ns (shading): both turned over
    when the material is two-sided and the incoming side is `behind` ng; (s, t, ns) the
    orthonormal frame of local directions."""
    ng, ns = facing_normals(two_sided, behind, ng, ns)
    s, t = basis(ns)
    return ng, ns, s, t


@inline_function
def to_local(v, s, t, n):
    """World direction v in the frame (s, t, n)."""
    return (dot(v, s), dot(v, t), dot(v, n))


@inline_function
def to_world(v, s, t, n):
    """Local direction v of the frame (s, t, n) in world coordinates."""
    return (
        s[0] * v[0] + t[0] * v[1] + n[0] * v[2],
        s[1] * v[0] + t[1] * v[1] + n[1] * v[2],
        s[2] * v[0] + t[2] * v[1] + n[2] * v[2],
    )
