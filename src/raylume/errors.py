"""Errors a user can fix: each carries one clear paragraph naming the file and the key."""


class RaylumeError(Exception):
    """Bad input (scene, mesh, flags, output path). The CLI prints it and exits with status 2."""


class SceneError(RaylumeError):
    pass


class OutputError(RaylumeError):
    pass
