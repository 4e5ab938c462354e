"""Solver options checked by name when a solver is built.

A misspelt option must not be ignored (DAQP, PIQP) nor fail at the first
call with an untyped error (OSQP, qpsolvers, CasADi): every solver that
takes ``solver_options`` checks the names here, at construction, and an
unknown one raises `InvalidValueError` naming the allowed ones.

Where the names come from:

* CasADi plugins (``casadi:PLUGIN``, ``casadi-c:PLUGIN``, the MPC's
  ``nlpsol``): CasADi itself, the options every conic / nlpsol takes
  (read from ``Function.print_options`` of a one-variable instance) plus
  the plugin's own (``casadi.conic_options`` / ``casadi.nlpsol_options``).
  The values and nested dicts (``{"osqp": {...}}``, ``qpsol_options``)
  are then checked by building a one-variable instance with them, so a
  bad nested name or value is refused at construction too.
* ``"osqp"`` and ``qpsolvers:osqp``: the fields of OSQP's settings
  (``OSQPSettings``) and the names its ``setup`` translates.
* ``"daqp"`` and ``qpsolvers:daqp``: the keys of ``daqp.Model().settings``.
* ``qpsolvers:clarabel``: the attributes of ``clarabel.DefaultSettings``;
  ``qpsolvers:piqp``: of a PIQP solver's settings; ``qpsolvers:proxqp``:
  the keyword arguments of ``proxsuite.proxqp.dense.solve``;
  ``qpsolvers:quadprog``: ``factorized`` only. Every qpsolvers backend
  also takes ``initvals`` and ``verbose`` and the keyword parameters of
  its qpsolvers wrapper (``backend`` for piqp and proxqp).
* Any other qpsolvers backend: not checked (its options are forwarded;
  its own error, if any, comes at the first call).
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import io
import re
from typing import Any

from .exceptions import InvalidValueError
from .validation import as_options

__all__ = ["check_backend_options", "check_nlpsol_options",
           "conic_option_names", "nlpsol_option_names"]

#: Options the toolbox reads itself, per backend family.
TOOLBOX_OPTIONS = {"osqp": frozenset({"accept_inaccurate"})}
#: Names OSQP's ``setup`` accepts besides its settings fields.
_OSQP_EXTRA = frozenset({"rho", "solver_type", "cg_preconditioner",
                         "polish", "warm_start"})
_QUIET = {"qrqp": {"print_iter": False, "print_header": False,
                   "print_info": False}}


def _printed_names(function) -> frozenset:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        function.print_options()
    return frozenset(re.findall(r'^> "([^"]+)"', buf.getvalue(), re.M))


def _tiny_conic(plugin: str, options: dict):
    import casadi as ca

    return ca.conic("option_check", plugin,
                    {"h": ca.Sparsity.dense(1, 1),
                     "a": ca.Sparsity.dense(0, 1)}, options)


def _tiny_nlpsol(plugin: str, options: dict):
    import casadi as ca

    x = ca.MX.sym("x")
    return ca.nlpsol("option_check", plugin, {"x": x, "f": x * x}, options)


@functools.lru_cache(maxsize=None)
def _conic_generic() -> frozenset:
    import casadi as ca

    names = _printed_names(_tiny_conic("qrqp", _QUIET["qrqp"]))
    return names - frozenset(ca.conic_options("qrqp"))


@functools.lru_cache(maxsize=None)
def _nlpsol_generic() -> frozenset:
    import casadi as ca

    opts = {"qpsol": "qrqp", "qpsol_options": _QUIET["qrqp"],
            "print_header": False, "print_iteration": False}
    names = _printed_names(_tiny_nlpsol("sqpmethod", opts))
    return names - frozenset(ca.nlpsol_options("sqpmethod"))


def conic_option_names(plugin: str) -> frozenset:
    """Option names ``casadi.conic`` takes for ``plugin`` (read from CasADi)."""
    import casadi as ca

    return _conic_generic() | frozenset(ca.conic_options(plugin))


def nlpsol_option_names(plugin: str) -> frozenset:
    """Option names ``casadi.nlpsol`` takes for ``plugin`` (from CasADi)."""
    import casadi as ca

    return _nlpsol_generic() | frozenset(ca.nlpsol_options(plugin))


def _osqp_names() -> frozenset:
    import osqp

    fields = osqp.OSQP().ext.OSQPSettings.__dict__
    return frozenset(k for k in fields if not k.startswith("_")) \
        | _OSQP_EXTRA


def _daqp_names() -> frozenset:
    import daqp

    return frozenset(daqp.Model().settings)


def _clarabel_names() -> frozenset:
    import clarabel

    return frozenset(k for k in dir(clarabel.DefaultSettings())
                     if not k.startswith("_") and k != "default")


def _piqp_names() -> frozenset:
    import piqp

    return frozenset(k for k in dir(piqp.DenseSolver().settings)
                     if not k.startswith("_"))


def _proxqp_names() -> frozenset:
    from proxsuite import proxqp

    names: set[str] = set()
    for solve in (proxqp.dense.solve, proxqp.sparse.solve):
        for line in (solve.__doc__ or "").splitlines():
            if line.startswith("solve("):
                names |= set(re.findall(r"(?:\(|, )(\w+):", line))
    return frozenset(names - {"H", "g", "A", "b", "C", "l", "u"})


#: qpsolvers backend -> the names its solver takes (see module doc)
_QPSOLVERS = {"osqp": _osqp_names, "daqp": _daqp_names,
              "clarabel": _clarabel_names, "piqp": _piqp_names,
              "proxqp": _proxqp_names,
              "quadprog": lambda: frozenset({"factorized"})}


def _qpsolvers_names(solver: str) -> frozenset | None:
    if solver not in _QPSOLVERS:
        return None
    names = _QPSOLVERS[solver]()
    try:
        import qpsolvers.solvers as solvers

        wrapper = getattr(solvers, f"{solver}_solve_problem", None)
        if wrapper is not None:
            names |= frozenset(
                p.name for p in inspect.signature(wrapper).parameters.values()
                if p.kind is p.KEYWORD_ONLY or (
                    p.kind is p.POSITIONAL_OR_KEYWORD and p.name != "problem"))
    except (ImportError, TypeError, ValueError):  # pragma: no cover
        pass
    return names | {"initvals", "verbose"}


def check_names(options: dict, allowed: frozenset, solver: str) -> None:
    """Raise `InvalidValueError` unless every key of ``options`` is allowed.

    The message names the unknown keys and every allowed one.
    """
    bad = sorted(str(k) for k in options if k not in allowed)
    if bad:
        raise InvalidValueError(
            f"unknown solver option(s) {bad} for {solver}; allowed: "
            f"{', '.join(sorted(allowed))}")


def _casadi_build(build, options: dict, solver: str) -> None:
    """Build a one-variable instance: a bad nested name or value raises."""
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            build(options)
    except RuntimeError as exc:
        lines = [ln for ln in str(exc).splitlines() if ln.strip()]
        raise InvalidValueError(
            f"solver_options rejected by {solver}: "
            f"{lines[-1] if lines else exc}") from None


def check_backend_options(family: str, plugin: str,
                          options: dict[str, Any] | None) -> dict:
    """Check ``options`` of QP backend ``family:plugin``; return a copy.

    Raises
    ------
    InvalidValueError
        Not a dict, an unknown name (the message lists the allowed
        ones), or a CasADi plugin refuses a nested name or a value.
    """
    options = as_options(options)
    own = TOOLBOX_OPTIONS.get(family, frozenset())
    if family in ("casadi", "casadi-c"):
        from .qp.backends.casadi_conic_ import plugin_options

        check_names(options, conic_option_names(plugin),
                    f"{family}:{plugin}")
        _casadi_build(lambda o: _tiny_conic(
            plugin, plugin_options(plugin, o)), options, f"{family}:{plugin}")
    elif family == "osqp":
        check_names(options, _osqp_names() | own, "osqp")
    elif family == "daqp":
        check_names(options, _daqp_names(), "daqp")
    elif family == "qpsolvers":
        allowed = _qpsolvers_names(plugin)
        if allowed is not None:
            check_names(options, allowed, f"qpsolvers:{plugin}")
    return options


def check_nlpsol_options(plugin: str, options: dict | None,
                         qp_plugin: str = "qrqp") -> dict:
    """Check the ``casadi.nlpsol`` options of ``plugin``; return a copy.

    For ``sqpmethod`` the nested ``qpsol_options`` are checked against
    the conic ``options.get("qpsol", qp_plugin)`` (names, then a
    one-variable build). Options of ``ipopt`` / ``fatrop`` passed in their
    own nested dict (``{"ipopt": {...}}``) are forwarded unchecked.

    Raises
    ------
    InvalidValueError
        Not a dict, or an unknown name (the message lists the allowed
        ones).
    """
    options = as_options(options)
    check_names(options, nlpsol_option_names(plugin), f"nlpsol {plugin!r}")
    if plugin == "sqpmethod":
        qp_plugin = options.get("qpsol", qp_plugin)
        qp_opts = options.get("qpsol_options", {})
        if isinstance(qp_plugin, str) and isinstance(qp_opts, dict):
            check_names(qp_opts, conic_option_names(qp_plugin),
                        f"qpsol {qp_plugin!r}")
            _casadi_build(lambda o: _tiny_conic(
                qp_plugin, {**_QUIET.get(qp_plugin, {}), **o}), qp_opts,
                f"qpsol {qp_plugin!r}")
    return options
