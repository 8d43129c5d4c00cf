"""The user-facing scene model: validated pydantic objects mirroring the scene-file schema.

Every table is optional and unknown keys are errors (README: Scene files). Tagged unions use
callable discriminators whose tags are written ``<name>`` so that error paths can drop them
(``objects[2].radius``, not ``objects.2.sphere.radius``).
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Tag,
    TypeAdapter,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic import Strict as StrictInput  # (Strict below is this module's base model)
from pydantic_core import PydanticCustomError

from ..errors import SceneError
from .validation_errors import format_validation_error

# Limits that keep a render inside memory and time a user would expect (documented in README).
MAX_SIDE = 16384
MAX_SPP = 4096
MAX_DEPTH = 64
MAX_LIGHT_SAMPLES = 1024
MAX_EXPOSURE = 64  # stops either way: 2^64 is past any display's range
PIXEL_FILTERS = ("box", "gaussian", "mitchell")


if TYPE_CHECKING:
    from pydantic._internal._model_construction import ModelMetaclass
else:
    ModelMetaclass = type(BaseModel)


class _SceneModels(ModelMetaclass):
    # raylume.Camera(positon=...) from Python: one SceneError naming the key, as the scene's other
    # paths give. Here, not in __init__: a model with its own __init__ has pydantic call it for
    # every nested table it validates. Hidden from type checkers, which then check the call
    # against the fields as for any pydantic model.
    if not TYPE_CHECKING:

        def __call__(cls, /, *args, **kwargs):
            try:
                return super().__call__(*args, **kwargs)
            except ValidationError as exc:
                raise SceneError(format_validation_error(exc, f"raylume.{cls.__name__}", cls)) from None


class Strict(BaseModel, metaclass=_SceneModels):
    # The docstring under each field describes it: tools/docs_reference.py reads them from this file into the
    # documentation's scene reference (not pydantic's use_attribute_docstrings: it costs ~0.08 s at import).
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)

    def __repr_args__(self):
        # an inline mesh of 100k triangles printed whole was 21 MB of text (a notebook's `scene`)
        for name, value in super().__repr_args__():
            yield name, _Abridged(value) if isinstance(value, list) and len(value) > _REPR_ITEMS else value


_REPR_ITEMS = 8  # a longer list shows its first items and its length in a model's repr


class _Abridged:
    def __init__(self, items: list):
        self.items = items

    def __repr__(self) -> str:
        shown = ", ".join(repr(item) for item in self.items[:3])
        return f"[{shown}, ... {len(self.items)} items]"


# float32's largest finite value: the kernels keep geometry, colours and the BVH's boxes in float32
F32_MAX = 3.4028234663852886e38


def beyond_float32(extent: float, space: str = "") -> str | None:
    """The words for geometry whose coordinates reach `extent` (`space`: where, e.g. " in world
    space"), when that is past float32's range (or NaN), in which the kernels store it; else None."""
    if extent <= F32_MAX:
        return None
    return (
        f"its coordinates reach {extent:.3g}{space}, beyond float32's range (3.4e38), "
        "in which the renderer stores geometry"
    )


def _shown(value) -> str:
    """A value as the scene file spells it: true, "32" (JSON's notation, which TOML shares)."""
    try:
        return json.dumps(value)
    except (TypeError, ValueError):
        return repr(value)


def _a_number(value):
    """A number where one goes: pydantic's lax mode would take "32" for 32 and true for 1 (numpy's
    true too, whose type is no bool)."""
    if isinstance(value, (str, bytes)) or type(value).__name__ in ("bool", "bool_"):
        raise PydanticCustomError("number_type", "a number is needed, got {shown}", {"shown": _shown(value)})
    return value


def _within_float32(value: float) -> float:
    if abs(value) > F32_MAX:
        raise ValueError(f"a number within float32's range (magnitude at most 3.4e38) is needed, got {value:g}")
    return value


def _true_or_false(value):
    """A boolean where one goes: lax mode would take "off", "yes" or 1 (numpy's bool is one)."""
    if type(value).__name__ not in ("bool", "bool_"):
        raise PydanticCustomError("bool_type", "true or false is needed, got {shown}", {"shown": _shown(value)})
    return value


# Strict: a string or a boolean is no number (numpy's floats and ints still are); checked in
# pydantic's core, so inline meshes validate as fast as before (a Python check a value: 3x slower)
FiniteFloat = Annotated[float, StrictInput(), Field(allow_inf_nan=False), AfterValidator(_within_float32)]
# (numpy's ints, which a strict int refuses, are whole numbers too)
WholeNumber = Annotated[int, BeforeValidator(_a_number)]
Flag = Annotated[bool, BeforeValidator(_true_or_false)]
Vec3 = tuple[FiniteFloat, FiniteFloat, FiniteFloat]


def _fspath(value):
    """A pathlib.Path (any os.PathLike) where a scene file names a file, as its string."""
    return os.fspath(value) if isinstance(value, os.PathLike) else value


# a file named by the scene: a string, or from Python a pathlib.Path
FileName = Annotated[str, BeforeValidator(_fspath)]


def _parse_hex(value: str) -> tuple[float, float, float]:
    text = value.strip()
    if not (len(text) == 7 and text[0] == "#"):
        raise ValueError(f"colour string {value!r} must look like '#rrggbb'")
    try:
        return tuple(int(text[k : k + 2], 16) / 255.0 for k in (1, 3, 5))  # type: ignore[return-value]
    except ValueError:
        raise ValueError(f"colour string {value!r} must look like '#rrggbb'") from None


def _from_numpy(value):
    """numpy's scalars and arrays as Python's numbers and lists (np.float32(1) -> 1.0, an array of
    shape (3,) -> [r, g, b]), also inside a list, so that colours computed with numpy are taken as
    positions are."""
    if isinstance(value, (list, tuple)):
        return [_python_value(c) for c in value]
    return _python_value(value)


def _python_value(value):
    return value.tolist() if type(value).__module__ == "numpy" and hasattr(value, "tolist") else value


def _colour(value, *, upper: float | None):
    """Accept [r, g, b] (linear floats) or '#rrggbb'; check components lie in 0..upper."""
    value = _from_numpy(value)
    if isinstance(value, str):
        rgb = _parse_hex(value)
    else:
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise ValueError("a colour is [r, g, b] or '#rrggbb'")
        for c in value:
            if isinstance(c, bool) or not isinstance(c, (int, float)):
                raise ValueError(f"colour components must be numbers, got {c!r}")
            if not math.isfinite(c) or abs(c) > F32_MAX:
                raise ValueError(f"colour components must be finite numbers within float32's range, got {c!r}")
        rgb = tuple(float(c) for c in value)
    if min(rgb) < 0 or (upper is not None and max(rgb) > upper):
        allowed = f"0..{upper:g}" if upper is not None else ">= 0"
        raise ValueError(f"colour components must be in {allowed}, got {list(rgb)}")
    return rgb


Color = Annotated[tuple[float, float, float], Field()]


def _intensity(value):
    """A light intensity: a number (grey) or [r, g, b], each >= 0 (may exceed 1)."""
    value = _from_numpy(value)
    if isinstance(value, bool):
        raise ValueError("intensity must be a number or [r, g, b]")
    if isinstance(value, (int, float)):
        if not math.isfinite(value) or value < 0 or value > F32_MAX:
            raise ValueError(f"intensity must be a finite number >= 0 within float32's range, got {value}")
        return (float(value),) * 3
    return _colour(value, upper=None)


def _nonzero(v: Vec3, what: str) -> Vec3:
    if v[0] == 0 and v[1] == 0 and v[2] == 0:
        raise ValueError(f"{what} must not be the zero vector")
    return v


class RenderSettings(Strict):
    width: WholeNumber = Field(default=600, ge=1, le=MAX_SIDE)
    """Image width in pixels."""
    height: WholeNumber = Field(default=600, ge=1, le=MAX_SIDE)
    """Image height in pixels."""
    spp: WholeNumber = Field(default=1, ge=1, le=MAX_SPP)
    """Samples per pixel; 1 traces the pixel centre, more are stratified over the pixel and combined by `filter`."""
    # Bounces (trace) or path segments (path, as Mitsuba counts them: 1 shows only emitters
    # seen directly, 2 is direct lighting, -1 unlimited with Russian roulette). Unset: 3 in
    # trace mode, -1 in path mode (`depth` is the value in force).
    max_depth: WholeNumber | None = Field(default=None, ge=-1, le=MAX_DEPTH)
    """Trace mode: reflection and refraction bounces (unset: 3). Path mode: path segments as Mitsuba counts them, 1 =
    emitters seen directly, 2 = direct light, -1 = unlimited with Russian roulette from 5 segments (unset: -1)."""
    mode: Literal["cast", "trace", "path", "raster"] = "trace"
    """`cast`: the hit material's colour, no lighting; `trace`: Whitted ray tracing with shadows, reflection,
    refraction and area lights; `path`: unbiased path tracing in radiometric units; `raster`: a z-buffer rasterizer
    with local lighting."""
    # Path mode's integrator: "path" (path tracing) or "bdpt" (bidirectional path tracing).
    integrator: Literal["path", "bdpt"] = "path"
    """Path mode's integrator: `path` (path tracing) or `bdpt` (bidirectional path tracing: camera and light subpaths
    connected by every strategy, weighted by MIS; for caustics and light through mirrors and glass). Both converge to
    the same image."""
    background: Color = (0.0, 0.0, 0.0)
    """Colour of rays that hit nothing, `[r, g, b]` or `"#rrggbb"` (an `[environment]` replaces it)."""
    encoding: Literal["clamp", "srgb"] = "clamp"
    """How linear colour becomes 8-bit: `clamp` (the seed's: clamp to 0..1, times 255) or `srgb` (the sRGB transfer
    curve)."""
    seed: WholeNumber = Field(default=0, ge=0, le=2**32 - 1)
    """Random seed of the samples: the image depends only on the scene, the seed and spp, not on threads or machines."""
    # Pixel reconstruction filter for spp > 1 (box: the pixel itself; gaussian: radius 1.5 px,
    # sigma 0.5; mitchell: B = C = 1/3, radius 2 px). One sample per pixel is always the centre.
    filter: Literal["box", "gaussian", "mitchell"] = "box"
    """Pixel reconstruction filter for spp > 1: `box` (the pixel), `gaussian` (radius 1.5 px, sigma 0.5), `mitchell` (B
    = C = 1/3, radius 2 px)."""
    # Exposure in stops: 8-bit outputs (PNG) are encoded from rgb * 2**exposure; float outputs
    # (.exr, .hdr, .npy) stay as rendered.
    exposure: FiniteFloat = Field(default=0.0, ge=-MAX_EXPOSURE, le=MAX_EXPOSURE)
    """Exposure in stops for 8-bit outputs (PNG, JPEG), encoded from rgb x 2**exposure; float outputs stay as
    rendered."""
    # Tone mapping for 8-bit outputs, after exposure and before encoding (image.tone_map).
    tonemap: Literal["none", "reinhard", "aces", "agx", "neutral"] = "none"
    """How 8-bit outputs (PNG, JPEG, the live view) bring linear colour into 0..1, after `exposure` and before
    `encoding`: `none` clips at 1 (the seed's), `reinhard` divides by 1 + luminance (hues kept), `aces` is Hill's fit
    of ACES (a film-like toe and shoulder; bright colours go to white), `agx` Blender's default view, `neutral`
    Khronos PBR Neutral (colours up to 0.76 as authored, only highlights compressed). Float outputs stay as
    rendered."""
    # Filter texture lookups over each pixel's footprint (ray cones; mip-maps for images), so
    # that far checkers and fine images do not alias. false: point lookups.
    texture_filter: Flag = True
    """Filter texture lookups over each pixel's footprint (ray cones, mip-maps) so that far checkers and fine images do
    not alias; false: point lookups."""
    # Path mode: run Intel Open Image Denoise on the image (with the albedo and normal AOVs).
    denoise: Flag = False
    """Path mode: run Intel Open Image Denoise on the image, guided by the albedo and normal AOVs (needs `pip install
    'raylume[denoise]'`)."""
    # The participating medium filling the space outside every object, a name in [media]
    # (fog); the camera sits in it. Path mode renders media; the others ignore them.
    medium: str | None = None
    """Path mode: the medium, a name in `[media]`, filling the space outside every object (fog); the camera sits
    in it."""

    # Adaptive sampling (raylume/adaptive.py): tiles of 16 x 16 pixels rendered in rounds of a
    # few samples until their noise is below the threshold; spp is then the most a pixel takes.
    # Unset: every pixel takes spp.
    noise_threshold: FiniteFloat | None = Field(default=None, gt=0)
    """Adaptive sampling: stop sampling a 16 x 16 tile once its pixels' mean error (Cycles' measure: the standard
    error of r + g + b over the square root of their mean) is below this, e.g. 0.01; `spp` is then the most a pixel
    takes. Unset: every pixel takes `spp` samples."""
    min_spp: WholeNumber | None = Field(default=None, ge=1, le=MAX_SPP)
    """Adaptive sampling: the samples every pixel takes before its tile may stop. Unset: Cycles' rule, ceil(16 /
    noise_threshold^0.3) (32 at 0.1, 40 at 0.05, 64 at 0.01); raise it where rare bright paths (caustics seen by path
    tracing) would be missed by the first samples."""
    time_limit: FiniteFloat | None = Field(default=None, gt=0)
    """Stop sampling after this many seconds of rendering (after the first round: ceil(spp / 256) samples a pixel, at
    least 2); `spp` is the most a pixel takes. The image then depends on the machine's speed."""

    @model_validator(mode="after")
    def _depth(self):
        if self.max_depth == -1 and self.mode == "trace":  # (cast and raster modes trace no bounces)
            raise ValueError("max_depth -1 (unlimited) is for path mode; trace mode needs a depth >= 0")
        return self

    def updated(self, **values) -> RenderSettings:
        """A copy with some keys replaced, validated as the table is (a pydantic ValidationError)."""
        return RenderSettings.model_validate({**self.model_dump(), **values})

    @property
    def depth(self) -> int:
        """max_depth in force: the set value, else 3 (trace) or -1 (path: unlimited)."""
        if self.max_depth is not None:
            return self.max_depth
        return -1 if self.mode == "path" else 3

    @field_validator("background", mode="before")
    @classmethod
    def _bg(cls, v):
        return _colour(v, upper=None)


class Camera(Strict):
    """A pinhole (or thin-lens, with `aperture`) camera: `raylume.Camera(position=(0, 1, -3),
    look_at=(0, 0, 0), fov=40)`. `fov` is the vertical field of view in degrees; the frame is
    left-handed, as the seed's (by default at the origin looking along +z, x right, y up). Frozen:
    `Scene.with_camera` and `Session.render(camera=...)` take a changed copy. A bad key or value
    is a SceneError naming it."""

    position: Vec3 = (0.0, 0.0, 0.0)
    """Where the camera is (the eye)."""
    look_at: Vec3 = (0.0, 0.0, 1.0)
    """The point the camera looks at, the centre of the image."""
    up: Vec3 = (0.0, 1.0, 0.0)
    """Which way is up; must not be parallel to the viewing direction."""
    fov: FiniteFloat = Field(default=53.13, gt=0, lt=180)
    """Vertical field of view in degrees (53.13: the seed's 1 x 1 viewport at distance 1)."""
    # Thin lens: the lens diameter (0: a pinhole camera, rays from one point) and the distance, along
    # the viewing direction, of the plane in focus (default: the distance to look_at).
    aperture: FiniteFloat = Field(default=0.0, ge=0)
    """Lens diameter of a thin-lens camera; 0 is a pinhole, > 0 gives depth of field."""
    focus_distance: FiniteFloat | None = Field(default=None, gt=0)
    """Distance of the plane in focus along the viewing direction (unset: the distance to look_at)."""

    @property
    def focus(self) -> float:
        """The distance of the plane in focus: `focus_distance`, else the distance to `look_at`."""
        if self.focus_distance is not None:
            return self.focus_distance
        return math.dist(self.position, self.look_at)

    @model_validator(mode="after")
    def _frame(self):
        f = [b - a for a, b in zip(self.position, self.look_at)]
        if not any(f):
            raise ValueError("look_at must differ from position")
        _nonzero(self.up, "up")
        # scaled to a largest component of 1 first: the squares of a look_at 1e-300 away underflow
        f = [c / max(abs(c) for c in f) for c in f]
        up = [c / max(abs(c) for c in self.up) for c in self.up]
        cross = (up[1] * f[2] - up[2] * f[1], up[2] * f[0] - up[0] * f[2], up[0] * f[1] - up[1] * f[0])
        norm_f = math.sqrt(sum(c * c for c in f))
        norm_u = math.sqrt(sum(c * c for c in up))
        if math.sqrt(sum(c * c for c in cross)) <= 1e-9 * norm_f * norm_u:
            raise ValueError("up must not be parallel to the viewing direction (look_at - position)")
        return self


def _tag_by_type(value):
    if isinstance(value, dict):
        kind = value.get("type")
        return f"<{kind}>" if isinstance(kind, str) else None
    kind = getattr(value, "type", None)
    return f"<{kind}>" if kind else None


class Checker(Strict):
    """A 3D checkerboard in world space: cells of side `scale` alternate between two colours."""

    type: Literal["checker"]
    """`"checker"`: a 3D checkerboard in world space."""
    colors: tuple[Color, Color] = ((1.0, 1.0, 1.0), (0.1, 0.1, 0.1))
    """The two colours of the cells, each `[r, g, b]` in 0..1 or `"#rrggbb"`."""
    scale: FiniteFloat = Field(default=1.0, gt=0)
    """Side of one cell, in scene units."""

    @field_validator("colors", mode="before")
    @classmethod
    def _cols(cls, v):
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise ValueError("colors must be a list of two colours")
        return tuple(_colour(c, upper=1.0) for c in v)


class ImageTexture(Strict):
    """A PNG or JPEG image (relative to the scene file) mapped by the surface's UVs, bilinear
    filtered and repeating; `scale` multiplies the UVs (2 = the image twice across). It
    replaces the material's colour; texels are sRGB-decoded to linear RGB."""

    type: Literal["image"]
    """`"image"`: a PNG or JPEG mapped by the surface's UVs, repeating; sRGB-decoded."""
    file: FileName
    """The image file, relative to the scene file."""
    scale: tuple[FiniteFloat, FiniteFloat] = (1.0, 1.0)
    """Multiplies the UVs: a number or `[u, v]` (2 = the image twice across)."""

    @field_validator("scale", mode="before")
    @classmethod
    def _scale(cls, v):
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = (v, v)
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise ValueError("scale must be a number or [u, v]")
        if any(isinstance(c, bool) or not isinstance(c, (int, float)) or not c > 0 for c in v):
            raise ValueError("scale factors must be numbers > 0")
        return tuple(v)


class _SurfaceMap(Strict):
    """What the normal, bump and alpha maps share: an image looked up by the surface's UVs."""

    file: FileName
    """The image file, relative to the scene file."""
    scale: tuple[FiniteFloat, FiniteFloat] = (1.0, 1.0)
    """Multiplies the UVs: a number or `[u, v]` (2 = the map twice across)."""

    _scale = field_validator("scale", mode="before")(ImageTexture._scale.__func__)


class NormalMap(_SurfaceMap):
    """A tangent-space normal map (PNG or JPEG, relative to the scene file), read as stored, not
    sRGB-decoded: a texel's (r, g, b) is the normal (2r - 1, 2g - 1, 2b - 1) in the frame of the
    surface's UV directions, x along increasing u, y along increasing v (up the image: OpenGL's
    and glTF's convention) and z the shading normal. Looked up by the UVs times `scale`,
    bilinear and repeating, as an image texture is."""

    strength: FiniteFloat = Field(default=1.0, ge=0)
    """Multiplies the normal's x and y before it is normalised (glTF's `normalTexture.scale`): 0
    leaves the surface flat, above 1 steepens it."""


class BumpMap(_SurfaceMap):
    """A height map (PNG or JPEG, relative to the scene file; grey, or the mean of r, g and b),
    read as stored (see `encoding`): the surface seen as displaced along its normal by `height`
    times the texel's value (0..1), its shading normal that of the displaced surface (pbrt-v4's
    and Mitsuba 3's bump mapping). Looked up by the UVs times `scale`, bilinear and repeating."""

    height: FiniteFloat = Field(default=0.01, ge=0)
    """The displacement of a white texel, in scene units (black: none)."""
    encoding: Literal["linear", "srgb"] = "linear"
    """How the texels encode heights: `"linear"` as stored, `"srgb"` decoded from sRGB first (as pbrt-v4 reads 8-bit
    images by default, and Mitsuba 3 bitmaps without `raw`)."""


class AlphaMap(_SurfaceMap):
    """A cut-out mask (PNG or JPEG, relative to the scene file): its alpha channel, or its grey
    (the mean of r, g and b) where it has none, read as stored (see `encoding`). Where the
    value, looked up by the UVs times `scale` (bilinear, repeating), is below `cutoff`, the
    surface has a hole: rays pass through as if it were not there (glTF's alphaMode MASK;
    leaves, fences, lace)."""

    cutoff: FiniteFloat = Field(default=0.5, gt=0, le=1)
    """Below this value (0..1) the surface is cut away (glTF's `alphaCutoff`)."""
    encoding: Literal["linear", "srgb"] = "linear"
    """How the texels encode coverage: `"linear"` as stored, `"srgb"` decoded from sRGB first, before the bilinear
    lookup (as pbrt-v4 reads an 8-bit PNG's alpha texture by default, and Mitsuba 3 a bitmap without `raw`)."""


TEXTURE_TYPES = ("checker", "image")
Texture = Annotated[
    Union[Annotated[Checker, Tag("<checker>")], Annotated[ImageTexture, Tag("<image>")]],
    Discriminator(
        _tag_by_type,
        custom_error_type="unknown_type",
        custom_error_message=f"type must be one of: {', '.join(TEXTURE_TYPES)}",
    ),
]


class _MaterialBase(Strict):
    """What every material type has: `color`, a reflectance (or a transmittance tint), so at
    most 1; `emission`, emitted radiance that makes the surface a light in path mode; and an
    optional texture replacing the colour."""

    color: Color = (1.0, 1.0, 1.0)
    """Reflectance (the transmittance tint for dielectrics), `[r, g, b]` in 0..1 or `"#rrggbb"`."""
    emission: Color = (0.0, 0.0, 0.0)  # emitted radiance
    """Emitted radiance `[r, g, b]`: makes the surface a light in path mode (its own colour added in trace mode)."""
    texture: Texture | None = None
    """A texture replacing `color`: `{ type = "checker", ... }` or `{ type = "image", file = ... }`."""
    normal_map: NormalMap | None = None
    """A tangent-space normal map turning the shading normal: `{ file = "bricks_normal.png" }`."""
    bump_map: BumpMap | None = None
    """A height map turning the shading normal: `{ file = "bumps.png", height = 0.01 }` (not with `normal_map`)."""
    alpha_map: AlphaMap | None = None
    """A cut-out mask, holes where its alpha is below `cutoff`: `{ file = "leaf.png" }` (not on an emitter)."""

    @field_validator("color", mode="before")
    @classmethod
    def _col(cls, v):
        return _colour(v, upper=1.0)

    @field_validator("emission", mode="before")
    @classmethod
    def _emitted(cls, v):
        return _colour(v, upper=None)

    @model_validator(mode="after")
    def _one_map(self):
        if self.normal_map is not None and self.bump_map is not None:
            raise ValueError("a material takes a normal_map or a bump_map, not both")
        if self.alpha_map is not None and any(self.emission):
            raise ValueError("an emitting material cannot take an alpha_map (its holes would be sampled as light)")
        return self

    @model_validator(mode="before")
    @classmethod
    def _keys_of_other_types(cls, data):
        """A key of another material type is named as such, not only as unknown."""
        if isinstance(data, dict):
            for key in data:
                owners = [name for name, model in MATERIAL_TYPES.items() if key in model.model_fields]
                if key not in cls.model_fields and owners:
                    kind = data.get("type", "phong")
                    raise ValueError(f"{key!r} is not a key of a {kind} material (it belongs to {', '.join(owners)})")
        return data


class PhongMaterial(_MaterialBase):
    """The seed's model, the default type: a Phong exponent `specular` (none: matte), mirror
    `reflective`, `transparency` with an index `ior` and Beer-Lambert `absorption` inside."""

    type: Literal["phong"] = "phong"
    """`"phong"`: the seed's model, the default when `type` is left out."""
    specular: FiniteFloat | None = Field(default=None, gt=0)
    """Phong exponent of the highlight; left out: a matte surface."""
    reflective: FiniteFloat = Field(default=0.0, ge=0, le=1)
    """Mirror reflectivity, 0..1 (reflective + transparency <= 1)."""
    transparency: FiniteFloat = Field(default=0.0, ge=0, le=1)
    """Share of light refracted through the surface, 0..1."""
    ior: FiniteFloat = Field(default=1.5, gt=0)
    """Index of refraction inside the surface."""
    absorption: Color = (0.0, 0.0, 0.0)
    """Beer-Lambert absorption coefficient per unit length inside, `[r, g, b]`."""

    @field_validator("absorption", mode="before")
    @classmethod
    def _unbounded(cls, v):
        return _colour(v, upper=None)

    @model_validator(mode="after")
    def _energy(self):
        if self.reflective + self.transparency > 1 + 1e-9:
            raise ValueError("reflective + transparency must not exceed 1")
        return self


class DiffuseMaterial(_MaterialBase):
    """Lambertian reflection of reflectance `color`."""

    type: Literal["diffuse"]
    """`"diffuse"`: Lambertian reflection of reflectance `color`."""


class ConductorMaterial(_MaterialBase):
    """A metal: `color` times the Fresnel reflectance of the complex index `eta` + i `k` (per
    RGB; neither: a perfect mirror times color), GGX `roughness` (alpha; 0 is smooth)."""

    type: Literal["conductor"]
    """`"conductor"`: a metal, `color` times the Fresnel reflectance of `eta` + i `k`."""
    roughness: FiniteFloat = Field(default=0.0, ge=0, le=1)  # GGX alpha, as Mitsuba's rough plugins
    """GGX alpha, as Mitsuba's rough plugins take it; 0 is a perfect mirror."""
    eta: Color | None = None
    """Real part of the complex index of refraction, per RGB (give `k` too; neither: a perfect mirror times `color`)."""
    k: Color | None = None
    """Imaginary part (extinction) of the complex index of refraction, per RGB."""

    @field_validator("eta", "k", mode="before")
    @classmethod
    def _unbounded(cls, v):
        return None if v is None else _colour(v, upper=None)

    @model_validator(mode="after")
    def _fresnel(self):
        if (self.eta is None) != (self.k is None):
            raise ValueError("a conductor's Fresnel needs both eta and k (or neither: a perfect mirror times color)")
        return self


class DielectricMaterial(_MaterialBase):
    """Glass: index `ior` inside, `color` the transmittance tint, Beer-Lambert `absorption`
    inside, GGX `roughness`."""

    type: Literal["dielectric"]
    """`"dielectric"`: glass, with Fresnel reflection and total internal reflection."""
    ior: FiniteFloat = Field(default=1.5, gt=0)
    """Index of refraction inside."""
    roughness: FiniteFloat = Field(default=0.0, ge=0, le=1)
    """GGX alpha; 0 is smooth glass."""
    absorption: Color = (0.0, 0.0, 0.0)
    """Beer-Lambert absorption coefficient per unit length inside, `[r, g, b]`."""

    @field_validator("absorption", mode="before")
    @classmethod
    def _unbounded(cls, v):
        return _colour(v, upper=None)


class PlasticMaterial(_MaterialBase):
    """Diffuse reflectance `color` under a dielectric coating of index `ior`, GGX `roughness`."""

    type: Literal["plastic"]
    """`"plastic"`: diffuse `color` under a dielectric coating (Mitsuba's plastic)."""
    ior: FiniteFloat = Field(default=1.5, gt=0)
    """Index of refraction of the coating, read within 1..3 (outside it, as its end): the fit of the diffuse Fresnel
    reflectance it uses, Mitsuba's, holds there."""
    roughness: FiniteFloat = Field(default=0.0, ge=0, le=1)
    """GGX alpha of the coating; 0 is smooth."""


class NullMaterial(Strict):
    """A boundary that does not bend or reflect light (an index-matched surface, as the boundary
    of a medium): no other key. It is white where a mode shows the boundary alone (cast, raster)."""

    type: Literal["null"]
    """`"null"`: an index-matched boundary that neither bends nor reflects light; no other key."""
    color: ClassVar[tuple[float, float, float]] = (1.0, 1.0, 1.0)
    emission: ClassVar[tuple[float, float, float]] = (0.0, 0.0, 0.0)
    texture: ClassVar[None] = None
    normal_map: ClassVar[None] = None
    bump_map: ClassVar[None] = None
    alpha_map: ClassVar[None] = None


# Material types: the scene's `type` -> its model class (kernels/shading/materials/ has a module
# of the same name for each).
MATERIAL_TYPES = {
    "phong": PhongMaterial,
    "diffuse": DiffuseMaterial,
    "conductor": ConductorMaterial,
    "dielectric": DielectricMaterial,
    "plastic": PlasticMaterial,
    "null": NullMaterial,
}


def _material_type(value):
    """The union tag of a material: its `type`, phong where it has none."""
    kind = value.get("type", "phong") if isinstance(value, dict) else getattr(value, "type", None)
    return f"<{kind}>" if isinstance(kind, str) else None


Material = Annotated[
    Union[tuple(Annotated[model, Tag(f"<{name}>")] for name, model in MATERIAL_TYPES.items())],
    Discriminator(
        _material_type,
        custom_error_type="unknown_type",
        custom_error_message=f"type must be one of: {', '.join(MATERIAL_TYPES)}",
    ),
]
MATERIAL_MODELS = tuple(MATERIAL_TYPES.values())


def parse_material(table: dict):
    """A material table (with or without `type`) as its model; a pydantic ValidationError."""
    return TypeAdapter(Material).validate_python(table)


def tagged_union(kinds: dict):
    """A union of models chosen by their `type` key, e.g. {"sphere": Sphere, ...}; an unknown
    type is one clear error listing the allowed ones."""
    members = tuple(Annotated[model, Tag(f"<{name}>")] for name, model in kinds.items())
    return Annotated[
        Union[members],
        Discriminator(
            _tag_by_type,
            custom_error_type="unknown_type",
            custom_error_message=f"type must be one of: {', '.join(kinds)}",
        ),
    ]


def _material_tag(value):
    if isinstance(value, str):
        return "<name>"
    if isinstance(value, (dict, *MATERIAL_MODELS)):
        return "<inline>"
    return None


MaterialRef = Annotated[
    Union[Annotated[str, Tag("<name>")], Annotated[Material, Tag("<inline>")]],
    Discriminator(
        _material_tag,
        custom_error_type="material_ref",
        custom_error_message="material must be a name from [materials] or an inline table",
    ),
]


class _LightBase(Strict):
    intensity: Color = (1.0, 1.0, 1.0)
    """A number or `[r, g, b]`, may exceed 1. Trace mode: the seed's intensity; path mode: radiometric (see the light's
    type)."""

    @field_validator("intensity", mode="before")
    @classmethod
    def _i(cls, v):
        return _intensity(v)


class AmbientLight(_LightBase):
    type: Literal["ambient"]
    """`"ambient"`: light from everywhere, no shadows (path mode: a uniform environment of radiance `intensity`)."""
    intensity: Color = (0.2, 0.2, 0.2)
    """A number or `[r, g, b]`; in path mode the environment's radiance."""


class PointLight(_LightBase):
    type: Literal["point"]
    """`"point"`: light from one point (path mode: radiant intensity in W/sr, falling off as 1/r^2)."""
    position: Vec3
    """Where the light is."""


class DirectionalLight(_LightBase):
    type: Literal["directional"]
    """`"directional"`: light from infinitely far away (path mode: irradiance on a surface facing it)."""
    direction: Vec3  # pointing towards the light
    """Pointing towards the light."""

    @field_validator("direction")
    @classmethod
    def _d(cls, v):
        return _nonzero(v, "direction")


class QuadLight(_LightBase):
    """A rectangle centred on `position` with edge vectors `u` and `v` (it spans
    position +- u/2 +- v/2), sampled with `samples` shadow rays per shading point."""

    type: Literal["quad"]
    """`"quad"`: a rectangular area light, soft shadows (path mode: an emitting surface of radiance `intensity`)."""
    position: Vec3
    """Centre of the rectangle."""
    u: Vec3
    """First edge vector: the light spans position +- u/2 +- v/2."""
    v: Vec3
    """Second edge vector."""
    samples: WholeNumber = Field(default=16, ge=1, le=MAX_LIGHT_SAMPLES)
    """Trace mode: shadow rays per shading point."""

    @model_validator(mode="after")
    def _edges(self):
        u, v = self.u, self.v
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        if not any(n):
            raise ValueError("u and v must be non-zero and not parallel")
        return self


class SpotLight(_LightBase):
    """A point light shining along `direction` within a cone of half-angle `angle` (degrees),
    at full intensity inside `inner_angle` and falling smoothly to 0 at `angle`."""

    type: Literal["spot"]
    """`"spot"`: a point light in a cone (every mode)."""
    position: Vec3
    """Where the light is."""
    direction: Vec3  # the way it shines
    """The way it shines."""
    angle: FiniteFloat = Field(default=30.0, gt=0, le=180)
    """Outer half-angle of the cone, degrees."""
    inner_angle: FiniteFloat | None = Field(default=None, ge=0, le=180)
    """Full intensity inside this half-angle, falling smoothly to 0 at `angle` (unset: 3/4 of angle)."""

    @field_validator("direction")
    @classmethod
    def _d(cls, v):
        return _nonzero(v, "direction")

    @model_validator(mode="after")
    def _cone(self):
        if self.inner_angle is not None and self.inner_angle > self.angle:
            raise ValueError(f"inner_angle ({self.inner_angle}) must not exceed angle ({self.angle})")
        return self

    @property
    def inner(self) -> float:
        """The inner angle in force: as set, else 3/4 of the outer angle."""
        return self.inner_angle if self.inner_angle is not None else 0.75 * self.angle


class SphereLight(_LightBase):
    """A sphere of `radius` around `position`, sampled with `samples` shadow rays per shading
    point (over its disk facing the point)."""

    type: Literal["sphere"]
    """`"sphere"`: a spherical area light (path mode: an emitting surface of radiance `intensity`)."""
    position: Vec3
    """Centre of the sphere."""
    radius: FiniteFloat = Field(gt=0)
    """Radius of the sphere."""
    samples: WholeNumber = Field(default=16, ge=1, le=MAX_LIGHT_SAMPLES)
    """Trace mode: shadow rays per shading point, over its disk facing the point."""


LIGHT_TYPES = {
    "ambient": AmbientLight,
    "point": PointLight,
    "directional": DirectionalLight,
    "quad": QuadLight,
    "sphere": SphereLight,
    "spot": SpotLight,
}
Light = tagged_union(LIGHT_TYPES)


Row4 = tuple[FiniteFloat, FiniteFloat, FiniteFloat, FiniteFloat]


class Transform(Strict):
    translate: Vec3 = (0.0, 0.0, 0.0)
    """Moves the shape, applied last."""
    rotate: Vec3 = (0.0, 0.0, 0.0)  # degrees, applied about x, then y, then z
    """Degrees about x, then y, then z, applied after scale."""
    scale: FiniteFloat | Vec3 = 1.0
    """A number or `[x, y, z]` (non-zero; a negative factor mirrors), applied first."""
    # Or a whole 4 x 4 object-to-world matrix, rows, column vectors (p' = M @ [p, 1]), instead of
    # the three above: what other renderers' files (pbrt, Mitsuba) hold, shears included.
    matrix: tuple[Row4, Row4, Row4, Row4] | None = None
    """Instead of translate, rotate and scale: a whole 4 x 4 object-to-world matrix, rows, column vectors (p' = M @ [p,
    1]); its last row `[0, 0, 0, 1]`."""

    @field_validator("scale")
    @classmethod
    def _s(cls, v):
        values = (v,) * 3 if isinstance(v, float) else v
        if any(c == 0 for c in values):
            raise ValueError("scale factors must be non-zero")
        return v

    @model_validator(mode="after")
    def _matrix_alone(self):
        if self.matrix is None:
            return self
        if self.translate != (0.0, 0.0, 0.0) or self.rotate != (0.0, 0.0, 0.0) or self.scale3 != (1.0, 1.0, 1.0):
            raise ValueError("matrix replaces translate, rotate and scale: give either the matrix or those")
        if tuple(self.matrix[3]) != (0.0, 0.0, 0.0, 1.0):
            raise ValueError(f"matrix's last row must be [0, 0, 0, 1] (affine), got {list(self.matrix[3])}")
        a = [row[:3] for row in self.matrix[:3]]
        det = (
            a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
        )
        size = math.prod(math.sqrt(sum(c * c for c in row)) for row in a)
        if not abs(det) > 1e-12 * size:
            raise ValueError("matrix is singular (it flattens the object)")
        return self

    @property
    def scale3(self) -> tuple[float, float, float]:
        return (self.scale,) * 3 if isinstance(self.scale, float) else self.scale


# `interior` (every object): the name of the medium inside a closed shape, in [media]; open
# shapes refuse it.
MediumRef = Annotated[str | None, Field(default=None, min_length=1)]


def _no_interior(obj, shape: str):
    """interior needs an inside: refuse it on shapes that have none (DESIGN.md section 7)."""
    if obj.interior is not None:
        raise ValueError(
            f"interior: a {shape} is open, it has no inside to fill; a medium needs a closed shape "
            "(a sphere, a capped cylinder or a closed mesh)"
        )
    return obj


class Sphere(Strict):
    type: Literal["sphere"]
    """`"sphere"`."""
    center: Vec3
    """Centre of the sphere."""
    radius: FiniteFloat = Field(gt=0)
    """Radius of the sphere."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table (default: matte white phong)."""
    transform: Transform = Transform()
    """Scale (uniform only), rotate (turns its UVs) and translate, after `center` and `radius`."""
    interior: MediumRef = None
    """Path mode: the medium inside, a name in `[media]`."""

    @field_validator("transform")
    @classmethod
    def _t(cls, v):
        return _similarity(v, "sphere")


class Plane(Strict):
    type: Literal["plane"]
    """`"plane"`: an infinite plane."""
    point: Vec3 = (0.0, 0.0, 0.0)
    """A point on the plane."""
    normal: Vec3 = (0.0, 1.0, 0.0)
    """The plane's normal (two-sided)."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table."""
    transform: Transform = Transform()
    """Scale, rotate and translate, applied to `point` and `normal`."""
    interior: MediumRef = None
    """Refused: a plane has no inside (the key exists for a clear error)."""

    @model_validator(mode="after")
    def _open(self):
        return _no_interior(self, "plane")

    @field_validator("normal")
    @classmethod
    def _n(cls, v):
        return _nonzero(v, "normal")


class Triangle(Strict):
    type: Literal["triangle"]
    """`"triangle"`: one triangle."""
    vertices: tuple[Vec3, Vec3, Vec3]
    """Three vertices `[[x, y, z], [x, y, z], [x, y, z]]`, not collinear."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table."""
    transform: Transform = Transform()
    """Scale, rotate and translate, applied to the vertices."""
    interior: MediumRef = None
    """Refused: a triangle has no inside (the key exists for a clear error)."""

    @model_validator(mode="after")
    def _open(self):
        return _no_interior(self, "triangle")

    @field_validator("vertices")
    @classmethod
    def _area(cls, v):
        a, b, c = v
        e1 = [b[k] - a[k] for k in range(3)]
        e2 = [c[k] - a[k] for k in range(3)]
        n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
        if not any(n):
            raise ValueError("the triangle's vertices are collinear (zero area)")
        return v


class Fit(Strict):
    """Place a mesh in a box: scaled uniformly so that the largest side of its bounding box is
    `size`, and moved so that the box's centre is `center`."""

    center: Vec3 = (0.0, 0.0, 0.0)
    """Where the centre of the mesh's bounding box goes."""
    size: FiniteFloat = Field(gt=0)
    """The largest side of the mesh's bounding box after the fit."""


class MeshTransform(Transform):
    """A mesh's transform: scale, rotate, translate as for every shape, or `fit` instead of
    scale and translate (the mesh is rotated, then fitted into the box)."""

    fit: Fit | None = None
    """Instead of scale and translate: rotate the mesh, then scale it uniformly and move it into this box: `{ center,
    size }`."""

    @model_validator(mode="after")
    def _fit_alone(self):
        # fit sets the size and the position: a scale or translate beside it would be ambiguous
        if self.fit is not None and (
            self.translate != (0.0, 0.0, 0.0) or self.scale3 != (1.0, 1.0, 1.0) or self.matrix is not None
        ):
            raise ValueError(
                "fit sets the mesh's size and position, so it cannot be combined with translate, scale or matrix; "
                "keep rotate and fit, or drop fit"
            )
        return self


Index3 = tuple[Annotated[int, Field(ge=0)], Annotated[int, Field(ge=0)], Annotated[int, Field(ge=0)]]


def _array_rows(value, width: int, integers: bool) -> list[tuple]:
    """An inline mesh table given as a numpy array, checked as a whole and returned as the list of
    row tuples that validating its rows one by one gives: at 1M triangles pydantic took 5 s over
    the rows (4 us a vertex), this ~1.5 s, most of it making the tuples. `integers`: face indices
    (whole numbers from 0), else finite numbers. Each message says what it got (the error's
    formatter would otherwise print the whole array)."""
    import numpy as np

    a = np.asarray(value)
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"an array of {width} columns is needed (one row of {width} values each), got shape {a.shape}")
    if a.dtype.kind not in "iuf":
        raise ValueError(f"the array's values must be numbers, got {a.dtype}")
    finite = np.isfinite(a).all(axis=1) if a.dtype.kind == "f" else np.ones(len(a), dtype=bool)
    if not finite.all():
        row = int(np.flatnonzero(~finite)[0])
        raise ValueError(f"row {row} holds a value that is not a finite number, got {a[row].tolist()}")
    # (float16 and float32 cannot pass float32's range: comparing them with 3.4e38 would warn)
    if a.dtype.kind == "f" and a.itemsize > 4 and len(a) and (huge := np.abs(a).max(axis=1) > F32_MAX).any():
        row = int(np.flatnonzero(huge)[0])
        raise ValueError(f"row {row} holds a value beyond float32's range (3.4e38), got {a[row].tolist()}")
    if integers:
        if a.dtype.kind == "f" and (a != np.round(a)).any():
            raise ValueError(f"face indices must be whole numbers, got {a[a != np.round(a)][0]}")
        if len(a) and a.min() < 0:
            raise ValueError(f"face indices count from 0, got {a.min()}")
        return list(map(tuple, a.astype(np.int64).tolist()))
    return list(map(tuple, a.astype(np.float64).tolist()))


