"""tools/profile_kernels.py --count reads callgrind's output: each instruction's own costs, a
call's inclusive cost left to the callee's lines (callgrind's format, as valgrind's manual gives
it: "Callgrind Format Specification")."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# positions: instr (--dump-instr=yes --dump-line=no --compress-pos=no): a cost line is an address
# and its events' counts, trailing zeros left out; the line after `calls=` is the call's
# inclusive cost, at the calling instruction
CALLGRIND_OUT = """\
version: 1
creator: callgrind-3.19.0
positions: instr
events: Ir Bc Bcm Bi Bim
fl=(1) ???
fn=(1) 0x0000000000401000
0x401000 3 1 1
0x401004 2
cfn=(2) 0x0000000000402000
calls=4 0x402000
0x401008 400 40 8
0x401008 1
fn=(2) 0x0000000000402000
0x402000 100 10 2
0x402000 300 30 6
totals: 406 41 9 0 0
"""


def _profile_kernels():
    spec = importlib.util.spec_from_file_location("profile_kernels", ROOT / "tools" / "profile_kernels.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_callgrind_costs_are_each_instructions_own(tmp_path):
    out = tmp_path / "callgrind.out"
    out.write_text(CALLGRIND_OUT)
    events, costs = _profile_kernels()._callgrind_costs(out)
    assert events == ["Ir", "Bc", "Bcm", "Bi", "Bim"]
    assert costs == {
        0x401000: [3, 1, 1, 0, 0],
        0x401004: [2, 0, 0, 0, 0],
        0x401008: [1, 0, 0, 0, 0],  # the call's 400 belong to the callee
        0x402000: [400, 40, 8, 0, 0],  # two lines for one address add up
    }
    # what callgrind itself totals
    assert sum(c[0] for c in costs.values()) == 406
    assert sum(c[2] for c in costs.values()) == 9
