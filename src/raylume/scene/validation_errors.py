"""pydantic ValidationErrors in words: one line that names the source, each key path and what is
wrong there. The one formatter of scene errors: scene files, `Scene.replace`, cameras, the
render settings of a call or of the command line's flags.

It takes the model class that failed as an argument, rather than importing the scene model, so
that the model can use it (scene/model.py imports this module)."""

from __future__ import annotations

import difflib
import re
import types
import typing
from collections.abc import Callable
from pathlib import Path

from pydantic import BaseModel, ValidationError

from .overrides import Overrides, assignments, touches

MAX_SHOWN = 5  # problems named in one message; the rest are counted
# How alike an unknown key must be to a known one to be suggested (difflib's ratio): close
# enough for typos (radus, colour, focus_distanse), far from unrelated words.
SUGGESTION_CUTOFF = 0.8


def format_validation_error(
    exc: ValidationError,
    source: str | Path,
    model: type[BaseModel],
    *,
    overrides: Overrides | None = None,
    table: tuple[str, ...] = (),
    context: str = "",
    key_name: Callable[[tuple], str] | None = None,
) -> str:
    """'{source}: {context}{key}: {problem}; ...' for the problems of `exc`, raised validating
    `model` (its key suggestions come from there). `table` is where that model sits in a scene
    (("camera",) names keys camera.fov, ...); `key_name` names a key another way (command-line
    flags). `overrides` (--set) are named when they caused a problem."""
    errors = _short_lists(_typos_for_missing_keys(merge_union_errors(exc.errors()), model))
    set_by = assignments(overrides)
    lines = []
    for error in errors[:MAX_SHOWN]:
        loc = (*table, *error["loc"])
        path = key_name(tuple(error["loc"])) if key_name is not None else key_path(loc)
        if error["type"] == "unknown_type":
            path = f"{path}.type" if path else "type"
        where = f"{path}: " if path else ""
        steps = [str(p) for p in loc if not (isinstance(p, str) and p.startswith("<"))]
        culprits = [text for keys, _, text in set_by if touches(keys, steps)]
        cause = f" (set by --set {culprits[-1]})" if culprits else ""
        lines.append(f"{where}{describe_error(error, model)}{cause}")
    more = f" (and {len(errors) - MAX_SHOWN} more problems)" if len(errors) > MAX_SHOWN else ""
    return f"{source}: {context}" + "; ".join(lines) + more


def _short_lists(errors: list[dict]) -> list[dict]:
    """Lists cut short (a centre of two numbers) said of the list: pydantic names each missing
    place as a required key ('center[2]: this key is required')."""
    out, seen = [], {}
    for error in errors:
        loc = tuple(error["loc"])
        if error["type"] != "missing" or not loc or not isinstance(loc[-1], int):
            out.append(error)
            continue
        parent, needed = loc[:-1], loc[-1] + 1
        if parent in seen:  # the same list, a later place missing too: the one error says the most
            seen[parent]["needed"] = max(seen[parent]["needed"], needed)
            continue
        given = len(error["input"]) if isinstance(error.get("input"), (list, tuple)) else None
        seen[parent] = {
            "type": "too_short",
            "loc": parent,
            "needed": needed,
            "given": given,
            "input": error.get("input"),
        }
        out.append(seen[parent])
    for error in seen.values():
        has = f"{error['given']} given" if error["given"] is not None else "fewer given"
        error["msg"] = f"too few values: {has}, {error['needed']} needed"
    return out


def _typos_for_missing_keys(errors: list[dict], model: type[BaseModel]) -> list[dict]:
    """The errors less each 'this key is required' that a misspelt key beside it explains:
    `radus = 1` in a sphere is one mistake, said once as the unknown key and its suggestion
    ('radus': did you mean 'radius'?), not also as a missing radius."""
    typos = set()
    for error in errors:
        if error["type"] == "extra_forbidden":
            loc = tuple(error["loc"])
            close = suggest(str(loc[-1]), loc, model)
            if close is not None:
                typos.add((*loc[:-1], close))
    return [e for e in errors if not (e["type"] == "missing" and tuple(e["loc"]) in typos)]


