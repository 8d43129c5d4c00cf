"""Mitsuba's homogeneous media as raylume's [media] (path mode renders them, DESIGN.md section 7):
sigma_s = albedo * sigma_t * scale, sigma_a = (1 - albedo) * sigma_t * scale, Henyey-Greenstein
g from an `hg` phase function (isotropic: 0). A shape's `interior` is its object's `interior`; the
sensor's medium fills the space outside every object ([render] medium).

Mitsuba's `path` integrator ignores media (only volpath renders them): read with `path`, the
media are left out, with a warning, so the image stays Mitsuba's.
"""

from __future__ import annotations

from .mitsuba_context import Context
from .mitsuba_props import colour_of
from .mitsuba_xml import Node


class Media:
    def __init__(self, ctx: Context, rendered: bool):
        self.ctx = ctx
        self.rendered = rendered  # the integrator renders media (volpath)
        self.tables: dict[str, dict] = {}
        self.names: dict[int, str] = {}  # id(node) -> its name in [media]
        self.outside: Node | None = None  # the sensor's medium: raylume's [render] medium

    def name(self, node: Node, holder: Node | None = None, role: str = "interior") -> str | None:
        """The [media] name of a <medium> element (defined on first use), or None when media are
        not rendered. `holder` and `role`: the element that names it and how, for the error
        where `node` is no medium (a <ref name="interior"> to a BSDF)."""
        if node.tag != "medium":
            where = holder if holder is not None else node
            key = f" (id {node.attrs['id']!r})" if "id" in node.attrs else ""
            raise where.error(f"{role}: expected a <medium>, got a <{node.tag}>{key}")
        if not self.rendered:
            self.ctx.warn(node, "Mitsuba's path integrator ignores media, so this one is left out (volpath renders it)")
            return None
        if id(node) not in self.names:
            name = node.attrs.get("id") or f"medium{len(self.tables)}"
            self.tables[name] = self.table(node)
            self.names[id(node)] = name
        return self.names[id(node)]

    def table(self, node: Node) -> dict:
        ctx = self.ctx
        if node.attrs.get("type") != "homogeneous":
            raise node.error("raylume reads Mitsuba's homogeneous media; a heterogeneous one needs its grid")
        props = ctx.props(node)

        def rgb(name: str, default: float) -> tuple[float, float, float]:
            value = props.take(name)
            if value is not None and value.tag == "volume":
                raise value.error(f"{name}: a volume grid has no raylume equivalent here; give a constant")
            return (default,) * 3 if value is None else colour_of(value, name)

        sigma_t, albedo = rgb("sigma_t", 1.0), rgb("albedo", 0.75)
        scale = props.float("scale", 1.0)
        for name in ("sample_emitters", "has_spectral_extinction"):
            props.take(name)  # sampling strategies: the image is the same
        g = 0.0
        for plugin in props.plugins:
            if plugin.tag != "phase":
                raise plugin.error(f"a medium cannot hold a <{plugin.tag}>")
            kind = plugin.attrs.get("type")
            phase = ctx.props(plugin)
            if kind == "hg":
                g = phase.float("g", 0.8)
            elif kind != "isotropic":
                ctx.warn(plugin, "raylume's media scatter by Henyey-Greenstein; isotropic (g = 0) replaces it")
            ctx.done(plugin, phase)
        ctx.done(node, props)
        return {
            "type": "homogeneous",
            "sigma_s": [a * t * scale for a, t in zip(albedo, sigma_t)],
            "sigma_a": [(1 - a) * t * scale for a, t in zip(albedo, sigma_t)],
            "g": g,
        }
