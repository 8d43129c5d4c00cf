"""Mitsuba BSDFs (and the textures they take) as raylume material tables (README: materials).

| Mitsuba | raylume |
| --- | --- |
| diffuse | diffuse |
| conductor, roughconductor | conductor (eta, k as RGB; named metals from scene/mitsuba_named.py) |
| dielectric, roughdielectric | dielectric (ior = int_ior / ext_ior) |
| thindielectric | null, with a warning: the sheet's reflection (2R / (1 + R)) is lost |
| plastic, roughplastic | plastic |
| twosided | its BSDF (raylume's surfaces are two-sided) |
| principled | dielectric, conductor or plastic by its dominant lobe, with a warning |
| null | null |
| normalmap | its BSDF, with the bitmap as the material's `normal_map` |
| bumpmap | its BSDF, with the bitmap as the material's `bump_map` (`scale` its height) |
| mask | its BSDF, with a bitmap `opacity` as its `alpha_map` (cut at 0.5); a constant: null below 0.5 |

Mitsuba's normalmap and bumpmap darken light that arrives at a grazing angle to the unperturbed
surface by a shadowing function (Estevez et al. 2019; `use_shadowing_function`, true by
default), which raylume does not have: with `use_shadowing_function = false` the two render the
same maps alike; with it, Mitsuba's grazing light is a little darker (a fraction of a percent
where the map leans 20 degrees and the light arrives within 30 degrees of the surface's normal).
The default passes in silence, as before the flag was read; `true` written out is warned about.

A mask's bitmap is read as Mitsuba's eval_1 reads it, as far as raylume's alpha map can: its
grey (alpha dropped), sRGB-decoded unless raw; an alpha channel is warned about.

Rough plugins map `alpha` to `roughness` (both GGX alpha); a Beckmann distribution becomes GGX
of the same alpha, with a warning. Anything else warns and becomes a grey diffuse material.
"""

from __future__ import annotations

import math

import numpy as np

from .mitsuba_context import Context
from .mitsuba_named import CONDUCTORS, IORS
from .mitsuba_props import Props, colour_of
from .mitsuba_xml import Node

GREY = [0.5, 0.5, 0.5]  # Mitsuba's default reflectance, and what replaces what raylume lacks
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def _ior(ctx: Context, props: Props, name: str, default: float) -> float:
    node = props.take(name)
    if node is None:
        return default
    if node.tag == "string":
        key = node.attrs.get("value", "").strip().lower()
        if key not in IORS:
            raise node.error(f"{name}: unknown material {key!r}; Mitsuba's names: {', '.join(IORS)}")
        return IORS[key]
    return colour_of(node, name)[0]


def _reflectance(ctx: Context, props: Props, name: str, default, table: dict, key: str = "color") -> None:
    """A colour or texture property into `table` (as `color`, or as `texture`)."""
    node = props.take(name)
    if node is None:
        table[key] = list(default)
        return
    if node.tag == "texture":
        texture = texture_table(ctx, node)
        if texture is not None:
            table["texture"] = texture
            return
        table[key] = list(GREY)
        return
    rgb = colour_of(node, name)
    if max(rgb) > 1 or min(rgb) < 0:
        ctx.warn(node, f"{name} {list(rgb)} lies outside 0..1; raylume clamps it (a reflectance cannot exceed 1)")
        rgb = tuple(min(max(c, 0.0), 1.0) for c in rgb)
    table[key] = list(rgb)


