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