def name_origins(message: str, origins: dict[str, str]) -> str:
    """A validation message whose key paths name the element (or pbrt directive) they came from:
    'objects[2].radius: ...' -> 'objects[2].radius (scene.xml:12 <shape type="sphere">): ...'."""
    keys = sorted(origins, key=len, reverse=True)

    def named(match: re.Match) -> str:
        path = match.group(1)
        for key in keys:
            if path == key or path.startswith((f"{key}.", f"{key}[")):
                return f"{path} ({origins[key]}):"
        return match.group(0)

    return re.sub(r"(?<=[:;] )([A-Za-z_][\w.\[\]+-]*):", named, message)


# How an untagged union's members read in a message (pydantic names each member in the error's
# location: 'float', 'tuple[...]', 'list[function-after[_matrix_alone(), Transform]]')
_MEMBER_WORDS = {
    "float": "a number",
    "int": "a whole number",
    "str": "a string",
    "bool": "true or false",
    "list": "a list",
    "tuple": "a list",
    "dict": "a table",
}
_WRAPPERS = ("function-after[", "function-before[", "function-wrap[", "function-plain[")


_MEMBER = re.compile(r"[a-z][a-z-]*\[.*\]")  # 'tuple[float, float]', 'function-after[_check(), float]'


def _is_member(part) -> bool:
    """Whether a location step names an untagged union's member rather than a key (a material's
    name may be any text: 'my-glass' is a key)."""
    return isinstance(part, str) and (part in _MEMBER_WORDS or _MEMBER.fullmatch(part) is not None)


def _member_word(part: str) -> str:
    """'function-after[_check(), function-before[_a_number(), float]]' -> 'a number'."""
    while part.startswith(_WRAPPERS):
        part = part[part.index("[") + 1 : -1].split(", ", 1)[-1]
    return _MEMBER_WORDS.get(part.split("[", 1)[0], "a table")


def _mismatch(error: dict) -> bool:
    """A member refused the value's type (so another member was meant), not its value."""
    return error["type"].endswith(("_type", "_parsing"))


def merge_union_errors(errors: list[dict]) -> list[dict]:
    """The errors of an untagged union (scale: a number or [x, y, z]) as a user sees them. Where
    the value has one member's type, that member's problems, its step dropped from the key path;
    where it has none, one error 'expected a number or a list'."""
    merged: list = []
    groups: dict[tuple, list[tuple[dict, int]]] = {}
    for error in errors:
        loc = tuple(error["loc"])
        at = next((i for i, part in enumerate(loc) if _is_member(part)), None)
        if at is None:
            merged.append(error)
            continue
        if loc[:at] not in groups:
            groups[loc[:at]] = []
            merged.append(loc[:at])  # the group's place among the errors
        groups[loc[:at]].append((error, at))
    out = []
    for item in merged:
        if isinstance(item, dict):
            out.append(item)
            continue
        members = groups[item]
        meant = [e for e, at in members if len(e["loc"]) > at + 1 or not _mismatch(e)]
        if meant:
            out.extend({**e, "loc": tuple(p for p in e["loc"] if not _is_member(p))} for e in meant)
        else:
            words = list(dict.fromkeys(_member_word(e["loc"][at]) for e, at in members))
            out.append(
                {
                    "type": "union_type",
                    "loc": item,
                    "msg": f"expected {' or '.join(words)}",
                    "input": members[0][0].get("input"),
                }
            )
    return out


