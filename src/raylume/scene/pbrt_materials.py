"""pbrt-v4 materials and textures as raylume material tables.

diffuse -> diffuse; conductor -> conductor (eta and k per RGB band: named metals from
pbrt_spectra.NAMED_RGB, a `reflectance` turned into the eta = 1, k = 2 sqrt(r) / sqrt(1 - r)
pbrt-v4 uses for it, so the Fresnel curve is pbrt's); dielectric -> dielectric; coateddiffuse ->
plastic (a diffuse base under a smooth or GGX-rough dielectric coat of index eta: raylume's
plastic has no coat thickness or albedo); interface -> null. Roughness: pbrt-v4's remapping
(alpha = sqrt(roughness), on by default) and raylume's GGX alpha (capped at 1); anisotropic
roughness becomes the mean of the two alphas. Anything else is replaced with a warning.

Every material's `"string normalmap"` (all but mix and interface) becomes its `normal_map`: pbrt-v4
reads the image as stored (ColorEncoding::Linear), bilinear and repeating, its texel at (u, 1 - v)
from the image's top (raylume's v = 1 is the top row too), x along dp/du and y = n x x.

Textures: `imagemap` -> image (uv mapping, uscale and vscale), `checkerboard` -> raylume's
world-space checker (3D, or a 2D one approximated by it). A float imagemap is a bump map where a
material's displacement names it, an alpha map where a shape's alpha does (`Materials.alpha`:
pbrt-v4's Bilerp<Float> reads one channel, an RGBA image's alpha unless it is all 1, else the
mean of r, g and b; raylume's alpha maps read alpha or grey alike, and the rest is warned about).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .pbrt_params import Params
from .pbrt_parse import Directive, resolve
from .pbrt_spectra import NAMED_RGB
from .pbrt_transform import similarity_scale
from .pbrt_v3 import V3_MATERIALS, v3_material

Warn = Callable[[Directive, str], None]
GREY = (0.5, 0.5, 0.5)
# Used for r = 1 in k = 2 sqrt(r) / sqrt(1 - r): a reflectance of 0.9999 at normal incidence.
MAX_REFLECTANCE = 0.9999


def _clip(rgb) -> list[float]:
    return [min(max(float(c), 0.0), 1.0) for c in rgb]


def _reading_differs(path) -> str | None:
    """Where pbrt-v4's float image texture reads a mask otherwise than raylume's alpha map: it
    drops a grey PNG's alpha channel and a palette's transparency, and reads the mean of r, g and
    b where an RGBA image's alpha is 1 everywhere; raylume reads the alpha in all three."""
    from PIL import Image as PILImage

    try:
        with PILImage.open(path) as im:
            if im.mode in ("LA", "La", "PA") or (im.mode == "P" and "transparency" in im.info):
                return (
                    "pbrt-v4 reads this image's grey (or colour), dropping its alpha; raylume's alpha map reads "
                    "the alpha channel"
                )
            if im.mode in ("RGBA", "RGBa") and im.getextrema()[3] == (255, 255):
                return (
                    "its alpha is 1 everywhere, so pbrt-v4 reads the mean of r, g and b; raylume's alpha map "
                    "reads the alpha channel (nothing is cut)"
                )
    except (OSError, ValueError):
        return None  # the compiler names an unreadable image
    return None