def _is_array(value) -> bool:
    """A numpy array, or a subclass of one (trimesh's TrackedArray, a mesh's own vertices and
    faces: checked row by row before, complex vertices taken), without importing numpy."""
    numpy = sys.modules.get("numpy")
    return numpy is not None and isinstance(value, numpy.ndarray)


class Mesh(Strict):
    type: Literal["mesh"]
    """`"mesh"`: a triangle mesh from a file (OBJ, PLY, STL, OFF, glTF/GLB through trimesh)."""
    # The triangles: a mesh file (relative to the scene file), or inline `vertices` with
    # `faces` (three vertex indices each, from 0; cross(v1 - v0, v2 - v0) is the front) and
    # optional per-vertex `normals` and `uvs`, as other renderers' files carry meshes.
    file: FileName | None = None
    """The mesh file, relative to the scene file (or inline `vertices` and `faces` instead)."""
    vertices: list[Vec3] | None = None
    """Inline triangles instead of `file`: the vertex positions."""
    faces: list[Index3] | None = None
    """With `vertices`: three vertex indices per triangle, from 0; cross(v1 - v0, v2 - v0) is the front."""
    normals: list[Vec3] | None = None
    """With `vertices`: a normal per vertex (smooth shading)."""
    uvs: list[tuple[FiniteFloat, FiniteFloat]] | None = None
    """With `vertices`: texture coordinates `[u, v]` per vertex."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table."""
    transform: MeshTransform = MeshTransform()
    """Scale, rotate and translate (or `fit`), applied to the mesh."""
    smooth: Flag | None = None  # None: use the file's vertex normals when it has them
    """Interpolate vertex normals (unset: when the file has them)."""
    # "right": the file is right-handed (most OBJ and glTF): mirror x before the transform
    handedness: Literal["left", "right"] = "left"
    """`"right"`: the file is right-handed (most OBJ and glTF files), mirrored across x before the transform."""
    shape_index: WholeNumber = Field(default=0, ge=0)
    """Which mesh of a Mitsuba `.serialized` file (it holds several), from 0: Mitsuba's `shape_index`."""
    # Copies of the mesh, each placed by a matrix after `transform` (column vectors, p' = M @ [p, 1]):
    # a .npy file of shape (N, 4, 4) or (N, 3, 4), relative to the scene file, or inline
    # transforms. The mesh and its BVH are stored once (scene/instances.py, compile/instances.py).
    instances: FileName | list[Transform] | None = None
    """Copies of the mesh, each placed by a matrix after `transform` (p' = M @ [p, 1]): a `.npy` of (N, 4, 4) or (N, 3,
    4) matrices relative to the scene file, or a list of transform tables. The mesh and its BVH are stored once."""
    interior: MediumRef = None  # the mesh must be closed (checked when it is loaded)
    """Path mode: the medium inside, a name in `[media]` (the mesh must be closed)."""

    @field_validator("vertices", "normals", "faces", "uvs", mode="wrap")
    @classmethod
    def _numpy_tables(cls, value, handler, info):
        """A numpy array (the Python API's usual way to hand over a mesh) checked as a whole;
        lists row by row, by the field's type."""
        if value is not None and _is_array(value):
            return _array_rows(value, 2 if info.field_name == "uvs" else 3, info.field_name == "faces")
        return handler(value)

    @field_validator("instances", mode="before")
    @classmethod
    def _instance_array(cls, v):
        """A numpy array of (N, 4, 4) or (N, 3, 4) matrices, as a .npy file holds them: each a
        `matrix` transform (it was refused with every matrix printed), checked as inline ones
        are (scene/instances.check_matrices, when the scene is compiled)."""
        if not _is_array(v):
            return v
        if v.ndim != 3 or v.shape[1:] not in ((4, 4), (3, 4)) or v.dtype.kind not in "iuf":
            raise ValueError("an array of instances holds (N, 4, 4) or (N, 3, 4) matrices of numbers")
        bottom = [[0.0, 0.0, 0.0, 1.0]] if v.shape[1] == 3 else []
        return [{"matrix": [*m.tolist(), *bottom]} for m in v.astype(float)]

    @field_validator("instances")
    @classmethod
    def _instances(cls, v):
        if isinstance(v, list) and not v:
            raise ValueError("instances must list at least one transform (or be left out)")
        if isinstance(v, str) and not v.strip():
            raise ValueError("instances must name a .npy file of (N, 4, 4) or (N, 3, 4) matrices")
        return v

    @model_validator(mode="after")
    def _one_source(self):
        if (self.file is None) == (self.vertices is None):
            raise ValueError('a mesh has either file = "model.obj" or inline vertices and faces (exactly one)')
        if self.file is not None:
            extra = [key for key in ("faces", "normals", "uvs") if getattr(self, key) is not None]
            if extra:
                raise ValueError(f"{', '.join(extra)} go with inline vertices, not with a mesh file")
            return self
        n = len(self.vertices)
        if not self.faces:
            raise ValueError("inline vertices need faces: a list of [i, j, k] vertex indices")
        top = max(max(face) for face in self.faces)
        if top >= n:
            raise ValueError(f"faces index vertex {top}, but there are {n} vertices (indices count from 0)")
        for key in ("normals", "uvs"):
            values = getattr(self, key)
            if values is not None and len(values) != n:
                raise ValueError(f"{key} has {len(values)} entries; it needs one per vertex ({n})")
        return self


