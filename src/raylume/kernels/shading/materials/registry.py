"""The material kinds, and the one dispatch over them for each question the integrators ask.

KINDS is the registry: one module per kind, each defining NAME (the scene's `type`), KIND (its
number in the table's MAT_KIND column), SOLID (clear inside without an interior medium: media),
`pack` and `trace_approximation` (host side), and the
kernel functions `evaluate`, `sample`, `delta_only`, `two_sided` and `aov_albedo` (lobes.py
gives their conventions). The switches below are made from KINDS (kernels/switch.py): for each question,
one function that compares the row's kind with each module's KIND in turn and returns that
module's answer, and for a kind that no module defines (never: compile/materials.py packs only registered
kinds) a failure, never another kind's answer."""

from ...switch import kind_switch
from ...vec import inline_function, kernel_function, mul
from . import conductor, dielectric, diffuse, null, phong, plastic
from .lobes import EVALUATE, FAILED, ZERO
from .table import MAT_IOR, MAT_KIND, MAT_REFLECTIVE, MAT_SPECULAR, MAT_TRANSPARENCY

KINDS = (phong, diffuse, conductor, dielectric, plastic, null)
BY_NAME = {kind.NAME: kind for kind in KINDS}
assert sorted(kind.KIND for kind in KINDS) == list(range(len(KINDS))), "KIND numbers: 0, 1, ... in any order"


def _switch(question: str, params: str, unknown, decorator):
    return kind_switch(question, params, f"int(mat[m, {MAT_KIND}])", KINDS, unknown, decorator)


# (f, pdf) of material row m for the unit local directions wo, wi (lobes.py)
bsdf_eval = _switch("evaluate", "mat, m, color, wo, wi", (ZERO, 0.0), kernel_function)
# (wi, weight, pdf, delta) as the kind's module returns it (pdf EVALUATE: weigh with evaluate)
sample_lobe = _switch("sample", "mat, m, color, wo, u0, u1, u2", FAILED, inline_function)
# every lobe a delta: next-event estimation cannot reach the material
delta_only = _switch("delta_only", "mat, m", True, inline_function)
# acts on whichever side a ray meets (the path's shading frame turns to face the ray)
two_sided = _switch("two_sided", "mat, m", True, inline_function)
# the `albedo` AOV (and the denoiser's guide) of row m whose colour at the hit is `color`
aov_albedo = _switch("aov_albedo", "mat, m, color", ZERO, inline_function)


@inline_function
def is_diffuse(mat, m):
    """A Lambertian surface: path mode's wavefront shades these together (path_wavefront.py)."""
    return int(mat[m, MAT_KIND]) == diffuse.KIND


# and the diffuse kind's direction sample as its vector loop takes it
diffuse_lane_sample = diffuse.lane_sample


@inline_function
def index_matched(mat, m):
    """A boundary that light passes unchanged (the null kind): path mode steps through it without
    a path vertex, and its shadow rays see through it."""
    return int(mat[m, MAT_KIND]) == null.KIND


@inline_function  # one call site (path.py); a call cost ~25 ns a bounce
def bsdf_sample(mat, m, color, wo, u0, u1, u2):
    """(wi, weight, pdf, delta) of material row m for wo, from uniforms u0 (the lobe), u1, u2
    (the direction) in [0, 1): a delta lobe, or a lobe whose weight the kind knows (diffuse), as
    its kind returns it, any other direction weighted f |cos wi| / pdf with the f and pdf of all
    the kind's lobes (evaluate)."""
    if wo[2] == 0.0:
        return FAILED
    wi, w, pdf, delta = sample_lobe(mat, m, color, wo, u0, u1, u2)
    if pdf != EVALUATE:
        return wi, w, pdf, delta
    f, pdf = bsdf_eval(mat, m, color, wo, wi)
    if not (pdf > 0.0 and pdf - pdf == 0.0):  # 0, inf or NaN (x - x is NaN for inf)
        return FAILED
    w = mul(f, abs(wi[2]) / pdf)
    if not (w[0] - w[0] == 0.0 and w[1] - w[1] == 0.0 and w[2] - w[2] == 0.0):
        return FAILED
    return wi, w, pdf, False


@inline_function
def radiance_factor(mat, m, wo, wi):
    """The radiance factor (n_wo / n_wi)^2 in the weight of a sample from wo to wi (local frame)
    that radiance transport has (lobes.py; a rough refraction's BTDF the same): 1 for every
    direction on wo's side. Kinds that refract keep their index in MAT_IOR (the null boundary 1)."""
    ior = mat[m, MAT_IOR]
    if (wo[2] > 0.0) == (wi[2] > 0.0) or not (ior > 0.0):
        return 1.0
    ratio = 1.0 / ior if wo[2] > 0.0 else ior  # n on wo's side / n on wi's side
    return ratio * ratio


@inline_function
def importance_delta_weight(mat, m, wo, wi, weight):
    """The weight of a delta sample (wi from wo, as `bsdf_sample` gave it) for importance, as a
    light subpath carries it (pbrt's TransportMode::Importance): a delta refraction's weight
    loses the radiance factor that radiance transport has; every other delta lobe (mirrors, the
    null boundary of index 1) is the same both ways."""
    return mul(weight, 1.0 / radiance_factor(mat, m, wo, wi))


def pack_material(mat, row) -> None:
    """The columns of a model material's table row that its kind decides: the kind, its
    trace-mode approximation in the phong columns, and the kind's own (its module's `pack`)."""
    kind = kind_module(mat.type)
    row[MAT_KIND] = kind.KIND
    row[MAT_SPECULAR], row[MAT_REFLECTIVE], row[MAT_TRANSPARENCY] = kind.trace_approximation(mat)
    kind.pack(mat, row)


def is_solid(mat) -> bool:
    """Whether a model material makes a closed object a solid, clear inside when it has no
    interior medium (dielectrics), rather than filled with the medium around it."""
    return kind_module(mat.type).SOLID


def kind_module(name: str):
    """The module of the material kind `name` (a scene's `type`); an unknown one is a ValueError."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise ValueError(f"unknown material type {name!r} (known: {', '.join(BY_NAME)})") from None
