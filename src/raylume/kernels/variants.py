"""Which compiled variant of the kernels a scene takes: the feature argument X that every kernel
receives (None, or the scene's Instances), chosen from the scene's shapes, materials, textures
and lights."""

import numpy as np

from .geometry.layout import NODE_REF, SPHERE_BLOCK, leaf_count, leaf_first
from .geometry.shapes import PRIM_KIND, SPHERE
from .scene import instances_of
from .shading import textures
from .shading.lights import SCENE_KINDS
from .shading.materials import MAT_ABSORPTION, MAT_TEXTURE

# the scene's lights that trace mode samples at points (area lights: quad, sphere)
_SAMPLED_LIGHTS = [kind.KIND for kind in SCENE_KINDS if not kind.DELTA and not kind.EVERYWHERE]
# the lights whose intensity trace mode scales by the direction (spot)
_FALLOFF_LIGHTS = [kind.KIND for kind in SCENE_KINDS if kind.FALLOFF]

# Basic scenes (spheres and opaque triangles, no image textures, no area lights: the seed scene,
# most meshes) compile without the code for the other shapes, planes, transparent shadows,
# image textures, area lights and instances: kernels take X = features(S), None for a basic
# scene, and test `X is not None` before that code; Numba drops a branch on a None argument
# before compiling it (the seed scene's trace kernel: 4% faster, and 72 s of compilation against
# 96 s). Every other scene gets its Instances (kernels/scene.py, empty when it has none): one
# variant with every shape's code, compiled once. (There were int8 and float64 variants for
# planes-only and other-shape scenes too; each mode's kernels compiled up to four times, and a
# fresh machine spent most of its first test run compiling them.)


def features(S):
    """None for a basic kernel scene (see above); the scene's Instances otherwise: that variant
    compiles every shape's code and the two-level traversal (traverse_instances.py), skipped at
    run time when the scene has no instances."""
    basic = (
        _basic_geometry(S)
        and not S.has_transparency
        and not (S.textures[:, textures.TEX_KIND] == textures.IMAGE).any()
        and not np.isin(S.light_kind[S.light_order], _SAMPLED_LIGHTS).any()
    )
    return None if basic else instances_of(S)


def geometry_features(S):
    """X of geometry-only queries (raylume.intersect): None, the basic variant with its ray
    packets, for every scene of spheres and triangles without instances. Materials, textures
    and lights, which features(S) also weighs, change no hit."""
    return None if _basic_geometry(S) else instances_of(S)


def _basic_geometry(S) -> bool:
    """Spheres and triangles alone, without instances."""
    return S.basic_shapes and S.instance_inverse.shape[0] == 0


def path_features(S):
    """X of path mode: one variant for every scene (a path-mode compile is ~55 s), the scene's
    Instances as for any scene that is not basic."""
    return instances_of(S)


def sphere_leaf(S) -> bool:
    """Whether the BVH root is one leaf of spheres alone: wavefront._sphere_leaf's answer
    (count > 0), in numpy (tests/test_wavefront.py checks the two agree)."""
    return sphere_leaf_range(S.node_index, S.prims)[1] > 0


def sphere_leaf_range(index: np.ndarray, prims: np.ndarray) -> tuple[int, int]:
    """wavefront._sphere_leaf in numpy: (first, count) of the root leaf when the BVH root
    (node_index `index`) is one leaf of spheres alone, else (0, 0)."""
    if not (index.shape[0] == 1 and index[0, NODE_REF, 1] >= 0):
        return 0, 0
    ref = int(index[0, NODE_REF, 0])
    first, count = leaf_first(ref), leaf_count(ref)
    if count < 0:  # a block: spheres when below -SPHERE_BLOCK
        if count >= -SPHERE_BLOCK or prims[first, PRIM_KIND] != SPHERE:
            return 0, 0
        count = -count - SPHERE_BLOCK
    if count <= 0 or not bool((prims[first : first + count, PRIM_KIND] == SPHERE).all()):
        return 0, 0
    return first, count


def trace_features(S, centres_only: bool):
    """B of trace mode's kernel (frame.trace_lane): None for the seed's kind of first picture,
    else 0 (one variant for every other basic scene). None takes a basic scene whose BVH root
    is one leaf of spheres, without an environment, textures, spot lights or absorbing
    materials (absorption matters only to a ray leaving a sphere: a camera inside one), rendered
    with one sample at each pixel's centre (`centres_only`: a pinhole camera, one sample per
    pixel, a film without unsigned sums). Its wavefront compiles none of the code of the BVH,
    the environment, textures, spot lights, absorption, camera and pixel-filter sampling or the
    film's running sums (the seed's first picture: 53 Numba compilations instead of 93). The
    same scene at more samples takes 0, with the same rays and image."""
    plain = (
        centres_only
        and not S.env_present
        and not (S.materials[:, MAT_TEXTURE] >= 0).any()
        and not (S.materials[:, MAT_ABSORPTION : MAT_ABSORPTION + 3] != 0.0).any()
        and not np.isin(S.light_kind[S.light_order], _FALLOFF_LIGHTS).any()
    )
    return None if plain and features(S) is None and sphere_leaf(S) else 0
