"""CasADi versions of the closed-form allocation methods (AD and C code).

Each builder returns a ``casadi.Function``

    ``name(M[3], lo[N], hi[N]) -> (m[N])``

with the semantics of the numpy method of the same name in
`allocation.methods`: demand ``M`` [N·m], caller's bounds ``lo``/``hi``
[N·m] intersected with ``±m_max`` (pass ``-m_max``/``m_max``, or
``-inf``/``inf``, for none), failed wheels held at zero, wheel torques
``m`` [N·m]. The array is a constant of the graph. The graphs hold no
Python, so they evaluate through ``Function.buffer()`` and export to C
(`generate_methods_c`). Unlike the numpy methods they cannot raise:
``lo > hi`` on a wheel gives a torque outside its bounds, and NaN in
gives NaN out.

The redistribution methods pick ``A_F⁺`` of the free wheels F from a
table of the 2ⁿ free sets of the n working wheels (numpy's own
pseudo-inverses, so the two agree to rounding), through a ``switch``
in C; the fixed-point iteration runs a fixed number of steps as a loop
(``Function.fold``). The active-set methods (WLS, direct allocation)
have no fixed-length closed form and are numpy only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import casadi as ca
import numpy as np

from adcs_common.codegen import compile_c, generate_c
from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import check_instance

from ..arrays import WheelArray
from ._common import pinv
from .inverse import default_groups
from .iterative import _fixed_point_operator

__all__ = [
    "SYMBOLIC_METHODS",
    "cascaded_inverse_function",
    "daisy_chain_function",
    "fixed_point_function",
    "generate_methods_c",
    "method_functions",
    "pseudo_inverse_function",
    "redistributed_pinv_function",
]

#: Most working wheels of the pseudo-inverse table (2ⁿ entries).
MAX_TABLE_WHEELS = 10

#: Fixed-point steps of `fixed_point_function` by default: the numpy
#: iteration stops earlier on most demands (30-160 steps on the pyramid).
FIXED_POINT_STEPS = 200


def _bounds(array: WheelArray, lo, hi):
    """Return the numpy `problem`'s ``(low, high)``: ±m_max ∩ caller."""
    mask = ca.DM(array.active.astype(float))
    m_max = ca.DM(np.asarray(array.m_max, dtype=float))
    return ca.fmax(-m_max, lo) * mask, ca.fmin(m_max, hi) * mask


def _clip(x, low, high):
    """``numpy.clip``: ``min(max(x, low), high)``."""
    return ca.fmin(ca.fmax(x, low), high)


def _symbols(array: WheelArray, kind=ca.SX):
    check_instance(array, WheelArray, "array")
    n = array.n_wheels
    return kind.sym("M", 3), kind.sym("lo", n), kind.sym("hi", n)


def _function(name: str, M, lo, hi, m) -> ca.Function:
    return ca.Function(name, [M, lo, hi], [m], ["M", "lo", "hi"], ["m"])


def pseudo_inverse_function(array: WheelArray,
                            name: str = "pseudo_inverse") -> ca.Function:
    r"""Build `pseudo_inverse`, :math:`\mathrm{sat}(A^+M)`, as a Function.

    Returns
    -------
    casadi.Function
        Inputs M (3,) [N·m], lo, hi (N,) [N·m]; output m (N,) [N·m].
    """
    M, lo, hi = _symbols(array)
    low, high = _bounds(array, lo, hi)
    m = _clip(ca.DM(pinv(array.working_axes)) @ M, low, high)
    return _function(name, M, lo, hi, m)


def daisy_chain_function(array: WheelArray,
                         groups: Sequence[Sequence[int]] | None = None,
                         name: str = "daisy_chain") -> ca.Function:
    """Build `daisy_chain` (groups fixed) as ``name(M, lo, hi) -> (m)``.

    Parameters
    ----------
    groups : sequence of sequences of int, optional
        0-based wheel indices of each group, in order (default
        `default_groups`); wheels in no group get zero torque.

    Returns
    -------
    casadi.Function
        Inputs M (3,) [N·m], lo, hi (N,) [N·m]; output m (N,) [N·m].
    """
    M, lo, hi = _symbols(array)
    low, high = _bounds(array, lo, hi)
    A = array.working_axes
    n = array.n_wheels
    groups = default_groups(array) if groups is None else groups
    seen: set[int] = set()
    m = [_clip(ca.SX(0.0), low[i], high[i]) for i in range(n)]
    r = M - ca.DM(A) @ ca.vertcat(*m)
    for g in groups:
        idx = [int(i) for i in g]
        if not idx:
            continue
        if any(i < 0 or i >= n for i in idx) or seen & set(idx):
            raise InvalidValueError(
                f"groups must hold distinct 0-based indices < {n}, got "
                f"{groups!r}")
        seen |= set(idx)
        Ag = ca.DM(A[:, idx])
        r = r + Ag @ ca.vertcat(*[m[i] for i in idx])
        mg = ca.DM(pinv(A[:, idx])) @ r
        for k, i in enumerate(idx):
            m[i] = _clip(mg[k], low[i], high[i])
        r = r - Ag @ ca.vertcat(*[m[i] for i in idx])
    return _function(name, M, lo, hi, ca.vertcat(*m))


