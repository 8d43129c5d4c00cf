"""The MIS weight of a bidirectional strategy (s light vertices, t camera vertices), as pbrt-v4's
BDPTIntegrator computes it (MISWeight; Veach's thesis, 10.2): the balance heuristic over every
strategy that could have made the same path, found by walking the ratio of reverse to forward
densities along both subpaths from the connection outwards. Delta vertices have no density
(remap0: a ratio of 1) and cannot be connection points: strategies that would connect at them,
or at a delta light, are left out of the sum.

The connection changes four reverse densities (those at and next to the two connection
vertices) and, for s = 1 and t = 1, a vertex itself (the caller writes the light or lens point it
sampled into the subpath's row and restores it after); they are set here for the strategy and
restored before returning."""

from ..vec import inline_function, kernel_function
from .bdpt_vertex import (
    V_DELTA,
    V_PDF_FWD,
    V_PDF_REV,
    is_delta_light,
    pdf_light,
    pdf_light_origin,
    vertex_pdf,
)


@inline_function
def remap0(x):
    return x if x != 0.0 else 1.0


@inline_function
def ratio(rev, fwd):
    """A step of the ratio walk: rev / fwd with delta densities (0) taken as 1; 0 past a vertex
    that no light subpath reaches (UNREACHABLE: a light at infinity shines from the bounding
    sphere's disk, and a plane reaches beyond it), which ends the strategies beyond it."""
    if rev < 0.0:
        return 0.0
    return remap0(rev) / remap0(fwd)


@kernel_function
def mis_weight(C, Vc, Vl, s, t):
    """The balance-heuristic weight of strategy (s, t) for the path made of light subpath
    Vl[0:s] and camera subpath Vc[0:t] (t >= 1)."""
    if s + t == 2:
        return 1.0
    pt = t - 1
    qs = s - 1
    ptm = t - 2
    qsm = s - 2
    # what the strategy changes, kept to restore
    pt_delta = Vc[pt, V_DELTA]
    pt_rev = Vc[pt, V_PDF_REV]
    qs_delta = Vl[qs, V_DELTA] if s > 0 else 0.0
    qs_rev = Vl[qs, V_PDF_REV] if s > 0 else 0.0
    ptm_rev = Vc[ptm, V_PDF_REV] if t > 1 else 0.0
    qsm_rev = Vl[qsm, V_PDF_REV] if s > 1 else 0.0

    Vc[pt, V_DELTA] = 0.0
    if s > 0:
        Vl[qs, V_DELTA] = 0.0
        Vc[pt, V_PDF_REV] = vertex_pdf(C, Vl, qs, Vl, qsm, Vc, pt)
    else:
        Vc[pt, V_PDF_REV] = pdf_light_origin(C, Vc, pt, Vc, ptm)
    if t > 1:
        if s > 0:
            Vc[ptm, V_PDF_REV] = vertex_pdf(C, Vc, pt, Vl, qs, Vc, ptm)
        else:
            Vc[ptm, V_PDF_REV] = pdf_light(C, Vc, pt, Vc, ptm)
    if s > 0:
        Vl[qs, V_PDF_REV] = vertex_pdf(C, Vc, pt, Vc, ptm, Vl, qs)
    if s > 1:
        Vl[qsm, V_PDF_REV] = vertex_pdf(C, Vl, qs, Vc, pt, Vl, qsm)

    total = 0.0
    ri = 1.0
    for i in range(t - 1, 0, -1):
        ri *= ratio(Vc[i, V_PDF_REV], Vc[i, V_PDF_FWD])
        if Vc[i, V_DELTA] == 0.0 and Vc[i - 1, V_DELTA] == 0.0:
            total += ri
    ri = 1.0
    for i in range(s - 1, -1, -1):
        ri *= ratio(Vl[i, V_PDF_REV], Vl[i, V_PDF_FWD])
        delta_before = Vl[i - 1, V_DELTA] != 0.0 if i > 0 else is_delta_light(Vl, 0)
        if Vl[i, V_DELTA] == 0.0 and not delta_before:
            total += ri

    Vc[pt, V_DELTA] = pt_delta
    Vc[pt, V_PDF_REV] = pt_rev
    if s > 0:
        Vl[qs, V_DELTA] = qs_delta
        Vl[qs, V_PDF_REV] = qs_rev
    if t > 1:
        Vc[ptm, V_PDF_REV] = ptm_rev
    if s > 1:
        Vl[qsm, V_PDF_REV] = qsm_rev
    return 1.0 / (1.0 + total)
