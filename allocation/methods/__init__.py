"""The allocation methods of the control-allocation literature.

Each method takes a `WheelArray` (axes (3, N), per-wheel torque limits
``m_max`` [N·m], failed wheels held at zero), a demanded array torque
``M`` (3,) [N·m] and optional per-wheel bounds ``lo``/``hi`` (N,) [N·m]
(momentum-limited wheels), and returns wheel torques ``m`` (N,) [N·m].
The exact bounded QP is `allocation.QPAllocator`; `METHODS` lists the
methods by the names the comparison (`allocation.method_comparison`)
reports. `allocation.methods.symbolic` holds the CasADi versions of the
closed-form ones (``SYMBOLIC_METHODS``: AD and C code), equal to these to
rounding.
"""

from __future__ import annotations

from typing import Callable

from ._common import bounded_lsq
from .direct import direct_allocation
from .inverse import (
    cascaded_inverse,
    daisy_chain,
    default_groups,
    pseudo_inverse,
    redistributed_pinv,
)
from .iterative import fixed_point, fixed_point_batch, wls_alloc
from .symbolic import (
    SYMBOLIC_METHODS,
    cascaded_inverse_function,
    daisy_chain_function,
    fixed_point_function,
    generate_methods_c,
    method_functions,
    pseudo_inverse_function,
    redistributed_pinv_function,
)

#: name -> method ``f(array, M, lo=None, hi=None) -> m`` (N,) [N·m]
METHODS: dict[str, Callable] = {
    "pseudo-inverse": pseudo_inverse,
    "redistributed pseudo-inverse": redistributed_pinv,
    "cascaded generalised inverse": cascaded_inverse,
    "daisy chain": daisy_chain,
    "fixed point": fixed_point,
    "WLS active set": wls_alloc,
    "direct allocation": direct_allocation,
}

__all__ = [
    "METHODS",
    "SYMBOLIC_METHODS",
    "bounded_lsq",
    "cascaded_inverse",
    "cascaded_inverse_function",
    "daisy_chain",
    "daisy_chain_function",
    "default_groups",
    "direct_allocation",
    "fixed_point",
    "fixed_point_batch",
    "fixed_point_function",
    "generate_methods_c",
    "method_functions",
    "pseudo_inverse",
    "pseudo_inverse_function",
    "redistributed_pinv",
    "redistributed_pinv_function",
    "wls_alloc",
]
