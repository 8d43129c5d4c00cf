"""Embree's C API called directly from compiled code, for the benchmarks: its single-ray and
its packet queries.

embreex's `EmbreeScene.run` (the benchmarks' Embree until now) calls `rtcIntersect1` ray by ray
and has no packet call. Its wheel ships the whole Embree 4 library, packets included, so this
module binds the few calls it needs through ctypes: a triangle scene built as embreex builds one
(the default build quality, robust), and Numba loops that trace rays through `rtcIntersect1` /
`rtcOccluded1` one at a time or `rtcIntersect8` / `rtcOccluded8` eight consecutive rays a
packet, as raylume's batch query groups them. The loops call Embree the same way (a C call from
compiled code, the ray structures in one scratch) and write what raylume's queries write (the
distance, geometry, primitive and instance ids; a blocked flag), so that they time Embree's
traversals with nothing of Python's between them. Robust, `rtcIntersect1` takes as long as
through embreex (bumpy 40k's hit rays 28-29 ms on the Zen 4); Embree's default, non-robust
traversal (`flags=0`) takes ~18% less, and is not watertight, as raylume's test is.

    scene = EmbreeScene(vertices, faces)
    t, geom, prim, inst = scene.intersect(origins, directions, packets=True)
    blocked = scene.occluded(origins, directions, tmax, packets=True)
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numba
import numpy as np

_INVALID = 0xFFFFFFFF  # RTC_INVALID_GEOMETRY_ID
ROBUST = 1 << 2  # RTC_SCENE_FLAG_ROBUST: embreex's EmbreeScene sets it, and raylume's test is watertight
# The rows of RTCRayHit (one ray) and RTCRayHit8 (each row eight lanes): the ray's org_x, org_y,
# org_z, tnear, dir_x, dir_y, dir_z, time, tfar, mask, id, flags, then the hit's Ng_x, Ng_y,
# Ng_z, u, v, primID, geomID, instID[1], instPrimID[1] (rtcore_ray.h)
_TFAR, _MASK, _PRIM, _GEOM, _INST = 8, 9, 17, 18, 19
_ROWS = 24  # 21 used, rounded up so that a RTCRayHit8 of 8-lane rows keeps 64-byte alignment


def _library() -> ctypes.CDLL:
    import embreex

    libs = Path(embreex.__file__).resolve().parent.parent / "embreex.libs"
    found = sorted(libs.glob("libembree4*.so*"))
    if not found:
        raise RuntimeError(f"no libembree4 in {libs}")
    lib = ctypes.CDLL(str(found[0]))
    p, u, z = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t
    for name, restype, argtypes in [
        ("rtcNewDevice", p, [ctypes.c_char_p]),
        ("rtcGetDeviceError", ctypes.c_int, [p]),
        ("rtcNewScene", p, [p]),
        ("rtcNewGeometry", p, [p, ctypes.c_int]),
        ("rtcSetNewGeometryBuffer", p, [p, ctypes.c_int, u, ctypes.c_int, z, z]),
        ("rtcCommitGeometry", None, [p]),
        ("rtcAttachGeometry", u, [p, p]),
        ("rtcReleaseGeometry", None, [p]),
        ("rtcSetSceneFlags", None, [p, ctypes.c_int]),
        ("rtcCommitScene", None, [p]),
        ("rtcReleaseScene", None, [p]),
        ("rtcReleaseDevice", None, [p]),
    ]:
        getattr(lib, name).restype = restype
        getattr(lib, name).argtypes = argtypes
    # the queries take pointers as 64-bit integers, which Numba passes from `array.ctypes.data`
    z4 = [z, z, z, z]
    for name, argtypes in [
        ("rtcIntersect1", z4[:3]),
        ("rtcOccluded1", z4[:3]),
        ("rtcIntersect8", z4),
        ("rtcOccluded8", z4),
    ]:
        getattr(lib, name).restype = None
        getattr(lib, name).argtypes = argtypes  # ([valid,] scene, ray(s), args: NULL for the defaults)
    return lib


try:
    _LIB = _library()
    _intersect1, _occluded1 = _LIB.rtcIntersect1, _LIB.rtcOccluded1
    _intersect8, _occluded8 = _LIB.rtcIntersect8, _LIB.rtcOccluded8
    _MISSING = None
except ModuleNotFoundError as exc:  # without embreex: a script's --help still answers, a run says why it cannot
    _LIB = _intersect1 = _occluded1 = _intersect8 = _occluded8 = None
    _MISSING = exc


def _aligned(shape, dtype, align: int = 64) -> np.ndarray:
    """A zeroed array whose data starts on an `align`-byte boundary (RTCRayHit8 asks for 32)."""
    n = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.zeros(n + align, np.uint8)
    start = -raw.ctypes.data % align
    return raw[start : start + n].view(dtype).reshape(shape)


@numba.njit(inline="always")
def _load(rays, bits, i, o, d, k, tmin, tmax):
    """Ray k into lane i of the scratch (a (_ROWS, lanes) view), its hit cleared."""
    for a in range(3):
        rays[a, i] = o[k, a]
        rays[4 + a, i] = d[k, a]
    rays[3, i] = tmin[min(k, tmin.shape[0] - 1)]
    rays[7, i] = 0.0
    rays[_TFAR, i] = tmax[min(k, tmax.shape[0] - 1)]
    bits[_MASK, i] = _INVALID
    bits[_MASK + 1, i] = 0
    bits[_MASK + 2, i] = 0
    bits[_GEOM, i] = _INVALID
    bits[_INST, i] = _INVALID


@numba.njit(inline="always")
def _store(rays, bits, i, k, out, occluded):
    """Lane i's answer into ray k's place: a hit's (t, geometry, primitive, instance), misses
    inf and -1; for occlusion its tfar alone, which Embree sets to -inf where the ray is blocked."""
    if occluded:
        out[0][k] = rays[_TFAR, i]
        return
    hit = bits[_GEOM, i] != _INVALID
    out[0][k] = rays[_TFAR, i] if hit else np.inf
    out[1][k] = bits[_GEOM, i] if hit else -1
    out[2][k] = bits[_PRIM, i] if hit else -1
    out[3][k] = np.int32(bits[_INST, i]) if hit else -1


@numba.njit(nogil=True)
def _single_rays(scene, o, d, tmin, tmax, out, ray, occluded):
    """rtcIntersect1 or rtcOccluded1 ray by ray; ray: float32 (_ROWS,) scratch. Written out
    rather than through _load and _store on a (_ROWS, 1) view, which cost ~4 ns a ray more."""
    bits = ray.view(np.uint32)
    for k in range(o.shape[0]):
        for a in range(3):
            ray[a] = o[k, a]
            ray[4 + a] = d[k, a]
        ray[3] = tmin[min(k, tmin.shape[0] - 1)]
        ray[7] = 0.0
        ray[_TFAR] = tmax[min(k, tmax.shape[0] - 1)]
        bits[_MASK] = _INVALID
        bits[_MASK + 1] = 0
        bits[_MASK + 2] = 0
        bits[_GEOM] = _INVALID
        bits[_INST] = _INVALID
        if occluded:
            _occluded1(scene, ray.ctypes.data, 0)
            out[0][k] = ray[_TFAR]
            continue
        _intersect1(scene, ray.ctypes.data, 0)
        hit = bits[_GEOM] != _INVALID
        out[0][k] = ray[_TFAR] if hit else np.inf
        out[1][k] = bits[_GEOM] if hit else -1
        out[2][k] = bits[_PRIM] if hit else -1
        out[3][k] = np.int32(bits[_INST]) if hit else -1


@numba.njit(nogil=True)
def _packets(scene, o, d, tmin, tmax, out, rays, valid, occluded):
    """rtcIntersect8 or rtcOccluded8 on eight consecutive rays at a time; rays: float32
    (_ROWS, 8), valid: int32 (8,) scratch."""
    bits = rays.view(np.uint32)
    n = o.shape[0]
    for start in range(0, n, 8):
        lanes = min(8, n - start)
        for i in range(8):
            valid[i] = -1 if i < lanes else 0
            _load(rays, bits, i, o, d, start + min(i, lanes - 1), tmin, tmax)  # a short packet's spare lanes masked off
        if occluded:
            _occluded8(valid.ctypes.data, scene, rays.ctypes.data, 0)
        else:
            _intersect8(valid.ctypes.data, scene, rays.ctypes.data, 0)
        for i in range(lanes):
            _store(rays, bits, i, start + i, out, occluded)


class EmbreeScene:
    """One triangle mesh in an Embree 4 scene of its own device, built as embreex builds one
    (the default build quality, the robust flag: the same answers as its `run`, to the ray),
    traced on the calling thread. flags=0: Embree's faster, non-robust traversal."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, flags: int = ROBUST) -> None:
        if _LIB is None:
            from common import missing_extra

            raise SystemExit(missing_extra(_MISSING) or str(_MISSING))
        lib = _LIB
        self._device = lib.rtcNewDevice(b"threads=1")
        self._scene = lib.rtcNewScene(self._device)
        lib.rtcSetSceneFlags(self._scene, flags)
        geometry = lib.rtcNewGeometry(self._device, 0)  # RTC_GEOMETRY_TYPE_TRIANGLE
        v = np.ascontiguousarray(vertices, np.float32)
        f = np.ascontiguousarray(faces, np.uint32)
        # RTC_BUFFER_TYPE_VERTEX (1), RTC_FORMAT_FLOAT3; RTC_BUFFER_TYPE_INDEX (0), RTC_FORMAT_UINT3
        for kind, fmt, array in ((1, 0x9003, v), (0, 0x5003, f)):
            pointer = lib.rtcSetNewGeometryBuffer(geometry, kind, 0, fmt, 12, len(array))
            ctypes.memmove(pointer, array.ctypes.data, array.nbytes)
        lib.rtcCommitGeometry(geometry)
        lib.rtcAttachGeometry(self._scene, geometry)
        lib.rtcReleaseGeometry(geometry)
        lib.rtcCommitScene(self._scene)
        if error := lib.rtcGetDeviceError(self._device):
            raise RuntimeError(f"Embree error {error} building the scene")
        self._ray = _aligned((_ROWS,), np.float32)
        self._rays = _aligned((_ROWS, 8), np.float32)
        self._valid = _aligned((8,), np.int32)

    def _run(self, o, d, tmin, tmax, out, occluded: bool, packets: bool) -> None:
        o = np.ascontiguousarray(o, np.float32)
        d = np.ascontiguousarray(d, np.float32)
        tmin = np.atleast_1d(np.asarray(tmin, np.float32))
        tmax = np.atleast_1d(np.asarray(tmax, np.float32))
        if packets:
            _packets(self._scene, o, d, tmin, tmax, out, self._rays, self._valid, occluded)
        else:
            _single_rays(self._scene, o, d, tmin, tmax, out, self._ray, occluded)
        if error := _LIB.rtcGetDeviceError(self._device):
            raise RuntimeError(f"Embree error {error} tracing")

    def intersect(self, origins: np.ndarray, directions: np.ndarray, packets: bool = False):
        """(t, geometry, primitive, instance) of each ray's nearest hit (inf and -1 for a
        miss), as raylume.intersect answers, through rtcIntersect8 on eight consecutive rays
        at a time when `packets`, else rtcIntersect1 ray by ray."""
        n = len(origins)
        out = (np.empty(n, np.float32), np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.int32))
        self._run(origins, directions, 0.0, np.inf, out, False, packets)
        return out

    def occluded(self, origins: np.ndarray, directions: np.ndarray, tmax, packets: bool = False) -> np.ndarray:
        """Whether something lies on each ray between 0 and its tmax (a number or one per ray),
        through rtcOccluded8 or rtcOccluded1."""
        unused = np.empty(1, np.int32)  # the hit's ids: one type of `out` for both queries
        out = (np.empty(len(origins), np.float32), unused, unused, unused)
        self._run(origins, directions, 0.0, tmax, out, True, packets)
        return out[0] == -np.inf

    def __del__(self) -> None:
        if getattr(self, "_scene", None):
            _LIB.rtcReleaseScene(self._scene)
            _LIB.rtcReleaseDevice(self._device)
