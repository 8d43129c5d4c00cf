"""The scene model -> the compiled scene: flat arrays for the kernels and the BVH, in stages
(scene.py has the order; docs/architecture.md, "Data flow")."""

from .geometry import BVH_LEAF_BLOCK, BVH_OPTIONS, BVH_TRAVERSAL_COST
from .materials import material_row, mip_levels
from .objects import ANALYTIC_MODELS, object_matrix
from .scene import CompiledScene, compile_scene

__all__ = [
    "ANALYTIC_MODELS",
    "BVH_LEAF_BLOCK",
    "BVH_OPTIONS",
    "BVH_TRAVERSAL_COST",
    "CompiledScene",
    "compile_scene",
    "material_row",
    "mip_levels",
    "object_matrix",
]
