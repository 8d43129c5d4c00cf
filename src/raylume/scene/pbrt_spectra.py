"""pbrt-v4 spectra as raylume's RGB: named spectra from a table, spectra written inline
(wavelength, value pairs) and blackbody emitters by the mean over three bands.

raylume renders RGB, pbrt spectra. Every spectrum becomes its mean over the blue (400-500 nm),
green (500-600 nm) and red (600-700 nm) bands, the piecewise-linear spectrum integrated exactly
over the part of each band it covers. NAMED_RGB holds pbrt-v4's named spectra converted this way
by tools/pbrt_spectra_rgb.py from pbrt-v4's own data (metals' eta and k, glasses' eta).
"""

from __future__ import annotations

import math

BANDS = ((600.0, 700.0), (500.0, 600.0), (400.0, 500.0))  # red, green, blue (nm)
# Rec. 709 luminance of linear RGB: pbrt-v4 scales emission spectra to unit luminance.
LUMINANCE = (0.2126, 0.7152, 0.0722)

# Made by tools/pbrt_spectra_rgb.py; do not edit by hand.
NAMED_RGB = {
    "metal-Ag-eta": (0.136293, 0.125141, 0.150100),
    "metal-Ag-k": (4.127181, 3.336757, 2.462041),
    "metal-Al-eta": (1.486911, 0.967191, 0.621731),
    "metal-Al-k": (7.795373, 6.679945, 5.470626),
    "metal-Au-eta": (0.176072, 0.411782, 1.417957),
    "metal-Au-k": (3.302028, 2.595472, 1.880714),
    "metal-Cu-eta": (0.242674, 0.875739, 1.162401),
    "metal-Cu-k": (3.604633, 2.644739, 2.380738),
    "metal-MgO-eta": (1.733824, 1.740695, 1.752885),
    "metal-MgO-k": (0.000000, 0.000000, 0.000000),
    "metal-TiO2-eta": (2.860989, 2.956846, 3.173523),
    "metal-TiO2-k": (0.000000, 0.000000, 0.002206),
    "glass-BK7": (1.514578, 1.518644, 1.525614),
    "glass-BAF10": (1.666210, 1.673266, 1.686001),
    "glass-FK51A": (1.484966, 1.487874, 1.492830),
    "glass-LASF9": (1.843313, 1.856251, 1.880701),
    "glass-F5": (1.667235, 1.677439, 1.696839),
    "glass-F10": (1.721645, 1.734056, 1.758091),
    "glass-F11": (1.776822, 1.791653, 1.820647),
}


def band_rgb(pairs: list[float]) -> tuple[float, float, float]:
    """(r, g, b): the means over the red, green and blue bands of the piecewise-linear spectrum
    given as wavelength (nm), value pairs in increasing wavelength. A band the spectrum does not
    reach takes the value at the nearer end (pbrt's data start below 400 and end above 700 nm)."""
    lambdas, values = pairs[0::2], pairs[1::2]
    if len(lambdas) == 1:
        return (values[0],) * 3
    out = []
    for lo, hi in BANDS:
        a, b = max(lo, lambdas[0]), min(hi, lambdas[-1])
        if a >= b:  # outside the data: the nearer end's value
            out.append(values[0] if hi <= lambdas[0] else values[-1])
            continue
        out.append(_integral(lambdas, values, a, b) / (b - a))
    return tuple(out)  # type: ignore[return-value]


def _integral(lambdas: list[float], values: list[float], a: float, b: float) -> float:
    """The integral over [a, b] of the piecewise-linear function through the samples."""
    total = 0.0
    for k in range(len(lambdas) - 1):
        x0, x1 = lambdas[k], lambdas[k + 1]
        lo, hi = max(a, x0), min(b, x1)
        if hi <= lo:
            continue
        y0, slope = values[k], (values[k + 1] - values[k]) / (x1 - x0)
        total += 0.5 * ((y0 + slope * (lo - x0)) + (y0 + slope * (hi - x0))) * (hi - lo)
    return total


def blackbody_rgb(kelvin: float) -> tuple[float, float, float]:
    """Planck's law at `kelvin`, band-averaged and scaled to unit luminance (pbrt-v4 normalises
    emission spectra to their luminance; the light's scale then sets the level)."""
    c, h, kb = 299792458.0, 6.62606957e-34, 1.3806488e-23
    pairs: list[float] = []
    for nm in range(400, 701, 5):
        lam = nm * 1e-9
        pairs += [float(nm), 2 * h * c * c / (lam**5 * (math.exp(h * c / (lam * kb * kelvin)) - 1))]
    return unit_luminance(band_rgb(pairs))


def unit_luminance(rgb: tuple[float, float, float]) -> tuple[float, float, float]:
    """rgb scaled so that its luminance is 1 (black stays black)."""
    y = sum(w * v for w, v in zip(LUMINANCE, rgb))
    return rgb if y <= 0 else tuple(v / y for v in rgb)  # type: ignore[return-value]
