"""KernelFunction (kernels/vec.py): per-ray functions compile for kernels without the wrappers
that let Python call them, and once per argument types; a call from Python still works."""

import importlib
import pkgutil

import numpy as np
from numba import njit
from numba.core.dispatcher import Dispatcher

import raylume.kernels
from raylume.kernels.vec import KernelFunction, add, inline_function, kernel_function


@inline_function
def _pair_sum(a, i, c):
    return a[i, c] + a[i, c + 1]


@kernel_function
def _first_row(out, x):
    out[0] = x
    return out


@njit
def _two_columns(a):
    # literal column offsets: Numba would compile _pair_sum once for each value
    return _pair_sum(a, 0, 0) + _pair_sum(a, 0, 3)


def test_literal_arguments_share_one_compilation():
    a = np.arange(12.0).reshape(2, 6)
    assert _two_columns(a) == (0 + 1) + (3 + 4)
    assert [tuple(str(t) for t in sig[1:]) for sig in _pair_sum.overloads] == [("int64", "int64")]


def test_kernels_compile_no_python_wrapper():
    _two_columns(np.zeros((2, 6)))
    (helper,) = _pair_sum.overloads.values()
    (caller,) = _two_columns.overloads.values()
    assert helper.fndesc.llvm_cpython_wrapper_name not in helper.library.get_llvm_str()
    assert caller.fndesc.llvm_cpython_wrapper_name in caller.library.get_llvm_str()  # the check can see one


def test_kernel_functions_are_linked_into_kernels_not_compiled_to_machine_code():
    """A per-ray function's library is LLVM IR for its callers to link: no machine code of its
    own (its function has no address), while the kernel that links it has its own, with the
    helper's work inside it."""
    a = np.arange(12.0).reshape(2, 6)
    assert _two_columns(a) == 8.0
    (helper,) = _pair_sum.overloads.values()
    (caller,) = _two_columns.overloads.values()
    assert helper.library.get_pointer_to_function(helper.fndesc.llvm_func_name) == 0
    assert caller.library.get_pointer_to_function(caller.fndesc.llvm_func_name) != 0
    assert helper.fndesc.llvm_func_name in helper.library.get_llvm_str()


def test_a_python_call_gives_the_kernels_result():
    a = np.arange(12.0).reshape(2, 6)
    assert _pair_sum(a, 1, 3) == 9.0 + 10.0
    assert add((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)) == (5.0, 7.0, 9.0)
    out = np.zeros(3)
    assert _first_row(out, 2.5) is not None and out[0] == 2.5  # hands back an array it was passed


def test_every_kernel_function_is_one_or_a_cached_entry_point():
    """A per-ray function written with plain @njit would compile its wrappers and literal
    specialisations again: only Python's entry points (cached) may be plain dispatchers."""
    plain = []
    for info in pkgutil.iter_modules(raylume.kernels.__path__):
        module = importlib.import_module(f"raylume.kernels.{info.name}")
        for name, obj in vars(module).items():
            if isinstance(obj, Dispatcher) and obj.py_func.__module__ == module.__name__:
                if not isinstance(obj, KernelFunction) and obj._cache.__class__.__name__ == "NullCache":
                    plain.append(f"{module.__name__}.{name}")
    assert plain == []
