"""NLP solvers offered for slews and their default options."""

from __future__ import annotations

import casadi as ca

from adcs_common.options import merge_options
from adcs_common.exceptions import (
    SolverNotFound,
)


_QUIET_SQP = {"record_time": True, "print_header": False,
              "print_iteration": False, "print_status": False,
              "print_time": False, "qpsol": "qpoases",
              "qpsol_options": {"printLevel": "none", "error_on_fail": False,
                                "sparse": True},
              "convexify_strategy": "regularize", "max_iter": 200}


#: Name -> (CasADi nlpsol plugin, default options) of the NLP solvers.
NLP_SOLVERS: dict[str, tuple[str, dict]] = {
    "ipopt": ("ipopt", {"print_time": False, "record_time": True,
                        "ipopt": {"print_level": 0, "sb": "yes",
                                  "max_iter": 1000, "tol": 1e-8}}),
    "sqpmethod": ("sqpmethod", _QUIET_SQP),
    # the code-generatable conic of the MPC; about 25x faster per SQP
    # iteration than qpOASES here
    "sqpmethod:qrqp": ("sqpmethod", {
        **{k: v for k, v in _QUIET_SQP.items() if k != "qpsol_options"},
        "qpsol": "qrqp", "max_iter": 300,
        "qpsol_options": {"print_iter": False, "print_header": False,
                          "print_info": False, "error_on_fail": False}}),
    "fatrop": ("fatrop", {"print_time": False, "record_time": True,
                          "structure_detection": "auto",
                          "fatrop": {"print_level": 0, "max_iter": 1000,
                                     "tol": 1e-8}}),
}


def available_nlp_solvers() -> tuple[str, ...]:
    """Names in `NLP_SOLVERS` whose CasADi plugin loads here."""
    return tuple(n for n, (plugin, _) in NLP_SOLVERS.items()
                 if ca.has_nlpsol(plugin))


def solver_entry(name: str) -> tuple[str, dict]:
    """``(plugin, default options)`` of an NLP solver name."""
    if not isinstance(name, str) or name not in NLP_SOLVERS:
        raise SolverNotFound(
            str(name), available_nlp_solvers(),
            hint="the slew NLPs use CasADi's nlpsol plugins; "
                 "pip install casadi brings ipopt and sqpmethod")
    plugin, opts = NLP_SOLVERS[name]
    if not ca.has_nlpsol(plugin):
        raise SolverNotFound(name, available_nlp_solvers(),
                             hint=f"CasADi plugin {plugin!r} is missing")
    return plugin, opts


def with_user_options(base: dict, user: dict | None) -> dict:
    """Merge the user's solver options over ``base``.

    A ``qpsol`` other than the default drops the default's
    ``qpsol_options`` (sqpmethod's qpOASES settings mean nothing to
    qrqp or osqp and would fail its setup).
    """
    user = user or {}
    if "qpsol" in user and user["qpsol"] != base.get("qpsol"):
        base = {k: v for k, v in base.items() if k != "qpsol_options"}
    return merge_options(base, user)


#: Options of the refined solve (``initial_guess="coarse"``): its guess
#: is feasible and near the optimum, so a small barrier parameter and
#: iterates kept close to the (active) bounds. Measured on the benchmark
#: slews; IPOPT's warm start with the interpolated multipliers was no
#: better.
WARM_START_OPTIONS: dict[str, dict] = {
    "ipopt": {"ipopt": {"mu_init": 1e-5, "bound_push": 1e-8,
                        "bound_frac": 1e-8}},
    "fatrop": {"fatrop": {"mu_init": 1e-5}},
}


#: Options of the coarse solve that seeds ``initial_guess="coarse"``
#: (a rough optimum is enough).
COARSE_OPTIONS: dict[str, dict] = {
    "ipopt": {"ipopt": {"tol": 1e-4}},
    "fatrop": {"fatrop": {"tol": 1e-4}},
}
