"""The `null` material [Mitsuba 3: null; pbrt-v4: interface]: a boundary that does not bend or
reflect light, an index-matched surface. Path mode passes every ray straight through it (a
delta transmission of weight 1), so alone it is invisible; it is there to bound a medium
(DESIGN.md section 7: `interior`). It still counts as a path segment for max_depth. Trace mode
shows it transparent with index 1 (invisible too, shadows pass); cast mode and the rasterizer,
which show the boundary's material alone, draw it white."""

import numpy as np

from ...vec import inline_function, kernel_function, mul
from .lobes import ONE, ZERO
from .table import MAT_IOR

NAME = "null"
KIND = 5
SOLID = False  # compile/media.py: no inside of its own (filled with the medium around it)


def pack(mat, row: np.ndarray) -> None:
    """The model material's own columns of its table row (table.py); the registry's
    pack_material writes the kind and the trace approximation."""
    row[MAT_IOR] = 1.0


def trace_approximation(mat) -> tuple[float, float, float]:
    """(Phong exponent or -1, reflective, transparency) of trace mode: fully transparent."""
    return -1.0, 0.0, 1.0


@kernel_function
def evaluate(mat, m, color, wo, wi):
    return ZERO, 0.0


@kernel_function
def sample(mat, m, color, wo, u0, u1, u2):
    return mul(wo, -1.0), ONE, 1.0, True


@inline_function
def delta_only(mat, m):
    return True


@inline_function
def two_sided(mat, m):
    return False


@inline_function
def aov_albedo(mat, m, color):
    """The `albedo` AOV and the denoiser's guide: white, as for a surface that lets all light
    through (OIDN's advice for perfect transmission)."""
    return ONE