class Materials:
    """Textures defined so far and the conversion of Material / MakeNamedMaterial directives."""

    def __init__(self, warn: Warn):
        self.warn = warn
        self.textures: dict[str, dict | None] = {}  # spectrum textures; None: not convertible
        self.float_textures: set[str] = set()
        self.float_images: dict[str, dict] = {}  # float imagemap textures, as bump maps (displacement)
        self.float_image_faults: dict[str, Exception] = {}  # what a map made of one would be refused for
        self.alpha_readings: dict[str, str | None] = {}  # how pbrt reads a float image as alpha, where not as raylume

    # -- textures ---------------------------------------------------------------------------
    def define_texture(self, d: Directive, p: Params, ctm: np.ndarray) -> None:
        name, kind, cls = d.args
        kind = "spectrum" if kind == "color" else kind  # pbrt-v3's word for it
        if kind == "float":
            self.float_textures.add(name)
            self.textures.pop(name, None)
            self.float_images.pop(name, None)
            self.float_image_faults.pop(name, None)
            self.alpha_readings.pop(name, None)
            if cls == "imagemap":  # a bump map, where a material's displacement names it
                self.float_images[name] = self._float_image(d, p)
            for q in d.params:
                q.used = True  # a float texture is only reported where a material uses it
            return
        if kind != "spectrum":
            raise d.fail(f'texture type {kind!r}: expected "spectrum" or "float"')
        self.float_textures.discard(name)
        if cls == "imagemap":
            self.textures[name] = self._image(d, p)
        elif cls == "checkerboard":
            self.textures[name] = self._checker(d, p, ctm)
        else:
            self.warn(d, f"texture class {cls!r} is not supported; materials using it keep their plain colour")
            self.textures[name] = None
            for q in d.params:
                q.used = True

    @staticmethod
    def _image_file(d: Directive, p: Params) -> str:
        """An imagemap's `"string filename"`, which must name a file."""
        filename = p.string("filename")
        if filename is None:
            raise d.fail('needs "string filename"')
        if not resolve(filename, d.search_dir).is_file():
            raise d.fail(f"no such image file {str(resolve(filename, d.search_dir))!r}")
        return filename

    def _image(self, d: Directive, p: Params) -> dict:
        filename = self._image_file(d, p)
        mapping = p.string("mapping", "uv")
        if mapping != "uv":
            self.warn(d, f"mapping {mapping!r} is not supported; the surface's (u, v) is used")
        if p.float("udelta", 0.0) or p.float("vdelta", 0.0):
            self.warn(d, "udelta/vdelta (texture offsets) are not supported; ignored")
        if p.float("scale", 1.0) != 1.0 or p.bool("invert", False):
            self.warn(d, "scale and invert (texel arithmetic) are not supported; the texels are used as they are")
        wrap = p.string("wrap", "repeat")
        if wrap != "repeat":
            self.warn(d, f"wrap {wrap!r} is not supported; the image repeats")
        encoding = p.string("encoding", "sRGB")
        if encoding.lower() not in ("srgb",):
            self.warn(d, f"encoding {encoding!r} is not supported; 8-bit texels are decoded as sRGB")
        p.string("filter")  # raylume filters textures its own way (mip-maps over the pixel's footprint)
        p.float("maxanisotropy")
        return {"type": "image", "file": filename, "scale": [p.float("uscale", 1.0), p.float("vscale", 1.0)]}

    def _float_image(self, d: Directive, p: Params) -> dict:
        """A float imagemap as a bump_map table: pbrt-v4 reads a PNG as sRGB unless its encoding
        says otherwise, other files as linear; its `scale` multiplies the heights."""
        filename = self._image_file(d, p)
        uscale, vscale = p.float("uscale", 1.0), p.float("vscale", 1.0)
        if not (uscale > 0 and vscale > 0):  # an error where a map uses it, named by this directive
            self.float_image_faults[d.args[0]] = d.fail(
                f"uscale {uscale:g} and vscale {vscale:g}: raylume's maps take scales > 0 (no mirroring)"
            )
        default = "sRGB" if filename.lower().endswith(".png") else "linear"
        encoding = p.string("encoding", default)
        if encoding.lower() not in ("srgb", "linear"):
            self.warn(d, f"encoding {encoding!r} is not supported; the texels are decoded as sRGB")
            encoding = "sRGB"
        if p.string("mapping", "uv") != "uv" or p.float("udelta", 0.0) or p.float("vdelta", 0.0):
            self.warn(d, "only the uv mapping with uscale and vscale is supported; the surface's (u, v) is used")
        if p.bool("invert", False):
            self.warn(d, "invert is not supported; the texels are used as they are")
        if p.string("wrap", "repeat") != "repeat":
            self.warn(d, "only wrap repeat is supported; the image repeats")
        return {
            "file": filename,
            "scale": [uscale, vscale],
            "height": p.float("scale", 1.0),
            "encoding": encoding.lower(),
        }

    def _checker(self, d: Directive, p: Params, ctm: np.ndarray) -> dict:
        colours = []
        for key, default in (("tex1", (1.0, 1.0, 1.0)), ("tex2", (0.0, 0.0, 0.0))):
            if p.type_of(key) == "texture":
                p.texture(key)
                self.warn(d, f'"texture {key}" (a texture inside a checkerboard) is not supported; {default} used')
                colours.append(_clip(default))
            else:
                colours.append(_clip(p.colour(key, default)))
        dimension = p.int("dimension", 2)
        if dimension == 3:
            s = similarity_scale(ctm)
            moved = not np.allclose(ctm[:3, 3], 0) or (s is not None and not np.allclose(ctm[:3, :3], s * np.eye(3)))
            if s is None or moved:
                self.warn(
                    d,
                    "a 3D checkerboard under a rotation, translation or non-uniform scale is drawn "
                    "axis-aligned through the origin, with cells of the transform's mean size",
                )
                s = float(abs(np.linalg.det(ctm[:3, :3])) ** (1 / 3))
            return {"type": "checker", "colors": colours, "scale": s}
        if dimension != 2:
            raise d.fail(f'"integer dimension" must be 2 or 3, got {dimension}')
        u, v = p.float("uscale", 1.0), p.float("vscale", 1.0)
        if u == 0 or v == 0:
            raise d.fail("uscale and vscale must not be 0")
        u, v = abs(u), abs(v)  # a mirrored checkerboard is the same pattern
        p.string("mapping")
        self.warn(
            d,
            "a 2D (uv) checkerboard is drawn as raylume's 3D world-space checker of cell size "
            f"1/uscale = {1 / u:g}; on a plane through the origin along the axes the two agree",
        )
        if u != v:
            self.warn(d, f"uscale ({u:g}) and vscale ({v:g}) differ; the checker's cells are cubes of side 1/uscale")
        return {"type": "checker", "colors": colours, "scale": 1.0 / u}

    # -- materials --------------------------------------------------------------------------
    def material(self, d: Directive, p: Params, kind: str, named: Callable[[str], dict | None]) -> dict:
        """The raylume material table of a material of type `kind` with parameters p, with its
        normal map. `named` looks up a named material (for mix)."""
        normal_map = None if kind == "mix" else self._normal_map(d, p)  # mix: its materials' own
        bump_map = None if kind == "mix" else self._bump_map(d, p)
        table = self._material(d, p, kind, named)
        if bump_map is not None and normal_map is not None:
            self.warn(d, "a displacement and a normalmap: pbrt-v4 bump-maps by the former; the normalmap is ignored")
            normal_map = None
        key, found = ("bump_map", bump_map) if bump_map is not None else ("normal_map", normal_map)
        if found is None:
            return table
        if table.get("type") == "null":
            self.warn(d, f"an interface material has no surface for a {key.replace('_', ' ')} to turn; it is ignored")
            return table
        return {**table, key: found}

    def _bump_map(self, d: Directive, p: Params) -> dict | None:
        """The bump_map table of `"texture displacement"`: a float imagemap's heights (pbrt-v4's
        BumpMap displaces the surface by the texture's value); None for none, or a constant."""
        kind = p.type_of("displacement")
        if kind is None:
            return None
        if kind != "texture":
            p.float("displacement")  # a constant displacement moves the surface, and turns no normal
            return None
        name, image = self._float_image_named(d, p, "displacement", "bump-maps")
        if image is None:
            return None
        if image["height"] < 0:
            self.warn(d, f"displacement texture {name!r} has a negative scale; raylume's heights rise: ignored")
            return None
        return dict(image)

    def _float_image_named(self, d: Directive, p: Params, key: str, verb: str) -> tuple[str, dict | None]:
        """The float imagemap a `"texture KEY"` parameter names, as _float_image made it: None
        (with a warning) for another float texture; an error for a spectrum texture, no texture,
        or an image raylume's maps refuse (float_image_faults)."""
        name = p.texture(key)
        if name in self.float_image_faults:
            raise self.float_image_faults[name]
        if name in self.float_images:
            return name, self.float_images[name]
        if name in self.float_textures:
            self.warn(d, f"{key} texture {name!r} is not an imagemap; raylume {verb} by images only: ignored")
            return name, None
        if name in self.textures:
            raise d.fail(f"texture {name!r} is a spectrum texture; {key} needs a float texture")
        raise d.fail(f"no texture named {name!r} (define it with Texture before using it)")

    def alpha(self, d: Directive, p: Params) -> dict | None | bool:
        """A shape's `alpha` (pbrt-v4 cuts where it is 0, and keeps a fraction `alpha` of the hits
        elsewhere, by a hash of the ray): an alpha_map table for a float imagemap (its texels
        decoded as pbrt-v4 decodes them, cut below 0.5, the texture's scale folded into the
        cutoff), None where nothing is cut, False where the whole shape is (left out)."""
        kind = p.type_of("alpha")
        if kind is None:
            return None
        if kind != "texture":
            a = p.float("alpha")
            if a >= 1:
                return None
            if a <= 0:
                self.warn(d, f'"float alpha" {a:g}: pbrt-v4 cuts the whole shape away; it is left out')
                return False
            fate = "left out" if a < 0.5 else "drawn solid"
            self.warn(
                d,
                f'"float alpha" {a:g}: pbrt-v4 keeps that fraction of the rays that hit the shape; raylume cuts masks '
                f"at 0.5, so the shape is {fate}",
            )
            return False if a < 0.5 else None
        name, image = self._float_image_named(d, p, "alpha", "cuts masks")
        if image is None:
            return None
        scale = image["height"]  # the texture's "float scale": pbrt's alpha is scale times the texel
        if scale < 0.5:
            self.warn(
                d,
                f"alpha texture {name!r} has scale {scale:g}, so its alpha stays below 0.5, where raylume cuts "
                "masks: the shape is left out",
            )
            return False
        table = {"file": image["file"], "scale": image["scale"], "cutoff": 0.5 / scale}
        if image["encoding"] == "srgb":
            table["encoding"] = "srgb"
        if name not in self.alpha_readings:
            self.alpha_readings[name] = _reading_differs(resolve(image["file"], d.search_dir))
        reading = self.alpha_readings[name]
        if reading:
            self.warn(d, f"alpha texture {name!r}: {reading}")
        return table

    def _normal_map(self, d: Directive, p: Params) -> dict | None:
        """The normal_map table of `"string normalmap"` (pbrt-v4 reads the image as stored, as
        raylume's normal maps are read), or None."""
        if not p.has("normalmap"):
            return None
        filename = p.string("normalmap")
        if not filename:
            return None  # pbrt-v4: an empty name is no normal map
        path = resolve(filename, d.search_dir)
        if not path.is_file():
            raise d.fail(f"no such normal map file {str(path)!r}")
        return {"file": filename}

    def _material(self, d: Directive, p: Params, kind: str, named: Callable[[str], dict | None]) -> dict:
        if kind == "diffuse":
            return self.coloured(d, p, "reflectance", GREY, {"type": "diffuse"})
        if kind == "coateddiffuse":
            table = self.coloured(d, p, "reflectance", GREY, {"type": "plastic"})
            table["ior"] = self.eta(d, p, "eta")
            table["roughness"] = self._alpha(d, p, "")
            return table
        if kind == "conductor":
            return self._conductor(d, p, "")
        if kind == "coatedconductor":
            self.warn(d, "coatedconductor is rendered as its conductor base, without the dielectric coat")
            return self._conductor(d, p, "conductor.")
        if kind in ("dielectric", "thindielectric"):
            if kind == "thindielectric":
                self.warn(d, "thindielectric is rendered as a (thick) dielectric of the same eta")
            return {"type": "dielectric", "ior": self.eta(d, p, "eta"), "roughness": self._alpha(d, p, "")}
        if kind in ("interface", "", "none"):
            return {"type": "null"}
        if kind == "mix":
            names = p.list("materials", "string") or []
            first = named(names[0]) if names else None
            self.warn(d, f"mix is not supported; the first of its materials ({names[0] if names else 'none'}) is used")
            for q in d.params:
                q.used = True
            return dict(first) if first is not None else {"type": "diffuse", "color": list(GREY)}
        if kind == "diffusetransmission":
            self.warn(d, "diffusetransmission is rendered as diffuse reflection (no transmission)")
            return self.coloured(d, p, "reflectance", (0.25, 0.25, 0.25), {"type": "diffuse"})
        if kind in V3_MATERIALS:
            return v3_material(self, d, p, kind)
        self.warn(d, f"material {kind!r} is not supported; replaced by a grey diffuse one (reflectance 0.5)")
        for q in d.params:
            q.used = True
        return {"type": "diffuse", "color": list(GREY)}

    def coloured(self, d: Directive, p: Params, key: str, default, table: dict) -> dict:
        """table with `color` (and `texture`) from a spectrum parameter or a texture."""
        if p.type_of(key) == "texture":
            name = p.texture(key)
            tex = self._spectrum_texture(d, name)
            if tex is not None:
                return {**table, "color": [1.0, 1.0, 1.0], "texture": tex}
            return {**table, "color": _clip(default)}
        return {**table, "color": _clip(p.colour(key, default))}

    def _spectrum_texture(self, d: Directive, name: str) -> dict | None:
        if name in self.float_textures:
            raise d.fail(f"texture {name!r} is a float texture; a colour needs a spectrum texture")
        if name not in self.textures:
            raise d.fail(f"no texture named {name!r} (define it with Texture before using it)")
        return self.textures[name]

    def _conductor(self, d: Directive, p: Params, prefix: str) -> dict:
        table: dict = {"type": "conductor", "roughness": self._alpha(d, p, prefix)}
        if p.has("reflectance"):
            if p.type_of("reflectance") == "texture":
                p.texture("reflectance")
                self.warn(d, "a textured conductor reflectance is not supported; a grey 0.5 one is used")
                r = GREY
            else:
                r = _clip(p.colour("reflectance"))
            r = [min(c, MAX_REFLECTANCE) for c in r]
            table.update(color=[1.0, 1.0, 1.0], eta=[1.0, 1.0, 1.0], k=[2 * math.sqrt(c) / math.sqrt(1 - c) for c in r])
            return table
        eta = self.spectrum(d, p, prefix + "eta", NAMED_RGB["metal-Cu-eta"])
        k = self.spectrum(d, p, prefix + "k", NAMED_RGB["metal-Cu-k"])
        table.update(color=[1.0, 1.0, 1.0], eta=list(eta), k=list(k))
        return table

    def spectrum(self, d: Directive, p: Params, key: str, default) -> tuple:
        if p.type_of(key) == "texture":
            p.texture(key)
            self.warn(d, f'"texture {key}" is not supported; the default {key} is used')
            return default
        return p.colour(key, default)

    def eta(self, d: Directive, p: Params, key: str) -> float:
        kind = p.type_of(key)
        if kind is None:
            return 1.5
        if kind == "float":
            eta = p.float(key)
        elif kind == "texture":
            p.texture(key)
            self.warn(d, f'"texture {key}" is not supported; eta 1.5 is used')
            return 1.5
        else:
            rgb = p.colour(key)
            eta = rgb[1]
            if max(rgb) - min(rgb) > 1e-6:
                self.warn(d, f"{key} varies with wavelength (dispersion); raylume uses its green-band value {eta:.4f}")
        if not eta > 0:
            raise d.fail(f'"{kind} {key}" must be > 0')
        return float(eta)

    def _alpha(self, d: Directive, p: Params, prefix: str) -> float:
        """GGX alpha from pbrt's roughness parameters (pbrt-v4: remapped by sqrt unless
        remaproughness is false)."""
        values = {}
        for key in ("roughness", "uroughness", "vroughness"):
            name = prefix + key
            if p.type_of(name) == "texture":
                p.texture(name)
                self.warn(d, f'"texture {name}" (a roughness map) is not supported; roughness 0 is used')
                values[key] = 0.0
            else:
                values[key] = p.float(name)
        base = values["roughness"] if values["roughness"] is not None else 0.0
        u = values["uroughness"] if values["uroughness"] is not None else base
        v = values["vroughness"] if values["vroughness"] is not None else base
        if min(u, v) < 0:
            raise d.fail(f"roughness must be >= 0, got {min(u, v):g}")
        if p.bool("remaproughness", True):
            u, v = math.sqrt(u), math.sqrt(v)
        if u != v:
            self.warn(d, f"anisotropic roughness (alpha {u:g} x {v:g}) is rendered isotropic, alpha {(u + v) / 2:g}")
        alpha = (u + v) / 2
        if alpha > 1:
            self.warn(d, f"roughness alpha {alpha:g} is above raylume's maximum; 1 is used")
            alpha = 1.0
        return alpha
