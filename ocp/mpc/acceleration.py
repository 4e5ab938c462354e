"""Anderson acceleration of the condensed SQP's fixed-point iteration.

Gauss–Newton SQP is a fixed-point iteration ``z ← G(z)`` (G: one
linearisation and QP step). Through a saturated slew it converges
linearly, each step about 0.8 of the last (the dynamics' curvature,
weighted by large multipliers, is missing from its Hessian). Anderson
acceleration (type II; H. F. Walker, P. Ni, "Anderson acceleration for
fixed-point iterations", *SIAM J. Numer. Anal.* 49(4), 2011)
mixes the last ``m`` iterates instead: with ``f_i = G(z_i) − z_i``,

.. math::
    γ = \\arg\\min_γ \\|f_i − ΔF γ\\|_2,\\qquad
    z_{i+1} = G(z_i) − ΔG γ,

ΔF, ΔG the differences of the last m + 1 residuals and images. On a
linear map it is a Krylov method (GMRES-like); here it cuts the slew's
50 Gauss–Newton iterations to about 10. Every returned plan is still a
QP step (`ocp.mpc.condensed` stops on a G step), so the answer is the
same optimum to the step tolerance; only the path to it changes.

`anderson_numpy` and `anderson_function` (CasADi, for the generated C)
are the same update; the tests hold them equal (1e-12).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from adcs_common.exceptions import InvalidValueError

from .riccati import chol_lower, inv_lower

#: Relative Tikhonov term on the m × m normal equations [1].
ANDERSON_RIDGE = 1e-10


def anderson_numpy(g: np.ndarray, z: np.ndarray, G_hist: np.ndarray,
                   F_hist: np.ndarray, valid: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                              np.ndarray]:
    """One Anderson update (numpy twin of `anderson_function`).

    Parameters
    ----------
    g : (n,) ndarray
        ``G(z)``, the image of the current iterate.
    z : (n,) ndarray
        The current iterate.
    G_hist, F_hist : (n, m + 1) ndarray
        Past images and residuals, oldest first.
    valid : (m + 1,) ndarray
        1 for the history columns that hold an iterate, else 0.

    Returns
    -------
    z_next, G_hist, F_hist, valid
        The next iterate and the histories with ``g``, ``g − z`` added.
    """
    f = g - z
    Gh = np.c_[G_hist[:, 1:], g]
    Fh = np.c_[F_hist[:, 1:], f]
    v = np.r_[valid[1:], 1.0]
    vd = v[:-1]
    dF = (Fh[:, 1:] - Fh[:, :-1]) * vd
    dG = (Gh[:, 1:] - Gh[:, :-1]) * vd
    M = dF.T @ dF
    M = M + np.diag(1.0 - vd) + ANDERSON_RIDGE * (np.trace(M) + 1e-30) \
        * np.eye(len(vd))
    gamma = np.linalg.solve(M, dF.T @ f)
    return g - dG @ gamma, Gh, Fh, v


def anderson_function(n: int, memory: int) -> ca.Function:
    """Return `anderson_numpy` as a CasADi Function.

    ``anderson(g, z, G_hist, F_hist, valid) -> (z_next, G_next, F_next,
    valid_next)``; ``n`` is the iterate's length, ``memory`` (m ≥ 1)
    the number of differences mixed; the histories are (n, m + 1). The
    n-long work is MX (loops in generated C), the m × m solve SX.
    """
    if int(memory) < 1:
        raise InvalidValueError(f"memory must be at least 1, got {memory}")
    m = int(memory)
    Ms, bs, vs = ca.SX.sym("M", m, m), ca.SX.sym("b", m), ca.SX.sym("vd", m)
    Mr = Ms + ca.diag(1.0 - vs) + ANDERSON_RIDGE * (ca.trace(Ms) + 1e-30) \
        * ca.SX.eye(m)
    Li = inv_lower(chol_lower(Mr))
    solve = ca.Function("anderson_solve", [Ms, bs, vs],
                        [ca.mtimes([Li.T, Li, bs])])
    g, z = ca.MX.sym("g", n), ca.MX.sym("z", n)
    Gh0, Fh0 = ca.MX.sym("G_hist", n, m + 1), ca.MX.sym("F_hist", n, m + 1)
    v0 = ca.MX.sym("valid", m + 1)
    f = g - z
    Gh = ca.horzcat(Gh0[:, 1:], g)
    Fh = ca.horzcat(Fh0[:, 1:], f)
    v = ca.vertcat(v0[1:], 1.0)
    vd = v[:-1]
    dF = ca.mtimes(Fh[:, 1:] - Fh[:, :-1], ca.diag(vd))
    dG = ca.mtimes(Gh[:, 1:] - Gh[:, :-1], ca.diag(vd))
    gamma = solve(ca.mtimes(dF.T, dF), ca.mtimes(dF.T, f), vd)
    return ca.Function("anderson", [g, z, Gh0, Fh0, v0],
                       [g - ca.mtimes(dG, gamma), Gh, Fh, v],
                       ["g", "z", "G_hist", "F_hist", "valid"],
                       ["z_next", "G_next", "F_next", "valid_next"])
