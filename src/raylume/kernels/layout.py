"""Column layout of the flat arrays the kernels read (shared by compile.py and the kernels)."""

# Materials: float64 (M, MAT_WIDTH)
MAT_COLOR = 0  # 3 columns, linear RGB
MAT_SPECULAR = 3  # Phong exponent, -1 for a matte surface
MAT_REFLECTIVE = 4
MAT_TRANSPARENCY = 5
MAT_IOR = 6
MAT_ABSORPTION = 7  # 3 columns, Beer-Lambert coefficient per unit length
MAT_TEXTURE = 10  # 0: none, 1: checker, 2: image
MAT_CHECK_A = 11  # 3 columns (image textures: the texture's mean colour, for callers without UVs)
MAT_CHECK_B = 14  # 3 columns
MAT_CHECK_SCALE = 17
MAT_TEX_OFFSET = 18  # image textures: first texel's row in the texture atlas
MAT_TEX_WIDTH = 19
MAT_TEX_HEIGHT = 20
MAT_TEX_SCALE_U = 21  # UVs are multiplied by these (tiling), then wrapped
MAT_TEX_SCALE_V = 22
MAT_WIDTH = 23

TEXTURE_NONE = 0
TEXTURE_CHECKER = 1
TEXTURE_IMAGE = 2

# Lights: int32 kind (L,) and float64 (L, LIGHT_WIDTH): position (a quad's or sphere's centre)
# or direction, RGB intensity, then the area lights' shape and shadow-sample count.
LIGHT_AMBIENT = 0
LIGHT_POINT = 1
LIGHT_DIRECTIONAL = 2
LIGHT_QUAD = 3  # centre +- u/2 +- v/2
LIGHT_SPHERE = 4
LIGHT_POSITION = 0
LIGHT_INTENSITY = 3
LIGHT_U = 6  # quad edge vectors (3 columns each)
LIGHT_V = 9
LIGHT_RADIUS = 12  # sphere
LIGHT_SAMPLES = 13  # shadow samples per shading point (area lights)
LIGHT_WIDTH = 14

# Hit kinds returned by traversal
HIT_NONE = 0
HIT_SPHERE = 1
HIT_TRIANGLE = 2
HIT_PLANE = 3

# BVH primitive types (prim_type)
PRIM_SPHERE = 0
PRIM_TRIANGLE = 1

# Camera: float64 (CAM_WIDTH,): position, forward, right * half-width, up * half-height (the
# pinhole of DESIGN.md, indices 0..11), then the thin lens and the pixel filter the film uses.
CAM_LENS_RADIUS = 12  # aperture / 2; 0 for the pinhole
CAM_FOCUS_DISTANCE = 13  # distance of the plane in focus, along the forward axis
CAM_HALF_WIDTH = 14  # w = tan(fov / 2) * W / H (|right * half-width|)
CAM_HALF_HEIGHT = 15  # h = tan(fov / 2)
CAM_FILTER = 16  # FILTER_BOX, ...
CAM_FILTER_NEGATIVE = 17  # |offset| beyond which the filter is negative (Mitchell); inf otherwise
CAM_FILTER_TABLE = 18  # FILTER_TABLE_SIZE offsets in pixels: the filter's inverse CDF
FILTER_TABLE_SIZE = 257
CAM_WIDTH = CAM_FILTER_TABLE + FILTER_TABLE_SIZE
FILTER_BOX = 0
FILTER_WARPED = 1  # any other filter: samples placed by the tabulated inverse CDF

# Size of per-thread traversal stacks; a BVH deeper than this is rejected at build time.
TRAVERSAL_STACK = 128
# Unused elements on either side of each thread's scratch arrays (at least 256 bytes: beyond a
# cache line and its prefetched neighbour). Small arrays allocated by two threads can lie back
# to back: without the gap one thread's stack ended in the cache line where another's began,
# and their writes fought over it (false sharing: the seed scene took 85 instead of 45 ms on
# 2 threads).
SCRATCH_PAD = 1024
