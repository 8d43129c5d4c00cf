"""Mitsuba 3 scene XML as a tree of nodes that remember their file and line: `<default>` and
`$name` parameters substituted, `<include>` files spliced in, `<path>` folders collected. What
the elements mean is scene/mitsuba_scene.py's business.

Parsed with the standard library's expat binding (xml.parsers.expat), which reports the line
of every element; ElementTree would forget it. Entity declarations are refused, so a file
cannot expand itself without bound.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import SceneError

PARAMETER = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")
MAX_INCLUDE_DEPTH = 32


@dataclass
class Node:
    """One XML element: its tag, attributes (parameters substituted), children, and where it is."""

    tag: str
    attrs: dict[str, str]
    file: Path
    line: int
    children: list[Node] = field(default_factory=list)

    @property
    def where(self) -> str:
        return f"{self.file}:{self.line}"

    def describe(self) -> str:
        """`<bsdf type="plastic">`, as the element reads in the file."""
        kind = self.attrs.get("type")
        return f'<{self.tag} type="{kind}">' if kind else f"<{self.tag}>"

    def error(self, message: str) -> SceneError:
        return SceneError(f"{self.where}: {self.describe()}: {message}")


@dataclass
class Document:
    """The scene element and what the files around it gave: parameter values, search folders."""

    root: Node
    parameters: dict[str, str]
    search_paths: list[Path]


def _parse_file(path: Path) -> Node:
    """The file's elements as nodes, with their lines; a SceneError naming file and line."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except IsADirectoryError:
        raise SceneError(f"{path}: is a folder, not a scene file") from None
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc.strerror or exc})") from None
    parser = xml.parsers.expat.ParserCreate()
    stack: list[Node] = []
    roots: list[Node] = []

    def start(tag, attrs):
        node = Node(tag, dict(attrs), path, parser.CurrentLineNumber)
        (stack[-1].children if stack else roots).append(node)
        stack.append(node)

    def end(tag):
        stack.pop()

    def entity(*args):  # no entity expansion: a few bytes could otherwise grow without bound
        raise SceneError(f"{path}:{parser.CurrentLineNumber}: entity declarations are not allowed")

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.EntityDeclHandler = entity
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        raise SceneError(f"{path}:{exc.lineno}: invalid XML: {xml.parsers.expat.ErrorString(exc.code)}") from None
    return roots[0]


def substitute(text: str, parameters: dict[str, str], node: Node, used: set[str] | None = None) -> str:
    """`$name` in an attribute replaced by its value (its name added to `used`); an undefined
    name is an error."""

    def value(match: re.Match) -> str:
        name = match.group(1)
        if name not in parameters:
            raise node.error(f"${name} is not defined (give it with --define {name}=VALUE or a <default>)")
        if used is not None:
            used.add(name)
        return parameters[name]

    return PARAMETER.sub(value, text)


class _Reader:
    def __init__(self, defines: dict[str, str], folder: Path):
        self.parameters = dict(defines)
        self.search_paths: list[Path] = []
        self.folder = folder  # the scene file's
        self.used: set[str] = set()  # parameters substituted or given a <default>

    def expand(self, node: Node, depth: int) -> list[Node]:
        """The node (or, for <include>, the included file's elements) after substitution."""
        node.attrs = {key: substitute(value, self.parameters, node, self.used) for key, value in node.attrs.items()}
        if node.tag == "default":
            name, value = node.attrs.get("name"), node.attrs.get("value")
            if name is None or value is None:
                raise node.error("needs name and value attributes")
            self.parameters.setdefault(name, value)  # a --define wins over the file's default
            self.used.add(name)
            return []
        if node.tag == "path":
            folder = node.attrs.get("value")
            if folder is None:
                raise node.error("needs a value attribute (a folder)")
            self.search_paths.append((node.file.parent / folder).resolve())
            return []
        if node.tag == "include":
            return self.include(node, depth)
        children = []
        for child in node.children:
            children.extend(self.expand(child, depth))
        node.children = children
        return [node]

    def include(self, node: Node, depth: int) -> list[Node]:
        name = node.attrs.get("filename")
        if name is None:
            raise node.error("needs a filename attribute")
        if depth >= MAX_INCLUDE_DEPTH:
            raise node.error(f"includes nest deeper than {MAX_INCLUDE_DEPTH} files (does a file include itself?)")
        path = find_file(name, node.file.parent, self.search_paths, self.folder)
        if path is None:
            raise node.error(f"no file {name!r} to include ({searched(node.file.parent, self.folder)})")
        if path.suffix.lower() != ".xml":
            raise node.error(f"{name!r}: only Mitsuba XML files can be included")
        root = _parse_file(path)
        if root.tag != "scene":
            raise SceneError(f"{root.where}: an included file's root element must be <scene>, not <{root.tag}>")
        expanded = []
        for child in root.children:
            expanded.extend(self.expand(child, depth + 1))
        return expanded


def find_file(name: str, folder: Path, search_paths: list[Path], scene_folder: Path) -> Path | None:
    """A file named in the scene: relative to the file that names it, then to each <path>, then
    to the scene file's folder (Mitsuba resolves names in an included file, and its includes, by
    its file resolver: the <path>s, then the folder of the scene file it loads)."""
    candidate = Path(name)
    if candidate.is_absolute():
        return candidate if candidate.exists() else None
    for base in (folder, *search_paths, scene_folder):
        if (base / candidate).exists():
            return (base / candidate).resolve()
    return None


def searched(folder: Path, scene_folder: Path) -> str:
    """Where find_file looked, for an error message (the <path>s left out)."""
    if folder.resolve() == scene_folder.resolve():
        return f"relative to {folder}"
    return f"relative to {folder} or to the scene's folder {scene_folder}"


def read_document(path: str | Path, defines: dict[str, str] | None = None) -> Document:
    """The scene of a Mitsuba XML file, parameters (`defines`, as Mitsuba's -D) substituted."""
    path = Path(path)
    root = _parse_file(path)
    if root.tag != "scene":
        raise SceneError(f"{root.where}: the root element of a Mitsuba scene is <scene>, not <{root.tag}>")
    version = root.attrs.get("version", "")
    if not version:
        raise root.error('needs a version attribute (e.g. version="3.0.0")')
    if version.split(".")[0] not in ("2", "3"):  # Mitsuba 3 reads 2.x files as they are
        raise root.error(f"version {version}: raylume reads Mitsuba 3 scenes (version 2.x or 3.x)")
    reader = _Reader(defines or {}, path.resolve().parent)
    reader.expand(root, 0)
    unused = sorted(set(defines or {}) - reader.used)
    if unused:  # a misspelt name would otherwise change nothing, without a word (Mitsuba refuses it too)
        known = ", ".join(f"${name}" for name in sorted(reader.used)) or "none"
        raise SceneError(f"{path}: --define {unused[0]}: the scene has no parameter ${unused[0]} (it has: {known})")
    return Document(root, reader.parameters, reader.search_paths)
