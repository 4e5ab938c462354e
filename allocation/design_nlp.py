"""The smooth NLP behind `allocation.design`: an epigraph over facets.

For a zonotope ``{sum_k c_k x_k a_k : |x_k| <= 1}`` in 3-D the facet
normals are ``n_ij = a_i x a_j / |a_i x a_j|`` (one per pair of axes) and
the inscribed radius is the smallest support value over them,

.. math:: r = \\min_{i<j} h(n_{ij}), \\qquad
          h(n) = \\sum_k c_k |n \\cdot a_k|.

With ``D_ijk = det(a_i, a_j, a_k) = |a_i x a_j| (n_ij . a_k)`` the
epigraph ``t |a_i x a_j| <= sum_k c_k |D_ijk|`` for every pair holds
exactly when ``t <= r``. The absolute value is replaced by the smooth
lower bound ``sqrt(D^2 + eps^2) - eps`` (never above ``|D|``, at most
``eps`` below), and ``|a_i x a_j|`` by ``sqrt(|a_i x a_j|^2 + eps^2)``
(never below), so every feasible ``t`` stays a lower bound of the true
radius; ``eps`` is lowered from start to finish (continuation) and the
answer is certified by the exact envelope code afterwards.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from .arrays import PYRAMID_SIGN_Y, PYRAMID_SIGN_Z

__all__ = ["FAMILIES", "DesignNLP", "family_axes", "build_design_nlp"]

#: Layout families: name -> (wheel counts allowed (None: any >= 3),
#: one-line description).
FAMILIES = {
    "free": (None, "every spin axis free"),
    "cone": (None, "axes equally spaced in azimuth on a cone about body z; "
             "the cone half-angle is free"),
    "pyramid": ((4,), "the four-wheel pyramid of [1] eq. (6); delta and "
                "gamma free"),
    "3+1": (None, "three wheels on the body axes, the others free (the "
            "NASA standard 3 + 1 for four wheels)"),
    "pairs": ((6,), "three orthogonal pairs, each pair canted by +-alpha "
              "from its body axis towards the next; alpha free"),
}

#: Continuation of the smoothing width (the last is the answer's).
EPS_SCHEDULE = (3.0, 1.0, 0.3, 0.1, 1e-2, 1e-4, 1e-7, 1e-10)


def _unit_cols(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=0)


def family_axes(family: str, n: int, params, lib=np):
    """Spin axes (3, n) of a family from its parameters.

    Parameters
    ----------
    family : str
        A key of `FAMILIES`.
    n : int
        Number of wheels.
    params : array_like or casadi.SX
        The family's decision parameters (angles [rad], or for ``free`` and
        ``3+1`` the stacked free axes (3 each) after the fixed ones).
    lib : module
        ``numpy`` for numbers, ``casadi`` for symbols.

    Returns
    -------
    numpy.ndarray or casadi.SX, shape (3, n)
        Spin axes as columns (unit for the angle families; for ``free``
        and ``3+1`` the free columns are unit only on the NLP's
        constraints).
    """
    cat = (lambda *cols: np.column_stack(cols)) if lib is np else ca.horzcat
    p = params
    if family == "cone":
        az = 2.0 * np.pi * np.arange(n) / n
        return cat(*[lib.vertcat(lib.sin(p[0]) * np.cos(a),
                                 lib.sin(p[0]) * np.sin(a), lib.cos(p[0]))
                     if lib is ca else np.array(
                         [np.sin(p[0]) * np.cos(a), np.sin(p[0]) * np.sin(a),
                          np.cos(p[0])]) for a in az])
    if family == "pyramid":
        d, g = p[0], p[1]
        cols = [[-lib.sin(d) * lib.cos(g), sy * lib.sin(d) * lib.sin(g),
                 sz * lib.cos(d)]
                for sy, sz in zip(PYRAMID_SIGN_Y, PYRAMID_SIGN_Z)]
        return cat(*[lib.vertcat(*c) if lib is ca else np.array(c)
                     for c in cols])
    if family == "pairs":
        a = p[0]
        cols = []
        for k in range(3):
            e, f = np.eye(3)[:, k], np.eye(3)[:, (k + 1) % 3]
            if lib is ca:
                e, f = ca.DM(e), ca.DM(f)
            for s in (1.0, -1.0):
                cols.append(lib.cos(a) * e + s * lib.sin(a) * f)
        return cat(*cols)
    fixed = 1 if family == "free" else 3
    head = np.eye(3)[:, [2]] if family == "free" else np.eye(3)
    if lib is np:
        return np.column_stack([head, np.reshape(p, (3, n - fixed),
                                                 order="F")])
    return ca.horzcat(ca.DM(head), ca.reshape(p, 3, n - fixed))


def n_params(family: str, n: int) -> int:
    """Number of decision parameters of a family's axes."""
    return {"cone": 1, "pyramid": 2, "pairs": 1}.get(
        family, 3 * (n - (1 if family == "free" else 3)))


