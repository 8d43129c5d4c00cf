"""Kernel entries marked min-legal-vector-width 256 (kernels/vector_width.py), so that LLVM
gives 512-bit vectors 256-bit registers where the CPU's tuning prefers them.

Checked against LLVM's own code generation for CPUs other than this one: the assembly of an
eight-double multiply for Intel's AVX-512 cores has zmm registers without the mark and none
with it; for AMD's Zen 4 and 5, whose tuning prefers 512-bit vectors, zmm either way; for an
AVX2 CPU none either way."""

from __future__ import annotations

import importlib.util
import re
import sys

import llvmlite.binding as ll
import numba
import numpy as np
import pytest
from numba import njit

from raylume.kernels import vector_width
from raylume.kernels.geometry.query import intersect_lane, occluded_lane
from raylume.kernels.integrators.frame import LANE
from raylume.kernels.vector_width import ATTRIBUTE, ENTRY_PIPELINE, narrow_vectors, narrowed

EIGHT_DOUBLES = """
define void @multiply(ptr %a, ptr %b) local_unnamed_addr {
  %x = load <8 x double>, ptr %a
  %y = load <8 x double>, ptr %b
  %z = fmul <8 x double> %x, %y
  store <8 x double> %z, ptr %a
  ret void
}
"""


def _registers(text: str, cpu: str) -> set[str]:
    """The vector register kinds (xmm, ymm, zmm) in LLVM's x86 assembly of `text` for `cpu`."""
    ll.initialize_native_target()
    ll.initialize_native_asmprinter()
    machine = ll.Target.from_triple("x86_64-unknown-linux-gnu").create_target_machine(cpu=cpu, opt=3)
    module = ll.parse_assembly(text)
    module.triple = machine.triple
    return set(re.findall(r"%([xyz]mm)\d+", machine.emit_assembly(module)))


@pytest.mark.parametrize("cpu", ["skylake-avx512", "icelake-server", "rocketlake", "sapphirerapids"])
def test_the_mark_splits_512_bit_vectors_for_intel_avx512(cpu):
    assert "zmm" in _registers(EIGHT_DOUBLES, cpu)
    marked = _registers(narrow_vectors(EIGHT_DOUBLES), cpu)
    assert "zmm" not in marked and "ymm" in marked


@pytest.mark.parametrize("cpu", ["znver4", "znver5"])
def test_cpus_that_prefer_512_bit_vectors_keep_them(cpu):
    assert "zmm" in _registers(narrow_vectors(EIGHT_DOUBLES), cpu)


def test_avx2_cpus_have_256_bit_registers_either_way():
    assert _registers(EIGHT_DOUBLES, "haswell") == _registers(narrow_vectors(EIGHT_DOUBLES), "haswell") == {"ymm"}


def _function_attributes(module: ll.ModuleRef) -> dict[str, bytes]:
    """Each defined function's attribute list, as LLVM holds it (function attributes first)."""
    return {f.name: b" ".join(f.attributes) for f in module.functions if not f.is_declaration}


def test_every_form_of_definition_numba_and_llvm_print_is_marked():
    personal = 'define internal fastcc void @"quoted(name)"(ptr dereferenceable(8) %a) unnamed_addr #0'
    text = f"""
declare i32 @__gxx_personality_v0(...)
{personal} personality ptr @__gxx_personality_v0 {{
  ret void
}}
define void @spaced() addrspace(1) #0 {{
  ret void
}}
define linkonce_odr range(i32 -1, -2) i32 @kernel(ptr noalias captures(none) %x) local_unnamed_addr {{
  ret i32 0
}}
define void @bare() {{
  ret void
}}
attributes #0 = {{ nounwind }}
"""
    marked = _function_attributes(narrowed(ll.parse_assembly(text)))
    assert set(marked) == {"quoted(name)", "spaced", "kernel", "bare"}
    for attributes in marked.values():
        assert ATTRIBUTE.encode() in attributes


def test_a_definition_with_parentheses_or_quotes_after_its_parameters_is_left_unmarked():
    for tail in ('section "text(1)"', 'section "text"', 'personality ptr @"p(1)"'):
        text = f'declare i32 @"p(1)"(...)\ndefine void @f() {tail} {{\n  ret void\n}}\n'
        assert narrow_vectors(text) == text
        ll.parse_assembly(text).verify()


def test_local_names_longer_than_llvms_limit_are_read_back_whole():
    """LLVM reads no local name longer than 1024 characters (its default limit), but its passes
    leave such names in a kernel's module (an inlined block's, named after a long mangled
    function name): narrowed reads them back whole."""
    first, second = "b" * 1100 + "first", "b" * 1100 + "second"
    text = f"""
define i32 @pick(i1 %c) {{
entry:
  br i1 %c, label %{first}, label %{second}
{first}:
  ret i32 1
{second}:
  ret i32 2
}}
"""
    ll.set_option("test", "-non-global-value-max-name-size=4096")  # the names as passes leave them
    try:
        module = ll.parse_assembly(text)
    finally:
        ll.set_option("test", "-non-global-value-max-name-size=1024")
    module = narrowed(module)
    module.verify()
    printed = str(module)
    assert f"{first}:" in printed and f"{second}:" in printed


def test_an_entry_compiled_through_the_pipeline_has_every_function_marked():
    assert vector_width._MARKABLE, "Numba no longer has the internal vector_width overrides"

    @njit(pipeline_class=ENTRY_PIPELINE)
    def total(values):
        return np.sum(values * values)

    assert total(np.arange(5.0)) == 30.0
    library = total.overloads[total.signatures[0]].library
    attributes = _function_attributes(library._final_module)
    assert attributes
    for name, found in attributes.items():
        assert ATTRIBUTE.encode() in found, name


def test_kernel_entries_take_the_pipeline():
    assert LANE["pipeline_class"] is ENTRY_PIPELINE
    for dispatcher in (intersect_lane, occluded_lane):
        assert dispatcher._compiler.pipeline_class is ENTRY_PIPELINE


def test_a_marked_entry_is_saved_to_and_loaded_from_numbas_disk_cache(tmp_path, monkeypatch):
    """The library is cached as Numba caches its own (its object code kept as it is compiled)."""
    source = tmp_path / "cached_entry_module.py"
    source.write_text(
        "from numba import njit\n"
        "from raylume.kernels.vector_width import ENTRY_PIPELINE\n\n"
        "@njit(cache=True, pipeline_class=ENTRY_PIPELINE)\n"
        "def twice(x):\n"
        "    return 2.0 * x\n"
    )
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))

    def load():
        spec = importlib.util.spec_from_file_location("cached_entry_module", source)
        module = importlib.util.module_from_spec(spec)
        monkeypatch.setitem(sys.modules, "cached_entry_module", module)
        spec.loader.exec_module(module)
        return module.twice

    first = load()
    assert first(21.0) == 42.0
    assert first.stats.cache_misses and not first.stats.cache_hits
    again = load()
    assert again(4.0) == 8.0
    assert again.stats.cache_hits
