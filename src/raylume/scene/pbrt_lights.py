"""pbrt-v4 lights as raylume lights (path mode's radiometric units).

pbrt-v4 scales every emission spectrum to unit luminance before its `scale` applies; an RGB
given with `rgb` is relative to the colour space's white, so it comes out as written. raylume
therefore takes RGB values as they are and other spectra at unit luminance (pbrt_params.colour),
times `scale`:

* point (`I`, `from`): a point light of radiant intensity I (W/sr), as raylume's; `power`
  sets I = power / 4 pi.
* spot (`from`, `to`, `coneangle`, `conedelta`): raylume's spot with angle = coneangle and
  inner_angle = coneangle - conedelta (the same smooth step in the cosine); `power` as pbrt:
  I = power / (2 pi (1 - (cos inner + cos outer) / 2)).
* distant (`L`, `from`, `to`): a directional light of irradiance L towards from - to.
* infinite (`L`): a constant environment of radiance L; with `filename`, see
  `environment_image`.
"""

from __future__ import annotations

import math

import numpy as np

from .pbrt_params import Params
from .pbrt_parse import Directive, resolve
from .pbrt_transform import apply_point, apply_vector

WHITE = (1.0, 1.0, 1.0)


def _scaled(rgb, factor: float) -> list[float]:
    return [float(c) * factor for c in rgb]


def light_tables(d: Directive, p: Params, m: np.ndarray, warn) -> tuple[list[dict], dict | None]:
    """(raylume lights, environment table or None) of a LightSource directive, placed by m."""
    kind = d.args[0]
    scale = p.float("scale", 1.0)
    if kind == "point":
        intensity = p.colour("I", WHITE, emission=True)
        power = p.float("power", -1.0)
        if power > 0:
            scale *= power / (4 * math.pi)
        position = apply_point(m, p.list("from", "point3", 3)[0] if p.has("from") else (0, 0, 0))
        return [{"type": "point", "position": position.tolist(), "intensity": _scaled(intensity, scale)}], None
    if kind == "spot":
        intensity = p.colour("I", WHITE, emission=True)
        start = np.array(p.list("from", "point3", 3)[0] if p.has("from") else (0.0, 0.0, 0.0))
        end = np.array(p.list("to", "point3", 3)[0] if p.has("to") else (0.0, 0.0, 1.0))
        cone = p.float("coneangle", 30.0)
        delta = p.float("conedelta", 5.0)
        if not 0 < cone <= 180:
            raise d.fail(f'"float coneangle" must be in (0, 180] degrees, got {cone:g}')
        inner = min(max(cone - delta, 0.0), cone)
        power = p.float("power", -1.0)
        if power > 0:
            k = 2 * math.pi * (1 - 0.5 * (math.cos(math.radians(inner)) + math.cos(math.radians(cone))))
            if not k > 0:
                raise d.fail('"power" needs a cone of some width (coneangle is too small)')
            scale *= power / k
        direction = apply_point(m, end) - apply_point(m, start)
        if not np.linalg.norm(direction) > 0:
            raise d.fail('"from" and "to" must differ')
        light = {
            "type": "spot",
            "position": apply_point(m, start).tolist(),
            "direction": direction.tolist(),
            "angle": cone,
            "inner_angle": inner,
            "intensity": _scaled(intensity, scale),
        }
        return [light], None
    if kind == "distant":
        radiance = p.colour("L", WHITE, emission=True)
        start = np.array(p.list("from", "point3", 3)[0] if p.has("from") else (0.0, 0.0, 0.0))
        end = np.array(p.list("to", "point3", 3)[0] if p.has("to") else (0.0, 0.0, 1.0))
        illuminance = p.float("illuminance", -1.0)
        if illuminance > 0:
            scale *= illuminance
        towards = apply_vector(m, start - end)
        if not np.linalg.norm(towards) > 0:
            raise d.fail('"from" and "to" must differ')
        return [{"type": "directional", "direction": towards.tolist(), "intensity": _scaled(radiance, scale)}], None
    if kind == "infinite":
        if p.has("illuminance"):
            p.float("illuminance")
            warn(d, '"illuminance" is not supported; the light\'s L and scale are used as given')
        if p.has("portal"):
            p.list("portal", "point3", 3)
            warn(d, "portals are not supported (they only guide sampling in pbrt); ignored")
        if p.has("mapname"):
            return [], v3_environment(d, p, m, scale, warn)
        filename = p.string("filename")
        if filename is None:
            return [], {"color": _scaled(p.colour("L", WHITE, emission=True), scale)}
        if p.has("L"):
            raise d.fail('give either "L" or "filename", not both')
        path = resolve(filename, d.search_dir)
        if not path.is_file():
            raise d.fail(f"no such image file {str(path)!r}")
        return [], environment_image(d, filename, m, scale)
    if kind in ("goniometric", "projection"):
        warn(d, f"{kind} lights are not supported; this light is left out")
        for q in d.params:
            q.used = True
        return [], None
    raise d.fail(f"unknown light type {kind!r} (pbrt-v4 has point, spot, distant, infinite, goniometric, projection)")