def param_bounds(family: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the family's parameters (angles in [rad])."""
    k = n_params(family, n)
    if family in ("cone", "pyramid"):
        return np.zeros(k), np.full(k, np.pi / 2)
    if family == "pairs":
        return np.zeros(1), np.full(1, np.pi / 4)
    return np.full(k, -1.0), np.full(k, 1.0)


def random_params(family: str, n: int, rng: np.random.Generator
                  ) -> np.ndarray:
    """A random start: uniform angles, or axes uniform on the sphere."""
    lo, hi = param_bounds(family, n)
    if family in ("cone", "pyramid", "pairs"):
        return rng.uniform(lo, hi)
    return _unit_cols(rng.normal(size=(3, len(lo) // 3))).ravel(order="F")


@dataclass
class DesignNLP:
    """A built NLP: one `casadi.nlpsol` for every start and re-solve.

    Decision vector ``z = [params, c (budget only), t]`` with ``t`` the
    epigraph variables (``t_nom``, then ``t_fail`` when failures > 0);
    parameters ``[eps, w, c (fixed capacities)]`` with ``w`` the weight of
    ``t_nom`` in the objective ``(1 - w) t_fail + w t_nom`` (ignored
    without failures).
    """

    solver: ca.Function
    family: str
    n: int
    n_par: int
    budget: float | None
    n_t: int
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray

    def solve(self, params: np.ndarray, capacity: np.ndarray,
              t0: np.ndarray, eps: float, weight: float = 1.0,
              t_fail_min: float = 0.0):
        """One IPOPT solve from ``params``; returns (z, success).

        ``weight`` is w of the objective; ``t_fail_min`` a lower bound on
        the failure epigraph variable [units] (the epsilon-constraint of
        a trade curve).
        """
        z0 = np.concatenate([params, capacity if self.budget else [],
                             t0])
        p = np.concatenate([[eps, weight], capacity])
        lbx = self.lbx
        if t_fail_min > 0 and self.n_t == 2:
            lbx = lbx.copy()
            lbx[-1] = t_fail_min
        sol = self.solver(x0=z0, p=p, lbx=lbx, ubx=self.ubx,
                          lbg=self.lbg, ubg=self.ubg)
        return (np.asarray(sol["x"]).ravel(),
                bool(self.solver.stats()["success"]))


def _pair_rows(A, c, eps, cases, t_of_case):
    """Epigraph rows ``sum_k c_k |D_ijk| - t |a_i x a_j| >= 0``."""
    n = A.shape[1]
    rows = []
    pair_cross = {}
    for i, j in itertools.combinations(range(n), 2):
        cr = ca.cross(A[:, i], A[:, j])
        dets = {k: ca.dot(cr, A[:, k]) for k in range(n) if k not in (i, j)}
        pair_cross[i, j] = (ca.sqrt(ca.sumsqr(cr) + eps ** 2), dets)
    for case, t in zip(cases, t_of_case):
        for (i, j), (norm, dets) in pair_cross.items():
            if i in case or j in case:
                continue
            s = sum(c[k] * (ca.sqrt(d ** 2 + eps ** 2) - eps)
                    for k, d in dets.items() if k not in case)
            rows.append(s - t * norm)
    return rows


def build_design_nlp(family: str, n: int, failures: int,
                     budget: float | None,
                     ipopt_options: dict | None = None) -> DesignNLP:
    """Build the epigraph NLP of one design problem.

    The objective maximises ``(1 - w) t_fail + w t_nom`` (``w`` a
    parameter of each solve; only ``t_nom`` with no failures), ``t_nom``
    below every nominal facet's support value and ``t_fail`` below every
    facet of every ``failures``-wheel failure.
    """
    k = n_params(family, n)
    par = ca.SX.sym("par", k)
    eps = ca.SX.sym("eps")
    w = ca.SX.sym("w")
    cap_p = ca.SX.sym("cap", n)
    c = ca.SX.sym("c", n) if budget else cap_p
    A = family_axes(family, n, par, lib=ca)
    cases: list[tuple[int, ...]] = [()]
    if failures > 0:
        cases += list(itertools.combinations(range(n), failures))
    n_t = 1 if failures == 0 else 2
    t = ca.SX.sym("t", n_t)
    t_of_case = [t[0]] + [t[n_t - 1]] * (len(cases) - 1)
    g = _pair_rows(A, c, eps, cases, t_of_case)
    lbg = [0.0] * len(g)
    ubg = [np.inf] * len(g)
    if family in ("free", "3+1"):
        fixed = 1 if family == "free" else 3
        for col in range(fixed, n):
            g.append(ca.sumsqr(A[:, col]))
            lbg.append(1.0)
            ubg.append(1.0)
    if budget:
        g.append(ca.sum1(c))
        lbg.append(budget)
        ubg.append(budget)
    lo, hi = param_bounds(family, n)
    z = ca.vertcat(par, c if budget else ca.SX(0, 1), t)
    lbx = np.concatenate([lo, np.zeros(n) if budget else [],
                          np.zeros(n_t)])
    ubx = np.concatenate([hi, np.full(n, budget) if budget else [],
                          np.full(n_t, np.inf)])
    f = -t[0] if n_t == 1 else -(w * t[0] + (1 - w) * t[1])
    opts: dict[str, Any] = {"print_time": False, "ipopt": {
        "print_level": 0, "sb": "yes", "tol": 1e-12, "max_iter": 300,
        "acceptable_tol": 1e-9, **(ipopt_options or {})}}
    solver = ca.nlpsol("array_design", "ipopt",
                       {"x": z, "p": ca.vertcat(eps, w, cap_p), "f": f,
                        "g": ca.vertcat(*g)}, opts)
    return DesignNLP(solver, family, n, k, budget, n_t, lbx, ubx,
                     np.array(lbg), np.array(ubg))
