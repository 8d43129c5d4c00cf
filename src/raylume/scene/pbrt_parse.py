"""pbrt-v4 files as a stream of directives: each directive's name, its positional arguments and
its parameter list ("float fov" 45), with `Include` and `Import` followed into the files they
name. Meaning (graphics state, shapes, materials) is scene/pbrt_scene.py's.

Relative file names resolve against the folder of the file given to `raylume` (pbrt-v4's
search directory), not the folder of the file that names them, as pbrt-v4 does.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from .files import read_scene_text
from .pbrt_tokens import PbrtError, Token, tokenize

# Positional arguments of each directive: n a number, s a string, w a bare word, m a matrix (16
# numbers, bracketed or not); + means a parameter list follows.
SIGNATURES = {
    "AttributeBegin": "",
    "AttributeEnd": "",
    "TransformBegin": "",
    "TransformEnd": "",
    "WorldBegin": "",
    "WorldEnd": "",
    "ObjectEnd": "",
    "ReverseOrientation": "",
    "Identity": "",
    "Translate": "nnn",
    "Scale": "nnn",
    "Rotate": "nnnn",
    "LookAt": "nnnnnnnnn",
    "Transform": "m",
    "ConcatTransform": "m",
    "TransformTimes": "nn",
    "ActiveTransform": "w",
    "Include": "s",
    "Import": "s",
    "ObjectBegin": "s",
    "ObjectInstance": "s",
    "NamedMaterial": "s",
    "CoordinateSystem": "s",
    "CoordSysTransform": "s",
    "ColorSpace": "s",
    "MediumInterface": "s",  # and an optional second name, read below
    "Camera": "s+",
    "Film": "s+",
    "Sampler": "s+",
    "Integrator": "s+",
    "PixelFilter": "s+",
    "Accelerator": "s+",
    "Shape": "s+",
    "Material": "s+",
    "LightSource": "s+",
    "AreaLightSource": "s+",
    "MakeNamedMaterial": "s+",
    "MakeNamedMedium": "s+",
    "Attribute": "s+",
    "Texture": "sss+",
    "Option": "+",
}

# Parameter types, with pbrt-v3's spellings mapped to pbrt-v4's.
ALIASES = {"point": "point3", "vector": "vector3", "normal": "normal3", "color": "rgb"}
NUMERIC = {"integer": 1, "float": 1, "point2": 2, "vector2": 2, "point3": 3, "vector3": 3, "normal3": 3, "rgb": 3}
TYPES = {*NUMERIC, "bool", "string", "texture", "spectrum", "blackbody"}
MAX_INCLUDE_DEPTH = 32


@dataclass
class Param:
    type: str
    name: str
    values: list
    token: Token
    used: bool = False

    @property
    def label(self) -> str:
        return f'"{self.type} {self.name}"'


@dataclass
class Directive:
    name: str
    args: list
    params: list[Param]
    token: Token
    search_dir: Path = field(default_factory=Path.cwd)

    @property
    def where(self) -> str:
        return self.token.where

    @property
    def label(self) -> str:
        """File, line and directive: 'scene.pbrt:3: Shape "sphere"'."""
        named = self.args and isinstance(self.args[0], str) and "+" in SIGNATURES[self.name]
        kind = f' "{self.args[0]}"' if named else ""
        return f"{self.where}: {self.name}{kind}"

    def fail(self, why: str) -> PbrtError:
        """The error to raise for this directive: file, line, directive, why."""
        return PbrtError(f"{self.label}: {why}")


def parse_file(path: Path, search_dir: Path | None = None, _stack: tuple[Path, ...] = ()) -> Iterator[Directive]:
    """The directives of a pbrt file, those of the files it includes in their place."""
    path = Path(path)
    search_dir = path.resolve().parent if search_dir is None else search_dir
    if len(_stack) > MAX_INCLUDE_DEPTH:
        raise PbrtError(f"{path}: files include each other more than {MAX_INCLUDE_DEPTH} deep")
    text = read_scene_text(path, "pbrt file", PbrtError)
    stack = (*_stack, path.resolve())
    for directive in _directives(tokenize(text, path), search_dir):
        if directive.name in ("Include", "Import"):
            target = resolve(directive.args[0], search_dir)
            if target.resolve() in stack:
                raise directive.fail(f'"{directive.args[0]}" includes itself (through {" -> ".join(map(str, stack))})')
            if not target.is_file():
                raise directive.fail(f"no such file {str(target)!r}")
            yield from parse_file(target, search_dir, stack)
        else:
            yield directive


def resolve(name: str, search_dir: Path) -> Path:
    """A file named in a pbrt file: absolute, or relative to the search directory."""
    path = Path(name)
    return path if path.is_absolute() else search_dir / path


def _directives(tokens: list[Token], search_dir: Path) -> Iterator[Directive]:
    i, n = 0, len(tokens)
    while i < n:
        token = tokens[i]
        if token.kind != "word":
            raise PbrtError(f"{token.where}: expected a directive, got {_show(token)}")
        if token.value not in SIGNATURES:
            raise PbrtError(f"{token.where}: unknown directive {token.value!r}")
        name = str(token.value)
        i += 1
        args: list = []
        signature = SIGNATURES[name]
        for kind in signature.rstrip("+"):
            i = _positional(tokens, i, kind, args, name, token)
        if name == "MediumInterface" and i < n and tokens[i].kind == "string":
            args.append(tokens[i].value)
            i += 1
        params: list[Param] = []
        if signature.endswith("+"):
            label = f'{name} "{args[0]}"' if args and isinstance(args[0], str) else name
            while i < n and tokens[i].kind == "string":
                i = _param(tokens, i, params, label)
        yield Directive(name, args, params, token, search_dir)


def _positional(tokens: list[Token], i: int, kind: str, args: list, name: str, start: Token) -> int:
    def need(k: int, what: str) -> Token:
        if k >= len(tokens):
            raise PbrtError(f"{start.where}: {name}: expected {what}, got the end of the file")
        return tokens[k]

    if kind == "m":
        if need(i, "16 numbers").kind == "numbers":
            if len(tokens[i].value) != 16:
                raise PbrtError(f"{tokens[i].where}: {name}: expected 16 numbers, got {len(tokens[i].value)}")
            args.append(list(tokens[i].value))
            return i + 1
        bracketed = need(i, "16 numbers").kind == "["
        i += bracketed
        values = []
        while len(values) < 16:
            t = need(i, "16 numbers")
            if t.kind != "number":
                raise PbrtError(f"{t.where}: {name}: expected 16 numbers, got {_show(t)} after {len(values)}")
            values.append(t.value)
            i += 1
        if bracketed:
            if need(i, "]").kind != "]":
                raise PbrtError(f"{tokens[i].where}: {name}: expected ] after 16 numbers, got {_show(tokens[i])}")
            i += 1
        args.append(values)
        return i
    wanted = {"n": ("number", "a number"), "s": ("string", "a quoted string"), "w": ("word", "a word")}[kind]
    t = need(i, wanted[1])
    if t.kind != wanted[0]:
        raise PbrtError(f"{t.where}: {name}: expected {wanted[1]}, got {_show(t)}")
    args.append(t.value)
    return i + 1


def _param(tokens: list[Token], i: int, params: list[Param], directive: str) -> int:
    """Read one `"type name" value` at i into params; the index after it."""
    decl = tokens[i]
    words = str(decl.value).split()
    if len(words) != 2:
        raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}" must be "type name", e.g. "float radius"')
    kind, pname = ALIASES.get(words[0], words[0]), words[1]
    if kind not in TYPES:
        raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}" has unknown type {words[0]!r}')
    i += 1
    if i >= len(tokens):
        raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}" has no value')
    values: list = []
    if tokens[i].kind == "numbers":
        if not tokens[i].value:
            raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}": no values')
        params.append(Param(kind, pname, _typed_numbers(kind, tokens[i].value, decl, directive), decl))
        return i + 1
    if tokens[i].kind == "[":
        i += 1
        while i < len(tokens) and tokens[i].kind in ("number", "string", "word"):
            values.append(tokens[i])
            i += 1
        if i >= len(tokens) or tokens[i].kind != "]":
            raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}": a [ without its ]')
        i += 1
    elif tokens[i].kind in ("number", "string") or (tokens[i].kind == "word" and tokens[i].value in ("true", "false")):
        values.append(tokens[i])
        i += 1
    else:
        raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}" has no value (got {_show(tokens[i])})')
    params.append(Param(kind, pname, _typed(kind, values, decl, directive), decl))
    return i


def _typed(kind: str, values: list[Token], decl: Token, directive: str) -> list:
    """The values of a parameter checked against its type: numbers, strings or bools."""

    def fail(why: str):
        raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}": {why}')

    if not values:
        fail("no values")
    if kind == "bool":
        out = []
        for t in values:
            if t.value not in ("true", "false"):
                fail(f"expected true or false, got {_show(t)}")
            out.append(t.value == "true")
        return out
    if kind in ("string", "texture") or (kind == "spectrum" and values[0].kind == "string"):
        if any(t.kind != "string" for t in values):
            fail("expected quoted strings")
        return [t.value for t in values]
    if any(t.kind != "number" for t in values):
        fail(f"expected numbers, got {_show(next(t for t in values if t.kind != 'number'))}")
    return _typed_numbers(kind, [t.value for t in values], decl, directive)


def _typed_numbers(kind: str, numbers: list, decl: Token, directive: str) -> list:
    def fail(why: str):
        raise PbrtError(f'{decl.where}: {directive}: parameter "{decl.value}": {why}')

    if kind in ("bool", "string", "texture"):
        fail(f"expected {'true or false' if kind == 'bool' else 'quoted strings'}, got numbers")
    width = NUMERIC.get(kind, 2 if kind == "spectrum" else 1)
    if len(numbers) % width:
        fail(f"{len(numbers)} numbers is not a whole number of {kind} values ({width} numbers each)")
    if kind == "integer":
        if any(v != int(v) for v in numbers):
            fail("expected whole numbers")
        return [int(v) for v in numbers]
    return numbers


def _show(token: Token) -> str:
    if token.kind == "numbers":
        return f"a list of {len(token.value)} numbers"
    if token.kind == "string":
        return f'"{token.value}"'
    return f"{token.value:g}" if token.kind == "number" else repr(token.value)
