"""Derive the RGB values of Mitsuba 3's named conductors and named indices of refraction from
Mitsuba itself, and write them as src/raylume/scene/mitsuba_named.py.

Mitsuba's `conductor` plugin with `material="Au"` reads the metal's measured spectra (eta and k)
and, in an RGB variant, turns them into RGB values; the dielectric plugins turn a named medium
(`int_ior="bk7"`) into a number. This script asks Mitsuba (scalar_rgb) for both, for every name
its documentation lists, so raylume's reader gives the same numbers Mitsuba renders with.

    python tools/mitsuba_named_data.py        # needs the bench extra (mitsuba)
    ruff format src/raylume/scene/mitsuba_named.py
"""

from __future__ import annotations

from pathlib import Path

import mitsuba as mi

OUT = Path(__file__).resolve().parents[1] / "src" / "raylume" / "scene" / "mitsuba_named.py"

# The names in Mitsuba 3's documentation (conductor: "Conductor materials"; dielectric: "IOR values").
CONDUCTORS = (
    "a-C Ag Al AlAs AlAs_palik AlSb AlSb_palik Au Be Cr CsI Cu Cu_palik Cu2O CuO d-C Hg HgTe Ir K Li MgO Mo "
    "Na_palik Nb Ni_palik Rh Se SiC SnTe Ta Te ThF4 TiC TiN TiO2 VC V_palik VN W"
).split()
IORS = (
    "vacuum",
    "helium",
    "hydrogen",
    "air",
    "carbon dioxide",
    "water",
    "acetone",
    "ethanol",
    "carbon tetrachloride",
    "glycerol",
    "benzene",
    "silicone oil",
    "bromine",
    "water ice",
    "fused quartz",
    "pyrex",
    "acrylic glass",
    "polypropylene",
    "bk7",
    "sodium chloride",
    "amber",
    "pet",
    "diamond",
)


def conductor_rgb(name: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    params = mi.traverse(mi.load_dict({"type": "conductor", "material": name}))
    return tuple(float(c) for c in params["eta.value"]), tuple(float(c) for c in params["k.value"])


def ior(name: str) -> float:
    # eta = int_ior / ext_ior, and ext_ior defaults to air: ask with ext_ior = 1 for the value itself
    params = mi.traverse(mi.load_dict({"type": "dielectric", "int_ior": name, "ext_ior": 1.0}))
    return float(params["eta"])


def main() -> None:
    mi.set_variant("scalar_rgb")
    lines = [
        '"""Mitsuba 3\'s named conductors (RGB eta and k) and named indices of refraction, as Mitsuba',
        f"{mi.__version__} (scalar_rgb) renders them. Written by tools/mitsuba_named_data.py; do not edit.",
        '"""',
        "",
        "# name -> ((eta r, g, b), (k r, g, b))",
        "CONDUCTORS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {",
    ]
    for name in CONDUCTORS:
        eta, k = conductor_rgb(name)
        lines.append(f"    {name!r}: ({eta!r}, {k!r}),")
    lines += ["}", "", "# name -> index of refraction", "IORS: dict[str, float] = {"]
    for name in IORS:
        lines.append(f"    {name!r}: {ior(name)!r},")
    lines += ["}", ""]
    OUT.write_text("\n".join(lines))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