def _similarity(transform: Transform, shape: str) -> Transform:
    if transform.matrix is not None:
        cols = [[transform.matrix[r][c] for r in range(3)] for c in range(3)]
        lengths = [math.sqrt(sum(x * x for x in col)) for col in cols]
        dots = [abs(sum(a * b for a, b in zip(cols[i], cols[j]))) for i, j in ((0, 1), (0, 2), (1, 2))]
        if max(lengths) - min(lengths) > 1e-9 * max(lengths) or max(dots) > 1e-9 * max(lengths) ** 2:
            raise ValueError(
                f"a {shape}'s transform.matrix must be a similarity (rotation, uniform scale, translation): "
                "anything else would make it elliptic"
            )
        return transform
    s = transform.scale3
    if not (abs(s[0]) == abs(s[1]) == abs(s[2])):
        raise ValueError(
            f"a {shape}'s transform.scale must be uniform (one number): a non-uniform scale "
            f"would make it elliptic; got {list(s)}"
        )
    return transform


class Disk(Strict):
    """A flat disk of `radius` around `center`, facing along `normal` (two-sided)."""

    type: Literal["disk"]
    """`"disk"`: a flat, two-sided disk."""
    center: Vec3 = (0.0, 0.0, 0.0)
    """Centre of the disk."""
    normal: Vec3 = (0.0, 1.0, 0.0)
    """The way the disk faces."""
    radius: FiniteFloat = Field(gt=0)
    """Radius of the disk."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table."""
    transform: Transform = Transform()
    """Scale (uniform only), rotate and translate."""
    interior: MediumRef = None
    """Refused: a disk has no inside (the key exists for a clear error)."""

    @model_validator(mode="after")
    def _open(self):
        return _no_interior(self, "disk")

    @field_validator("normal")
    @classmethod
    def _n(cls, v):
        return _nonzero(v, "normal")

    @field_validator("transform")
    @classmethod
    def _t(cls, v):
        return _similarity(v, "disk")


