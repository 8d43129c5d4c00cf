"""pbrt-v4 scene files as tokens: quoted strings, numbers, bare words (directives, true/false)
and brackets, each with the file and line it came from, comments dropped.

The format is pbrt-v4's (https://pbrt.org/fileformat-v4): `#` starts a comment outside a
string; strings are double-quoted with C escapes; everything else is separated by white space
or brackets.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

from ..errors import SceneError


class PbrtError(SceneError):
    """A pbrt file that cannot be read: the message names the file, the line and the directive."""


class Token(NamedTuple):
    kind: str  # "string", "number", "word", "[" or "]"
    value: str | float
    file: Path
    line: int

    @property
    def where(self) -> str:
        return f"{self.file}:{self.line}"


_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "b": "\b", "f": "\f", "\\": "\\", '"': '"', "'": "'"}
_SEPARATORS = ' \t\r\n[]"#'


def tokenize(text: str, file: Path) -> list[Token]:
    """The tokens of a pbrt file's text. A PbrtError names the file and line of an unterminated
    string, a bad escape or a word that is neither a number nor a name."""
    tokens: list[Token] = []
    i, line, n = 0, 1, len(text)
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            i += 1
        elif c in " \t\r":
            i += 1
        elif c == "#":
            end = text.find("\n", i)
            i = n if end < 0 else end
        elif c in "[]":
            tokens.append(Token(c, c, file, line))
            i += 1
        elif c == '"':
            i, value = _string(text, i + 1, file, line)
            tokens.append(Token("string", value, file, line))
        else:
            j = i
            while j < n and text[j] not in _SEPARATORS:
                j += 1
            tokens.append(_bare(text[i:j], file, line))
            i = j
    return tokens


def _string(text: str, i: int, file: Path, line: int) -> tuple[int, str]:
    """The string starting after its opening quote at i: (index after the closing quote, value)."""
    out: list[str] = []
    n = len(text)
    while i < n:
        c = text[i]
        if c == '"':
            return i + 1, "".join(out)
        if c == "\n":
            break
        if c == "\\":
            if i + 1 >= n or text[i + 1] not in _ESCAPES:
                raise PbrtError(f"{file}:{line}: unknown escape {text[i : i + 2]!r} in a string")
            out.append(_ESCAPES[text[i + 1]])
            i += 2
            continue
        out.append(c)
        i += 1
    raise PbrtError(f'{file}:{line}: unterminated string (a " is missing before the end of the line)')


def _bare(word: str, file: Path, line: int) -> Token:
    if word[0].isalpha():
        return Token("word", word, file, line)
    try:
        value = float(word)
    except ValueError:
        raise PbrtError(f"{file}:{line}: unexpected {word!r}: expected a directive, number, string or [ ]") from None
    if not math.isfinite(value):
        raise PbrtError(f"{file}:{line}: {word!r} is not a finite number")
    return Token("number", value, file, line)
