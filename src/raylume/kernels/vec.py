"""3-vectors as tuples of floats inside Numba kernels: no allocation, inlined by LLVM; and the
decorators of every per-ray function (`kernel_function`, `inline_function`)."""

import math

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import cgutils, compiler, config, types
from numba.core.codegen import JITCodeLibrary
from numba.core.registry import CPUDispatcher
from numba.extending import intrinsic

from .vector_width import ENTRY_PIPELINE

# fastmath without 'nnan'/'ninf': traversal relies on +-inf behaving as IEEE says.
FAST = {"nsz", "arcp", "contract", "afn"}

# Options for per-ray functions. They never allocate, so they run without Numba's reference
# counting: otherwise every call increments and decrements the count of each array it is
# passed, atomically, and that cost more than the traversal itself (210 vs 117 ns per ray on
# the bunny), and made two threads slower than one as they fought over the counters.
# forceinline is said on every one: a Numba function that leaves it unset inherits it from the
# function whose compilation triggered its own (as with fastmath), and a call kept on purpose
# (the transparent-shadow walk, area-light sampling) would then be inlined.
KERNEL = dict(fastmath=FAST, error_model="numpy", _nrt=False, forceinline=False)
# Per-ray functions that take arrays and run once or more per ray: inlined by LLVM
# (`alwaysinline`), because a call passes each array descriptor by value (the seed's trace lost a
# quarter of its speed to that). Not Numba's own inline="always", which inlined at the level of
# Numba IR and typed every inlined copy again: a cold render of the seed spent 40 of its 81 s of
# compilation inlining and 13 more typing; with LLVM's inlining it compiles in 38 s.
INLINE = dict(KERNEL, forceinline=True)


# What KernelFunction compiles without, and the options a plain njit entry for Python leaves out.
_NO_WRAPPERS = {"no_cpython_wrapper": True, "no_cfunc_wrapper": True}
_NOT_FOR_NJIT = {"nopython", *_NO_WRAPPERS}


# --- code that only kernels call: LLVM IR, optimised once in the kernel ------------------------
# Numba makes a library of every function it compiles, optimises it with everything it links in
# (its callees' libraries) and turns the result into machine code. For a per-ray function only
# the kernels' copies ever run, so each level of the call tree repeated the optimisation of all
# the code below it and made machine code that nothing called. These libraries are linked as
# Numba hands them over (its function passes done) and optimised and compiled once, in the
# kernel that links them: a cold compile of raylume.intersect ~1.4 s shorter, every image and
# hit bit-identical (docs/performance.md, "Cold compile"; docs/architecture.md, "_LinkedOnlyLibrary").


class _LinkedOnlyLibrary(JITCodeLibrary):
    """A library that is only ever linked into its callers': no module optimisation of its own
    (the caller's covers it) and no machine code."""

    def _optimize_final_module(self):
        pass

    def _finalize_final_module(self):
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True

    def get_pointer_to_function(self, name):
        self._ensure_finalized()
        return 0  # nothing to call from Python (KernelFunction.__call__ compiles an entry)

    @property
    def codegen(self):
        return _WithoutEnvironment(self._codegen)


class _OptimisedLinkedOnlyLibrary(_LinkedOnlyLibrary):
    """A _LinkedOnlyLibrary optimised by itself before its callers link it (vector_loop: LLVM's
    loop vectoriser must see the loop alone), still without machine code of its own."""

    _optimize_final_module = JITCodeLibrary._optimize_final_module


class _WithoutEnvironment:
    """The JIT code generator, less set_env: a library without machine code has no environment
    variable to point at its Python environment (none of these functions uses one: they never
    touch Python objects, which is also why kernels loaded from the disk cache need none)."""

    def __init__(self, codegen):
        self._codegen = codegen

    def set_env(self, env_name, env) -> None:
        pass

    def __getattr__(self, name):
        return getattr(self._codegen, name)