class Quad(Strict):
    """A parallelogram centred on `position` with edge vectors `u` and `v`: it spans
    position +- u/2 +- v/2, like the quad light (two-sided)."""

    type: Literal["quad"]
    """`"quad"`: a parallelogram, two-sided."""
    position: Vec3 = (0.0, 0.0, 0.0)
    """Its centre: it spans position +- u/2 +- v/2."""
    u: Vec3
    """First edge vector."""
    v: Vec3
    """Second edge vector, not parallel to u."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table."""
    transform: Transform = Transform()
    """Scale, rotate and translate."""
    interior: MediumRef = None
    """Refused: a quad has no inside (the key exists for a clear error)."""

    @model_validator(mode="after")
    def _edges(self):
        u, v = self.u, self.v
        n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        if (
            math.sqrt(sum(c * c for c in n))
            <= 1e-12 * math.sqrt(sum(c * c for c in u)) * math.sqrt(sum(c * c for c in v))
            or not any(u)
            or not any(v)
        ):
            raise ValueError("u and v must be non-zero and not parallel (the quad would have no area)")
        return _no_interior(self, "quad")


class Cylinder(Strict):
    """A cylinder from `p0` to `p1` (the centres of its ends) of `radius`; `capped` closes both
    ends with disks, otherwise it is an open tube."""

    type: Literal["cylinder"]
    """`"cylinder"`."""
    p0: Vec3
    """Centre of one end."""
    p1: Vec3
    """Centre of the other end."""
    radius: FiniteFloat = Field(gt=0)
    """Radius of the cylinder."""
    capped: Flag = True
    """true: both ends closed with disks; false: an open tube."""
    material: MaterialRef = "default"
    """A name from `[materials]` or an inline material table."""
    transform: Transform = Transform()
    """Scale (uniform only), rotate and translate."""
    interior: MediumRef = None
    """Path mode: the medium inside a capped cylinder, a name in `[media]`."""

    @model_validator(mode="after")
    def _axis(self):
        if self.p0 == self.p1:
            raise ValueError("p0 and p1 must differ (the cylinder would have no length)")
        if not self.capped:
            _no_interior(self, "cylinder without caps (capped = false)")
        return self

    @field_validator("transform")
    @classmethod
    def _t(cls, v):
        return _similarity(v, "cylinder")


