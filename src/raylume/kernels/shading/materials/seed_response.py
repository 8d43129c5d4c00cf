"""The seed's response of a surface to a light, trace mode's shading of every material (each kind
shown through its trace-mode approximation in the phong columns): diffuse N.L plus the Phong
highlight (R.V)^s, as the lecture's ComputeLighting computes it."""

from ...vec import dot, inline_function, mul, sub


@inline_function
def highlight(cos_rv, specular):
    """cos_rv ** specular, the Phong highlight, by repeated squaring where the exponent is a
    whole number up to 2**16 (the seed's 10, 500 and 1000): libm's pow took ~7% of the seed's
    trace kernel. Callers skip cos_rv <= 1 - 50 / specular, so no square underflows."""
    n = int(specular)
    if n != specular or n > 65536:
        return cos_rv**specular
    result = 1.0
    base = cos_rv
    while n > 0:
        if n & 1:
            result *= base
        base *= base
        n >>= 1
    return result


@inline_function
def phong_response(n, l, view, specular):
    """The seed's diffuse + specular factor for the unit direction l towards a light (n and
    view unit too; specular <= 0 for a matte surface)."""
    n_dot_l = dot(n, l)
    scale = max(n_dot_l, 0.0)
    if specular > 0.0:
        # the seed adds the highlight whatever the sign of N.L (R and V decide)
        r = sub(mul(n, 2.0 * n_dot_l), l)
        cos_rv = dot(r, view)  # the seed divides by |R| |V|: both are 1 here
        if cos_rv > 0.0:
            # Below 1 - 50/s the highlight is under e^-50 (about 2e-22): skip the power, whose
            # result would otherwise often be a slow subnormal number.
            if cos_rv > 1.0 - 50.0 / specular:
                scale += highlight(cos_rv, specular)
    return scale
