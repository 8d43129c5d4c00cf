"""Bidirectional path tracing's subpath vertices, and the densities its MIS weights are made of
(pbrt-v4's `Vertex`: f, PDF, PdfLight, PdfLightOrigin, ConvertDensity).

A subpath is a float64 array (vertices, V_WIDTH), one row per vertex: its point, geometric and
shading normals (outward, as `surface` gives them), the unit direction towards the vertex before
it on its own subpath (wo), the throughput beta of the subpath up to it, the colour of its
material there, for lights at infinity the direction towards the light, the forward and reverse
area densities (pdfFwd: the density with which its own subpath made it, pdfRev: with which the
other subpath would), its kind and flags, its material row, its light row and its hit, and for
participating media the medium it lies in (a surface: the medium its subpath's ray arrived
through), its object and a medium vertex's Henyey-Greenstein asymmetry.

Kinds: CAMERA (a point on the lens), LIGHT (a point on a light; a light at infinity, whose point
is a direction; an area light that a camera subpath met, which ends it), SURFACE and MEDIUM (a
scattering in a participating medium: the phase function in place of a BSDF, no normal, so its
area densities have no cosine, pbrt-v3's ConvertDensity). Densities of vertices at infinity are
solid angles (pbrt's convention)."""

import math
from typing import NamedTuple

import numpy as np

from ..film.camera import camera_importance
from ..geometry.shapes import NO_HIT
from ..scene import Emitters, Geometry, Media, Surfaces
from ..shading.environment import Environment, environment_pdf
from ..shading.frame import shading_frame, to_local
from ..shading.lights import emission_pdf, pick_probability
from ..shading.lights.sampling import disk_density
from ..shading.materials import bsdf_eval, delta_only, two_sided
from ..shading.media import hg_eval, medium_leaving
from ..vec import dot, inline_function, mul, row3, sub

INF = math.inf
V_P = 0
V_NG = 3
V_NS = 6
V_WO = 9
V_BETA = 12
V_COLOUR = 15
V_DIR = 18  # a light at infinity: the unit direction towards it
V_PDF_FWD = 21
V_PDF_REV = 22
V_KIND = 23
V_DELTA = 24  # 1: the BSDF sample that left this vertex was a delta lobe
V_FLAGS = 25
V_M = 26  # material row (-1: none)
V_E = 27  # light row (-1: none; a surface that emits without a light row: not sampled by lights)
V_HIT = 28  # the primitive (or instance hit) of a surface or of a point on an emissive primitive
V_MED = 29  # the medium (-1: none) of a medium vertex; a surface's: the one its ray arrived in
V_OBJ = 30  # a surface's object (which media lie on its two sides)
V_G = 31  # a medium vertex's Henyey-Greenstein asymmetry
V_WIDTH = 32

CAMERA = 0
LIGHT = 1
SURFACE = 2
MEDIUM = 3
F_INFINITE = 1  # a light at infinity (ambient, environment, directional; an escaped camera ray)
F_DELTA_LIGHT = 2  # a point, spot or directional light
F_ON_SURFACE = 4  # a light vertex with a normal: area lights, emissive surfaces
F_EMISSIVE = 8  # a surface that emits (a camera subpath counts its emission, s = 0)
UNION = -1  # V_E of an escaped camera ray: every light at infinity together
UNREACHABLE = -1.0  # a reverse density of a vertex no light subpath can reach (bdpt_mis.py)


class Context(NamedTuple):
    """What the densities need: the scene's views, the camera and image size, the bounding sphere
    B = (centre x, y, z, radius) from which lights at infinity send their rays."""

    G: Geometry
    F: Surfaces
    X: object
    Em: Emitters
    Env: Environment
    Md: Media
    cam: np.ndarray
    B: np.ndarray
    width: int
    height: int
    background: tuple  # what a camera ray that leaves a scene without lights at infinity sees
    glint: np.ndarray  # the glint strategy's guide as a cdf over the image's pixels; (1,) without (bdpt_glint.py)
    pixel_filter: np.ndarray  # the film's pixel filter (film.filter_array)