class Gltf(Strict):
    """A glTF 2.0 file's meshes and materials (scene/gltf.py), placed by `transform` after the
    file's own node transforms and the right- to left-handed conversion. Its cameras and lights
    are not imported into a scene that places it (`raylume render file.glb` uses them)."""

    type: Literal["gltf"]
    """`"gltf"`: the meshes and materials of a glTF 2.0 file (its cameras and lights are not imported)."""
    file: FileName
    """The `.gltf` or `.glb` file, relative to the scene file."""
    transform: Transform = Transform()
    """Applied after the file's own node transforms and the right- to left-handed conversion."""

    @property
    def material(self) -> str:
        return "default"  # materials come from the file


OBJECT_TYPES = {
    "sphere": Sphere,
    "plane": Plane,
    "triangle": Triangle,
    "mesh": Mesh,
    "disk": Disk,
    "quad": Quad,
    "cylinder": Cylinder,
    "gltf": Gltf,
}
SceneObject = tagged_union(OBJECT_TYPES)

DEFAULT_MATERIAL = PhongMaterial()


class Environment(Strict):
    """Light from every direction for rays that hit nothing (it replaces `background`): a
    constant `color` or an equirectangular image `file` (.exr or .hdr; its centre column
    looks along +z, its top row along +y), scaled by `intensity`, turned by `rotate` (degrees,
    as object transforms)."""

    color: Color | None = None
    """Constant radiance `[r, g, b]` from every direction (give `color` or `file`)."""
    file: FileName | None = None
    """An equirectangular `.hdr` or `.exr` image, relative to the scene file; importance-sampled in path mode."""
    intensity: FiniteFloat = Field(default=1.0, ge=0)
    """Scales the environment."""
    rotate: Vec3 = (0.0, 0.0, 0.0)
    """Degrees about x, then y, then z, as object transforms."""
    # Or the world-from-environment matrix itself (3 x 3 rows, orthogonal: a rotation, or one
    # with a mirror), as other renderers' files give it.
    matrix: tuple[Vec3, Vec3, Vec3] | None = None
    """Instead of `rotate`: the world-from-environment matrix, 3 x 3 rows, orthogonal (a rotation, possibly with a
    mirror)."""
    # How the file covers the sphere: "equirectangular", or pbrt-v4's square "equal-area"
    # octahedral map (converted to equirectangular when the scene is compiled).
    mapping: Literal["equirectangular", "equal-area"] = "equirectangular"
    """How the image covers the sphere: `equirectangular`, or pbrt-v4's square `equal-area` octahedral map."""

    @field_validator("matrix")
    @classmethod
    def _orthogonal(cls, v):
        if v is None:
            return v
        for i in range(3):
            for j in range(3):
                dot = sum(v[k][i] * v[k][j] for k in range(3))
                if abs(dot - (1.0 if i == j else 0.0)) > 1e-6:
                    raise ValueError("matrix must be orthogonal (a rotation, possibly with a mirror)")
        return v

    @field_validator("color", mode="before")
    @classmethod
    def _col(cls, v):
        return _colour(v, upper=None)

    @model_validator(mode="after")
    def _one_source(self):
        if (self.color is None) == (self.file is None):
            raise ValueError('give exactly one of color = [r, g, b] and file = "sky.hdr"')
        if self.matrix is not None and self.rotate != (0.0, 0.0, 0.0):
            raise ValueError("matrix replaces rotate: give one of them")
        if self.mapping != "equirectangular" and self.file is None:
            raise ValueError("mapping applies to an image file")
        return self


