"""The z-buffer rasterizer's kernels (--mode raster)."""
