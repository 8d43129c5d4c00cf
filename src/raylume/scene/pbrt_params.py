"""Typed access to one pbrt directive's parameter list, remembering which parameters were read,
so that those raylume does not use can be named in a warning rather than dropped silently."""

from __future__ import annotations

from .pbrt_parse import Directive, Param, resolve
from .pbrt_spectra import NAMED_RGB, band_rgb, blackbody_rgb, unit_luminance
from .pbrt_tokens import PbrtError

Rgb = tuple[float, float, float]


class Params:
    def __init__(self, directive: Directive):
        self.directive = directive
        self.by_name: dict[str, Param] = {}
        for p in directive.params:
            if p.name in self.by_name:
                raise self.error(p, "is given twice")
            self.by_name[p.name] = p

    def error(self, p: Param, why: str) -> PbrtError:
        return self.directive.fail(f"parameter {p.label} {why}")

    def _get(self, name: str, types: tuple[str, ...]) -> Param | None:
        p = self.by_name.get(name)
        if p is None:
            return None
        if p.type not in types:
            raise self.error(p, f"must be of type {' or '.join(types)}")
        p.used = True
        return p

    def has(self, name: str) -> bool:
        return name in self.by_name

    def type_of(self, name: str) -> str | None:
        p = self.by_name.get(name)
        return None if p is None else p.type

    def one(self, name: str, kind: str, default=None):
        p = self._get(name, (kind,))
        if p is None:
            return default
        if len(p.values) != 1:
            raise self.error(p, f"takes one value, got {len(p.values)}")
        return p.values[0]

    def float(self, name: str, default: float | None = None) -> float | None:
        return self.one(name, "float", default)

    def int(self, name: str, default: int | None = None) -> int | None:
        return self.one(name, "integer", default)

    def string(self, name: str, default: str | None = None) -> str | None:
        return self.one(name, "string", default)

    def bool(self, name: str, default: bool) -> bool:
        return self.one(name, "bool", default)

    def texture(self, name: str) -> str | None:
        return self.one(name, "texture")

    def list(self, name: str, kind: str, width: int = 1) -> list | None:
        """The values of a parameter as a list of width-tuples (numbers for width 1)."""
        p = self._get(name, (kind,))
        if p is None:
            return None
        if width == 1:
            return list(p.values)
        return [tuple(p.values[k : k + width]) for k in range(0, len(p.values), width)]

    def floats(self, name: str, count: int) -> tuple | None:
        """A float parameter of exactly `count` values (as a tuple), or None."""
        p = self._get(name, ("float",))
        if p is None:
            return None
        if len(p.values) != count:
            raise self.error(p, f"takes {count} values, got {len(p.values)}")
        return tuple(p.values)

    def colour(self, name: str, default: Rgb | None = None, emission: bool = False) -> Rgb | None:
        """An rgb, spectrum, blackbody or float parameter as RGB (pbrt_spectra.py). Emission
        spectra (`emission`) other than rgb are scaled to unit luminance, as pbrt-v4 does."""
        p = self._get(name, ("rgb", "spectrum", "blackbody", "float"))
        if p is None:
            return default
        if p.type == "rgb":
            if len(p.values) != 3:
                raise self.error(p, f"takes 3 values (r g b), got {len(p.values)}")
            return tuple(p.values)
        if p.type == "float":
            if len(p.values) != 1:
                raise self.error(p, f"takes one value, got {len(p.values)}")
            return (p.values[0],) * 3
        if p.type == "blackbody":
            if len(p.values) != 1 or not p.values[0] > 0:
                raise self.error(p, "takes one temperature in kelvin, > 0")
            return blackbody_rgb(p.values[0])
        if isinstance(p.values[0], str):
            if len(p.values) != 1:
                raise self.error(p, "takes one spectrum name")
            name_ = p.values[0]
            if name_ == "stdillum-D65":
                return (1.0, 1.0, 1.0)  # sRGB's white point: white at unit luminance
            if name_ in NAMED_RGB:
                rgb = NAMED_RGB[name_]
            elif resolve(name_, self.directive.search_dir).is_file():
                rgb = band_rgb(self._spectrum_file(p, resolve(name_, self.directive.search_dir)))
            else:
                known = ", ".join(NAMED_RGB)
                raise self.error(p, f"names spectrum {name_!r}: no such file, nor a spectrum raylume knows ({known})")
        else:
            pairs = p.values
            if any(pairs[k] >= pairs[k + 2] for k in range(0, len(pairs) - 2, 2)):
                raise self.error(p, "must list wavelength, value pairs in increasing wavelength")
            rgb = band_rgb(pairs)
        return unit_luminance(rgb) if emission else rgb

    def _spectrum_file(self, p: Param, path) -> list[float]:
        """A spectrum file as pbrt reads it: wavelength, value pairs as numbers, # comments."""
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise self.error(p, f"cannot read the spectrum file {str(path)!r} ({exc})") from None
        words = " ".join(line.split("#", 1)[0] for line in text.splitlines()).split()
        try:
            pairs = [float(w) for w in words]
        except ValueError:
            raise self.error(p, f"{path} holds something that is not a number") from None
        if not pairs or len(pairs) % 2 or any(pairs[k] >= pairs[k + 2] for k in range(0, len(pairs) - 2, 2)):
            raise self.error(p, f"{path} must hold wavelength, value pairs in increasing wavelength")
        return pairs

    def unused(self) -> list[Param]:
        return [p for p in self.directive.params if not p.used]