@inline_function
def put_vertex(V, i, kind, p, ng, ns, wo, beta, pdf_fwd, m, e, colour, hit, flags):
    """Write vertex i (not delta, pdfRev 0, no direction at infinity)."""
    for c in range(3):
        V[i, V_P + c] = p[c]
        V[i, V_NG + c] = ng[c]
        V[i, V_NS + c] = ns[c]
        V[i, V_WO + c] = wo[c]
        V[i, V_BETA + c] = beta[c]
        V[i, V_COLOUR + c] = colour[c]
        V[i, V_DIR + c] = 0.0
    V[i, V_PDF_FWD] = pdf_fwd
    V[i, V_PDF_REV] = 0.0
    V[i, V_KIND] = kind
    V[i, V_DELTA] = 0.0
    V[i, V_FLAGS] = flags
    V[i, V_M] = m
    V[i, V_E] = e
    V[i, V_HIT] = hit
    V[i, V_MED] = -1.0
    V[i, V_OBJ] = -1.0
    V[i, V_G] = 0.0


@inline_function
def put_medium_vertex(V, i, p, wo, beta, med, g):
    """Write medium vertex i: a scattering at p in medium med (asymmetry g), wo towards the
    vertex before it."""
    put_vertex(V, i, MEDIUM, p, wo, wo, wo, beta, 0.0, -1, -1, (0.0, 0.0, 0.0), NO_HIT, 0)
    V[i, V_MED] = med
    V[i, V_G] = g


@inline_function
def kind_of(V, i):
    return int(V[i, V_KIND])


@inline_function
def has_flag(V, i, flag):
    return (int(V[i, V_FLAGS]) & flag) != 0


@inline_function
def on_surface(V, i):
    return kind_of(V, i) == SURFACE or has_flag(V, i, F_ON_SURFACE)


@inline_function
def is_light(V, i):
    """Does the vertex emit (a light, or a surface that emits)?"""
    return kind_of(V, i) == LIGHT or (kind_of(V, i) == SURFACE and has_flag(V, i, F_EMISSIVE))


@inline_function
def is_delta_light(V, i):
    return kind_of(V, i) == LIGHT and has_flag(V, i, F_DELTA_LIGHT)


@inline_function
def connectible(F, V, i):
    """Can a connection end at the vertex? Not at a surface whose every lobe is a delta, not at a
    directional light, not at a light a camera subpath met (pbrt's IsConnectible and the rule
    that a camera subpath's light vertex is only for s = 0)."""
    k = kind_of(V, i)
    if k == CAMERA or k == MEDIUM:
        return True
    if k == LIGHT:
        return not (has_flag(V, i, F_INFINITE) and has_flag(V, i, F_DELTA_LIGHT))
    return not delta_only(F.materials, int(V[i, V_M]))


@inline_function
def toward(A, i, N, k):
    """The unit direction from vertex A[i] to N[k] and the squared distance (inf towards or from
    a light at infinity; 0: the same point)."""
    if has_flag(N, k, F_INFINITE) and kind_of(N, k) == LIGHT:
        return row3(N, k, V_DIR), INF
    if has_flag(A, i, F_INFINITE) and kind_of(A, i) == LIGHT:
        return mul(row3(A, i, V_DIR), -1.0), INF
    w = sub(row3(N, k, V_P), row3(A, i, V_P))
    d2 = dot(w, w)
    if not (d2 > 0.0):
        return (0.0, 0.0, 1.0), 0.0
    return mul(w, 1.0 / math.sqrt(d2)), d2


@inline_function
def convert_density(pdf, A, i, N, k):
    """A solid-angle density at A[i] towards N[k] as an area density at N[k] (pbrt's
    ConvertDensity; unchanged towards a light at infinity)."""
    if kind_of(N, k) == LIGHT and has_flag(N, k, F_INFINITE):
        return pdf
    w, d2 = toward(A, i, N, k)
    if not (d2 > 0.0) or d2 == INF:
        return 0.0
    if on_surface(N, k):
        pdf *= abs(dot(row3(N, k, V_NG), w))
    return pdf / d2