def _coefficients(value):
    """A medium's coefficient: a number (grey) or [r, g, b], per scene unit of length, >= 0."""
    return _intensity(value)


class _MediumBase(Strict):
    # absorption and scattering coefficients per scene unit of length (RGB), and the
    # Henyey-Greenstein asymmetry g (-1 back, 0 isotropic, 1 forward; the ends excluded)
    sigma_a: Color = (0.0, 0.0, 0.0)
    """Absorption coefficient per scene unit of length, a number or `[r, g, b]`."""
    sigma_s: Color = (0.0, 0.0, 0.0)
    """Scattering coefficient per scene unit of length, a number or `[r, g, b]`."""
    g: FiniteFloat = Field(default=0.0, gt=-1, lt=1)
    """Henyey-Greenstein asymmetry: -1 back, 0 isotropic, 1 forward (the ends excluded)."""

    @field_validator("sigma_a", "sigma_s", mode="before")
    @classmethod
    def _coefficient(cls, v):
        return _coefficients(v)


class HomogeneousMedium(_MediumBase):
    """A medium of the same density everywhere (fog, milk, smoke of even density)."""

    type: Literal["homogeneous"]
    """`"homogeneous"`: the same density everywhere (fog, milk)."""


class GridMedium(_MediumBase):
    """A medium whose density varies: `density` a .npy float array (nz, ny, nx) >= 0 filling the
    box bounds_min..bounds_max (voxel (k, j, i) its cell at z index k, y index j, x index i),
    interpolated trilinearly between the cells' centres; sigma_a and sigma_s are scaled by it.
    Outside the box the density is 0."""

    type: Literal["grid"]
    """`"grid"`: a density that varies, from a voxel grid."""
    density: FileName = Field(min_length=1)
    """A `.npy` float array of shape (nz, ny, nx), >= 0, relative to the scene file; scales sigma_a and sigma_s,
    trilinearly interpolated."""
    bounds_min: Vec3
    """The world box's lower corner that the grid fills."""
    bounds_max: Vec3
    """The world box's upper corner."""

    @model_validator(mode="after")
    def _box(self):
        if any(hi <= lo for lo, hi in zip(self.bounds_min, self.bounds_max)):
            raise ValueError(
                f"bounds_max must exceed bounds_min on every axis, got {list(self.bounds_min)} .. "
                f"{list(self.bounds_max)}"
            )
        return self


