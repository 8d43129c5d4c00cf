"""Shadow rays of path mode where light may pass things on its way: through index-matched (null)
boundaries, and through participating media, whose transmittance it multiplies in (Mitsuba 3's
volpath does the same). Scenes with neither take any_hit instead (path.py)."""

from ..film.sampler import sub_key
from ..geometry.shapes import NO_HIT, offset_epsilon, surface
from ..geometry.traverse import closest_hit
from ..shading.materials import index_matched
from ..shading.media import medium_beyond, transmittance
from ..vec import dot, hadamard, inline_function, madd

ZERO3 = (0.0, 0.0, 0.0)
# Boundaries one shadow ray passes at most (a guard: a ray grazing a mesh could otherwise
# cross and re-cross it by rounding without end)
MAX_CROSSINGS = 256


@inline_function
def shadow_transmittance(G, F, X, Md, o, d, tmax, med, key, node_stack, t_stack):
    """The fraction of light (RGB) that travels from o along d over (0, tmax) through the media
    and null boundaries in between, starting in medium med; 0 when anything else blocks it."""
    tr = (1.0, 1.0, 1.0)
    for crossing in range(MAX_CROSSINGS):
        t, prim, b1, b2 = closest_hit(G, X, o, d, 0.0, tmax, node_stack, t_stack)
        if med >= 0:
            tr = hadamard(tr, transmittance(Md, med, o, d, t if prim != NO_HIT else tmax, sub_key(key, crossing)))
            if tr[0] == 0.0 and tr[1] == 0.0 and tr[2] == 0.0:
                return tr
        if prim == NO_HIT:
            return tr
        p = madd(o, d, t)
        ng, _, m, obj, _ = surface(G, X, prim, b1, b2, p)
        if not index_matched(F.materials, m):
            return ZERO3
        if Md.present:
            med = medium_beyond(Md, obj, d, ng)
        eps = offset_epsilon(F.epsilon_floor, p)
        o = madd(p, ng, eps if dot(d, ng) > 0.0 else -eps)
        tmax -= t
    return ZERO3
