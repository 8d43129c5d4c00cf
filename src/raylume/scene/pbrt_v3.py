"""pbrt-v3's material names in a pbrt file, read as their pbrt-v4 counterparts (many public
scene collections are still in pbrt-v3's format, which pbrt-v4 reads after `pbrt --upgrade`).

matte (Kd) -> diffuse; plastic (Kd, roughness) -> plastic (its Ks is not used: raylume's
plastic coat reflects by Fresnel); glass (index) -> smooth dielectric; mirror (Kr) -> a perfect
mirror tinted Kr; metal (eta, k, roughness) -> conductor; substrate (Kd, roughness) -> plastic;
uber (Kd) -> diffuse. pbrt-v3 remaps roughness with its own polynomial (RoughnessToAlpha in
pbrt-v3's microfacet.h) rather than pbrt-v4's square root.
"""

from __future__ import annotations

import math

from .pbrt_params import Params
from .pbrt_parse import Directive
from .pbrt_spectra import NAMED_RGB

V3_MATERIALS = ("matte", "plastic", "glass", "mirror", "metal", "substrate", "uber")


def v3_alpha(p: Params, key: str = "roughness", default: float = 0.0) -> float:
    """GGX alpha of a pbrt-v3 roughness (remapped unless remaproughness is false), capped at 1."""
    r = p.float(key, default) if p.type_of(key) != "texture" else default
    if p.type_of(key) == "texture":
        p.texture(key)
    if p.bool("remaproughness", True):
        x = math.log(max(r, 1e-3))
        r = 1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x**3 + 0.000640711 * x**4
    return min(max(r, 0.0), 1.0)


def v3_material(materials, d: Directive, p: Params, kind: str) -> dict:
    """The raylume table of a pbrt-v3 material (kind in V3_MATERIALS)."""
    materials.warn(d, f"pbrt-v3's {kind!r} material is read as its pbrt-v4 counterpart (see the README)")
    if kind in ("matte", "uber"):
        grey = 0.5 if kind == "matte" else 0.25
        return materials.coloured(d, p, "Kd", (grey,) * 3, {"type": "diffuse"})
    if kind in ("plastic", "substrate"):
        grey = 0.25 if kind == "plastic" else 0.5
        key = "roughness" if kind == "plastic" else "uroughness"
        return materials.coloured(d, p, "Kd", (grey,) * 3, {"type": "plastic", "roughness": v3_alpha(p, key, 0.1)})
    if kind == "glass":
        index = p.float("index") if p.type_of("index") == "float" else None
        return {"type": "dielectric", "ior": index if index is not None else materials.eta(d, p, "eta")}
    if kind == "mirror":
        kr = p.colour("Kr", (0.9, 0.9, 0.9)) if p.type_of("Kr") != "texture" else (0.9, 0.9, 0.9)
        return {"type": "conductor", "color": [min(max(c, 0.0), 1.0) for c in kr]}
    return {  # metal
        "type": "conductor",
        "color": [1.0, 1.0, 1.0],
        "eta": list(materials.spectrum(d, p, "eta", NAMED_RGB["metal-Cu-eta"])),
        "k": list(materials.spectrum(d, p, "k", NAMED_RGB["metal-Cu-k"])),
        "roughness": v3_alpha(p, "roughness", 0.01),
    }