class _LinkedOnlyCompiler(compiler.Compiler):
    """Numba's compiler, writing into a _LinkedOnlyLibrary."""

    library_class = _LinkedOnlyLibrary

    def compile_extra(self, func):
        if self.state.library is None:
            self.state.library = self.library_class(self.state.targetctx.codegen(), func.__qualname__)
        return super().compile_extra(func)


class _VectorLoopCompiler(_LinkedOnlyCompiler):
    library_class = _OptimisedLinkedOnlyLibrary


# The library overrides Numba's internals (as of Numba 0.68): a Numba without them compiles
# these functions its own way, slower to compile but correct (test_kernel_function.py notices).
_LINKABLE = all(
    hasattr(JITCodeLibrary, name)
    for name in ("_optimize_final_module", "_finalize_final_module", "_finalize_dynamic_globals",
                 "_verify_declare_only_symbols", "_ensure_finalized")
)  # fmt: skip
_PIPELINE = _LinkedOnlyCompiler if _LINKABLE else compiler.Compiler
_VECTOR_PIPELINE = _VectorLoopCompiler if _LINKABLE else compiler.Compiler

# jit_options of @overload implementations that kernels inline (they are never called from
# Python either)
INLINE_OVERLOAD = dict(INLINE, **_NO_WRAPPERS, pipeline_class=_PIPELINE)


class KernelFunction(CPUDispatcher):
    """A Numba function that kernels call: compiled without the wrappers that let Python call
    it, and once per argument types rather than once more per literal value (`row3(a, i, 3)`
    and `row3(a, i, 6)` share one compilation; LLVM sees the constant after inlining anyway).
    Each compilation is a library of LLVM IR that its callers link in (_LinkedOnlyLibrary).
    Compiled with Python's wrappers, path mode's few hundred of them had made the warm-up's
    path job take 113 s instead of 69 s. A call from Python (tests, a notebook) goes to a plain
    Numba compilation of the same function, made on first use: without a wrapper, Numba's own
    call from Python would crash."""

    def get_call_template(self, args, kws):
        args = [types.unliteral(a) for a in args]
        return super().get_call_template(args, {k: types.unliteral(v) for k, v in kws.items()})

    def __call__(self, *args, **kws):
        entry = self.__dict__.get("_python_entry")
        if entry is None:
            entry = self._python_entry = python_entry(self)
        return entry(*args, **kws)


def python_entry(function: KernelFunction, cache: bool = False):
    """The same Python function compiled once more as a plain Numba function, wrappers included
    (an entry that called `function` could not hand back an array without reference counting);
    with `cache`, into Numba's disk cache (benchmarks/common.cached_entry); for the vector width
    the CPU prefers, as the kernels' entries are (vector_width.py)."""
    options = {k: v for k, v in function.targetoptions.items() if k not in _NOT_FOR_NJIT}
    return njit(cache=cache, pipeline_class=ENTRY_PIPELINE, **options)(function.py_func)


def kernel_function(py_func=None, /, **options):
    """Decorator of per-ray functions: `@kernel_function` compiles a KernelFunction with the
    options KERNEL; `@kernel_function(**options)` with these Numba options instead (none:
    Numba's defaults)."""
    if py_func is None:
        return lambda f: _kernel_function(f, options)
    return _kernel_function(py_func, KERNEL)


def vector_loop(py_func=None, /, fastmath=False):
    """Decorator of loops over arrays of rays meant to run SIMD (kernels/integrators/wavefront.py): no
    bounds checks, exact arithmetic unless `fastmath` says otherwise, and a library optimised on
    its own before a kernel links it (_OptimisedLinkedOnlyLibrary), so LLVM's loop vectoriser
    sees the loop with its arrays as separate arguments. Linked into a kernel and only optimised
    there, inlined first, the loops stayed scalar."""
    if py_func is None:
        return lambda f: vector_loop(f, fastmath=fastmath)
    if config.DISABLE_JIT:
        return py_func
    options = dict(fastmath=fastmath, error_model="numpy", _nrt=False, forceinline=False, boundscheck=False)
    targetoptions = dict(options, nopython=True, **_NO_WRAPPERS)
    return KernelFunction(py_func=py_func, locals={}, targetoptions=targetoptions, pipeline_class=_VECTOR_PIPELINE)


