"""The wheel QP allocator as one casadi Function (for buffers and C code)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError, SolverNotFound
from adcs_common.validation import (as_finite_array, as_finite_scalar,
                                   as_vector, check_instance, check_positive)

from ..arrays import WheelArray
from adcs_common.qp import INSTALL_HINT

from .solvers import available_solvers
from .problem import facet_normals

_MARGIN = 1e-9


def weighted_pseudo_inverse(array: WheelArray, weights=None
                            ) -> np.ndarray:
    """``P = W Aᵀ (A W Aᵀ)⁻¹`` of the working wheels, ``W = diag(1/V)``.

    ``P M`` is the minimiser of ``Σ V_i m_i²`` subject to ``A m = M``
    with the failed wheels at zero (their rows of P are zero).

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        The weighted minimum-norm map [1].
    """
    n = array.n_wheels
    V = np.ones(n) if weights is None else as_vector(weights, n, "weights")
    A = array.working_axes
    W = np.where(array.active, 1.0 / V, 0.0)
    AW = A * W
    return np.linalg.solve(AW @ A.T, AW).T


def wheel_qp_method(array: WheelArray, fast_path: bool = True) -> str:
    """How `conic_allocator_function` solves the QP of ``array``.

    Returns
    -------
    str
        ``"closed form"`` (3 or 4 working wheels with ``fast_path``: no
        conic in the Function, so its C needs no solver library),
        ``"min-norm check + conic"`` (5 or more) or ``"conic"``.
    """
    if not fast_path:
        return "conic"
    if int(array.active.sum()) <= 4:
        return "closed form"
    return "min-norm check + conic"


def _null_direction(array: WheelArray) -> np.ndarray:
    """Return the unit vector (N,) spanning ``{n : A n = 0, n_failed = 0}``.

    Only for arrays with one more working wheel than 3.
    """
    act = np.flatnonzero(array.active)
    _, _, vt = np.linalg.svd(array.axes[:, act])
    out = np.zeros(array.n_wheels)
    out[act] = vt[-1]
    return out


def conic_allocator_function(array: WheelArray,
                             weights: ArrayLike | None = None, *,
                             dt: float | None = None, plugin: str = "daqp",
                             name: str = "wheel_qp",
                             plugin_options: dict | None = None,
                             fast_path: bool = True,
                             margin: float = _MARGIN) -> ca.Function:
    """`QPAllocator` (``saturation="scale"``) as a single casadi Function.

    The same law as the numpy allocator: bounds ``|m_i| <= m_max_i`` (and
    ``|h_i + m_i dt| <= h_max_i`` when ``dt`` is given), failed wheels at 0,
    the largest ``α <= 1`` with ``α M`` attainable (from the zonotope
    facets, written symbolically), then ``min Σ V_i m_i²`` subject to
    ``A m = α (1 - 1e-9) M``. The graph holds no Python, so it can be
    called through ``Function.buffer()`` or exported with ``generate()``
    (daqp and qrqp generate self-contained C).

    With ``fast_path`` (default) the QP is solved exactly without the
    conic whenever that is possible (the cost has no linear term, so the
    weighted minimum-norm point ``m₀ = P t``, `weighted_pseudo_inverse`, is
    the unconstrained optimum of the equality-constrained problem):

    * 3 working wheels: ``m₀`` is the only point with ``A m = t``;
    * 4 working wheels: the feasible set is the segment ``m₀ + s n``
      (``n`` spans the null space of A, V-orthogonal to ``m₀``), so the
      optimum is ``s`` = 0 clamped to the interval the bounds leave (an
      exact 1-D QP: no conic in the graph, SX arithmetic only);
    * 5 or more: ``m₀`` when it is within the bounds (then it is the QP
      optimum: KKT holds with zero bound multipliers), else the conic
      (evaluated only then, a short-circuit ``if_else``).

    ``fast_path=False`` always calls the conic (the reference).

    Parameters
    ----------
    array : WheelArray
    weights : array_like (N,), optional
        Positive weights V_i (default ones).
    dt : float, optional
        Step [s]; adds the input ``h`` (wheel momenta [N·m·s]) and the
        momentum bound.
    plugin : str
        CasADi conic plugin (``"daqp"`` default, ``"qrqp"``, ``"osqp"``).
    fast_path : bool
        Use the exact closed forms above before the conic.
    margin : float
        Relative margin of the scale: ``α (1 - margin)`` when α < 1
        (default 1e-9; a float export needs more, 1 - 1e-9 is 1.0f:
        `ocp.codegen.precision.TOLERANCES`).

    Returns
    -------
    casadi.Function
        ``wheel_qp(M[3] [, h[N]]) -> (m[N], alpha, violation)``:
        motor torques [N·m], the scale reached, and the largest
        violation of ``A m = α M`` or of the bounds (check it against
        your tolerance: the conic's own success flag is not an output; on
        an infeasible QP the closed forms return a point with a positive
        violation). Called from Python with numbers, it refuses NaN, inf
        or a wrong shape (`InvalidValueError` / `ShapeError`); through a
        buffer, ``call``, ``map`` or generated C (which cannot raise), NaN
        or inf in ``M`` or ``h`` give NaN torques and a NaN
        ``violation``: that output is the status, and ``violation <= tol``
        is then false.
    """
    check_instance(array, WheelArray, "array")
    array.require_full_rank()
    if f"casadi:{plugin}" not in available_solvers():
        raise SolverNotFound(f"casadi:{plugin}", available_solvers(),
                             INSTALL_HINT)
    n = array.n_wheels
    V = np.ones(n) if weights is None else as_vector(weights, n, "weights")
    check_positive(V, "weights")
    A = array.working_axes
    active = array.active.astype(float)
    nullity = int(array.active.sum()) - 3
    closed = wheel_qp_method(array, fast_path) == "closed form"
    normals = facet_normals(A[:, array.active])
    NA = np.abs(normals @ A)

    # SX for the closed form, MX around a conic call (either: Any)
    sym: Any = ca.SX if closed else ca.MX
    M = sym.sym("M", 3)
    inputs, names = [M], ["M"]
    m_max = ca.DM(array.m_max)
    lo, hi = -m_max, m_max
    if dt is not None:
        dt = as_finite_scalar(dt, "dt")
        if dt <= 0:
            raise InvalidValueError(f"dt must be positive, got {dt}")
        h = sym.sym("h", n)
        inputs.append(h)
        names.append("h")
        h_max = ca.DM(array.h_max)
        lo = ca.fmax(lo, (-h_max - h) / dt)
        hi = ca.fmin(hi, (h_max - h) / dt)
        back = -ca.sign(h) * m_max
        over = lo > hi
        lo = ca.if_else(over, back, lo)
        hi = ca.if_else(over, back, hi)
    lo = lo * ca.DM(active)
    hi = hi * ca.DM(active)

    center = ca.DM(A) @ ((lo + hi) / 2)
    d = ca.DM(normals) @ center + ca.DM(NA) @ ((hi - lo) / 2)
    s = ca.DM(normals) @ M
    ratio = ca.if_else(s > 1e-15, d / s, ca.inf)
    alpha = ca.fmax(ca.fmin(1.0, ca.mmin(ratio)), 0.0)
    alpha = ca.if_else(alpha < 1.0, alpha * (1.0 - margin), alpha)
    target = alpha * M

    if fast_path:
        m0 = ca.DM(weighted_pseudo_inverse(array, V)) @ target
    if closed:
        m = m0
        if nullity == 1:
            m = m0 + _segment_step(_null_direction(array), m0, lo, hi)
    else:
        m = _conic_call(name, plugin, plugin_options, n, V, A, target, lo,
                        hi)
        if fast_path:
            inside = ca.mmax(ca.vertcat(lo - m0, m0 - hi)) <= 0.0
            m = ca.if_else(inside, m0, m, True)
    # NaN or inf anywhere in or out makes the violation NaN (a check
    # `violation <= tol` then fails): mmax alone skips NaN (even to -inf)
    finite = ca.mmin(ca.fabs(ca.vertcat(m, *inputs)) < np.inf)
    violation = ca.if_else(finite, ca.mmax(ca.vertcat(
        ca.fabs(ca.DM(A) @ m - target), lo - m, m - hi)), np.nan)
    return WheelQPFunction(ca.Function(name, inputs, [m, alpha, violation],
                                       names, ["m", "alpha", "violation"]))


class WheelQPFunction(ca.Function):
    """A `casadi.Function` whose numeric Python calls check their input.

    Symbolic calls (SX/MX), buffers, ``call``, ``map`` and generated C
    are the plain Function's (NaN in gives a NaN ``violation``).
    """

    def __call__(self, *args, **kwargs):
        """Evaluate; numeric ``M`` (3,) and ``h`` (N,) must be finite."""
        values = list(args) + [kwargs[k] for k in self.name_in()
                               if k in kwargs]
        if len(values) == self.n_in() and not any(
                isinstance(v, (ca.SX, ca.MX)) for v in values):
            for i, v in enumerate(values):
                if isinstance(v, ca.DM):
                    v = v.full()
                arr = np.asarray(v, dtype=object)
                if arr.ndim == 2 and 1 in arr.shape:
                    v = arr.reshape(-1)
                as_finite_array(v, self.name_in(i), (self.size1_in(i),))
        return super().__call__(*args, **kwargs)


def _segment_step(direction: np.ndarray, m0, lo, hi):
    """``s n`` with ``s`` = 0 clamped to ``{s : lo <= m0 + s n <= hi}``.

    ``direction`` (N,) is constant; wheels with ``n_i`` = 0 do not bound
    ``s`` (their torque is fixed by the equality).
    """
    tol = 1e-12 * float(np.abs(direction).max())
    s_lo, s_hi = [], []
    for i, ni in enumerate(direction):
        if abs(ni) <= tol:
            continue
        a = (lo[i] - m0[i]) / ni
        b = (hi[i] - m0[i]) / ni
        s_lo.append(a if ni > 0 else b)
        s_hi.append(b if ni > 0 else a)
    step = ca.fmin(ca.fmax(0.0, ca.mmax(ca.vertcat(*s_lo))),
                   ca.mmin(ca.vertcat(*s_hi)))
    return step * ca.DM(direction)


def _conic_call(name: str, plugin: str, plugin_options: dict | None,
                n: int, V: np.ndarray, A: np.ndarray, target, lo, hi):
    """``min Σ V_i m_i²`` s.t. ``A m = target``, ``lo <= m <= hi`` (MX)."""
    opts = dict(plugin_options or {})
    if plugin == "qrqp":
        opts.setdefault("print_iter", False)
        opts.setdefault("print_header", False)
        opts.setdefault("print_info", False)
    if plugin == "daqp":
        # DAQP's default primal_tol (1e-6) leaves the torques ~4e-8 off
        # the optimum on arrays of 5+ working wheels; 1e-10 is exact to
        # the other backends (tests: 3 to 8 wheels, also in generated C)
        opts.setdefault("daqp", {"primal_tol": 1e-10})
    opts.setdefault("error_on_fail", False)
    solver = ca.conic(f"{name}_conic", plugin,
                      {"h": ca.Sparsity.dense(n, n),
                       "a": ca.Sparsity.dense(3, n)}, opts)
    sol = solver(h=ca.DM(np.diag(2.0 * V)), g=ca.DM.zeros(n), a=ca.DM(A),
                 lba=target, uba=target, lbx=lo, ubx=hi)
    return sol["x"]


def conic_c_flags(plugin: str = "daqp") -> list[str]:
    """Return the gcc flags that build C generated for a conic ``plugin``.

    qrqp generates self-contained C; daqp's C includes ``daqp/api.h`` and
    links the static DAQP library that the casadi wheel ships.

    Returns
    -------
    list of str
        Flags to append after the source file (includes and libraries).
    """
    from pathlib import Path

    root = Path(ca.__file__).parent
    flags = [f"-I{root / 'include'}"]
    if plugin == "daqp":
        flags.append(str(root / "libdaqpstat.a"))
    return flags + ["-lm"]