def fixed_point_function(array: WheelArray,
                         iterations: int = FIXED_POINT_STEPS,
                         epsilon: float = 1e-4,
                         name: str = "fixed_point") -> ca.Function:
    r"""Build `fixed_point` with a fixed number of steps as a Function.

    ``iterations`` projected steps
    :math:`m \leftarrow \mathrm{sat}[(1-\varepsilon)\eta A^T M + (I-\eta H)m]`
    from :math:`\mathrm{sat}(0)`, run as a loop in C (``Function.fold``).
    Equals ``fixed_point(array, M, lo, hi, epsilon=epsilon,
    max_iter=iterations, tol=0.0)``; the numpy default stops earlier,
    once a step moves no wheel by more than ``1e-12 max(m_max)``.

    Parameters
    ----------
    iterations : int
        Steps (>= 1).
    epsilon : float
        ε in (0, 1) [1], the weight of the control effort.

    Returns
    -------
    casadi.Function
        Inputs M (3,) [N·m], lo, hi (N,) [N·m]; output m (N,) [N·m].
    """
    check_instance(array, WheelArray, "array")
    iterations = int(iterations)
    if iterations < 1:
        raise InvalidValueError(
            f"iterations must be at least 1, got {iterations}")
    n = array.n_wheels
    A = array.working_axes
    step, gain = _fixed_point_operator(A, float(epsilon))
    x = ca.SX.sym("x", 4 * n)            # (u, drive, low, high)
    u, drive, low, high = (x[k * n:(k + 1) * n] for k in range(4))
    nxt = _clip(drive + ca.DM(step) @ u, low, high)
    one = ca.Function(f"{name}_step", [x],
                      [ca.vertcat(nxt, drive, low, high)])
    loop = one.fold(iterations)
    M, lo, hi = _symbols(array, ca.MX)
    low, high = _bounds(array, lo, hi)
    drive = gain * (ca.DM(A.T) @ M)
    u0 = _clip(ca.MX.zeros(n), low, high)
    xs = loop(ca.vertcat(u0, drive, low, high))
    return _function(name, M, lo, hi, xs[-1][:n] if isinstance(
        xs, (list, tuple)) else xs[:n])


def _table(array: WheelArray, name: str) -> tuple[ca.Function, list[int]]:
    """Build ``name_pinv(code, r) -> (m)``: ``A_F⁺ r`` of the free set.

    ``code = Σ_j 2^j`` over the free working wheels j (in index order);
    the rows of the other wheels are zero. A ``switch`` in C.
    """
    work = [int(i) for i in np.flatnonzero(array.active)]
    if len(work) > MAX_TABLE_WHEELS:
        raise InvalidValueError(
            f"the redistribution table holds at most {MAX_TABLE_WHEELS} "
            f"working wheels, got {len(work)}")
    A = array.working_axes
    n = array.n_wheels
    r = ca.SX.sym("r", 3)
    cases = []
    for code in range(2 ** len(work)):
        free = [w for j, w in enumerate(work) if code >> j & 1]
        P = np.zeros((n, 3))
        if free:
            P[free] = pinv(A[:, free])
        cases.append(ca.Function(f"{name}_pinv_{code}", [r],
                                 [ca.DM(P) @ r]))
    zero = ca.Function(f"{name}_pinv_none", [r], [ca.SX.zeros(n)])
    return ca.Function.conditional(f"{name}_pinv", cases, zero), work


def _saturate_all(m, free, low, high):
    """Clip and saturate every free violator (`_saturate_all`)."""
    bad = free * ((m < low) + (m > high) > 0)
    return ca.if_else(bad, _clip(m, low, high), m), bad


