"""No masked stores in the vector kernels, compiled for AMD's Zen 3 (AVX2), whatever the host.

A vector blend stored back where its old value came from, `store(select(mask, new, load(p)),
p)`, is turned by LLVM into a masked store (vmaskmovpd / vpmaskmovq) on AVX2 targets. Zen 1-3
run those microcoded at tens of cycles: the packet traversal took 3-4x its time on a Zen 3
(bench_hits.py: bumpy 40k hit rays 48 -> 30 ms once they were gone), and an AVX-512 machine,
whose masked stores are cheap, never showed it. Each kernel's LLVM IR is compiled here for
`znver3` with llvmlite, so the check runs on any host; the kernels keep such values in
registers and store them plainly.
"""

import re

import llvmlite.binding as llvm
import numpy as np
import pytest
from numba import typeof
from test_packets import PACKET_WORKER, _camera_rays, _compiled_mesh, _packets

from raylume.kernels.geometry import wavefront_spheres
from raylume.kernels.integrators import wavefront
from raylume.scene.procedural import bumpy_sphere

# AT&T order: source register, mask register, memory destination (the load form starts with
# its memory operand)
MASKED_STORE = re.compile(r"\bv(?:p)?maskmov\w*\s+%[xy]mm\d+, %[xy]mm\d+, [^%\n]*\(")


def masked_stores(ir: str, cpu: str = "znver3") -> list[str]:
    """The masked-store instructions in the machine code of the LLVM module `ir` for `cpu`."""
    module = llvm.parse_assembly(ir)
    machine = llvm.Target.from_triple(module.triple).create_target_machine(cpu=cpu, opt=3)
    return MASKED_STORE.findall(machine.emit_assembly(module))


def test_the_pattern_is_caught():
    """The check itself: the blend-and-store-back pattern does give a masked store for znver3."""
    ir = """
    target triple = "x86_64-unknown-linux-gnu"
    define void @blend(<4 x double>* %p, <4 x double> %new, <4 x i1> %m) {
      %old = load <4 x double>, <4 x double>* %p, align 8
      %v = select <4 x i1> %m, <4 x double> %new, <4 x double> %old
      store <4 x double> %v, <4 x double>* %p, align 8
      ret void
    }
    """
    assert masked_stores(ir)


@PACKET_WORKER
def test_packet_traversal_has_no_masked_stores(tmp_path):
    v, f = bumpy_sphere(500)
    compiled = _compiled_mesh(tmp_path, v, f)
    o, d = _camera_rays(np.zeros(3), 1.2, 16)
    _packets(compiled.kernel, o, d, 8)
    ir = "\n".join(_packets.inspect_llvm().values())
    assert not masked_stores(ir), "the packet traversal stores through a mask (slow on Zen 3)"


@pytest.mark.parametrize("name", ["tile_closest", "_gather_light"])
def test_wavefront_stages_have_no_masked_stores(name):
    R = np.zeros(wavefront.WAVE_ROWS * wavefront.STRIDE)
    I = np.zeros(wavefront.WAVE_INT_ROWS * wavefront.STRIDE, dtype=np.int64)
    rows = (wavefront.OX, wavefront.OY, wavefront.OZ, wavefront.DX, wavefront.DY, wavefront.DZ, wavefront.T, 0)
    function, args = {
        "tile_closest": (wavefront_spheres.tile_closest, (R, I, rows, 16, np.zeros((2, 4)), 0, 2)),
        "_gather_light": (wavefront._gather_light, (R, I, 16, 0.0, 0.0, 0.0)),
    }[name]
    signature = tuple(typeof(a) for a in args)
    function.compile(signature)
    ir = function.overloads[signature].library.get_llvm_str()
    assert not masked_stores(ir), f"{name} stores through a mask (slow on Zen 3)"