def texture_table(ctx: Context, node: Node) -> dict | None:
    """A <texture> as raylume's texture table, or None (with a warning) where it has none."""
    props = ctx.props(node)
    kind = node.attrs.get("type")
    if kind == "bitmap":
        name = props.string("filename")
        if name is None:
            raise node.error("needs a filename")
        if not name.lower().endswith(IMAGE_SUFFIXES):
            ctx.warn(node, f"{name}: raylume's image textures are PNG or JPEG; a grey 0.5 replaces it")
            return None
        if props.boolean("raw", False):
            ctx.warn(node, "raw = true: raylume decodes 8-bit texels from sRGB all the same")
        scale = _uv_scale(ctx, node, props, "image texture")
        for ignored in ("filter_type", "wrap_mode", "format"):
            props.take(ignored)  # raylume filters bilinearly (with mip-maps) and repeats
        ctx.done(node, props)
        return {"type": "image", "file": ctx.file(node, name, IMAGE_SUFFIXES), "scale": scale}
    if kind == "checkerboard":
        colours = []
        for name, default in (("color0", 0.4), ("color1", 0.2)):
            value = props.take(name)
            colours.append(list(colour_of(value, name)) if value is not None else [default] * 3)
        m = _to_uv(props)
        ctx.done(node, props)
        side = 0.5 / max(abs(float(m[0, 0])), 1e-9)
        ctx.warn(
            node,
            f"raylume's checker is a 3D pattern in world space, not in UV space: cells of side {side:g} replace "
            "Mitsuba's 2 x 2 checks per UV square",
        )
        return {"type": "checker", "colors": colours, "scale": side}
    ctx.warn(node, "raylume has no such texture; a grey 0.5 replaces it")
    return None


def _to_uv(props: Props) -> np.ndarray:
    """A texture's `to_uv` (Mitsuba 3's name; `to_world`, which Mitsuba 3 refuses on a texture,
    is read as it was before raylume read `to_uv`)."""
    return props.transform("to_uv") if props.has("to_uv") else props.transform("to_world")


def _uv_scale(ctx: Context, node: Node, props: Props, what: str) -> list[float]:
    """The scale of the UVs a bitmap's to_uv gives (raylume's images take a scale alone)."""
    m = _to_uv(props)
    scale = [float(m[0, 0]), float(m[1, 1])]
    if abs(m[0, 1]) + abs(m[1, 0]) + abs(m[:2, 2:]).sum() > 0 or min(scale) <= 0:  # a turn, shear or offset
        ctx.warn(node, f"its to_uv is more than a scale of the UVs; raylume's {what} takes only that")
        scale = [abs(scale[0]) or 1.0, abs(scale[1]) or 1.0]
    return scale


def normal_map_table(ctx: Context, node: Node, props: Props) -> dict | None:
    """The `normal_map` of a <bsdf type="normalmap">: its bitmap, read as stored (Mitsuba's
    `raw = true`), its to_uv's scale; None (with a warning) where raylume cannot read it."""
    texture = props.plugin("normalmap")
    if texture is None:
        raise node.error('needs a <texture name="normalmap" type="bitmap">')
    bitmap = _map_bitmap(ctx, texture, "normal map")
    if bitmap is None:
        return None
    table, raw = bitmap
    if not raw:
        ctx.warn(
            texture,
            "raw = false: Mitsuba decodes this normal map's texels from sRGB before reading them as normals; "
            "raylume reads them as stored (as raw = true does)",
        )
    return table


def bump_map_table(ctx: Context, node: Node, props: Props) -> dict | None:
    """The `bump_map` of a <bsdf type="bumpmap">: its texture (a bitmap, sRGB-decoded unless
    `raw`), its to_uv's scale, the plugin's `scale` as the height (Mitsuba multiplies the texture's
    gradient by it); None (with a warning) where raylume cannot read it."""
    textures = [p for p in props.plugins if p.tag == "texture"]
    if not textures:
        ctx.warn(node, "a bumpmap without a nested <texture> (its heights): the BSDF inside is drawn without one")
        return None
    if "name" in textures[0].attrs:  # Mitsuba takes the texture by any name
        props.take(textures[0].attrs["name"])
    bitmap = _map_bitmap(ctx, textures[0], "bump map")
    height = props.float("scale", 1.0)
    if bitmap is None:
        return None
    if height < 0:
        ctx.warn(node, f"scale {height:g}: raylume's bump maps raise the surface (height >= 0); drawn without it")
        return None
    table, raw = bitmap
    return {**table, "height": height, "encoding": "linear" if raw else "srgb"}


