"""Camera rays as DESIGN.md defines them: pixel (i, j) from the top-left, centres at +0.5;
optionally through a thin lens for depth of field.

The camera is a float64 (CAM_WIDTH,) array made per render (`camera_frame`): a Session renders
one compiled scene through any number of cameras."""

import math

import numpy as np

from ..vec import inline_function, kernel_function, madd, normalize, sub
from .film import filter_sample
from .sampler import concentric_disk, lens_sample, pixel_sample, sample_key

CAM_POSITION = 0  # 3 columns
CAM_FORWARD = 3  # 3 columns, unit
CAM_RIGHT = 6  # 3 columns: right * w, w = tan(fov / 2) * W / H
CAM_UP = 9  # 3 columns: up * h, h = tan(fov / 2)
CAM_LENS_RADIUS = 12  # aperture / 2; 0 for the pinhole
CAM_FOCUS_DISTANCE = 13  # distance of the plane in focus, along the forward axis
CAM_HALF_WIDTH = 14  # w
CAM_HALF_HEIGHT = 15  # h
CAM_CONE_SPREAD = 16  # a pixel's ray cone: its radius per unit distance (0: textures unfiltered)
CAM_WIDTH = 17


def camera_frame(position, look_at, up, fov_degrees, width, height, aperture=0.0, focus_distance=1.0) -> np.ndarray:
    """The camera array: origin, forward, right * w, up * h (left-handed: r = up x f), then the
    lens (radius aperture / 2, focus distance), w and h."""
    p = np.asarray(position, dtype=np.float64)
    f = np.asarray(look_at, dtype=np.float64) - p
    f /= np.abs(f).max()  # scale first: tiny differences must not underflow
    f /= np.linalg.norm(f)
    r = np.cross(np.asarray(up, dtype=np.float64), f)
    r /= np.abs(r).max()
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    h = math.tan(math.radians(fov_degrees) / 2.0)
    w = h * width / height
    cam = np.zeros(CAM_WIDTH, dtype=np.float64)
    cam[CAM_POSITION : CAM_POSITION + 3] = p
    cam[CAM_FORWARD : CAM_FORWARD + 3] = f
    cam[CAM_RIGHT : CAM_RIGHT + 3] = r * w
    cam[CAM_UP : CAM_UP + 3] = u * h
    cam[CAM_LENS_RADIUS] = 0.5 * aperture
    cam[CAM_FOCUS_DISTANCE] = focus_distance
    cam[CAM_HALF_WIDTH] = w
    cam[CAM_HALF_HEIGHT] = h
    return cam


def set_cone_spread(cam: np.ndarray, height: int, spp: int, texture_filter: bool = True) -> np.ndarray:
    """Give the camera array the ray cone its texture lookups filter over: half a pixel's
    height per unit distance, narrowed as pbrt narrows its ray differentials when a pixel takes
    several samples (1 / sqrt(spp), at least 1/8 of the pixel); 0 without filtering."""
    spread = cam[CAM_HALF_HEIGHT] / height * max(0.125, 1.0 / math.sqrt(spp))
    cam[CAM_CONE_SPREAD] = spread if texture_filter else 0.0
    return cam


def camera_of(model, width: int, height: int) -> np.ndarray:
    """The camera array of a scene model's Camera."""
    return camera_frame(
        model.position,
        model.look_at,
        model.up,
        model.fov,
        width,
        height,
        aperture=model.aperture,
        focus_distance=model.focus,
    )


@inline_function
def obliquity(cam, d):
    """cos of the angle between d and the viewing axis: a pixel away from the image's centre
    subtends a smaller angle (by this factor across the ray), so its ray cone is narrower."""
    return abs(d[0] * cam[CAM_FORWARD] + d[1] * cam[CAM_FORWARD + 1] + d[2] * cam[CAM_FORWARD + 2])


@kernel_function
def camera_ray(cam, x, y, width, height):
    """Unit direction through the image point (x, y) in pixels; (i + 0.5, j + 0.5) is a centre."""
    a = x / width * 2.0 - 1.0
    b = 1.0 - y / height * 2.0
    d = (
        cam[CAM_FORWARD] + cam[CAM_RIGHT] * a + cam[CAM_UP] * b,
        cam[CAM_FORWARD + 1] + cam[CAM_RIGHT + 1] * a + cam[CAM_UP + 1] * b,
        cam[CAM_FORWARD + 2] + cam[CAM_RIGHT + 2] * a + cam[CAM_UP + 2] * b,
    )
    return (cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2]), normalize(d)


