"""Mitsuba emitters as raylume lights, environments and emission (path mode's radiometric units
are Mitsuba's: W/sr for point and spot intensity, irradiance for directional lights, radiance
for area lights and environments).

| Mitsuba | raylume |
| --- | --- |
| point | point light |
| spot | spot light (cutoff_angle -> angle, beam_width -> inner_angle) |
| directional | directional light (direction: towards the light) |
| area (in a shape) | the shape's material `emission` (one-sided: see mitsuba_shapes.Shapes.one_sided) |
| constant | [environment] color |
| envmap | [environment] file, intensity = scale, rotate from to_world |
"""

from __future__ import annotations

import numpy as np

from .affine import decompose
from .mitsuba_context import MIRROR, Context
from .mitsuba_props import colour_of
from .mitsuba_xml import Node

ENVIRONMENT_SUFFIXES = (".exr", ".hdr")
# Mitsuba's RGB variants read a constant <spectrum> on an emitter as light of equal energy at
# every wavelength, whose linear sRGB (D65 white) is this: a constant emitter of spectrum 1
# evaluates to it in Mitsuba 3.9.1's scalar_rgb (an <rgb> or a number stays grey)
EQUAL_ENERGY_RGB = (1.20479, 0.948291, 0.908916)


def _colour(ctx: Context, node: Node, props, name: str, default: float = 1.0) -> list[float]:
    value = props.take(name)
    if value is None:
        return [default] * 3
    if value.tag == "texture":
        raise value.error(f"{name}: a textured emitter has no raylume equivalent; give <rgb>")
    rgb = colour_of(value, name)
    if value.tag == "spectrum":
        return [c * e for c, e in zip(rgb, EQUAL_ENERGY_RGB, strict=True)]
    return list(rgb)


def area_radiance(ctx: Context, node: Node) -> list[float]:
    """The radiance of an area emitter inside a shape."""
    props = ctx.props(node)
    radiance = _colour(ctx, node, props, "radiance")
    ctx.done(node, props)
    return radiance


def light_or_environment(ctx: Context, node: Node) -> tuple[dict | None, dict | None]:
    """(a light table, an [environment] table): one of them, for a top-level <emitter>."""
    kind = node.attrs.get("type")
    props = ctx.props(node)
    light = environment = None
    if kind == "point":
        position = props.point("position")
        m = props.transform()
        light = {
            "type": "point",
            "position": ctx.point(m, position if position is not None else (0.0, 0.0, 0.0)),
            "intensity": _colour(ctx, node, props, "intensity"),
        }
    elif kind == "spot":
        m = props.transform()
        cutoff = props.float("cutoff_angle", 20.0)
        beam = props.float("beam_width", cutoff * 0.75)
        if beam < cutoff:
            ctx.warn(
                node,
                "between beam_width and cutoff_angle raylume's spot falls off by a smooth step in the cosine "
                "(pbrt's), Mitsuba's linearly in the angle",
            )
        light = {
            "type": "spot",
            "position": ctx.point(m),
            "direction": ctx.vector(m, (0.0, 0.0, 1.0)),
            "angle": cutoff,
            "inner_angle": min(beam, cutoff),
            "intensity": _colour(ctx, node, props, "intensity"),
        }
    elif kind == "directional":
        m = props.transform()
        d = props.point("direction")
        shine = ctx.vector(m, d if d is not None else (0.0, 0.0, 1.0))
        light = {
            "type": "directional",
            "direction": [-c + 0.0 for c in shine],  # raylume's points towards the light
            "intensity": _colour(ctx, node, props, "irradiance"),
        }
    elif kind == "constant":
        environment = {"color": _colour(ctx, node, props, "radiance")}
    elif kind == "envmap":
        environment = _envmap(ctx, node, props)
    elif kind == "area":
        raise node.error("an area emitter belongs inside a <shape>")
    else:
        raise node.error("raylume has no such emitter, and no light that could honestly replace it")
    ctx.done(node, props)
    return light, environment


def _envmap(ctx: Context, node: Node, props) -> dict:
    name = props.string("filename")
    if name is None:
        raise node.error("needs a filename")
    table: dict = {"file": ctx.file(node, name, ENVIRONMENT_SUFFIXES), "intensity": props.float("scale", 1.0)}
    m = props.transform()
    scale = np.linalg.norm(m[:3, :3], axis=0)
    if not scale.min() > 0:  # only the to_world's turn matters, and a scale of 0 leaves no turn to find
        raise node.error("its to_world is singular (it scales by 0), so it does not say which way the map faces")
    r = m[:3, :3] / scale
    # raylume's equirectangular lookup at x-mirrored directions is Mitsuba's (u = atan2(x, z) / 2pi
    # + 0.5 against atan2(x, -z) / 2pi): raylume's world-from-environment is world @ R @ mirror
    w = ctx.world[:3, :3] @ r @ MIRROR[:3, :3]
    if np.linalg.det(w) > 0:
        turn = np.eye(4)
        turn[:3, :3] = w
        rotate = decompose(turn)["rotate"]
        if any(rotate):
            table["rotate"] = rotate
    else:  # a mirrored sensor (or a mirroring to_world) shows the map mirrored, as Mitsuba does
        table["matrix"] = [[float(c) + 0.0 for c in row] for row in w]
    return table