def inline_function(py_func):
    """Decorator of per-ray functions inlined by LLVM into every caller (the options INLINE)."""
    return _kernel_function(py_func, INLINE)


def _kernel_function(py_func, options):
    if config.DISABLE_JIT:
        return py_func
    targetoptions = dict(options, nopython=True, **_NO_WRAPPERS)
    return KernelFunction(py_func=py_func, locals={}, targetoptions=targetoptions, pipeline_class=_PIPELINE)


@vector_loop
def fill(row, n, value):
    """row[0..n-1] = value"""
    for k in range(n):
        row[k] = value


@vector_loop
def count_up(row, n):
    """row[k] = k for k in 0..n-1"""
    for k in range(n):
        row[k] = k


@kernel_function
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@kernel_function
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@kernel_function
def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@kernel_function
def hadamard(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@kernel_function
def madd(a, b, s):
    """a + b * s"""
    return (a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s)


@kernel_function
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel_function
def any_positive(c):
    """Whether any component of the triple c is above 0 (a colour that carries light)."""
    return c[0] > 0.0 or c[1] > 0.0 or c[2] > 0.0


@kernel_function
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@kernel_function
def length(a):
    return math.sqrt(dot(a, a))


@kernel_function
def normalize(a):
    n = length(a)
    if n == 0.0:
        return (0.0, 0.0, 0.0)
    inv = 1.0 / n
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@kernel_function
def max_abs(a):
    return max(abs(a[0]), abs(a[1]), abs(a[2]))


@kernel_function
def row3(arr, i, k):
    """arr[i, k:k+3] as a float tuple (float64 even when arr is float32)."""
    return (float(arr[i, k]), float(arr[i, k + 1]), float(arr[i, k + 2]))


@inline_function
def last_at_most(values, first, n, x):
    """The largest i in 0..n-1 with values[first + i] <= x, for values[first:first + n]
    non-decreasing and values[first] <= x (0 otherwise): where a cdf's interval holds x (path
    mode's light and instanced-emitter picks). The range halves each step, log2 n steps whatever
    x is. Written as a select so that it could be a conditional move, but LLVM's x86 backend
    turns a select on a loop's critical path back into a branch: where that costs (the
    environment's cells, ~10% of examples/materials.toml's path-mode time), an alias table
    takes one step instead (shading/environment.py)."""
    base = 0
    length = n
    while length > 1:
        half = length >> 1
        base = base + half if values[first + base + half] <= x else base
        length -= half
    return base


# fdlibm's minimax polynomials for sin and cos on [-pi/4, pi/4] (k_sin.c, k_cos.c: error below
# 2**-58 there), in Horner form.
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)  # fmt: skip
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)  # fmt: skip


@kernel_function
def quarter_sincos(a):
    """(cos a, sin a) for |a| <= pi/4, to about an ulp, without a libm call."""
    z = a * a
    s = a + a * z * (_S[0] + z * (_S[1] + z * (_S[2] + z * (_S[3] + z * (_S[4] + z * _S[5])))))
    c = 1.0 - 0.5 * z + z * z * (_C[0] + z * (_C[1] + z * (_C[2] + z * (_C[3] + z * (_C[4] + z * _C[5])))))
    return c, s


# fdlibm's arctangent (s_atan.c): atan(0.5) and atan(1), each as a float64 and the rest (its
# reductions around 1.5 and infinity are not needed: atan2 takes atan of numbers in [0, 1]), and
# the odd polynomial for |x| <= 7/16, in Horner form.
_ATAN_HI = (4.63647609000806093515e-01, 7.85398163397448278999e-01)
_ATAN_LO = (2.26987774529616870924e-17, 3.06161699786838301793e-17)
_AT = (3.33333333333329318027e-01, -1.99999999998764832476e-01, 1.42857142725034663711e-01,
       -1.11111104054623557880e-01, 9.09088713343650656196e-02, -7.69187620504482999495e-02,
       6.66107313738753120669e-02, -5.83357013379057348645e-02, 4.97687799461593236017e-02,
       -3.65315727442169155270e-02, 1.62858201153657823623e-02)  # fmt: skip