@kernel_function
def thin_lens_ray(cam, o, d, u1, u2):
    """The pinhole ray (o, d) through a thin lens: from the lens point of (u1, u2) (concentric
    disk of radius aperture / 2, in the camera's right/up plane) towards the point where the
    pinhole ray meets the focus plane (forward . (x - o) = focus_distance). Points on that
    plane therefore image to the same spot whatever the aperture."""
    lx, ly = concentric_disk(u1, u2)
    radius = cam[CAM_LENS_RADIUS]
    sx = lx * radius / cam[CAM_HALF_WIDTH]
    sy = ly * radius / cam[CAM_HALF_HEIGHT]
    lens = (
        o[0] + cam[CAM_RIGHT] * sx + cam[CAM_UP] * sy,
        o[1] + cam[CAM_RIGHT + 1] * sx + cam[CAM_UP + 1] * sy,
        o[2] + cam[CAM_RIGHT + 2] * sx + cam[CAM_UP + 2] * sy,
    )
    t = cam[CAM_FOCUS_DISTANCE] / (d[0] * cam[CAM_FORWARD] + d[1] * cam[CAM_FORWARD + 1] + d[2] * cam[CAM_FORWARD + 2])
    focus = madd(o, d, t)
    return lens, normalize(sub(focus, lens))


@inline_function
def camera_sample(cam, filt, seed, i, j, s, total_spp, width, height):
    """Camera sample s (of total_spp per pixel) of pixel (i, j): (origin, direction, filter
    weight, random key)."""
    key = sample_key(seed, j * width + i, s)
    weight = 1.0
    if total_spp == 1:
        x = i + 0.5
        y = j + 0.5
    else:
        ux, uy = pixel_sample(key)
        x, y, weight = filter_sample(filt, i, j, ux, uy)
    o, d = camera_ray(cam, x, y, width, height)
    if cam[CAM_LENS_RADIUS] > 0.0:
        lu, lv = lens_sample(key)
        o, d = thin_lens_ray(cam, o, d, lu, lv)
    return o, d, weight, key


# --- the camera as bidirectional path tracing sees it: its importance, pbrt's PerspectiveCamera


@inline_function
def lens_area(cam):
    """The lens's area (pi r^2); 1 for the pinhole, whose position pdf is a delta (pbrt)."""
    r = cam[CAM_LENS_RADIUS]
    return math.pi * r * r if r > 0.0 else 1.0


@kernel_function
def lens_point(cam, u1, u2):
    """A point uniform on the lens (the camera's position for the pinhole), as thin_lens_ray
    places it."""
    o = (cam[CAM_POSITION], cam[CAM_POSITION + 1], cam[CAM_POSITION + 2])
    radius = cam[CAM_LENS_RADIUS]
    if radius <= 0.0:
        return o
    lx, ly = concentric_disk(u1, u2)
    sx = lx * radius / cam[CAM_HALF_WIDTH]
    sy = ly * radius / cam[CAM_HALF_HEIGHT]
    return (
        o[0] + cam[CAM_RIGHT] * sx + cam[CAM_UP] * sy,
        o[1] + cam[CAM_RIGHT + 1] * sx + cam[CAM_UP + 1] * sy,
        o[2] + cam[CAM_RIGHT + 2] * sx + cam[CAM_UP + 2] * sy,
    )


@kernel_function
def camera_importance(cam, width, height, o, d):
    """The camera's importance We of the ray leaving lens point o along the unit d, the
    solid-angle pdf with which camera rays take that direction, and the image point (x, y) in
    pixels the ray belongs to; We = 0 outside the image. As pbrt's PerspectiveCamera: with A
    the image plane's area at distance 1 (2w x 2h), We = 1 / (A lens_area cos^4) and the pdf
    1 / (A cos^3), cos the angle to the viewing axis, so that We integrates to 1 over the image."""
    f = (cam[CAM_FORWARD], cam[CAM_FORWARD + 1], cam[CAM_FORWARD + 2])
    cos_t = d[0] * f[0] + d[1] * f[1] + d[2] * f[2]
    if not (cos_t > 0.0):
        return 0.0, 0.0, -1.0, -1.0
    # the pinhole direction of the point where the ray meets the plane in focus
    pd = (d[0], d[1], d[2])
    if cam[CAM_LENS_RADIUS] > 0.0:
        t = cam[CAM_FOCUS_DISTANCE] / cos_t
        pd = (
            o[0] + d[0] * t - cam[CAM_POSITION],
            o[1] + d[1] * t - cam[CAM_POSITION + 1],
            o[2] + d[2] * t - cam[CAM_POSITION + 2],
        )
    w = cam[CAM_HALF_WIDTH]
    h = cam[CAM_HALF_HEIGHT]
    k = pd[0] * f[0] + pd[1] * f[1] + pd[2] * f[2]
    a = (pd[0] * cam[CAM_RIGHT] + pd[1] * cam[CAM_RIGHT + 1] + pd[2] * cam[CAM_RIGHT + 2]) / (k * w * w)
    b = (pd[0] * cam[CAM_UP] + pd[1] * cam[CAM_UP + 1] + pd[2] * cam[CAM_UP + 2]) / (k * h * h)
    x = (a + 1.0) * 0.5 * width
    y = (1.0 - b) * 0.5 * height
    if not (x >= 0.0 and x < width and y >= 0.0 and y < height):
        return 0.0, 0.0, -1.0, -1.0
    area = 4.0 * w * h
    cos2 = cos_t * cos_t
    return 1.0 / (area * lens_area(cam) * cos2 * cos2), 1.0 / (area * cos2 * cos_t), x, y