def _saturate_worst(m, free, low, high):
    """Saturate the free wheel most beyond its bound, relative to its range.

    As numpy's `_saturate_worst` (ties: the first).
    """
    n = m.numel()
    over = ca.if_else(free, ca.fmax(m - high, low - m), -np.inf)
    span = ca.fmax(high - low, 1e-300)
    score = ca.if_else(free, over / span, -np.inf)
    eq = score == ca.mmax(score)
    before = ca.DM(np.tril(np.ones((n, n)), -1)) @ eq
    pick = eq * (before == 0) * (ca.mmax(over) > 0)
    m = ca.if_else(pick, ca.if_else(m > high, high, low), m)
    return m, pick


def _redistribution(array: WheelArray, passes: int | None, name: str,
                    saturate: Callable) -> ca.Function:
    """Build the cascade of `_redistribute` with a fixed number of passes."""
    check_instance(array, WheelArray, "array")
    n = array.n_wheels
    passes = n + 1 if passes is None else int(passes)
    if passes < 1:
        raise InvalidValueError(f"passes must be at least 1, got {passes}")
    table, work = _table(array, name)
    weights = np.zeros(n)
    weights[work] = 2.0 ** np.arange(len(work))
    A = ca.DM(array.working_axes)
    M, lo, hi = _symbols(array, ca.MX)
    low, high = _bounds(array, lo, hi)
    sat = low == high
    m = ca.if_else(sat, low, 0.0)
    for _ in range(passes):
        free = 1 - sat
        r = M - A @ ca.if_else(sat, m, 0.0)
        code = ca.dot(ca.DM(weights), free)
        m = ca.if_else(sat, m, table(code, r))
        m, moved = saturate(m, free, low, high)
        sat = sat + moved
    return _function(name, M, lo, hi, _clip(m, low, high))


def redistributed_pinv_function(array: WheelArray,
                                passes: int | None = None,
                                name: str = "redistributed_pinv"
                                ) -> ca.Function:
    """Build `redistributed_pinv` with a fixed number of passes.

    Parameters
    ----------
    passes : int, optional
        Redistribution passes (default N + 1: numpy's cap, so the two
        agree on every demand; a pass after the last violation changes
        nothing). Fewer passes truncate the cascade.

    Returns
    -------
    casadi.Function
        ``name(M, lo, hi) -> (m)``: M (3,), lo, hi, m (N,) [N·m].
    """
    return _redistribution(array, passes, name, _saturate_all)


def cascaded_inverse_function(array: WheelArray, passes: int | None = None,
                              name: str = "cascaded_inverse"
                              ) -> ca.Function:
    """Build `cascaded_inverse` (a wheel per stage), fixed number of passes.

    Parameters
    ----------
    passes : int, optional
        Stages (default N + 1, numpy's cap: the two agree everywhere).

    Returns
    -------
    casadi.Function
        ``name(M, lo, hi) -> (m)``: M (3,), lo, hi, m (N,) [N·m].
    """
    return _redistribution(array, passes, name, _saturate_worst)


#: method name (as in `allocation.methods.METHODS`) -> builder
#: ``f(array) -> casadi.Function``
SYMBOLIC_METHODS: dict[str, Callable[[WheelArray], ca.Function]] = {
    "pseudo-inverse": pseudo_inverse_function,
    "redistributed pseudo-inverse": redistributed_pinv_function,
    "cascaded generalised inverse": cascaded_inverse_function,
    "daisy chain": daisy_chain_function,
    "fixed point": fixed_point_function,
}


def method_functions(array: WheelArray) -> dict[str, ca.Function]:
    """Every `SYMBOLIC_METHODS` Function of ``array``, by method name."""
    return {k: build(array) for k, build in SYMBOLIC_METHODS.items()}


def generate_methods_c(functions: Sequence[ca.Function], folder,
                       name: str = "alloc_methods", *, build: bool = True,
                       opt: str = "-O2", cc: str | None = None) -> Path:
    """Write the C of ``functions`` (and build a shared library).

    Parameters
    ----------
    functions : sequence of casadi.Function
        E.g. the values of `method_functions` (self-contained C, libm
        only).
    folder : path
        Existing output folder.
    build : bool
        Compile ``folder/name.so`` (`adcs_common.codegen.compile_c`).

    Returns
    -------
    pathlib.Path
        The shared library (``build``) or the C source.

    Raises
    ------
    CompilerNotFound, CompileError
        ``build`` and no compiler, or the compiler failed.
    """
    src = generate_c(functions, folder, name, {"with_header": True})
    if not build:
        return src
    return compile_c([src], Path(folder) / f"{name}.so", cc=cc, opt=opt)