# fdlibm's arc cosine (e_acos.c): pi and pi/2 as a float64 and the rest, and the rational
# approximation of (asin(sqrt z) - sqrt z) / z**1.5 for z in [0, 1/4]
_PI_HI, _PIO2_HI, _PIO2_LO = 3.14159265358979311600e00, 1.57079632679489655800e00, 6.12323399573676603587e-17
_PS = (1.66666666666666657415e-01, -3.25565818622400915405e-01, 2.01212532134862925881e-01,
       -4.00555345006794114027e-02, 7.91534994289814532176e-04, 3.47933107596021167570e-05)  # fmt: skip
_QS = (-2.40339491173441421878e00, 2.02094576023350569471e00, -6.88283971605453293030e-01,
       7.70381505559019352791e-02)  # fmt: skip


@inline_function
def _atan_unit(x):
    """atan(x) for x in [0, 1], by fdlibm's reduction to |x| <= 7/16 around 0, 0.5 or 1, each
    written as atan(c) + atan((a x + b) / (p x + q)): the case is an index, its constants picked
    by it (element), so that a random x costs no mispredicted branch."""
    case = int(x >= 0.4375) + int(x >= 0.6875)  # near 0 (the polynomial at x itself), 0.5, 1
    # x / 1; (2 x - 1) / (2 + x); (x - 1) / (x + 1): the products by 0, 1 and 2 are exact
    x = (element((1.0, 2.0, 1.0), case) * x + element((0.0, -1.0, -1.0), case)) / (
        element((0.0, 1.0, 1.0), case) * x + element((1.0, 2.0, 1.0), case)
    )
    hi = element((0.0, _ATAN_HI[0], _ATAN_HI[1]), case)
    lo = element((0.0, _ATAN_LO[0], _ATAN_LO[1]), case)
    z = x * x
    w = z * z
    s1 = z * (_AT[0] + w * (_AT[2] + w * (_AT[4] + w * (_AT[6] + w * (_AT[8] + w * _AT[10])))))
    s2 = w * (_AT[1] + w * (_AT[3] + w * (_AT[5] + w * (_AT[7] + w * _AT[9]))))
    return element((x - x * (s1 + s2), hi - ((x * (s1 + s2) - lo) - x)), int(case > 0))


@kernel_function
def atan2(y, x):
    """The angle of the point (x, y) from the x axis, in [-pi, pi], as libm's atan2 to a few
    ulps, for finite x, y (0 at the origin, +-pi at (-0, +-0)), without a libm call: the
    environment's image coordinates take one per lookup, ~4% of path mode's time on
    examples/materials.toml as a call. Without branches (a random direction's octant is
    unpredictable): atan of the smaller over the larger of |x|, |y|, then turned by picks."""
    ax = abs(x)
    ay = abs(y)
    steep = int(ay > ax)  # atan(|y| / |x|) = pi/2 - atan(|x| / |y|)
    # the smaller over the larger; 0 at the origin (5e-324: the least float above 0)
    a = _atan_unit(element((ay, ax), steep) / max(element((ax, ay), steep), 5e-324))
    a = element((a, _PIO2_HI - (a - _PIO2_LO)), steep)
    a = element((a, _PI_HI - (a - 2.0 * _PIO2_LO)), int(math.copysign(1.0, x) < 0.0))  # x < 0 or -0: pi - a
    return math.copysign(a, y)


@inline_function
def _acos_ratio(z):
    p = z * (_PS[0] + z * (_PS[1] + z * (_PS[2] + z * (_PS[3] + z * (_PS[4] + z * _PS[5])))))
    q = 1.0 + z * (_QS[0] + z * (_QS[1] + z * (_QS[2] + z * _QS[3])))
    return p / q


