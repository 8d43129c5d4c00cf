"""The light kinds, and the one dispatch over them for each question the integrators ask.

KINDS is the registry: one module per kind, each defining NAME, KIND (its number in the light
table's kind column), its flags, `power` (host side, for path mode's light distribution; its
arguments are the kind's own), and the kernel functions path mode calls, `sample` (a direction
towards the light, its distance, the radiance arriving, the solid-angle pdf, delta) and `pdf`
(that pdf for a direction a BSDF sample found, for MIS), kinds sampled by a point uniform over
a surface also `surface_point` (that point, which `sample` takes on from), and for
bidirectional path tracing's light subpaths `emit` (a point on the light, a direction leaving
it, the radiance or intensity along it, the position and direction pdfs, as pbrt's SampleLe)
and `emit_pdf` (those for a given point and direction, pbrt's PDF_Le; lights at infinity start
from the disk of the scene's bounding sphere
that faces them). The scene's own lights (SCENE_KINDS)
also have `pack` (model light -> table row) and trace mode's `trace_sample` (a point on the
light seen from a shading point, in the seed's units: the lecture's ComputeLighting).

Flags: DELTA (a single point or direction: no random numbers, no MIS), INFINITE (at infinity),
VISIBLE (rays see it beside the BVH: the area lights, path mode), FALLOFF (trace mode scales
its intensity by `falloff` of the direction), EVERYWHERE (trace mode adds its intensity
unshadowed: the seed's ambient light).

The switches (kernels/switch.py) compare the row's kind with each module's KIND in turn; a kind
no module defines gets no light, never another kind's answer."""

import numpy as np

from ...switch import kind_switch
from ...vec import inline_function, kernel_function
from . import ambient, directional, environment, instanced, point, quad, sphere, spot, surface
from .sampling import NO_EMISSION

KINDS = (ambient, point, directional, quad, sphere, spot, surface, environment, instanced)
SCENE_KINDS = (ambient, point, directional, quad, sphere, spot)  # the scene's [[lights]] types
BY_NAME = {kind.NAME: kind for kind in KINDS}
assert sorted(kind.KIND for kind in KINDS) == list(range(len(KINDS)))

_NONE = ((0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, False)  # no sample
_PATH = "G, X, Em, Env, e, p"


def _flag(name: str):
    """A kernel function of a kind: its flag `name` (False for a kind no module defines), read
    from a bit mask of the kinds that have it."""
    mask = sum(1 << k.KIND for k in KINDS if getattr(k, name))

    @inline_function
    def flag(kind):
        return kind >= 0 and kind < 63 and (mask >> kind) & 1 != 0

    return flag


is_delta = _flag("DELTA")
is_everywhere = _flag("EVERYWHERE")
has_falloff = _flag("FALLOFF")
at_infinity = _flag("INFINITE")

# path mode: emitter row e seen from p
sample_light = kind_switch("sample", f"{_PATH}, u1, u2, key", "Em.kind[e]", KINDS, _NONE, inline_function)
light_pdf = kind_switch("pdf", f"{_PATH}, wi, dist, n_hit, hit", "Em.kind[e]", KINDS, 0.0, kernel_function)
# the kinds whose sample is a point uniform over a surface: (whether this row's is, the point, its
# unit normal, the surface's area, its radiance), from which `sample` makes the direction and the
# solid-angle pdf seen from p (sampling.towards_point); path mode's wavefront does that step SIMD
light_point = kind_switch(
    "light_point", "G, X, Em, e, u1, u2", "Em.kind[e]", [k for k in KINDS if hasattr(k, "surface_point")],
    (False, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0)), inline_function, attribute="surface_point",
)  # fmt: skip
# bidirectional path tracing: light leaving emitter row e (a point, its normal, a direction, the
# radiance or intensity along it, the position and direction pdfs, the hit of the point), and
# those for a given point and direction (B: the scene's bounding sphere, for lights at infinity)
sample_emission = kind_switch(
    "emit", "G, X, Em, Env, e, u1, u2, u3, u4, key, B", "Em.kind[e]", KINDS, NO_EMISSION, kernel_function
)
emission_pdf = kind_switch(
    "emit_pdf", "G, X, Em, Env, e, p, n, w, hit, B", "Em.kind[e]", KINDS, ((0.0, 0.0, 0.0), 0.0, 0.0), kernel_function
)
# the primitive a light row's points lie on (kinds that are primitives: surface), NO_HIT (-1) for
# the others: what a shadow ray towards it ends short of
light_primitive = kind_switch(
    "primitive", "Em, e", "Em.kind[e]", [k for k in KINDS if hasattr(k, "primitive")], np.int64(-1), inline_function
)
# bdpt: does a light outside the BVH hide its own sampled point (the far side of a sphere light)
hides_own_point = kind_switch(
    "hides", "Em, e, p, n, w", "Em.kind[e]", [k for k in KINDS if hasattr(k, "hides")], False, inline_function
)
visible_hit = kind_switch(
    "hit", "Em, e, o, d, tmax", "Em.kind[e]", [k for k in KINDS if k.VISIBLE], (np.inf, (0.0, 0.0, 1.0)),
    inline_function,
)  # fmt: skip
# trace mode: light k seen from p, delta lights inline, area lights by a call (direct.py)
trace_delta = kind_switch(
    "trace_sample", "L, k, p, u1, u2", "L.kind[k]", [k for k in SCENE_KINDS if k.DELTA], ((0.0, 0.0, 1.0), 0.0),
    inline_function,
)  # fmt: skip
trace_area = kind_switch(
    "trace_sample", "L, k, p, u1, u2", "L.kind[k]",
    [k for k in SCENE_KINDS if not k.DELTA and not k.EVERYWHERE], ((0.0, 0.0, 1.0), 0.0), kernel_function,
)  # fmt: skip
trace_falloff = kind_switch(
    "trace_falloff", "L, k, l", "L.kind[k]", [k for k in SCENE_KINDS if k.FALLOFF], 1.0, inline_function
)


def visible_bounds(kind: int, row: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) of the box around a light that rays see beside the BVH (its kind's `bounds`), or
    None for a kind without one."""
    module = next((k for k in KINDS if k.KIND == kind), None)
    return module.bounds(row) if module is not None and hasattr(module, "bounds") else None


def pack_light(light) -> tuple[int, np.ndarray]:
    """(kind, table row) of a model light (scene/model.py's light classes)."""
    kind = BY_NAME.get(light.type)
    if kind not in SCENE_KINDS:
        raise ValueError(f"unknown light type {light.type!r} (known: {', '.join(k.NAME for k in SCENE_KINDS)})")
    return kind.KIND, kind.pack(light)