def mask_table(ctx: Context, node: Node, props: Props) -> dict | bool | None:
    """The `alpha_map` of a <bsdf type="mask">: its bitmap opacity, sRGB-decoded unless `raw`, cut
    below 0.5 (Mitsuba keeps a fraction `opacity` of the hits, which 0.5 approximates for masks
    of 0 and 1). A constant opacity (Mitsuba's default 0.5) cuts nothing (None) from 0.5 up and
    everything (False: the mask is then Mitsuba's null BSDF) below; None too (with a warning)
    where raylume cannot read the texture."""
    opacity = props.take("opacity")
    if opacity is not None and opacity.tag == "texture":
        bitmap = _map_bitmap(ctx, opacity, "opacity mask")
        if bitmap is None:
            return None
        table, raw = bitmap
        if _has_alpha(ctx.folder / table["file"]):
            ctx.warn(
                opacity,
                "Mitsuba drops this bitmap's alpha channel and reads its grey (the luminance of r, g and b); "
                "raylume's alpha map reads the alpha channel",
            )
        return {**table, "cutoff": 0.5, **({} if raw else {"encoding": "srgb"})}
    if opacity is None:
        value = 0.5
    else:
        r, g, b = colour_of(opacity, "opacity")
        value = 0.2126 * r + 0.7152 * g + 0.0722 * b  # Mitsuba reads a colour's luminance as a float
    value = min(max(value, 0.0), 1.0)
    if value >= 1.0:
        return None
    if value <= 0.0:
        return False  # exactly Mitsuba's null BSDF
    ctx.warn(
        node,
        f"opacity {value:g}: Mitsuba keeps that fraction of the rays that hit the surface; raylume cuts masks at "
        f"0.5, so it is {'invisible (null)' if value < 0.5 else 'drawn solid'}",
    )
    return False if value < 0.5 else None


def _has_alpha(path) -> bool:
    """Whether the image has an alpha channel (or a palette's transparency)."""
    from PIL import Image as PILImage

    try:
        with PILImage.open(path) as im:
            return "A" in im.getbands() or (im.mode == "P" and "transparency" in im.info)
    except (OSError, ValueError):
        return False  # the compiler names an unreadable image


def _map_bitmap(ctx: Context, texture: Node, what: str) -> tuple[dict, bool] | None:
    """A normal or bump map's bitmap: ({file, scale}, raw), or None (with a warning) where it is
    not a PNG or JPEG bitmap."""
    if texture.tag != "texture" or texture.attrs.get("type") != "bitmap":
        ctx.warn(texture, f"raylume's {what}s are images (a bitmap): the BSDF inside is drawn without one")
        return None
    tprops = ctx.props(texture)
    name = tprops.string("filename")
    if name is None:
        raise texture.error("needs a filename")
    if not name.lower().endswith(IMAGE_SUFFIXES):
        ctx.warn(texture, f"{name}: raylume's {what}s are PNG or JPEG; the BSDF inside is drawn without one")
        return None
    raw = tprops.boolean("raw", False)
    scale = _uv_scale(ctx, texture, tprops, what)
    for ignored in ("filter_type", "wrap_mode", "format"):
        tprops.take(ignored)  # raylume reads its maps bilinearly and repeats them
    ctx.done(texture, tprops)
    return {"file": ctx.file(texture, name, IMAGE_SUFFIXES), "scale": scale}, raw


def _roughness(ctx: Context, node: Node, props: Props) -> float:
    distribution = props.string("distribution", "beckmann")
    alpha = props.float("alpha")
    alpha_u, alpha_v = props.float("alpha_u"), props.float("alpha_v")
    props.take("sample_visible")  # a sampling strategy: the image is the same
    if alpha is None and (alpha_u is not None or alpha_v is not None):
        alpha = math.sqrt((alpha_u or 0.1) * (alpha_v or 0.1))
        if alpha_u != alpha_v:
            ctx.warn(node, f"anisotropic roughness (alpha_u {alpha_u}, alpha_v {alpha_v}) becomes isotropic {alpha:g}")
    alpha = 0.1 if alpha is None else alpha
    if distribution != "ggx":
        ctx.warn(
            node, f"distribution {distribution!r}: raylume's microfacets are GGX; GGX of alpha {alpha:g} replaces it"
        )
    return min(max(alpha, 0.0), 1.0)


