"""`--set KEY=VALUE`: edit a parsed scene document before it is validated (README: Command line).

KEY is a dotted path into the document (`camera.fov`, `materials.glass.ior`, `objects.2.radius`):
names step into tables, integers into lists. VALUE is read as a TOML value (`40`, `[0, 1, -3]`,
`"cast"`, `{ color = [1, 0, 0] }`); text that is not valid TOML is taken as a string, so
`render.mode=cast` works without shell-quoted quotes. A missing table on the way is created;
a list index out of range, or a step into something that is neither table nor list, is an
error naming the key path. The edited document is then validated like the file, so a bad
value or an unknown key is reported as any other.
"""

from __future__ import annotations

import copy
import re
import sys
import tomllib
from collections.abc import Iterable, Mapping
from typing import Any

from ..errors import SceneError
from .nesting import too_deep

Overrides = Iterable[str] | Mapping[str, Any]


def parse_value(text: str) -> Any:
    """A TOML value, or the text itself (stripped) when it is not one. A value nested too deeply,
    or an integer of more digits than Python converts, is a ValueError."""
    try:
        parsed = tomllib.loads(f"value = {text}")
    except tomllib.TOMLDecodeError:
        return text.strip()
    except RecursionError:
        raise ValueError("tables or lists nested too deeply") from None
    except ValueError:
        raise ValueError(f"a number of more than {sys.get_int_max_str_digits()} digits") from None
    if set(parsed) != {"value"}:  # e.g. "1\nother = 2": not one value
        return text.strip()
    return parsed["value"]


def split_key(key: str, text: str | None = None) -> list[str]:
    """'objects.2.radius' -> ['objects', '2', 'radius']; empty steps are an error."""
    parts = [part.strip() for part in key.strip().split(".")]
    if not key.strip() or not all(parts):
        raise SceneError(f"--set {text or key}: the key must be a dotted path such as camera.fov or objects.0.radius")
    return parts


def parse_assignment(text: str) -> tuple[list[str], Any]:
    """'camera.fov=40' -> (['camera', 'fov'], 40)."""
    key, sep, value = text.partition("=")
    if not sep:
        raise SceneError(f"--set {text}: expected KEY=VALUE, e.g. --set camera.fov=40")
    path = split_key(key, text)
    try:
        return path, parse_value(value)
    except ValueError as exc:
        raise SceneError(f"--set {key.strip()}: {exc}") from None


def assignments(overrides: Overrides | None) -> list[tuple[list[str], Any, str]]:
    """(key path, value, how the user wrote it) for each override, in order."""
    if overrides is None:
        return []
    if isinstance(overrides, Mapping):
        return [(split_key(key), value, f"{key}={value!r}") for key, value in overrides.items()]
    if isinstance(overrides, str):
        overrides = [overrides]
    return [(*parse_assignment(text), text) for text in overrides]


def apply_overrides(document: dict, overrides: Overrides | None, source: object = "the scene") -> dict:
    """A copy of `document` with each override applied in turn (later ones win). `source`
    names the document in the error for one nested too deeply to copy."""
    try:
        document = copy.deepcopy(document)
    except RecursionError:
        raise too_deep(document, str(source)) from None
    for path, value, text in assignments(overrides):
        _assign(document, path, copy.deepcopy(value), text)
    return document


def _assign(document: dict, path: list[str], value: Any, text: str) -> None:
    node: Any = document
    for depth, part in enumerate(path):
        last = depth == len(path) - 1
        where = ".".join(path[: depth + 1])
        if isinstance(node, dict):
            if last:
                node[part] = value
            elif part not in node:
                if path[depth + 1].lstrip("-").isdigit():
                    raise SceneError(
                        f"--set {text}: {where} is not in the scene, so there is no list to index "
                        f"with {path[depth + 1]}"
                    )
                node[part] = {}  # a path into a missing table creates it
            node = node[part]
        elif isinstance(node, list):
            index = _index(part, len(node), where, text)
            if last:
                node[index] = value
            node = node[index]
        else:
            parent = ".".join(path[:depth])
            raise SceneError(
                f"--set {text}: {parent} is not a table or a list (it is {node!r}), so it has no key {part!r}"
            )


def _index(part: str, length: int, where: str, text: str) -> int:
    if not part.isdigit():
        raise SceneError(f"--set {text}: {where}: a list is indexed by a number from 0, not {part!r}")
    index = int(part)
    if index >= length:
        raise SceneError(
            f"--set {text}: {where}: index {index} is out of range; the list has {length} "
            f"item{'s' if length != 1 else ''}"
        )
    return index


def attributed(message: str, overrides: Overrides | None) -> str:
    """An error found after validation (a texture file, a mesh file) with the --set that set the
    key it names, as validation's errors say it (format_validation_error): the last override
    whose key (or a table above it) the message names after its file."""
    if "(set by --set" in message:
        return message
    try:
        given = assignments(overrides)
    except SceneError:  # (a malformed --set is that very error)
        return message
    for keys, _, text in reversed(given):
        name = "".join(f"[{k}]" if k.isdigit() else f".{k}" for k in keys).lstrip(".")
        if re.search(rf": {re.escape(name)}(?=[.:\[])", message):
            return f"{message} (set by --set {text})"
    return message


def touches(path: list[str], loc: list[str]) -> bool:
    """Whether a validation error at `loc` concerns the value set at `path` (one lies within the
    other: an error inside the new value, or a check of the table that holds it). A table's
    `type` decides what every key of the table may be: setting it concerns them all."""
    if len(path) > 1 and path[-1] == "type":
        path = path[:-1]
    n = min(len(path), len(loc))
    return n > 0 and path[:n] == loc[:n]
