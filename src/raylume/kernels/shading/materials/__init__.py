"""Materials: one module per kind (phong.py, diffuse.py, conductor.py, dielectric.py, plastic.py,
null.py), each all that its kind is: its row of the table packed from the model, its trace-mode
approximation, path mode's evaluate / sample, its flags and its albedo for the AOV and the
denoiser. registry.py lists the kinds and
makes the one dispatch per question; table.py the table's columns, the colour at a hit and
Beer-Lambert absorption. A new kind: its module, its line in registry.KINDS, its model class
(scene/model.py) — docs/architecture.md, "Adding a material"."""

from .registry import (
    BY_NAME,
    KINDS,
    aov_albedo,
    bsdf_eval,
    bsdf_sample,
    delta_only,
    diffuse_lane_sample,
    importance_delta_weight,
    index_matched,
    is_diffuse,
    kind_module,
    pack_material,
    two_sided,
)
from .table import (
    MAT_ABSORPTION,
    MAT_COLOR,
    MAT_EMISSION,
    MAT_ETA,
    MAT_HAS_ETA,
    MAT_IOR,
    MAT_K,
    MAT_KIND,
    MAT_REFLECTIVE,
    MAT_ROUGHNESS,
    MAT_SPECULAR,
    MAT_TEXTURE,
    MAT_TRANSPARENCY,
    MAT_WIDTH,
    albedo,
    beer_lambert,
)

__all__ = [
    "BY_NAME",
    "KINDS",
    "MAT_ABSORPTION",
    "MAT_COLOR",
    "MAT_EMISSION",
    "MAT_ETA",
    "MAT_HAS_ETA",
    "MAT_IOR",
    "MAT_K",
    "MAT_KIND",
    "MAT_REFLECTIVE",
    "MAT_ROUGHNESS",
    "MAT_SPECULAR",
    "MAT_TEXTURE",
    "MAT_TRANSPARENCY",
    "MAT_WIDTH",
    "albedo",
    "aov_albedo",
    "beer_lambert",
    "bsdf_eval",
    "bsdf_sample",
    "delta_only",
    "diffuse_lane_sample",
    "importance_delta_weight",
    "index_matched",
    "is_diffuse",
    "kind_module",
    "pack_material",
    "two_sided",
]
