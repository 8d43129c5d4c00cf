"""The medium table: float64 (K, MED_WIDTH), one row per [media] entry in the scene's order, its
kind in MED_KIND (a kind module's KIND). Grid media keep their densities in one flat float32
array and their coarse majorant grids in one flat float64 array, found by the offsets here."""

MED_KIND = 0
MED_SIGMA_A = 1  # 3 columns: absorption per scene unit (at density 1 for a grid)
MED_SIGMA_S = 4  # 3 columns: scattering per scene unit (at density 1 for a grid)
MED_G = 7  # Henyey-Greenstein asymmetry
MED_SIGMA_T_MAX = 8  # the largest channel of sigma_a + sigma_s: a homogeneous medium's majorant
MED_BOX_MIN = 9  # 3 columns: a grid's box
MED_BOX_MAX = 12  # 3 columns
MED_DENSITY = 15  # offset of the grid's densities (nz, ny, nx, C order) in the density array
MED_NX = 16  # the grid's voxels along x, y, z
MED_NY = 17
MED_NZ = 18
MED_CELLS = 19  # offset of its majorant cells (mz, my, mx, C order) in the majorant array
MED_MX = 20  # majorant cells along x, y, z
MED_MY = 21
MED_MZ = 22
MED_WIDTH = 23