@kernel_function
def acos(x):
    """The arc cosine of x in [-1, 1] (NaN outside), as libm's to a couple of ulps, without a libm
    call (fdlibm's e_acos.c, less its last refinement near 1): pi/2 - asin(x) for |x| <= 1/2,
    else twice the arc sine of sqrt((1 -+ x) / 2)."""
    if x > 0.5:
        z = (1.0 - x) * 0.5
        s = math.sqrt(z)
        return 2.0 * (s + s * _acos_ratio(z))
    if x < -0.5:
        z = (1.0 + x) * 0.5
        s = math.sqrt(z)
        return _PI_HI - 2.0 * (s + (s * _acos_ratio(z) - _PIO2_LO))
    return _PIO2_HI - (x - (_PIO2_LO - x * _acos_ratio(x * x)))


@kernel_function
def turn(u):
    """(cos 2 pi u, sin 2 pi u): the point at the fraction u of a turn around the unit circle.

    Sampling draws angles as fractions of a turn, and reducing a fraction to the nearest
    quarter turn is exact, so this is quarter_sincos after a subtraction and a swap: a few
    multiply-adds in place of libm's sincos, which cost a call (and the spills around it in
    the path kernel) per sampled direction, ~6% of the Cornell box's path time."""
    q = math.floor(4.0 * u + 0.5)  # the nearest quarter turn
    c, s = quarter_sincos(2.0 * math.pi * (u - 0.25 * q))
    # k quarter turns on: (cos, sin)(a + k pi/2) is (c, s), (-s, c), (-c, -s), (s, -c), picked
    # from (c, s, -c, -s) by index (branches on a random k were mispredicted half the time)
    k = int(q)
    turned = (c, s, -c, -s)
    return element(turned, -k & 3), element(turned, (1 - k) & 3)


@inline_function
def at(row, slot):
    """The index of a slot of a row, unsigned: Numba wraps negative indices around, a compare
    and a conditional move on every scalar access that LLVM cannot prove non-negative (a
    counter of kept rays, an index loaded from a table)."""
    return np.uint64(row + slot)


@inline_function
def turn_in_lanes(u):
    """turn(u) for vector loops: the quarter turn picked by selects, which LLVM vectorises (turn's
    load from a stack copy is a scalar load per lane; its selects there became branches)."""
    q = math.floor(4.0 * u + 0.5)
    c, s = quarter_sincos(2.0 * math.pi * (u - 0.25 * q))
    k = q - 4.0 * math.floor(q * 0.25)  # q mod 4, as a float
    odd = (k == 1.0) or (k == 3.0)
    neg_c = (k == 1.0) or (k == 2.0)
    neg_s = (k == 2.0) or (k == 3.0)
    cc = s if odd else c
    ss = c if odd else s
    return (-cc if neg_c else cc), (-ss if neg_s else ss)


# --- a tuple's element at a run-time index, without a branch --------------------------------


def stack_element(builder, values, k):
    """values[k] (LLVM values of one type; k an i64 in range) as a load from a stack copy of them.
    A chain of selects says the same, but LLVM's x86 backend turns selects on a ray's critical
    path into branches, and on random rays (path mode's bounces) those are mispredicted about
    half the time: `turn` took 15 ns a random fraction with them, 8-10 ns with the load. Not a
    rule: where one branch lets LLVM specialise much code below it, the branch can be cheaper
    (docs/architecture.md, kernel conventions)."""
    slots = cgutils.alloca_once(builder, ir.ArrayType(values[0].type, len(values)))  # in the entry block
    i32 = ir.IntType(32)
    for i, x in enumerate(values):
        builder.store(x, builder.gep(slots, [ir.Constant(i32, 0), ir.Constant(i32, i)], inbounds=True))
    return builder.load(builder.gep(slots, [ir.Constant(i32, 0), k], inbounds=True))


@intrinsic
def element(typingctx, values, k):
    """values[k] of a homogeneous tuple for a run-time k in range, without a branch (stack_element)."""
    if not isinstance(values, types.UniTuple) or not isinstance(k, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        index = context.cast(builder, args[1], sig.args[1], types.int64)
        return stack_element(builder, cgutils.unpack_tuple(builder, args[0], values.count), index)

    return values.dtype(values, k), codegen
