"""The light table: one row per light of every kind, float64 (E, LIGHT_ROW_WIDTH), a kind per row
(int32 (E,), a kind module's KIND). Trace mode and path mode read the same rows.

Rows, in order (compile/lights.py builds them):
* area lights (`quad`, `sphere`): first, so that path mode's ray test loops over rows
  0..n_area-1 only;
* the other lights of the scene (point, spot, directional);
* emissive primitives (`surface`) and emissive instanced meshes (`instanced`);
* the ambient lights summed into one row (path mode's uniform environment), the environment;
  path mode's power distribution (a cdf) covers the rows up to here;
* each ambient light of the scene by itself (trace mode adds them one by one, in turn).
`order` lists the rows of the scene's lights in the scene's order: trace mode's loop.

Columns: the kinds' modules say which they use; these are shared."""

import numpy as np

LIGHT_POSITION = 0  # 3 columns: a point light's position, a quad's or sphere's centre
LIGHT_DIRECTION = 0  # 3 columns: a directional light's unit vector towards the light
LIGHT_INTENSITY = 3  # 3 columns, RGB: intensity, irradiance or radiance (the kind says)
LIGHT_U = 6  # quad edge vectors (3 columns each)
LIGHT_V = 9
LIGHT_AXIS = 6  # 3 columns: a spot light's unit direction (the way it shines)
LIGHT_COS_OUTER = 9  # cos of a spot's outer half-angle (0 beyond it)
LIGHT_COS_INNER = 10  # cos of its inner half-angle (full intensity inside)
LIGHT_RADIUS = 12  # sphere
LIGHT_SAMPLES = 13  # trace mode's shadow samples per shading point (area lights; 1 for the others)
LIGHT_WIDTH = 14  # the columns of the scene's own lights
EMIT_PRIM = 14  # surface rows: the primitive's index in the primitive table
EMIT_AREA = 15  # its area
LIGHT_ROW_WIDTH = 16
# instanced rows (beside the radiance in LIGHT_INTENSITY): where the mesh's distributions lie
# in the lights' distributions array (float64): its instances' cdf (count + 1 values,
# unnormalised) followed by those instances' rows of the instance table (as floats), and its
# triangles' cdf (by area in object space, count + 1 values); EMIT_PRIM is the mesh's first
# primitive row (its triangles' rows are consecutive), EMIT_AREA its object-space area.
INST_CDF = 0
INST_COUNT = 1
TRI_CDF = 2
TRI_COUNT = 6

# Trace mode's shadow rays towards a point on an area light stop this fraction short of it, so a
# light placed on a surface (a lamp on a ceiling) is not shadowed by that surface.
AREA_SHADOW_SHORTEN = 1e-6
# Path mode's shadow rays towards a sampled point stop this fraction short of it (the emitter
# itself must not count as a blocker).
SHADOW_SHORTEN = 1e-5


def scene_light_row(light) -> np.ndarray:
    """A table row of a model light with what every kind of scene light has: its intensity, and
    trace mode's shadow samples (area lights' `samples`; 1 for the others). The kind's `pack`
    adds its own columns."""
    row = np.zeros(LIGHT_ROW_WIDTH)
    row[LIGHT_INTENSITY : LIGHT_INTENSITY + 3] = light.intensity
    row[LIGHT_SAMPLES] = getattr(light, "samples", 1)
    return row


def mean_intensity(row: np.ndarray) -> float:
    """The mean of a row's intensity channels, which path mode's powers weigh."""
    return float(np.mean(row[LIGHT_INTENSITY : LIGHT_INTENSITY + 3]))
