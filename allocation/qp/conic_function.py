"""The wheel QP allocator as one casadi Function (for buffers and C code)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError, SolverNotFound
from adcs_common.validation import as_finite_scalar, as_vector, check_positive

from ..arrays import WheelArray
from .backends import INSTALL_HINT, _casadi_names, available_solvers
from .problem import facet_normals

_MARGIN = 1e-9


def conic_allocator_function(array: WheelArray, weights=None, *,
                             dt: float | None = None, plugin: str = "daqp",
                             name: str = "wheel_qp",
                             plugin_options: dict | None = None
                             ) -> ca.Function:
    """`QPAllocator` (``saturation="scale"``) as a single casadi Function.

    The same law as the numpy allocator: bounds ``|m_i| <= m_max_i`` (and
    ``|h_i + m_i dt| <= h_max_i`` when ``dt`` is given), failed wheels at 0,
    the largest ``α <= 1`` with ``α M`` attainable (from the zonotope
    facets, written symbolically), then ``min Σ V_i m_i²`` subject to
    ``A m = α (1 - 1e-9) M`` by a CasADi ``conic``. The graph holds no
    Python, so it can be called through ``Function.buffer()`` or exported
    with ``generate()`` (daqp and qrqp generate self-contained C).

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

    Returns
    -------
    casadi.Function
        ``wheel_qp(M[3] [, h[N]]) -> (m[N], alpha, violation)``:
        motor torques [N·m], the scale reached, and the largest
        violation of ``A m = α M`` or of the bounds (check it against
        your tolerance: the conic's own success flag is not an output).
    """
    array.require_full_rank()
    if f"casadi:{plugin}" not in _casadi_names():
        raise SolverNotFound(f"casadi:{plugin}", available_solvers(),
                             INSTALL_HINT)
    n = array.n_wheels
    V = np.ones(n) if weights is None else as_vector(weights, n, "weights")
    check_positive(V, "weights")
    A = array.working_axes
    active = array.active.astype(float)
    normals = facet_normals(A[:, array.active])
    NA = np.abs(normals @ A)

    M = ca.MX.sym("M", 3)
    inputs, names = [M], ["M"]
    m_max = ca.DM(array.m_max)
    lo, hi = -m_max, m_max
    if dt is not None:
        dt = as_finite_scalar(dt, "dt")
        if dt <= 0:
            raise InvalidValueError(f"dt must be positive, got {dt}")
        h = ca.MX.sym("h", n)
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
    alpha = ca.if_else(alpha < 1.0, alpha * (1.0 - _MARGIN), alpha)
    target = alpha * M

    opts = dict(plugin_options or {})
    if plugin == "qrqp":
        opts.setdefault("print_iter", False)
        opts.setdefault("print_header", False)
        opts.setdefault("print_info", False)
    opts.setdefault("error_on_fail", False)
    solver = ca.conic(f"{name}_conic", plugin,
                      {"h": ca.Sparsity.dense(n, n),
                       "a": ca.Sparsity.dense(3, n)}, opts)
    sol = solver(h=ca.DM(np.diag(2.0 * V)), g=ca.DM.zeros(n), a=ca.DM(A),
                 lba=target, uba=target, lbx=lo, ubx=hi)
    m = sol["x"]
    violation = ca.mmax(ca.vertcat(ca.fabs(ca.DM(A) @ m - target),
                                   lo - m, m - hi))
    return ca.Function(name, inputs, [m, alpha, violation], names,
                       ["m", "alpha", "violation"])


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
