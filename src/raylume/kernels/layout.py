"""Column layout of the flat arrays the kernels read (shared by compile.py and the kernels)."""

# Materials: float64 (M, MAT_WIDTH)
MAT_COLOR = 0  # 3 columns, linear RGB
MAT_SPECULAR = 3  # Phong exponent, -1 for a matte surface
MAT_REFLECTIVE = 4
MAT_TRANSPARENCY = 5
MAT_IOR = 6
MAT_ABSORPTION = 7  # 3 columns, Beer-Lambert coefficient per unit length
MAT_TEXTURE = 10  # 0: none, 1: checker
MAT_CHECK_A = 11  # 3 columns
MAT_CHECK_B = 14  # 3 columns
MAT_CHECK_SCALE = 17
MAT_WIDTH = 18

TEXTURE_NONE = 0
TEXTURE_CHECKER = 1

# Lights: int32 kind (L,) and float64 (L, 6): position or direction, then RGB intensity
LIGHT_AMBIENT = 0
LIGHT_POINT = 1
LIGHT_DIRECTIONAL = 2

# Hit kinds returned by traversal
HIT_NONE = 0
HIT_SPHERE = 1
HIT_TRIANGLE = 2
HIT_PLANE = 3

# BVH primitive types (prim_type)
PRIM_SPHERE = 0
PRIM_TRIANGLE = 1

# Render modes
MODE_CAST = 0
MODE_TRACE = 1

# Camera: float64 (12,): position, forward, right * half-width, up * half-height
# Size of per-thread traversal stacks; a BVH deeper than this is rejected at build time.
TRAVERSAL_STACK = 128
