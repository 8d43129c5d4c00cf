"""Tone mapping: linear colour of any brightness into 0..1 for 8-bit outputs and the live view,
after exposure and before the encoding (image.encode_levels). Each operator is a pure function of
the pixel, so crops, tiles and passes map alike.
"""

from __future__ import annotations

import numpy as np

TONEMAPS = ("none", "reinhard", "aces", "agx", "neutral")
# Stephen Hill's fit of the ACES reference rendering and sRGB output transforms (BakingLab's
# ACES.hlsl, MIT): linear sRGB into the RRT's saturated space, the fitted curve per channel, and
# back out of the ODT's; each row sums to 1 (to 5 decimals), so greys stay grey.
_ACES_IN = np.array([[0.59719, 0.35458, 0.04823], [0.07600, 0.90834, 0.01566], [0.02840, 0.13383, 0.83777]])
_ACES_OUT = np.array([[1.60475, -0.53108, -0.07367], [-0.10208, 1.10813, -0.00605], [-0.00327, -0.07276, 1.07602]])
_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # of linear sRGB (Rec. 709)
# AgX (Troy Sobotka's, Blender's default view since 4.0), as Filament and three.js fit it: linear
# sRGB to Rec. 2020, the inset matrix, log2 between AGX_EV (middle grey 0.18 at -10 .. +6.5
# stops), a 6th-order fit of the sigmoid (iolite-engine's "minimal AgX"), the outset matrix, the
# 2.2 power, back to linear sRGB. Matrices as rows that a row vector multiplies (x @ M).
_SRGB_TO_2020 = np.array([[0.6274, 0.0691, 0.0164], [0.3293, 0.9195, 0.0880], [0.0433, 0.0113, 0.8956]])
_2020_TO_SRGB = np.array([[1.6605, -0.1246, -0.0182], [-0.5876, 1.1329, -0.1006], [-0.0728, -0.0083, 1.1187]])
_AGX_INSET = np.array(
    [
        [0.856627153315983, 0.137318972929847, 0.11189821299995],
        [0.0951212405381588, 0.761241990602591, 0.0767994186031903],
        [0.0482516061458583, 0.101439036467562, 0.811302368396859],
    ]
)
_AGX_OUTSET = np.array(
    [
        [1.1271005818144368, -0.1413297634984383, -0.14132976349843826],
        [-0.11060664309660323, 1.157823702216272, -0.11060664309660294],
        [-0.016493938717834573, -0.016493938717834257, 1.2519364065950405],
    ]
)
AGX_EV = (-12.47393, 4.026069)  # log2 of 0.18 x 2^-10 and 0.18 x 2^6.5
_AGX_SIGMOID = (15.5, -40.14, 31.96, -6.868, 0.4298, 0.1191, -0.00232)  # x^6 .. x^0


def agx(rgb: np.ndarray) -> np.ndarray:
    """AgX's base view of linear sRGB (above), linear sRGB out."""
    x = np.maximum(rgb @ _SRGB_TO_2020 @ _AGX_INSET, 1e-10)
    x = ((np.log2(x) - AGX_EV[0]) / (AGX_EV[1] - AGX_EV[0])).clip(0.0, 1.0)
    x = np.polyval(_AGX_SIGMOID, x) @ _AGX_OUTSET
    return np.maximum(x, 0.0) ** 2.2 @ _2020_TO_SRGB


def pbr_neutral(rgb: np.ndarray) -> np.ndarray:
    """Khronos PBR Neutral (2024), the tone map for glTF product renders: colours up to 0.76 keep
    their values and hue (less a 0.04 offset that deepens blacks), brighter ones are compressed
    towards 1 along a hyperbola and desaturated by how much they were compressed."""
    start, desaturation = 0.8 - 0.04, 0.15
    low = rgb.min(axis=-1, keepdims=True)
    x = rgb - np.where(low < 0.08, low - 6.25 * low * low, 0.04)
    peak = x.max(axis=-1, keepdims=True)
    d = 1.0 - start
    new_peak = 1.0 - d * d / (peak + d - start)
    compressed = x * (new_peak / np.maximum(peak, 1e-30))
    g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0)
    compressed = compressed * (1.0 - g) + new_peak * g
    return np.where(peak < start, x, compressed)


def aces_curve(v: np.ndarray) -> np.ndarray:
    """Hill's fitted RRT + ODT curve of one channel."""
    return (v * (v + 0.0245786) - 0.000090537) / (v * (0.983729 * v + 0.4329510) + 0.238081)


def tone_map(rgb: np.ndarray, tonemap: str) -> np.ndarray:
    """Linear RGB of any brightness -> linear RGB in 0..1 (float64). 'none' clips at 1 (the
    seed's); 'reinhard' scales each pixel by 1 / (1 + L), L its luminance (Reinhard et al. 2002,
    their simple operator on luminance: hues kept, 1 reached only at infinity, a channel above
    its luminance clipped); 'aces' is Hill's fit of ACES (the filmic look of game engines: a toe,
    a soft shoulder, bright colours desaturating towards white); 'agx' is Blender's default view
    (agx); 'neutral' is Khronos PBR Neutral (pbr_neutral), for glTF materials shown as authored."""
    # (above 1e9 every operator gives its white; ACES's curve would overflow float64 near 1e154)
    x = np.asarray(rgb, dtype=np.float64).clip(0.0, 1e9)
    if tonemap == "reinhard":
        x = x / (1.0 + x @ _LUMINANCE)[..., None]
    elif tonemap == "aces":
        x = aces_curve(x @ _ACES_IN.T) @ _ACES_OUT.T
    elif tonemap == "agx":
        x = agx(x)
    elif tonemap == "neutral":
        x = pbr_neutral(x)
    elif tonemap != "none":
        raise ValueError(f"unknown tonemap {tonemap!r}; use one of {', '.join(TONEMAPS)}")
    return x.clip(0.0, 1.0)