def key_path(loc: tuple) -> str:
    """('objects', 2, '<sphere>', 'radius') -> 'objects[2].radius' (union tags dropped)."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif isinstance(part, str) and part.startswith("<") and part.endswith(">"):
            continue
        else:
            out += f".{part}" if out else str(part)
    return out


def describe_error(error: dict, model: type[BaseModel]) -> str:
    """One pydantic error in words, with the offending value unless the message names it."""
    kind, msg = error["type"], error["msg"]
    if kind == "extra_forbidden":
        bad = str(error["loc"][-1])
        close = suggest(bad, tuple(error["loc"]), model)
        hint = f" (did you mean {close!r}?)" if close else ""
        return f"unknown key {bad!r}{hint}"
    if kind == "missing":
        return "this key is required"
    msg = msg.removeprefix("Value error, ")
    value = error.get("input")
    if kind == "unknown_type" and isinstance(value, dict):
        value = value.get("type")
    elif kind in ("unknown_type", "material_ref") or isinstance(value, (dict, list)):
        return msg
    if hasattr(value, "shape") and hasattr(value, "dtype"):  # a numpy array: its kind, not its values
        return f"{msg} (got a {value.dtype} array of shape {value.shape})"
    return msg if _names_value(msg, value) else f"{msg} (got {value!r})"


def _names_value(msg: str, value) -> bool:
    """Whether a validator's message already shows the value ("..., got -1", "'#12345' must ...")."""
    return " got " in f" {msg}" or (isinstance(value, str) and repr(value) in msg)


def suggest(bad: str, loc: tuple, model: type[BaseModel]) -> str | None:
    """A close match for an unknown key, from the keys valid where it was found."""
    candidates = keys_at(loc, model)
    close = difflib.get_close_matches(
        bad, candidates if candidates is not None else known_keys(model), n=1, cutoff=SUGGESTION_CUTOFF
    )
    return close[0] if close else None


def known_keys(model: type[BaseModel]) -> list[str]:
    """Every key of `model` and of the models inside it."""
    keys: set[str] = set()
    seen: set[type] = set()

    def visit(node) -> None:
        for arg in typing.get_args(node):
            visit(arg)
        if isinstance(node, type) and issubclass(node, BaseModel) and node not in seen:
            seen.add(node)
            keys.update(node.model_fields)
            for field in node.model_fields.values():
                visit(field.annotation)

    visit(model)
    return sorted(keys)


def keys_at(loc: tuple, model: type[BaseModel]) -> list[str] | None:
    """The keys `model` allows in the table that holds the last step of `loc` (an error
    location such as ('objects', 0, '<sphere>', 'radus')), or None when the model cannot be
    followed there. Union tags ('<sphere>') choose the member of a tagged union."""
    node = model
    for part in loc[:-1]:
        node = _step(node, part)
        if node is None:
            return None
    node = _unwrap(node, None)
    if isinstance(node, type) and issubclass(node, BaseModel):
        return sorted(node.model_fields)
    return None


def _step(node, part):
    node = _unwrap(node, part if isinstance(part, str) and part.startswith("<") else None)
    if isinstance(part, str) and part.startswith("<"):
        return node
    origin = typing.get_origin(node)
    if isinstance(part, int) and origin in (list, tuple):
        return typing.get_args(node)[0]
    if origin is dict:
        return typing.get_args(node)[1]
    if isinstance(node, type) and issubclass(node, BaseModel) and part in node.model_fields:
        return node.model_fields[part].annotation
    return None


def _unwrap(node, tag: str | None):
    """Strip Annotated and Optional; in a tagged union, pick the member with `tag`."""
    while True:
        origin = typing.get_origin(node)
        if origin is typing.Annotated:
            node = typing.get_args(node)[0]
        elif origin in (typing.Union, types.UnionType):
            members = [a for a in typing.get_args(node) if a is not type(None)]
            chosen = [a for a in members if tag is not None and _tag_of(a) == tag]
            if chosen:
                node = chosen[0]
            elif len(members) == 1:
                node = members[0]
            else:
                models = [
                    a for a in members if isinstance(_unwrap(a, None), type) and issubclass(_unwrap(a, None), BaseModel)
                ]
                return models[0] if len(models) == 1 else node
        else:
            return node


def _tag_of(annotated) -> str | None:
    for meta in getattr(annotated, "__metadata__", ()):
        tag = getattr(meta, "tag", None)
        if isinstance(tag, str):
            return tag
    return None
