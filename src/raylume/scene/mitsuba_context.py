"""What every part of the Mitsuba reader shares: the elements by id, the file's folder, the world
mirror that keeps the image the right way round, and how to warn about an element.

Mitsuba's world is right-handed and raylume's left-handed: the same numbers seen through the
same camera give mirror images. Mirroring the whole world (x -> -x) once, camera included,
shows what Mitsuba shows. A sensor whose to_world mirrors already (Blender's exports put a
`<scale x="-1"/>` in it) shows a mirror image in Mitsuba too, and then the world stays as it is.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SceneError
from .checks import SceneWarning
from .mitsuba_props import Props
from .mitsuba_xml import Node, find_file, searched

MIRROR = np.diag([-1.0, 1.0, 1.0, 1.0])


@dataclass
class Context:
    folder: Path  # the scene file's folder: file names in the document are relative to it
    search_paths: list[Path]
    ids: dict[str, Node] = field(default_factory=dict)
    world: np.ndarray = field(default_factory=lambda: MIRROR.copy())  # Mitsuba's world -> raylume's
    warned: set[str] = field(default_factory=set)

    def warn(self, node: Node, message: str) -> None:
        text = f"{node.where}: {node.describe()}: {message}"
        if text not in self.warned:  # once, though a shared BSDF or a group's shape is read many times
            self.warned.add(text)
            warnings.warn(text, SceneWarning, stacklevel=2)

    def props(self, node: Node) -> Props:
        return Props(node, self.ids)

    def done(self, node: Node, props: Props) -> None:
        """Warn about the properties of `node` the reader did not use."""
        for name in props.unused():
            self.warn(node, f"property {name!r} is not supported by raylume and is ignored")

    def file(self, node: Node, name: str, suffixes: tuple[str, ...] | None = None) -> str:
        """A file the element names, as the scene document names it: relative to the scene's folder."""
        path = find_file(name, node.file.parent, self.search_paths, self.folder)
        if path is None:
            raise node.error(f"no file {name!r} ({searched(node.file.parent, self.folder)})")
        if suffixes is not None and path.suffix.lower() not in suffixes:
            raise node.error(f"{name!r}: raylume reads {', '.join(suffixes)} files here")
        return Path(os.path.relpath(path, self.folder)).as_posix()

    def point(self, m: np.ndarray, p=(0.0, 0.0, 0.0)) -> list[float]:
        """A point of Mitsuba's object space placed by `m`, in raylume's world."""
        q = self.world @ m @ np.array([*p, 1.0])
        return [float(c) + 0.0 for c in q[:3]]

    def vector(self, m: np.ndarray, v) -> list[float]:
        q = (self.world @ m)[:3, :3] @ np.asarray(v, dtype=np.float64)
        return [float(c) + 0.0 for c in q]


def uniform_scale(node: Node, m: np.ndarray, shape: str) -> float:
    """The scale factor of a similarity transform; a SceneError for a shape a non-uniform scale
    or shear would distort into something raylume's analytic shapes cannot be."""
    a = m[:3, :3]
    s = np.linalg.norm(a, axis=0)
    if not s.min() > 0:  # a scale of 0: nothing to divide the rotation out by, and no shape left
        raise SceneError(
            f"{node.where}: {node.describe()}: its to_world is singular (it scales by 0), which would collapse the "
            f"{shape}; raylume's {shape} needs a size"
        )
    r = a / s
    if np.ptp(s) > 1e-6 * s.max() or np.abs(r.T @ r - np.eye(3)).max() > 1e-6:
        raise SceneError(
            f"{node.where}: {node.describe()}: its to_world scales unevenly or shears, which would make the "
            f"{shape} {'an ellipsoid' if shape == 'sphere' else 'elliptic'}; raylume's {shape} cannot be"
        )
    return float(s[0])
