"""Which medium lies on each side of an object's surface: the kernels' interface table, int32
(objects, 2), the medium inside (column 0) and outside (column 1), -1 for none. The compile
stage (compile/media.py) fills it: inside is the object's `interior`, outside the medium of the
innermost object around it, or the scene's outer medium."""

from ...vec import dot, inline_function


@inline_function
def medium_beyond(Md, obj, d, ng):
    """The medium a ray travelling along d enters when it crosses object obj's surface (outward
    geometric normal ng)."""
    return Md.interface[obj, 0] if dot(d, ng) < 0.0 else Md.interface[obj, 1]


@inline_function
def medium_leaving(Md, med, obj, d, ng, w):
    """The medium a ray leaving object obj's surface along w travels in, the surface having been
    reached along d through medium med: med where w goes back to d's side (a reflection), the
    medium beyond the surface where it crosses (a transmission, or a shadow ray towards the other
    side). ng: the outward geometric normal."""
    if Md.present and (dot(w, ng) < 0.0) == (dot(d, ng) < 0.0):
        return medium_beyond(Md, obj, d, ng)
    return med
