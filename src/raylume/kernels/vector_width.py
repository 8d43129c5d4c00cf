"""Kernel entry points compiled for the vector width the CPU prefers: 256-bit registers on
Intel's AVX-512 cores.

The ray packets' explicit IR (packet.py: `packet_load`, the eight-lane triangle test) spells
eight float64 lanes, `<8 x double>`, 512 bits. LLVM's x86 backend splits such a vector into two
256-bit halves only in a function that says the narrower width is enough, with the attribute
"min-legal-vector-width" (clang sets it on every function it compiles); a function without
it, as all of Numba's are, gets them whole, in zmm registers, even on a CPU whose tuning prefers
256-bit vectors. On Intel's AVX-512 cores a 512-bit instruction in flight switches off the
vector unit of port 1 (and can lower the clock), so a few of them in a loop of 256-bit work
slow all of it: on an Intel Xeon (AVX-512, LLVM's `rocketlake` tuning) the packets of hit and
shadow rays took 1.2-1.3x the time of the same code with 256-bit vectors (docs/architecture.md,
"256-bit vectors on AVX-512 cores").

So every kernel entry (`ENTRY_PIPELINE`) marks each function of its module, after LLVM's
optimisation and before machine code, with min-legal-vector-width 256. Where the CPU's tuning
prefers 256-bit vectors the 512-bit ones are then split; where it prefers 512-bit ones
(`getPreferVectorWidth`), or the CPU has no AVX-512, nothing changes. Marked after
optimisation because LLVM drops the attribute from a function into which it inlines one
without it, and a kernel inlines Numba's own helpers. llvmlite sets no string attributes, so the
module goes through its IR text once (0.31 s of a 63 s cold compile of path mode's kernels).
"""

from __future__ import annotations

import re

import llvmlite.binding as ll
from numba.core import compiler
from numba.core.codegen import JITCodeLibrary

ATTRIBUTE = '"min-legal-vector-width"="256"'

# A definition's first line: `define <linkage, return type> @name(<parameters>)`, then the
# optional unnamed_addr and address space, then its attributes and the rest up to `{`, where the
# attribute goes in (after the address space, before a `#N` group, personality or `!dbg`). The
# greedy `.*\)` ends at the line's last parenthesis: the parameters' or the address space's. A
# rest with parentheses or quotes (a section's name, a prefix) is not matched: left unmarked.
_DEFINITION = re.compile(r'^(define .*\)(?: local_unnamed_addr| unnamed_addr)?)([^()"]* \{)$', re.M)


def narrow_vectors(text: str) -> str:
    """LLVM IR text with every function definition marked min-legal-vector-width 256 (one whose
    first line has parentheses or quotes after its parameters is left as it is)."""
    return _DEFINITION.sub(rf"\1 {ATTRIBUTE}\2", text)


# LLVM cuts a local name (a block's, a value's) to 1024 characters as it is set, and keeps the
# cut names apart with a suffix, so a printed module has longer names (Numba's mangled names,
# in the names of inlined blocks, run to thousands); read back at that limit they are refused or
# cut to one name, which broke a path kernel. The module is read at a limit that keeps every
# name it prints whole, then at LLVM's default again.
_NAME_LIMIT = "-non-global-value-max-name-size"
_LLVM_NAME_LIMIT = 1024


def narrowed(module: ll.ModuleRef) -> ll.ModuleRef:
    """The module again, with its functions marked as narrow_vectors marks them."""
    text = narrow_vectors(str(module))
    ll.set_option("raylume", f"{_NAME_LIMIT}={len(text)}")
    try:
        marked = ll.parse_assembly(text)
    finally:
        ll.set_option("raylume", f"{_NAME_LIMIT}={_LLVM_NAME_LIMIT}")
    marked.name = module.name
    return marked


class _NarrowVectorLibrary(JITCodeLibrary):
    """Numba's library of an entry point, its final module marked before machine code."""

    def _finalize_final_module(self):
        self._final_module = narrowed(self._final_module)
        super()._finalize_final_module()


class _NarrowVectorCompiler(compiler.Compiler):
    """Numba's compiler, writing into a _NarrowVectorLibrary."""

    def compile_extra(self, func):
        if self.state.library is None:
            self.state.library = _NarrowVectorLibrary(self.state.targetctx.codegen(), func.__qualname__)
            self.state.library.enable_object_caching()  # as Numba's lowering does for its own
        return super().compile_extra(func)


# The library overrides a Numba internal (as of Numba 0.68): a Numba without it compiles entries
# its own way (test_vector_width.py notices).
_MARKABLE = hasattr(JITCodeLibrary, "_finalize_final_module")

# pipeline_class of every kernel entry point (njit, roomy_njit, python_entry)
ENTRY_PIPELINE = _NarrowVectorCompiler if _MARKABLE else compiler.Compiler