MEDIUM_TYPES = {"homogeneous": HomogeneousMedium, "grid": GridMedium}
Medium = tagged_union(MEDIUM_TYPES)


MAX_FRAMES = 1_000_000


class CameraKey(Strict):
    """A camera keyframe of [animation]: the frame it holds at, and any of the camera's
    position, look_at, up and fov (the others are interpolated from the keyframes that have
    them, or taken from [camera])."""

    frame: WholeNumber = Field(ge=0, lt=MAX_FRAMES)
    """The frame this keyframe holds at, from 0."""
    position: Vec3 | None = None
    """The camera's position at this frame."""
    look_at: Vec3 | None = None
    """The camera's look_at at this frame."""
    up: Vec3 | None = None
    """The camera's up at this frame."""
    fov: FiniteFloat | None = Field(default=None, gt=0, lt=180)
    """The camera's vertical field of view at this frame, degrees."""


class Animation(Strict):
    """`[animation]`: `frames` frames at `fps`, the camera interpolated between the keyframes
    of `[[animation.camera]]` (raylume/animation.py)."""

    frames: WholeNumber = Field(ge=1, le=MAX_FRAMES)
    """Number of frames."""
    fps: FiniteFloat = Field(default=24.0, gt=0, le=1000)
    """Frames per second of a video."""
    interpolation: Literal["linear", "catmull-rom"] = "catmull-rom"
    """`catmull-rom` (smooth through every keyframe) or `linear`."""
    camera: list[CameraKey] = []
    """Camera keyframes, `[[animation.camera]]` tables."""

    @model_validator(mode="after")
    def _keyframes(self):
        seen: dict[int, int] = {}
        for k, key in enumerate(self.camera):
            if key.frame >= self.frames:
                raise ValueError(
                    f"camera[{k}].frame: {key.frame} is past the last frame, {self.frames - 1} "
                    f"(frames = {self.frames} counts from 0)"
                )
            if key.frame in seen:
                earlier = seen[key.frame]
                raise ValueError(f"camera[{k}].frame: frame {key.frame} has a keyframe already (camera[{earlier}])")
            seen[key.frame] = k
        return self


