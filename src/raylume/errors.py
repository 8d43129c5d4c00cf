"""Errors a user can fix: each carries one clear paragraph naming the file and the key."""


class RaylumeError(Exception):
    """Bad input (scene, mesh, flags, output path): its message names the file (or the call) and
    the key. The base class of every error raylume raises for its input, so `except
    raylume.RaylumeError` catches them all; the command line prints the message on one line and
    exits with status 2."""


class SceneError(RaylumeError, ValueError):
    """A scene that cannot be read or is invalid: a file's syntax, a key, a value, a mesh or
    texture file (also a ValueError)."""


class OutputError(RaylumeError):
    """An output that cannot be written: its format, its folder, a bit depth for its format."""
