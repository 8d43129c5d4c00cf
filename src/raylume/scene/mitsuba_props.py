"""The properties of one Mitsuba plugin element (`<float name="alpha" value="0.1"/>`, `<rgb>`,
`<transform>`, nested plugins and `<ref>`s), read by name and type. Every property the reader
takes is ticked off, so the ones raylume does not use can be named in a warning.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import SceneError
from .mitsuba_xml import Node

PLUGIN_TAGS = ("bsdf", "emitter", "shape", "sensor", "film", "rfilter", "sampler", "integrator", "texture", "medium")
PLUGIN_TAGS += ("phase", "volume")
VALUE_TAGS = ("float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector", "transform")
_SEPARATORS = re.compile(r"[,\s]+")


def numbers(text: str, node: Node, what: str) -> list[float]:
    """Numbers separated by commas and/or spaces, as Mitsuba writes them."""
    try:
        values = [float(part) for part in _SEPARATORS.split(text.strip()) if part]
    except ValueError:
        raise node.error(f"{what}: expected numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise node.error(f"{what}: numbers must be finite, got {text!r}")
    return values


def number(text: str, node: Node, what: str) -> float:
    """Exactly one number."""
    values = numbers(text, node, what)
    if len(values) != 1:
        raise node.error(f"{what}: expected one number, got {text!r}")
    return values[0]


def attr(node: Node, key: str) -> str:
    value = node.attrs.get(key)
    if value is None:
        raise node.error(f"needs a {key} attribute")
    return value


def vector3(node: Node, default: float = 0.0) -> np.ndarray:
    """A point or vector: x, y, z attributes (missing ones `default`) or value="x, y, z"."""
    if "value" in node.attrs:
        values = numbers(node.attrs["value"], node, "value")
        if len(values) == 1:
            values *= 3
        if len(values) != 3:
            raise node.error(f"value: expected 1 or 3 numbers, got {len(values)}")
        return np.array(values)
    return np.array([number(node.attrs.get(k, str(default)), node, k) for k in "xyz"])


def _triple(text: str, node: Node, what: str) -> np.ndarray:
    values = numbers(text, node, what)
    if len(values) != 3:
        raise node.error(f"{what}: expected 3 numbers, got {len(values)}")
    return np.array(values)


def rotation(axis: np.ndarray, degrees: float) -> np.ndarray:
    """Rotation by `degrees` about `axis`, counter-clockwise looking down the axis (Rodrigues)."""
    n = np.linalg.norm(axis)
    if n == 0:
        raise ValueError("the rotation axis is the zero vector")
    x, y, z = axis / n
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    m = np.eye(4)
    m[:3, :3] = c * np.eye(3) + s * k + (1 - c) * np.outer([x, y, z], [x, y, z])
    return m


def look_at(origin: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Mitsuba's look_at: columns left = up x dir, up' = dir x left, dir, origin."""
    d = target - origin
    if not np.any(d):
        raise ValueError("origin and target are the same point")
    d = d / np.linalg.norm(d)
    left = np.cross(up, d)
    if np.linalg.norm(left) < 1e-12:
        raise ValueError("up is parallel to the viewing direction")
    left /= np.linalg.norm(left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, np.cross(d, left), d, origin
    return m


def _operation(op: Node) -> np.ndarray:
    m = np.eye(4)
    if op.tag == "translate":
        m[:3, 3] = vector3(op, 0.0)
    elif op.tag == "scale":
        if "value" in op.attrs:
            m[:3, :3] = np.diag(vector3(op))
        else:
            m[:3, :3] = np.diag(vector3(op, 1.0))
    elif op.tag == "rotate":
        axis = vector3(op, 0.0)
        return rotation(axis, number(attr(op, "angle"), op, "angle"))
    elif op.tag == "matrix":
        values = numbers(attr(op, "value"), op, "value")
        if len(values) == 16:
            m = np.array(values).reshape(4, 4)
        elif len(values) == 9:
            m[:3, :3] = np.array(values).reshape(3, 3)
        else:
            raise op.error(f"value: expected 16 (4 x 4) or 9 (3 x 3) numbers, got {len(values)}")
    elif op.tag == "lookat":
        origin, target = _triple(attr(op, "origin"), op, "origin"), _triple(attr(op, "target"), op, "target")
        if "up" in op.attrs:
            up = _triple(op.attrs["up"], op, "up")
        else:  # Mitsuba's: the first axis of its coordinate_system about the direction (not +y)
            up = _basis_first_axis(np.subtract(target, origin, dtype=np.float64))
        return look_at(origin, target, up)
    else:
        raise op.error("is not a transform operation (translate, rotate, scale, matrix, lookat)")
    return m


def _basis_first_axis(direction: np.ndarray) -> np.ndarray:
    """The first tangent of Mitsuba's coordinate_system(n) (Duff et al. 2017, "Building an
    orthonormal basis, revisited") for n the unit `direction`; a zero direction is left to
    look_at's own error. The kernels' lights/sampling.basis, which the scene layer does not
    import, is the same frame but for n.z = -0.0, where Mitsuba takes the sign's (checked)."""
    length = float(np.linalg.norm(direction))
    if not length > 0:
        return np.array([0.0, 1.0, 0.0])
    x, y, z = direction / length
    sign = math.copysign(1.0, z)
    a = -1.0 / (sign + z)
    b = x * y * a
    return np.array([1.0 + sign * x * x * a, sign * b, -sign * x])


def transform(node: Node) -> np.ndarray:
    """A <transform>'s 4 x 4 matrix: its operations applied in the order they are written."""
    m = np.eye(4)
    for op in node.children:
        try:
            m = _operation(op) @ m
        except ValueError as exc:
            raise op.error(str(exc)) from None
    return m


class Props:
    """A plugin element's named properties and nested plugins. `ids` resolves <ref id=...>."""

    def __init__(self, node: Node, ids: dict[str, Node]):
        self.node = node
        self.ids = ids
        self.named: dict[str, Node] = {}
        self.plugins: list[Node] = []  # nested plugin elements (and refs), in order
        self.used: set[str] = set()
        for child in node.children:
            if child.tag == "ref":
                target = self.resolve(child)
                if "name" in child.attrs:
                    self.named[child.attrs["name"]] = target
                    if child.attrs["name"] == "bsdf" and target.tag == "bsdf":
                        self.plugins.append(target)  # a shape's BSDF by its property name, as exporters write it
                else:
                    self.plugins.append(target)
            elif child.tag in VALUE_TAGS or (child.tag in PLUGIN_TAGS and "name" in child.attrs):
                self.named[attr(child, "name")] = child
                if child.tag in PLUGIN_TAGS:
                    self.plugins.append(child)
            elif child.tag in PLUGIN_TAGS:
                self.plugins.append(child)
            else:
                raise child.error(f"unknown element inside {node.describe()}")

    def resolve(self, ref: Node) -> Node:
        key = attr(ref, "id")
        if key not in self.ids:
            raise ref.error(f"no element with id {key!r} before this point")
        return self.ids[key]

    def has(self, name: str) -> bool:
        return name in self.named

    def take(self, name: str) -> Node | None:
        self.used.add(name)
        return self.named.get(name)

    def _value(self, name: str, tags: tuple[str, ...]) -> Node | None:
        node = self.take(name)
        if node is not None and node.tag not in tags:
            raise node.error(f"{name}: expected {' or '.join(f'<{t}>' for t in tags)}")
        return node

    def float(self, name: str, default: float | None = None) -> float | None:
        node = self._value(name, ("float", "integer"))
        return default if node is None else number(attr(node, "value"), node, name)

    def integer(self, name: str, default: int | None = None) -> int | None:
        node = self._value(name, ("integer",))
        if node is None:
            return default
        try:
            return int(attr(node, "value"))
        except ValueError:
            raise node.error(f"{name}: expected an integer, got {node.attrs['value']!r}") from None

    def boolean(self, name: str, default: bool) -> bool:
        node = self._value(name, ("boolean",))
        if node is None:
            return default
        value = attr(node, "value").strip().lower()
        if value not in ("true", "false"):
            raise node.error(f"{name}: expected true or false, got {value!r}")
        return value == "true"

    def string(self, name: str, default: str | None = None) -> str | None:
        node = self._value(name, ("string",))
        return default if node is None else attr(node, "value")

    def point(self, name: str, default=None) -> np.ndarray | None:
        node = self._value(name, ("point", "vector"))
        return default if node is None else vector3(node)

    def transform(self, name: str = "to_world") -> np.ndarray:
        node = self._value(name, ("transform",))
        return np.eye(4) if node is None else transform(node)

    def plugin(self, name: str) -> Node | None:
        """A nested plugin (or the one a <ref name=...> names) given as the property `name`."""
        node = self.take(name)
        if node is not None and node.tag not in PLUGIN_TAGS:
            raise node.error(f"{name}: expected a nested plugin element")
        return node

    def unused(self) -> list[str]:
        return [name for name in self.named if name not in self.used]


def colour_of(node: Node, name: str) -> tuple[float, float, float]:
    """An <rgb>, a constant <spectrum> or a number as an RGB triple. A spectrum of wavelength:value
    pairs is refused: raylume would need Mitsuba's spectral upsampling to read it as Mitsuba does."""
    if node.tag in ("float", "integer"):
        v = number(attr(node, "value"), node, name)
        return (v, v, v)
    if node.tag == "rgb":
        values = numbers(attr(node, "value"), node, name)
        if len(values) == 1:
            values *= 3
        if len(values) != 3:
            raise node.error(f"{name}: expected 1 or 3 numbers, got {len(values)}")
        return tuple(values)  # type: ignore[return-value]
    if node.tag == "spectrum":
        if "filename" in node.attrs or ":" in node.attrs.get("value", ""):
            raise node.error(
                f"{name}: a spectrum of wavelength:value pairs or from a file has no RGB value raylume "
                "can derive as Mitsuba does; give <rgb> instead"
            )
        v = numbers(attr(node, "value"), node, name)
        if len(v) != 1:
            raise node.error(f"{name}: a constant spectrum is one number")
        return (v[0], v[0], v[0])
    raise SceneError(f"{node.where}: {name}: expected <rgb>, <spectrum> or <float>, got <{node.tag}>")