class Scene(Strict):
    """A validated scene: the tables of a scene file (`render`, `camera`, `materials`, `lights`,
    `objects`, `environment`, `media`, `animation`). Made by `raylume.load` (a file),
    `raylume.scene_from_dict` (a dict as a file would hold it) or `raylume.builtin_scene`;
    rendered by `raylume.render`, `raylume.Session` and `raylume.view`. Frozen: `replace`,
    `with_camera` and `with_render` give validated copies. The keys are documented in the
    scene reference (docs/reference/scene.md)."""

    render: RenderSettings = RenderSettings()
    """How to render: size, samples, mode, encoding."""
    camera: Camera = Camera()
    """The camera."""
    materials: dict[str, Material] = {}
    """Named materials, `[materials.NAME]`, that objects refer to by name."""
    lights: list[Light] = []
    """The lights, `[[lights]]` tables."""
    objects: list[SceneObject] = []
    """The objects, `[[objects]]` tables."""
    environment: Environment | None = None
    """Light from every direction for rays that hit nothing; replaces `background`."""
    animation: Animation | None = None
    """A camera flight: frames and keyframes."""
    media: dict[str, Medium] = {}
    """Named participating media, `[media.NAME]`, for objects' `interior` and `[render] medium`."""

    # Folder that relative paths (mesh files) are resolved against; set by the loader.
    _base_dir: Path = PrivateAttr(default_factory=Path.cwd)
    # Where a pbrt or Mitsuba file's tables came from ({"objects[3]": 'scene.pbrt:12: Shape "plymesh"'}),
    # set by the loader, so that errors found later (an unreadable mesh file) name the source line.
    _origins: dict[str, str] = PrivateAttr(default_factory=dict)
    # Frozen, but its tables (materials) are dicts: not hashable. Said by the class, rather than
    # as pydantic's hash of its fields failing with "unhashable type: 'dict'".
    __hash__ = None  # type: ignore[assignment]

    @model_validator(mode="after")
    def _material_names(self):
        for k, obj in enumerate(self.objects):
            ref = obj.material
            if isinstance(ref, str) and ref != "default" and ref not in self.materials:
                known = ", ".join(sorted(self.materials)) or "none are defined"
                raise ValueError(f"objects[{k}].material: no material named {ref!r} in [materials] ({known})")
        known_media = ", ".join(sorted(self.media)) or "none are defined"
        for k, obj in enumerate(self.objects):
            name = getattr(obj, "interior", None)
            if name is not None and name not in self.media:
                raise ValueError(f"objects[{k}].interior: no medium named {name!r} in [media] ({known_media})")
        if self.render.medium is not None and self.render.medium not in self.media:
            raise ValueError(f"render.medium: no medium named {self.render.medium!r} in [media] ({known_media})")
        return self

    @property
    def base_dir(self) -> Path:
        return self._base_dir

    def with_base_dir(self, base_dir: Path) -> Scene:
        self._base_dir = Path(base_dir)
        return self

    @property
    def origins(self) -> dict[str, str]:
        return self._origins

    def with_origins(self, origins: dict[str, str]) -> Scene:
        self._origins = dict(origins)
        return self

    def material_of(self, obj) -> Material:
        ref = obj.material
        if isinstance(ref, MATERIAL_MODELS):
            return ref
        return self.materials.get(ref, DEFAULT_MATERIAL)

    def with_render(self, **overrides: Any) -> Scene:
        """A copy whose [render] table has the given (non-None) values replaced, re-validated
        (`scene.with_render(width=64, spp=16)`); errors are SceneErrors naming the key."""
        values = {k: v for k, v in overrides.items() if v is not None}
        if not values:
            return self
        return self._changed({"render": values}, "Scene.with_render")

    def replace(self, **changes: Any) -> Scene:
        """A validated copy with some tables changed, e.g. `scene.replace(camera={"fov": 40},
        render={"width": 64})`. A dict is merged into the table it names, nested tables too
        (`materials={"glass": {"ior": 1.33}}` changes one key of one material); anything else (a
        list of lights or objects, a Camera) replaces the table. Errors are SceneErrors naming
        the key path."""
        return self._changed(changes, "Scene.replace")

    def with_camera(self, camera: Camera | dict | None = None, **keys: Any) -> Scene:
        """A copy with another camera: a Camera, or camera keys changing the current one
        (`scene.with_camera(fov=40)`, `scene.with_camera({"position": [0, 1, -3]})`)."""
        if camera is not None and not isinstance(camera, (Camera, dict)):
            raise TypeError(f"camera must be a raylume.Camera or a dict of camera keys, got {camera!r}")
        table = camera.model_dump() if isinstance(camera, Camera) else dict(camera or {})
        return self._changed({"camera": {**table, **keys}}, "Scene.with_camera")

    def _changed(self, changes: dict, call: str) -> Scene:
        for key in changes:
            if key not in type(self).model_fields:
                raise SceneError(f"{call}: unknown key {key!r}; a scene has {', '.join(type(self).model_fields)}")
        document = self.model_dump(exclude_unset=True)
        for key, value in changes.items():
            if isinstance(value, BaseModel):
                value = value.model_dump()  # a whole table: every key of the old one is replaced
                document[key] = value
            else:
                document[key] = _merged(document.get(key), value)
        try:
            scene = type(self).model_validate(document)
        except ValidationError as exc:
            raise SceneError(format_validation_error(exc, call, type(self))) from None
        return scene.with_base_dir(self.base_dir)


def _merged(old, new):
    """`new` merged into `old` where both are tables (recursively); otherwise `new`."""
    if isinstance(old, dict) and isinstance(new, dict):
        return {**old, **{key: _merged(old.get(key), value) for key, value in new.items()}}
    return new