def _conductor(ctx: Context, node: Node, props: Props, rough: bool) -> dict:
    table: dict = {"type": "conductor"}
    material = props.string("material", None)
    eta_node, k_node = props.take("eta"), props.take("k")
    if eta_node is not None or k_node is not None:
        if material is not None:
            raise node.error("give either material or eta and k, not both")
        eta = colour_of(eta_node, "eta") if eta_node is not None else (0.0, 0.0, 0.0)
        k = colour_of(k_node, "k") if k_node is not None else (1.0, 1.0, 1.0)
        table.update(eta=list(eta), k=list(k))
    else:
        material = "none" if material is None else material
        if material != "none":
            if material not in CONDUCTORS:
                raise node.error(f"material {material!r}: unknown; Mitsuba's names: none, {', '.join(CONDUCTORS)}")
            eta, k = CONDUCTORS[material]
            table.update(eta=list(eta), k=list(k))
    ext = _ior(ctx, props, "ext_eta", 1.0)
    if ext != 1.0 and "eta" in table:
        table["eta"] = [c / ext for c in table["eta"]]
        table["k"] = [c / ext for c in table["k"]]
    _reflectance(ctx, props, "specular_reflectance", (1.0, 1.0, 1.0), table)
    if rough:
        table["roughness"] = _roughness(ctx, node, props)
    return table


def _dielectric(ctx: Context, node: Node, props: Props, kind: str) -> dict:
    ior = _ior(ctx, props, "int_ior", IORS["bk7"]) / _ior(ctx, props, "ext_ior", IORS["air"])
    if props.has("specular_reflectance"):
        rgb = colour_of(props.take("specular_reflectance"), "specular_reflectance")
        if rgb != (1.0, 1.0, 1.0):
            ctx.warn(node, "specular_reflectance other than 1: raylume's dielectrics reflect as Fresnel says")
    table: dict = {"type": "dielectric", "ior": ior}
    _reflectance(ctx, props, "specular_transmittance", (1.0, 1.0, 1.0), table)
    if kind == "roughdielectric":
        table["roughness"] = _roughness(ctx, node, props)
    if kind == "thindielectric":
        r = ((ior - 1) / (ior + 1)) ** 2
        ctx.warn(
            node,
            f"raylume has no thin dielectric: a null surface (light passes straight through) replaces it; the "
            f"sheet's reflection at normal incidence, {2 * r / (1 + r):.3f}, is lost",
        )
        return {"type": "null"}
    return table


def _plastic(ctx: Context, node: Node, props: Props, rough: bool) -> dict:
    ior = _ior(ctx, props, "int_ior", 1.49) / _ior(ctx, props, "ext_ior", IORS["air"])
    table: dict = {"type": "plastic", "ior": ior}
    _reflectance(ctx, props, "diffuse_reflectance", (0.5, 0.5, 0.5), table)
    if props.has("specular_reflectance"):
        rgb = colour_of(props.take("specular_reflectance"), "specular_reflectance")
        if rgb != (1.0, 1.0, 1.0):
            ctx.warn(node, "specular_reflectance other than 1: raylume's plastic coating reflects as Fresnel says")
    if props.boolean("nonlinear", False):
        ctx.warn(node, "nonlinear = true: raylume's plastic models the linear (default) case")
    if rough:
        table["roughness"] = _roughness(ctx, node, props)
    return table


PRINCIPLED_EXTRAS = ("specular", "spec_tint", "anisotropic", "sheen", "sheen_tint", "clearcoat", "clearcoat_gloss")
PRINCIPLED_EXTRAS += ("flatness", "diff_trans", "main_specular", "spec_srate")