def environment_image(d: Directive, filename: str, m: np.ndarray, scale: float) -> dict:
    """An image infinite light: pbrt-v4's square equal-area octahedral map (raylume resamples it
    when compiling, compile/equal_area.py), turned by the CTM. The matrix is set when the
    document is finished (`_ctm`: the world may still be mirrored for the camera)."""
    if not filename.lower().endswith((".exr", ".hdr")):
        raise d.fail(f"{filename}: raylume reads environment images from .exr or .hdr files")
    return {"file": filename, "mapping": "equal-area", "intensity": scale, "_ctm": m.copy()}


# pbrt-v3's lat-long maps: texel (u, v) looks along (sin t cos f, sin t sin f, cos t) of the light's
# frame, f = 2 pi u, t = pi v; raylume's equirectangular direction d (kernels/shading/environment.py)
# is that one with w = V3_FROM_ENVIRONMENT @ d.
V3_FROM_ENVIRONMENT = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def v3_environment(d: Directive, p: Params, m: np.ndarray, scale: float, warn) -> dict:
    """pbrt-v3's image infinite light (`mapname`, an equirectangular .exr/.hdr, z up in the light's
    frame), tinted by L (a grey L scales it; raylume's environment takes one number)."""
    mapname = p.string("mapname")
    if not mapname.lower().endswith((".exr", ".hdr")):
        raise d.fail(f"{mapname}: raylume reads environment images from .exr or .hdr files")
    if not resolve(mapname, d.search_dir).is_file():
        raise d.fail(f"no such image file {str(resolve(mapname, d.search_dir))!r}")
    tint = p.colour("L", WHITE)
    if max(tint) - min(tint) > 1e-9:
        warn(d, f"a coloured L {list(tint)} on an image is not supported; its mean scales the image")
    return {"file": mapname, "intensity": scale * sum(tint) / 3, "_ctm": m.copy(), "_turn": V3_FROM_ENVIRONMENT}


def area_emission(d: Directive, p: Params, warn) -> tuple[list[float], bool]:
    """(radiance, twosided) of an AreaLightSource "diffuse"."""
    kind = d.args[0]
    if kind != "diffuse":
        raise d.fail(f'unknown area light type {kind!r} (pbrt-v4 has "diffuse")')
    radiance = p.colour("L", WHITE, emission=True)
    scale = p.float("scale", 1.0)
    if p.has("filename"):
        p.string("filename")
        warn(d, "an image on an area light is not supported; its L is used instead")
    if p.has("power"):
        p.float("power")
        warn(d, '"power" on an area light is not supported (it needs the shape\'s area); L and scale are used')
    return _scaled(radiance, scale), p.bool("twosided", False)
