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
        or inf in ``M`` or ``h`` give a NaN ``violation`` (and NaN in
        ``M`` NaN torques): that output is the status, and
        ``violation <= tol`` is then false.
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
    nullity = int(array.active.sum()) - 3
    closed = wheel_qp_method(array, fast_path) == "closed form"
    normals = facet_normals(A[:, array.active])

    # the bounds, the scale and the check in SX (scalar arithmetic); the
    # conic, when one is needed, in MX around them
    M = ca.SX.sym("M", 3)
    inputs, names = [M], ["M"]
    h = None
    if dt is not None:
        dt = as_finite_scalar(dt, "dt")
        if dt <= 0:
            raise InvalidValueError(f"dt must be positive, got {dt}")
        h = ca.SX.sym("h", n)
        inputs.append(h)
        names.append("h")
    lo, hi = _torque_bounds(array, h, dt)
    alpha = _scale(normals, A, lo, hi, M, margin)
    target = alpha * M
    P = ca.DM(weighted_pseudo_inverse(array, V))
    if closed:
        m = P @ target
        if nullity == 1:
            m = _segment_step(_null_direction(array), m, lo, hi)
        violation = _violation(A, m, target, lo, hi, inputs)
        return WheelQPFunction(ca.Function(
            name, inputs, [m, alpha, violation], names,
            ["m", "alpha", "violation"]))
    m_s, t_s = ca.SX.sym("m", n), ca.SX.sym("t", 3)
    scale = ca.Function(f"{name}_scale", inputs,
                        [ca.vertcat(*lo), ca.vertcat(*hi), alpha])
    check = ca.Function(f"{name}_check", [m_s, t_s, *inputs],
                        [_violation(A, m_s, t_s, lo, hi, inputs)])
    inputs = [ca.MX.sym(k, x.sparsity()) for k, x in zip(names, inputs)]
    lo_v, hi_v, alpha = scale(*inputs)
    target = alpha * inputs[0]
    m = _conic_call(name, plugin, plugin_options, n, V, A, target, lo_v,
                    hi_v)
    if fast_path:
        m0 = P @ target
        inside = ca.mmax(ca.vertcat(lo_v - m0, m0 - hi_v)) <= 0.0
        m = ca.if_else(inside, m0, m, True)
    violation = check(m, target, *inputs)
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


def _dot(coeffs: np.ndarray, xs: list) -> Any:
    """``Σ c_i x_i`` over the non-zero constants ``c_i`` (0 if none)."""
    out: Any = None
    for c, x in zip(coeffs, xs):
        if c != 0.0:
            term = x if c == 1.0 else (-x if c == -1.0 else float(c) * x)
            out = term if out is None else out + term
    return 0.0 if out is None else out


def _lesser(a: Any, b: Any) -> Any:
    """``min(a, b)`` as one comparison and a select.

    For operands that are never NaN where the result matters (the ratios
    of the scale, the segment's ends, the violation's terms: a NaN there
    comes from NaN or inf in ``M`` or ``h``, which make the torques or
    the violation NaN anyway), or for a NaN ``b`` only: the result is
    then ``a``, as C99 ``fmin`` gives (the torque bounds). In C it is
    about 5 instructions, against 9 for ``fmin``'s NaN rules
    (`ocp.codegen.patches.patch_minmax`).
    """
    return ca.if_else(b < a, b, a)


def _greater(a: Any, b: Any) -> Any:
    """``max(a, b)`` as one comparison and a select (see `_lesser`)."""
    return ca.if_else(b > a, b, a)


def _torque_bounds(array: WheelArray, h: Any, dt: float | None
                   ) -> tuple[list, list]:
    """Per-wheel torque bounds ``lo``, ``hi`` [N·m] (lists of N scalars).

    As `allocation.qp.problem.torque_bounds`: ``|m_i| <= m_max_i`` and,
    with ``h`` (wheel momenta [N·m·s]) and ``dt`` [s], ``|h_i + m_i dt|
    <= h_max_i``; failed wheels at 0. A wheel beyond ``h_max`` by more
    than one step of torque gets ``lo = hi = -sign(h_i) m_max_i``: that
    is the momentum bound clamped to ``[-m_max, m_max]`` (the bound whose
    interval is empty lies beyond ``m_max`` on the side of ``-h``), so
    four minima/maxima per wheel give the numpy law's bounds bit for bit.
    NaN in ``h_i`` gives ``±m_max``, as C99 ``fmax``/``fmin`` would (the
    NaN operand is the compared one, so the select keeps the constant;
    the violation reports the NaN).
    """
    lo, hi = [], []
    for i in range(array.n_wheels):
        mx = float(array.m_max[i]) if array.active[i] else 0.0
        if dt is None or mx == 0.0:
            lo.append(-mx)
            hi.append(mx)
            continue
        hx = float(array.h_max[i])
        lo.append(_lesser(_greater(-mx, (-hx - h[i]) / dt), mx))
        hi.append(_greater(_lesser(mx, (hx - h[i]) / dt), -mx))
    return lo, hi


def _facet_pairs(normals: np.ndarray) -> tuple[list[int], list[int]]:
    """Rows of ``normals`` one per ``±n`` pair (exact negation), and the
    rows without a partner."""
    pairs, singles, used = [], [], set()
    for k, row in enumerate(normals):
        if k in used:
            continue
        partner = [j for j in range(k + 1, len(normals)) if j not in used
                   and np.array_equal(normals[j], -row)]
        used.add(k)
        if partner:
            used.add(partner[0])
            pairs.append(k)
        else:
            singles.append(k)
    return pairs, singles