def _principled(ctx: Context, node: Node, props: Props) -> dict:
    """Mitsuba's (and Blender's) principled BSDF as the raylume type nearest its dominant lobe,
    as the glTF import maps pbrMetallicRoughness: transmission >= 0.5 glass, metallic >= 0.5
    metal, else plastic; roughness r is GGX alpha r^2, as in Mitsuba's principled."""
    table: dict = {}
    roughness = props.float("roughness", 0.5)
    metallic, transmission = props.float("metallic", 0.0), props.float("spec_trans", 0.0)
    eta = props.float("eta", 1.5)
    _reflectance(ctx, props, "base_color", (0.5, 0.5, 0.5), table)
    extras = [name for name in PRINCIPLED_EXTRAS if props.take(name) is not None]
    alpha = min(max(roughness, 0.0), 1.0) ** 2
    if transmission >= 0.5:
        table.update(type="dielectric", ior=eta, roughness=alpha)
    elif metallic >= 0.5:
        table.update(type="conductor", roughness=alpha)
    else:
        table.update(type="plastic", ior=eta, roughness=alpha)
    lost = f"; {', '.join(extras)} ignored" if extras else ""
    ctx.warn(
        node,
        f"raylume has no principled BSDF: a {table['type']} material (base_color, GGX alpha = roughness^2) replaces "
        f"it, metallic {metallic:g} and spec_trans {transmission:g} taken as all or nothing{lost}",
    )
    return table


def _nested_bsdfs(node: Node, props: Props) -> list[Node]:
    """The BSDFs a wrapping BSDF (twosided, normalmap, bumpmap, mask, blendbsdf) holds: one at least."""
    nested = [p for p in props.plugins if p.tag == "bsdf"]
    if not nested:
        raise node.error("needs a nested <bsdf>")
    return nested


def bsdf_table(ctx: Context, node: Node) -> dict:
    """The raylume material table of a <bsdf> element."""
    kind = node.attrs.get("type")
    props = ctx.props(node)
    if kind == "twosided":
        nested = _nested_bsdfs(node, props)
        if len(nested) > 1:
            ctx.warn(node, "two different BSDFs for the two sides: raylume uses the first on both")
        return bsdf_table(ctx, nested[0])
    if kind in ("normalmap", "bumpmap"):
        nested = _nested_bsdfs(node, props)
        key, what = ("normal_map", "normal map") if kind == "normalmap" else ("bump_map", "bump map")
        found = normal_map_table(ctx, node, props) if kind == "normalmap" else bump_map_table(ctx, node, props)
        if props.boolean("use_shadowing_function", False):  # asked for in so many words (module docstring)
            ctx.warn(
                node,
                "use_shadowing_function = true: raylume has no shadowing function for normal and bump maps "
                "(grazing light a little brighter than Mitsuba's); drawn without it",
            )
        table = bsdf_table(ctx, nested[0])
        ctx.done(node, props)
        if found is None:
            return table
        if table.get("type") == "null":
            ctx.warn(node, f"a null BSDF has no surface for a {what} to turn; it is ignored")
            return table
        if "normal_map" in table or "bump_map" in table:
            ctx.warn(node, f"a {what} around another map: raylume keeps the inner one")
            return table
        return {**table, key: found}
    if kind == "mask":
        nested = _nested_bsdfs(node, props)
        alpha = mask_table(ctx, node, props)
        table = bsdf_table(ctx, nested[0])
        ctx.done(node, props)
        if alpha is False:
            return {"type": "null"}
        if alpha is None or table.get("type") == "null":
            return table
        if "alpha_map" in table:
            ctx.warn(node, "a mask around another mask: raylume keeps the inner one")
            return table
        return {**table, "alpha_map": alpha}
    if kind == "blendbsdf":
        nested = _nested_bsdfs(node, props)
        ctx.warn(node, f"raylume has no {kind}: the (first) BSDF inside it replaces it")
        return bsdf_table(ctx, nested[0])
    if kind == "diffuse":
        table: dict = {"type": "diffuse"}
        _reflectance(ctx, props, "reflectance", (0.5, 0.5, 0.5), table)
    elif kind in ("conductor", "roughconductor"):
        table = _conductor(ctx, node, props, kind == "roughconductor")
    elif kind in ("dielectric", "roughdielectric", "thindielectric"):
        table = _dielectric(ctx, node, props, kind)
    elif kind in ("plastic", "roughplastic"):
        table = _plastic(ctx, node, props, kind == "roughplastic")
    elif kind == "null":
        table = {"type": "null"}
    elif kind == "principled":
        table = _principled(ctx, node, props)
    else:
        ctx.warn(node, "raylume has no such BSDF: a grey diffuse material (reflectance 0.5) replaces it")
        return {"type": "diffuse", "color": list(GREY)}
    ctx.done(node, props)
    return table