@inline_function
def surface_bsdf(F, V, i, wo_w, wi_w):
    """(f, pdf of wi given wo) of surface vertex V[i] for the world directions wo (the
    radiance's way out: towards the camera's side) and wi (towards the light's side). A
    two-sided material faces wo's side (shading/frame.py) and sees nothing from the other side."""
    mat = F.materials
    m = int(V[i, V_M])
    ng = row3(V, i, V_NG)
    ns = row3(V, i, V_NS)
    two = two_sided(mat, m)
    ng, ns, s_axis, t_axis = shading_frame(two, dot(wo_w, ng) < 0.0, ng, ns)
    if two and not dot(wi_w, ng) > 0.0:
        return (0.0, 0.0, 0.0), 0.0
    wo = to_local(wo_w, s_axis, t_axis, ns)
    wi = to_local(wi_w, s_axis, t_axis, ns)
    colour = row3(V, i, V_COLOUR)
    return bsdf_eval(mat, m, colour, wo, wi)


@inline_function
def shading_correction(ng, ns, w_prev, w_next):
    """Veach's adjoint BSDF factor for importance at a surface with shading normals (thesis
    5.3): |w_prev.ns| |w_next.ng| / (|w_prev.ng| |w_next.ns|); 1 where ns = ng."""
    den = abs(dot(w_prev, ng)) * abs(dot(w_next, ns))
    if not (den > 0.0):
        return 0.0
    return abs(dot(w_prev, ns)) * abs(dot(w_next, ng)) / den


@inline_function
def vertex_f(F, V, i, w_next, importance):
    """f at surface vertex V[i] towards w_next (the other subpath's vertex), coming from its
    own subpath's vertex before it: radiance on a camera subpath, importance on a light subpath
    (the adjoint: light flows from the previous vertex on to w_next, with the shading-normal
    correction); the phase function at a medium vertex, the same both ways."""
    w_prev = row3(V, i, V_WO)
    if kind_of(V, i) == MEDIUM:
        phase = hg_eval(V[i, V_G], -dot(w_prev, w_next))
        return (phase, phase, phase)
    if importance:
        f, _ = surface_bsdf(F, V, i, w_next, w_prev)
        return mul(f, shading_correction(row3(V, i, V_NG), row3(V, i, V_NS), w_prev, w_next))
    f, _ = surface_bsdf(F, V, i, w_prev, w_next)
    return f


@inline_function
def covered(B, p, to_light):
    """Can the rays a light at infinity sends from the bounding sphere's disk reach p? (Not
    beyond the sphere: planes reach past it.)"""
    rel = (p[0] - B[0], p[1] - B[1], p[2] - B[2])
    along = dot(rel, to_light)
    return along <= B[3] and dot(rel, rel) - along * along <= B[3] * B[3]


@inline_function
def infinite_density(C, to_light):
    """The density with which light subpaths leave the lights at infinity towards -to_light:
    their pick probabilities times their direction pdfs, summed (pbrt's InfiniteLightDensity)."""
    Em = C.Em
    pdf = 0.0
    if Em.ambient_row >= 0:
        pdf += pick_probability(Em.cdf, Em.ambient_row) * (0.25 / math.pi)
    if Em.environment_row >= 0:
        pdf += pick_probability(Em.cdf, Em.environment_row) * environment_pdf(C.Env, to_light)
    return pdf


