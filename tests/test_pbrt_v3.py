"""pbrt-v3 files (many public scenes are still in its format): its material names, its `image`
film and its lat-long infinite lights, read as pbrt-v4's counterparts."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import raylume
from raylume.image import save_array
from raylume.scene.pbrt_scene import pbrt_document


def test_v3_materials(tmp_path):
    (tmp_path / "v3.pbrt").write_text(
        """
Film "image" "integer xresolution" 8 "integer yresolution" 8
WorldBegin
Material "matte" "color Kd" [0.1 0.2 0.3]
Shape "sphere"
Material "glass" "float index" 1.33
Shape "sphere"
Material "mirror" "rgb Kr" [0.5 0.6 0.7]
Shape "sphere"
Material "plastic" "rgb Kd" [0.4 0.4 0.4] "rgb Ks" [0.2 0.2 0.2] "float roughness" 0.1
Shape "sphere"
Material "metal" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "bool remaproughness" false
    "float roughness" 0.05
Shape "sphere"
"""
    )
    document, messages = pbrt_document(tmp_path / "v3.pbrt")
    tables = [document["materials"][obj["material"]] for obj in document["objects"]]
    assert tables[0] == {"type": "diffuse", "color": [0.1, 0.2, 0.3]}
    assert tables[1]["type"] == "dielectric" and tables[1]["ior"] == 1.33
    assert tables[2] == {"type": "conductor", "color": [0.5, 0.6, 0.7]}
    # pbrt-v3's RoughnessToAlpha(0.1): its polynomial in ln(0.1), evaluated by hand: 0.46176
    assert tables[3]["type"] == "plastic" and tables[3]["roughness"] == pytest.approx(0.46176, abs=1e-4)
    assert tables[4]["roughness"] == 0.05 and tables[4]["eta"][0] < tables[4]["eta"][2]
    assert any("'matte'" in m and "pbrt-v4 counterpart" in m for m in messages)
    assert any('"rgb Ks"' in m for m in messages)  # the plastic's Ks is named as unused


@pytest.mark.filterwarnings("ignore:the scene has no objects")
def test_a_v3_lat_long_sky_is_seen_where_pbrt_v3_shows_it(tmp_path):
    """pbrt-v3's map: texel (u, v) looks along (sin t cos f, sin t sin f, cos t), f = 2 pi u,
    t = pi v, in the light's frame (here the world's). Coloured by octant, each pixel shows the
    octant of pbrt's ray through it."""
    height, width = 64, 128
    t = math.pi * (np.arange(height) + 0.5) / height
    f = 2 * math.pi * (np.arange(width) + 0.5) / width
    sin_t, cos_t = np.sin(t)[:, None], np.cos(t)[:, None]
    w = np.stack([sin_t * np.cos(f), sin_t * np.sin(f), cos_t * np.ones(width)], -1)
    save_array(tmp_path / "latlong.exr", (w > 0).astype(np.float32))
    (tmp_path / "sky.pbrt").write_text(
        """
LookAt 0 0 0  1 0.7 0.4  0 0 1
Camera "perspective" "float fov" 90
Film "image" "integer xresolution" 24 "integer yresolution" 16
WorldBegin
LightSource "infinite" "string mapname" "latlong.exr"
"""
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        image = raylume.render(tmp_path / "sky.pbrt", mode="cast", spp=1, aovs=False).rgb
    target, up = np.array([1, 0.7, 0.4]), np.array([0.0, 0, 1])  # the camera sits at the origin
    d0 = target / np.linalg.norm(target)
    right = np.cross(up, d0)
    right /= np.linalg.norm(right)
    new_up = np.cross(d0, right)
    checked = 0
    for y in range(16):
        for x in range(24):
            sx = -1.5 + (x + 0.5) / 24 * 3  # the screen window of a 3:2 film, fov 90 on the height
            sy = 1 - (y + 0.5) / 16 * 2
            d = right * sx + new_up * sy + d0
            d /= np.linalg.norm(d)
            if (np.abs(d) > 0.15).all():
                np.testing.assert_allclose(image[y, x], (d > 0).astype(float), atol=1e-6, err_msg=f"({x}, {y})")
                checked += 1
    assert checked > 100