def _scale(normals: np.ndarray, A: np.ndarray, lo: list, hi: list, M: Any,
           margin: float) -> Any:
    """The largest ``α`` in [0, 1] with ``α M`` attainable, times
    ``1 - margin`` when below 1.

    Facet ``k`` (unit normal ``n``, ``b = n A``) bounds ``α n·M <= d``
    with ``d = Σ_i max(b_i lo_i, b_i hi_i)`` [N·m] (the support of the
    zonotope: centre and half-widths folded in), counted where
    ``n·M > 1e-15``. The normals come in ``±n`` pairs: one ``n·M`` and
    one set of products ``b_i lo_i``, ``b_i hi_i`` serve both, and only
    the one facet of a pair that faces ``M`` costs a division.
    """
    B = normals @ A
    Ms = [M[j] for j in range(3)]
    pairs, singles = _facet_pairs(normals)
    alpha: Any = 1.0
    for k in pairs + singles:
        b = B[k]
        s = _dot(normals[k], Ms)
        up = [hi[i] if b[i] > 0 else lo[i] for i in range(len(b))]
        down = [lo[i] if b[i] > 0 else hi[i] for i in range(len(b))]
        d_plus = _dot(b, up)
        if k in singles:
            t, d_sel = s, d_plus
        else:
            t = ca.fabs(s)
            d_sel = ca.if_else(s > 0, d_plus, -_dot(b, down))
        # min(α, d/t) over the facets with t > 1e-15 (the others bound
        # nothing): one select, the guard and the comparison joined
        ratio = d_sel / t
        alpha = ca.if_else(ca.logic_and(t > 1e-15, ratio < alpha), ratio,
                           alpha)
    alpha = _greater(alpha, 0.0)
    return alpha * ca.if_else(alpha < 1.0, 1.0 - margin, 1.0)


def _violation(A: np.ndarray, m: Any, target: Any, lo: list, hi: list,
               inputs: list) -> Any:
    """The largest violation of ``A m = target`` or of the bounds [N·m];
    NaN when ``m`` or an input holds NaN or inf.

    A bound's violation is written ``|m_i - c_i| - r_i`` (centre ``c``,
    half-width ``r``: one maximum per wheel instead of two). The NaN test
    is one sum: ``Σ`` of those terms and of ``2⁻ᵏ x`` over the inputs
    (scaled so that finite inputs cannot overflow it; NaN, or infinities
    of either sign, make it NaN or infinite) is finite exactly when every
    part is.
    """
    terms = [ca.fabs(r) for r in ca.vertsplit(ca.DM(A) @ m - target)]
    for i in range(len(lo)):
        c, r = 0.5 * (lo[i] + hi[i]), 0.5 * (hi[i] - lo[i])
        terms.append(ca.fabs(m[i] - c) - r)
    values = [x[j] for x in inputs for j in range(x.numel())]
    scale = 2.0 ** -int(np.ceil(np.log2(len(values) + 2)))
    total = terms[0]
    for t in terms[1:]:
        total = total + t
    for x in values:
        total = total + scale * x
    worst = terms[0]
    for t in terms[1:]:
        worst = _greater(worst, t)
    return ca.if_else(ca.fabs(total) < np.inf, worst, np.nan)


def _segment_step(direction: np.ndarray, m0: Any, lo: list, hi: list
                  ) -> Any:
    """``m0 + s n`` with ``s`` = 0 clamped to ``{s : lo <= m0 + s n <= hi}``.

    ``direction`` (N,) spans the null space of the working axes; it is
    scaled to a largest entry of 1, and entries within 1e-14 of ±1 are
    taken as ±1 (the pyramid's null vector is exactly ``(±1, …)``:
    subtractions instead of products). Wheels with ``n_i`` = 0 do not
    bound ``s`` (their torque is fixed by the equality). ``m0``: the
    minimum-norm torques (N,) [N·m]; ``lo``, ``hi``: lists of N bounds
    [N·m]. Returns the torques (N,) [N·m].
    """
    n = direction / float(np.abs(direction).max())
    n = np.where(np.abs(np.abs(n) - 1.0) <= 1e-14, np.sign(n), n)
    step: Any = 0.0
    s_hi: Any = None
    for i, ni in enumerate(n):
        if abs(ni) <= 1e-12:
            continue
        if abs(ni) == 1.0:
            a, b = lo[i] - m0[i], hi[i] - m0[i]
            low, high = (a, b) if ni > 0 else (-b, -a)
        else:
            inv = 1.0 / float(ni)
            a, b = (lo[i] - m0[i]) * inv, (hi[i] - m0[i]) * inv
            low, high = (a, b) if ni > 0 else (b, a)
        step = _greater(step, low)
        s_hi = high if s_hi is None else _lesser(s_hi, high)
    step = _lesser(step, s_hi)
    return ca.vertcat(*[
        m0[i] if abs(ni) <= 1e-12 else m0[i] + step if ni == 1.0
        else m0[i] - step if ni == -1.0 else m0[i] + step * float(ni)
        for i, ni in enumerate(n)])


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