@inline_function
def pdf_light(C, A, i, N, k):
    """The area density at N[k] of light vertex A[i]'s emission towards it (pbrt's PdfLight)."""
    if has_flag(A, i, F_INFINITE) and kind_of(A, i) == LIGHT:
        to_light = row3(A, i, V_DIR)
        w = mul(to_light, -1.0)
        # UNREACHABLE where the disk's rays cannot reach N: no strategy that starts there makes
        # the path (a zero would read as a delta's, remap0)
        pdf = disk_density(C.B) if covered(C.B, row3(N, k, V_P), to_light) else UNREACHABLE
    else:
        w, d2 = toward(A, i, N, k)
        if not (d2 > 0.0):
            return 0.0
        e = int(A[i, V_E])
        if e < 0:
            return 0.0
        _, _, pdf_dir = emission_pdf(
            C.G, C.X, C.Em, C.Env, e, row3(A, i, V_P), row3(A, i, V_NG), w, np.int64(A[i, V_HIT]), C.B
        )
        pdf = pdf_dir / d2
    if on_surface(N, k):
        pdf *= abs(dot(row3(N, k, V_NG), w))
    return pdf


@inline_function
def pdf_light_origin(C, A, i, N, k):
    """The density with which a light subpath starts at light vertex A[i] (towards N[k]): the
    light's pick probability times its position density (pbrt's PdfLightOrigin); UNREACHABLE
    where no light subpath can start there (a light of pick probability 0: the sky of a scene
    with no bounded geometry, whose power scales with its extent). A 0 would read as a delta's
    density in the ratio walk (remap0) and credit strategies that never make the path."""
    if has_flag(A, i, F_INFINITE) and kind_of(A, i) == LIGHT:
        pdf = infinite_density(C, row3(A, i, V_DIR))
        return pdf if pdf > 0.0 else UNREACHABLE
    e = int(A[i, V_E])
    if e < 0:
        return 0.0
    w, d2 = toward(A, i, N, k)
    if not (d2 > 0.0):
        return 0.0
    _, pdf_pos, _ = emission_pdf(
        C.G, C.X, C.Em, C.Env, e, row3(A, i, V_P), row3(A, i, V_NG), w, np.int64(A[i, V_HIT]), C.B
    )
    pick = pick_probability(C.Em.cdf, e)
    return pick * pdf_pos if pick > 0.0 else UNREACHABLE


@inline_function
def vertex_pdf(C, A, i, P, j, N, k):
    """The area density at N[k] with which vertex A[i], reached from P[j] (none for the camera),
    samples the direction towards N[k] (pbrt's Vertex::PDF)."""
    kind = kind_of(A, i)
    if kind == LIGHT:
        return pdf_light(C, A, i, N, k)
    wn, d2 = toward(A, i, N, k)
    if not (d2 > 0.0):
        return 0.0
    if kind == CAMERA:
        _, pdf, _, _ = camera_importance(C.cam, C.width, C.height, row3(A, i, V_P), wn)
    elif kind == MEDIUM:
        wp, d2p = toward(A, i, P, j)
        if not (d2p > 0.0):
            return 0.0
        pdf = hg_eval(A[i, V_G], -dot(wp, wn))
    else:
        wp, d2p = toward(A, i, P, j)
        if not (d2p > 0.0):
            return 0.0
        _, pdf = surface_bsdf(C.F, A, i, wp, wn)
    return convert_density(pdf, A, i, N, k)


@inline_function
def cosine_at(V, i, w):
    """|cos| between w and the shading normal of vertex V[i]; 1 at a medium vertex (no normal)."""
    if kind_of(V, i) == MEDIUM:
        return 1.0
    return abs(dot(row3(V, i, V_NS), w))


@inline_function
def medium_towards(C, V, i, w):
    """The medium a connection leaving vertex V[i] along w starts in: a medium vertex's own; at
    a surface, the one its ray arrived in if w leaves on that side, else the medium beyond the
    surface (path mode's rule for its shadow rays); the camera's otherwise."""
    Md = C.Md
    kind = kind_of(V, i)
    if kind == MEDIUM:
        return int(V[i, V_MED])
    if kind != SURFACE:
        return Md.camera
    d_in = mul(row3(V, i, V_WO), -1.0)
    return medium_leaving(Md, int(V[i, V_MED]), int(V[i, V_OBJ]), d_in, row3(V, i, V_NG), w)


NO_VERTEX_HIT = NO_HIT
