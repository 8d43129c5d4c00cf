"""pbrt-v4 scene files as tokens: quoted strings, numbers, bare words (directives, true/false)
and brackets, each with the file and line it came from, comments dropped.

The format is pbrt-v4's (https://pbrt.org/fileformat-v4): `#` starts a comment outside a
string; strings are double-quoted with C escapes; everything else is separated by white space
or brackets.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import NamedTuple

from ..errors import SceneError


class PbrtError(SceneError):
    """A pbrt file that cannot be read: the message names the file, the line and the directive."""


class Token(NamedTuple):
    kind: str  # "string", "number", "word", "[", "]", or "numbers": a bracketed list of numbers (a list)
    value: str | float
    file: Path
    line: int

    @property
    def where(self) -> str:
        return f"{self.file}:{self.line}"


_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "b": "\b", "f": "\f", "\\": "\\", '"': '"', "'": "'"}
# One alternative per kind of token; a lone quote is the start of a string never closed.
_TOKEN = re.compile(
    r"""(?P<space>[ \t\r\n]+)|(?P<comment>\#[^\n]*)|(?P<string>"(?:[^"\\\n]|\\.)*")"""
    r"""|(?P<numbers>\[[-+.0-9eE \t\r\n]*\])|(?P<open>\[)|(?P<close>\])"""
    r"""|(?P<bare>[^ \t\r\n\[\]"\#]+)|(?P<quote>")"""
)


def tokenize(text: str, file: Path) -> list[Token]:
    """The tokens of a pbrt file's text. A PbrtError names the file and line of an unterminated
    string, a bad escape or a word that is neither a number nor a name."""
    tokens: list[Token] = []
    append = tokens.append
    line = 1
    for m in _TOKEN.finditer(text):
        kind = m.lastgroup
        if kind == "space":
            line += m.group().count("\n")
        elif kind == "bare":
            word = m.group()
            if word[0].isalpha():
                append(Token("word", word, file, line))
            else:
                append(_number(word, file, line))
        elif kind == "string":
            body = m.group()[1:-1]
            append(Token("string", _unescape(body, file, line) if "\\" in body else body, file, line))
        elif kind == "numbers":  # one token for a whole list: meshes hold millions of numbers
            text_ = m.group()
            append(_numbers(text_[1:-1], file, line))
            line += text_.count("\n")
        elif kind == "open" or kind == "close":
            append(Token(m.group(), m.group(), file, line))
        elif kind == "quote":
            raise PbrtError(f'{file}:{line}: unterminated string (a " is missing before the end of the line)')
    return tokens


def _unescape(body: str, file: Path, line: int) -> str:
    out: list[str] = []
    i = 0
    while i < len(body):
        c = body[i]
        if c == "\\":
            if i + 1 >= len(body) or body[i + 1] not in _ESCAPES:
                raise PbrtError(f"{file}:{line}: unknown escape {body[i : i + 2]!r} in a string")
            out.append(_ESCAPES[body[i + 1]])
            i += 2
        else:
            out.append(c)
            i += 1
    return "".join(out)


def _numbers(body: str, file: Path, line: int) -> Token:
    try:
        values = [float(word) for word in body.split()]
    except ValueError:
        for word in body.split():
            _number(word, file, line)  # names the word that is not a number
        raise
    if not all(map(math.isfinite, values)):
        raise PbrtError(f"{file}:{line}: a number in the list [ ... ] is not finite")
    return Token("numbers", values, file, line)


def _number(word: str, file: Path, line: int) -> Token:
    try:
        value = float(word)
    except ValueError:
        raise PbrtError(f"{file}:{line}: unexpected {word!r}: expected a directive, number, string or [ ]") from None
    if not math.isfinite(value):
        raise PbrtError(f"{file}:{line}: {word!r} is not a finite number")
    return Token("number", value, file, line)
