"""pbrt-v4's rendering options (Camera, Film, Sampler, Integrator, PixelFilter) as raylume's
[camera] and [render] tables.

Camera: pbrt's camera space looks along +z with +y up and +x to the image's right, as
raylume's camera (DESIGN.md section 3: r = cross(up, f)), so position, look_at and up come
straight from the camera-to-world matrix. pbrt's `fov` spans the image's shorter side; raylume's
spans its height. A camera-to-world matrix that mirrors (pbrt-v3 exports often begin with
`Scale -1 1 1`) cannot be a raylume camera; the world is mirrored across the camera's vertical
plane instead (`flip`), which leaves the image unchanged.

Depth: pbrt's maxdepth counts bounces (1 is direct lighting), raylume's max_depth counts path
segments as Mitsuba does (2 is direct lighting): max_depth = maxdepth + 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .model import MAX_DEPTH
from .pbrt_params import Params
from .pbrt_parse import Directive

FILTERS = {"gaussian": "gaussian", "box": "box", "mitchell": "mitchell"}
# raylume's filters (README): pbrt's defaults for these are the same shapes and sizes.
FILTER_SIZES = {"gaussian": {"radius": 1.5, "sigma": 0.5}, "box": {"radius": 0.5}, "mitchell": {"radius": 2.0}}
PATH_LIKE = ("path", "volpath", "simplepath", "simplevolpath", "randomwalk", "bdpt", "mlt", "sppm", "lightpath")


@dataclass
class Options:
    width: int = 1280
    height: int = 720
    spp: int = 16
    maxdepth: int = 5
    integrator: str = "volpath"
    filter: str = "gaussian"
    seed: int | None = None
    camera_from_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    fov: float = 90.0
    lens_radius: float = 0.0
    focal_distance: float = 1e6

    def camera(self, d: Directive, p: Params, ctm: np.ndarray, warn) -> None:
        kind = d.args[0]
        if kind != "perspective":
            raise d.fail(f"{kind!r} cameras are not supported; raylume renders perspective cameras only")
        a = ctm[:3, :3]
        if not abs(np.linalg.det(a)) > 1e-12 * np.prod(np.linalg.norm(a, axis=0)) or not np.isfinite(a).all():
            raise d.fail("the camera's transform is singular (a zero scale?): it has no inverse")
        self.camera_from_world = ctm.copy()
        self.fov = p.float("fov", 90.0)
        if not 0 < self.fov < 180:
            raise d.fail(f'"float fov" must be between 0 and 180 degrees, got {self.fov:g}')
        self.lens_radius = p.float("lensradius", 0.0)
        self.focal_distance = p.float("focaldistance", 1e6)
        if self.lens_radius < 0 or not self.focal_distance > 0:
            raise d.fail("lensradius must be >= 0 and focaldistance > 0")
        for key in ("screenwindow", "frameaspectratio"):
            if p.has(key):
                p.list(key, "float")
                warn(d, f'"{key}" is not supported; the image is framed by fov and the film\'s aspect ratio')
        for key in ("shutteropen", "shutterclose"):
            p.float(key)  # motion blur is not supported; without moving transforms they change nothing

    def film(self, d: Directive, p: Params, warn) -> None:
        if d.args[0] not in ("rgb", "gbuffer", "spectral", "image"):  # image: pbrt-v3's
            raise d.fail(f"unknown film {d.args[0]!r} (pbrt-v4 has rgb, gbuffer and spectral)")
        self.width = p.int("xresolution", 1280)
        self.height = p.int("yresolution", 720)
        if not (0 < self.width <= 16384 and 0 < self.height <= 16384):
            raise d.fail(f"resolution {self.width} x {self.height}: each side must be 1..16384")
        p.string("filename")  # the output is raylume's -o
        for key in ("cropwindow", "pixelbounds"):
            if p.has(key):
                p.list(key, p.type_of(key))
                warn(d, f'"{key}" is not supported here; the whole image is rendered (raylume render --crop does this)')

    def sampler(self, d: Directive, p: Params) -> None:
        # Every sampler converges to the same image; raylume uses its own stratified one.
        self.spp = p.int("pixelsamples", 16)
        if not 0 < self.spp <= 4096:
            raise d.fail(f'"integer pixelsamples" must be 1..4096, got {self.spp}')
        for q in d.params:
            q.used = True

    def integrator_directive(self, d: Directive, p: Params, warn) -> None:
        kind = d.args[0]
        if kind not in PATH_LIKE:
            raise d.fail(f"integrator {kind!r} does not render the light transport raylume's path tracer does")
        if kind not in ("path", "volpath", "bdpt", "simplepath", "simplevolpath", "randomwalk"):
            warn(d, f"integrator {kind!r} is rendered with raylume's path tracer (the same image, once converged)")
        self.integrator = kind
        self.maxdepth = p.int("maxdepth", 5)
        if self.maxdepth < 0:
            raise d.fail(f'"integer maxdepth" must be >= 0, got {self.maxdepth}')
        for key in ("regularize", "lightsampler", "samplelights", "samplebsdf"):
            if p.has(key):
                p.by_name[key].used = True  # sampling choices: the converged image is the same

    def pixel_filter(self, d: Directive, p: Params, warn) -> None:
        kind = d.args[0]
        self.filter = FILTERS.get(kind, "gaussian")
        if kind not in FILTERS:
            warn(d, f"filter {kind!r} is not supported; raylume's gaussian (radius 1.5, sigma 0.5) is used")
            for q in d.params:
                q.used = True
            return
        for key, value in FILTER_SIZES[kind].items():
            if p.type_of(key) == "float":
                given = p.float(key)
                if abs(given - value) > 1e-9:
                    warn(d, f'"float {key}" {given:g} is not supported; raylume\'s {kind} filter has {key} {value:g}')
        for key in ("xradius", "yradius", "B", "C"):
            if p.has(key):
                p.float(key)
                warn(d, f'"float {key}" is not supported; raylume\'s {kind} filter is used as it is')

    def flip(self) -> np.ndarray:
        """The world mirror that makes a mirroring camera a proper one (identity when it is)."""
        world_from_camera = np.linalg.inv(self.camera_from_world)
        if np.linalg.det(world_from_camera[:3, :3]) >= 0:
            return np.eye(4)
        return world_from_camera @ np.diag([-1.0, 1.0, 1.0, 1.0]) @ self.camera_from_world

    def camera_table(self, warn_camera) -> dict:
        w = self.flip() @ np.linalg.inv(self.camera_from_world)
        a = w[:3, :3]
        if not np.allclose(a.T @ a, np.eye(3), atol=1e-6):
            warn_camera("the camera's transform scales or shears; raylume uses its position and direction only")
        position = w[:3, 3]
        forward = a[:, 2] / np.linalg.norm(a[:, 2])
        up = a[:, 1] / np.linalg.norm(a[:, 1])
        half = math.tan(math.radians(self.fov) / 2)
        if self.height > self.width:  # pbrt's fov spans the shorter side, here the width
            half *= self.height / self.width
        table = {
            "position": position.tolist(),
            "look_at": (position + forward).tolist(),
            "up": up.tolist(),
            "fov": math.degrees(2 * math.atan(half)),
        }
        if self.lens_radius > 0:
            table.update(aperture=2 * self.lens_radius, focus_distance=self.focal_distance)
        return table

    def render_table(self, warn_integrator) -> dict:
        depth = self.maxdepth + 1
        if depth > MAX_DEPTH:
            warn_integrator(f"maxdepth {self.maxdepth} is above raylume's limit; max_depth {MAX_DEPTH} is used")
            depth = MAX_DEPTH
        table = {
            "mode": "path",
            "width": self.width,
            "height": self.height,
            "spp": self.spp,
            "max_depth": depth,
            "encoding": "srgb",
            "filter": self.filter,
        }
        if self.seed is not None:
            table["seed"] = self.seed
        if self.integrator == "bdpt":
            table["integrator"] = "bdpt"
        return table
