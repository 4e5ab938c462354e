"""Single-precision C export: float code and the tolerances for float.

CasADi's ``CodeGenerator`` option ``casadi_real: "float"`` makes
``casadi_real`` a ``float`` typedef, but the code it writes still holds
double literals (constants are printed with ``%.16e``) and calls the
double math functions (``sqrt``, ``fabs``, ``fmin`` …), so a float
build computes in double half of the time: on a single-precision FPU
(Cortex-M4F) every such operation is a software routine. `to_single`
turns that text into genuine float code:

* every floating literal outside comments and strings gets the ``f``
  suffix; literals beyond float's range are mapped to documented float
  equivalents (`FLOAT_MAX_LITERAL` for ``|v| > FLT_MAX``, the "infinite"
  bounds such as ``1e300``, which stay finite as in the double code;
  `FLOAT_MIN_LITERAL` for ``0 < |v| < FLT_MIN``, the division guards
  such as ``1e-300``, which stay positive; gcc would otherwise warn
  ``-Woverflow`` and round them to inf or 0);
* every call of a C99 math function in `MATH_FUNCTIONS` is renamed to
  its float variant (``sqrt(`` → ``sqrtf(``; CasADi's own
  ``casadi_fabs`` etc. are left alone: they are written on
  ``casadi_real`` and call the renamed functions inside);
* every ``double`` in code becomes ``casadi_real`` (CasADi's DAQP
  runtime declares ``casadi_daqp_solve`` on ``double`` pointers);
* a ``printf`` of a ``casadi_real`` (qrqp's iteration log, compiled out
  unless printing is on) gets an explicit ``(double)`` so that
  ``-Wdouble-promotion`` stays quiet.

`double_math_symbols` lists the double math symbols an object file still
references (``nm``): empty for a transformed export.

`TOLERANCES` is the one table of the generation-time constants that
assume double arithmetic, per precision, each with its reason; the
export looks them up with `tolerances`.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

from adcs_common.exceptions import InvalidValueError

__all__ = [
    "DAQP_SINGLE_FLAG",
    "FLOAT_EPS",
    "FLOAT_MAX_LITERAL",
    "FLOAT_MIN_LITERAL",
    "MATH_FUNCTIONS",
    "PRECISIONS",
    "SINGLE_MPC_VARIANTS",
    "TOLERANCES",
    "c_real",
    "check_precision",
    "double_math_symbols",
    "float_literals",
    "stagewise_options",
    "to_single",
    "tolerances",
]


#: Precisions `ocp.codegen.export_c` accepts.
PRECISIONS = ("double", "single")

#: Machine epsilon of IEEE-754 single precision (2⁻²³).
FLOAT_EPS = 1.1920929e-07

#: Float spelling of a double literal above FLT_MAX (an "infinite" bound):
#: FLT_MAX itself, finite like the double constant it replaces.
FLOAT_MAX_LITERAL = "3.40282347e+38f"

#: Float spelling of a nonzero double literal below FLT_MIN (a guard
#: against division by zero): FLT_MIN, the smallest normal float (a
#: subnormal would be flushed to zero on FPUs in flush-to-zero mode).
FLOAT_MIN_LITERAL = "1.17549435e-38f"

_FLT_MAX = 3.4028234663852886e38
_FLT_MIN = 1.1754943508222875e-38

#: C99 math functions renamed to their ``f`` variants by `to_single`.
MATH_FUNCTIONS = (
    "acos", "acosh", "asin", "asinh", "atan", "atan2", "atanh", "cbrt",
    "ceil", "copysign", "cos", "cosh", "erf", "erfc", "exp", "exp2",
    "expm1", "fabs", "floor", "fma", "fmax", "fmin", "fmod", "hypot",
    "ldexp", "lgamma", "log", "log10", "log1p", "log2", "nearbyint",
    "pow", "remainder", "rint", "round", "sin", "sinh", "sqrt", "tan",
    "tanh", "tgamma", "trunc")


# Generation-time constants that assume double, per precision. Each value
# for "single" is chosen against float's epsilon (1.2e-7) and the scale
# of what it tests; the reason follows each entry.
TOLERANCES: dict[str, dict[str, float]] = {
    "double": {
        "row_tol": 1e-10,          # ocp.mpc.condensed_qp.ROW_TOL
        "step_tol": 1e-6,          # ocp.mpc.condensed.STEP_TOL
        "qp_kkt_tol": 1e-6,        # ocp.mpc.problem.QP_KKT_TOL
        "bound_tol": 1e-6,         # ocp.mpc.problem.BOUND_TOL
        "regularization": 1e-4,    # AttitudeMPC.regularization
        "qrqp_tol": 1e-8,          # qrqp constr_viol_tol, dual_inf_tol
        "daqp_primal_tol": 1e-10,  # conic options of wheel and duty QPs
        "wheel_margin": 1e-9,      # allocation.qp.conic_function._MARGIN
        "duty_viol_tol": 1e-6,     # certified_duty_function viol_tol
        "duty_kkt_tol": 1e-9,      # duty_function kkt_tol
        "duty_slack_tol": 1e-7,    # certified_duty_function slack_tol
        "duty_attain_tol": 1e-9,   # thrusters.qp.certified._ATTAIN_TOL
        "duty_daqp_eps_prox": 0.0,  # DAQP's proximal weight on duty_qp
    },
    "single": {
        # momentum rows [N·m·s] (h_max ~ 0.01-0.1) summed over up to 20
        # intervals in float: rounding ~ 20 · 1.2e-7 · 0.05 ≈ 1e-7, so a
        # row test below 1e-6 would chase rounding (and add a second QP)
        "row_tol": 1e-6,
        # max |δu / m_max| of a float QP step is not resolved below
        # ~ 100 eps (condensing and Riccati factors accumulate rounding):
        # iterating further does not move the plan
        "step_tol": 1e-5,
        # relative KKT residual of a float QP point: stationarity sums
        # ~ N·n_u terms of rounding 1.2e-7 each; 1e-4 leaves 100x margin
        # over the residuals measured (≈ 1e-6)
        "qp_kkt_tol": 1e-4,
        # scaled bound violation [1]: float rounding of the plan (relative
        # 1.2e-7) plus the QP's tolerance below, 10x margin
        "bound_tol": 1e-5,
        # kept: ρ = 1e-4 relative to the Gauss-Newton Hessian (O(1)
        # scaled) is ~ 800 eps, well above float rounding, and changing
        # it would move the optimum away from the double controller's
        "regularization": 1e-4,
        # qrqp stops at constraint violation / dual infeasibility below
        # this: 1e-8 is below float's resolution of O(1) quantities
        # (qrqp then runs to max_iter and reports failure); 1e-6 is ~ 8 eps
        "qrqp_tol": 1e-6,
        # DAQP's own default (1e-6), the tolerance of its float build
        "daqp_primal_tol": 1e-6,
        # α (1 - margin) keeps α M inside the attainable set: 1 - 1e-9 is
        # 1.0f, so the margin must exceed the rounding of α (~ 4 eps)
        "wheel_margin": 1e-6,
        # scaled violation of a duty point computed in float: the rows
        # scaled by 1/h_max (~ 80) give ~ 1e-5 (measured up to 1.0e-5 on
        # 300 random cycles, qrqp at 1e-6); 5x margin
        "duty_viol_tol": 5e-5,
        # KKT residuals of the reduced duty QP in float: ~ 1e-6 measured,
        # 1e-9 would fail every certificate (status 4)
        "duty_kkt_tol": 1e-4,
        # scaled slack above which the momentum bound counts as relaxed:
        # above the rounding of the slack (≈ 1e-6)
        "duty_slack_tol": 1e-5,
        # relative margin of the attainability test: rounding of the
        # facet products (~ 10 eps); a demand this close to the boundary
        # goes to the solver, whose certificate then decides
        "duty_attain_tol": 1e-6,
        # the reduced duty QP is nearly an LP (Hessian 1e-4 I): DAQP's
        # dual form x = -R⁻¹(M'λ + v) with R⁻¹ = 100 I cancels terms
        # ~ 1e4 larger than x, and in float its point landed ~ 1e-3 off
        # its active rows (every certificate failed, 300 of 300 cycles;
        # its active set was wrong on 12). DAQP's proximal iterations
        # solve with the Hessian + eps_prox I, which ends the
        # cancellation: 3,000 of 3,000 cycles certified, duties 7e-8
        # from the double QP's (about 1,500 more instructions a call)
        "duty_daqp_eps_prox": 1.0,
    },
}


def check_precision(precision: str) -> str:
    """Return ``precision`` if it is one of `PRECISIONS`, else raise."""
    if precision not in PRECISIONS:
        raise InvalidValueError(
            f"precision must be one of {PRECISIONS}, got {precision!r}")
    return precision


def tolerances(precision: str = "double") -> dict[str, float]:
    """Return the tolerance table of ``precision`` (a copy)."""
    return dict(TOLERANCES[check_precision(precision)])


def c_real(precision: str = "double") -> str:
    """C type of ``casadi_real``: ``"double"`` or ``"float"``."""
    return "float" if check_precision(precision) == "single" else "double"


# comments, string and character literals (kept as they are), else code
_SKIP = re.compile(r'/\*.*?\*/|//[^\n]*|"(?:\\.|[^"\\\n])*"|'
                   r"'(?:\\.|[^'\\\n])*'", re.S)
# a decimal floating literal (with a point or an exponent) not already
# suffixed and not part of an identifier or of a longer number
_LITERAL = re.compile(
    r"(?<![\w.])((?:\d+\.\d*|\.\d+)(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)"
    r"(?![\w.])")
_MATH = re.compile(r"(?<![\w.>])(" + "|".join(MATH_FUNCTIONS)
                   + r")(\s*\()")
# ``double`` in code (the typedef is rewritten first): CasADi's DAQP
# runtime declares casadi_daqp_solve(..., const double** arg, ...)
_DOUBLE = re.compile(r"\bdouble\b")
# printf arguments that are casadi_real: qrqp's log prints d->f etc.
_PRINTF_REAL = re.compile(
    r"(printf\s*\([^;]*?\"\s*,)([^;]*?)(\)\s*;)", re.S)


def _float_literal(match: re.Match) -> str:
    text = match.group(1)
    value = abs(float(text))
    if value > _FLT_MAX:
        return FLOAT_MAX_LITERAL
    if 0.0 < value < _FLT_MIN:
        return FLOAT_MIN_LITERAL
    return text + "f"


def _code(text: str, rename_double: bool = True) -> str:
    # CasADi's DAQP runtime spells some casadi_real as double
    if rename_double:
        text = _DOUBLE.sub("casadi_real", text)
    text = _LITERAL.sub(_float_literal, text)
    return _MATH.sub(lambda m: m.group(1) + "f" + m.group(2), text)


def to_single(text: str) -> tuple[str, dict[str, int]]:
    """Turn CasADi C generated with ``casadi_real`` float into float code.

    Parameters
    ----------
    text : str
        The generated source (CodeGenerator option ``casadi_real:
        "float"``; a double typedef is rewritten to float too).

    Returns
    -------
    text : str
        The float source (comments and strings unchanged).
    counts : dict
        ``literals`` suffixed, ``clamped`` (literals mapped to
        `FLOAT_MAX_LITERAL` / `FLOAT_MIN_LITERAL`), ``math`` (calls
        renamed), ``double`` (``double`` declarations made
        ``casadi_real``: CasADi's DAQP runtime).
    """
    text = re.sub(r"#define casadi_real double\b", "#define casadi_real "
                  "float", text)
    counts = {"literals": 0, "clamped": 0, "math": 0,
              "double": len(_DOUBLE.findall(_SKIP.sub(" ", text)))}
    for m in _LITERAL.finditer(_SKIP.sub(" ", text)):
        v = abs(float(m.group(1)))
        counts["clamped" if v > _FLT_MAX or 0 < v < _FLT_MIN
               else "literals"] += 1
    counts["math"] = len(_MATH.findall(_SKIP.sub(" ", text)))
    out, pos = [], 0
    for m in _SKIP.finditer(text):
        out.append(_code(text[pos:m.start()]))
        out.append(m.group(0))
        pos = m.end()
    out.append(_code(text[pos:]))
    return _cast_printf("".join(out)), counts


def float_literals(text: str) -> str:
    """Float literals and float math in C code that is float already.

    What `to_single` does to literals and math calls, without touching
    ``double`` declarations: for DAQP's sources in its float build
    (``c_float`` float, but ``1e-12``, ``0.5*x`` and ``sqrt(x)`` in
    double), so that a single-precision FPU runs them without software
    double routines (`ocp.codegen.copy_daqp_sources`).
    """
    out, pos = [], 0
    for m in _SKIP.finditer(text):
        out.append(_code(text[pos:m.start()], rename_double=False))
        out.append(m.group(0))
        pos = m.end()
    out.append(_code(text[pos:], rename_double=False))
    return "".join(out)


def _cast_printf(text: str) -> str:
    """``(double)`` before printf arguments that are float expressions.

    CasADi's runtime prints ``casadi_real`` values with ``%g`` / ``%e``
    (qrqp's log); a variadic call promotes them to double, which
    ``-Wdouble-promotion`` reports. Integer arguments are left alone.
    """
    def cast(m: re.Match) -> str:
        fmt = m.group(1)
        spec = re.findall(r"%[-+ #0-9.]*(?:l|ll|z|h)?([a-zA-Z])",
                          fmt)
        args = _split_args(m.group(2))
        if len(spec) != len(args) or not any(s in "eEfgG" for s in spec):
            return m.group(0)
        new = [f"(double)({a.strip()})" if s in "eEfgG" and not
               a.strip().startswith("(double)") else a.strip()
               for s, a in zip(spec, args)]
        return m.group(1) + " " + ", ".join(new) + m.group(3)
    return _PRINTF_REAL.sub(cast, text)


def _split_args(args: str) -> list[str]:
    """Split a C argument list at top-level commas."""
    out, depth, cur = [], 0, ""
    for ch in args:
        if ch in "([":
            depth += 1
        elif ch in ")]":
            depth -= 1
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    out.append(cur)
    return out


def double_math_symbols(obj: str | Path, nm: str = "nm") -> list[str]:
    """Double math symbols (``sqrt``, ``sin`` …) an object references.

    Runs ``nm -u`` on ``obj`` and returns the undefined symbols that are
    in `MATH_FUNCTIONS` (the double variants): empty for float code.
    """
    run = subprocess.run([nm, "-u", str(obj)], capture_output=True,
                         text=True, check=True)
    names = {line.split()[-1].split("@")[0]
             for line in run.stdout.splitlines() if line.strip()}
    return sorted(names & set(MATH_FUNCTIONS))


# ------------------------------------------------ builders' options
def wheel_qp_options(precision: str = "double", plugin: str = "qrqp"
                     ) -> dict:
    """Keywords of `allocation.conic_allocator_function` for a precision."""
    tol = tolerances(precision)                 # checks the name too
    if precision == "double":
        return {}
    return {"margin": tol["wheel_margin"],
            "plugin_options": _conic_options(tol, plugin)}


def _conic_options(tol: dict, plugin: str) -> dict:
    """The conic's own stopping tolerances from a tolerance table."""
    if plugin == "qrqp":
        return {"constr_viol_tol": tol["qrqp_tol"],
                "dual_inf_tol": tol["qrqp_tol"]}
    return {"daqp": {"primal_tol": tol["daqp_primal_tol"]}}


def duty_qp_options(precision: str = "double", plugin: str = "qrqp"
                    ) -> dict:
    """Keywords of `thrusters.qp.certified.certified_duty_function`."""
    tol = tolerances(precision)                 # checks the name too
    if precision == "double":
        return {}
    opts = _conic_options(tol, plugin)
    if plugin == "daqp":
        opts["daqp"]["eps_prox"] = tol["duty_daqp_eps_prox"]
    return {"viol_tol": tol["duty_viol_tol"],
            "slack_tol": tol["duty_slack_tol"],
            "kkt_tol": tol["duty_kkt_tol"],
            "attain_tol": tol["duty_attain_tol"], "options": opts}


def condensed_options(precision: str = "double") -> dict:
    """``solver_options`` of a condensed `ocp.mpc.AttitudeMPC`."""
    tol = tolerances(precision)
    if precision == "double":
        return {}
    return {"step_tol": tol["step_tol"], "row_tol": tol["row_tol"],
            "qp_tol": tol["qrqp_tol"], "kkt_tol": tol["qp_kkt_tol"]}


def stagewise_options(precision: str = "double") -> dict:
    """``solver_options`` of a stage-wise `ocp.mpc.AttitudeMPC` (its
    QP's certificate threshold and SQP step tolerance; rqp's own step
    tolerance follows the C type, `ocp.mpc.riccati_qp.RQP_TOL`)."""
    tol = tolerances(precision)
    if precision == "double":
        return {}
    return {"step_tol": tol["step_tol"], "kkt_tol": tol["qp_kkt_tol"]}


#: MPC variants a single-precision export writes: the condensed RTI step
#: with DAQP's float build (`DAQP_SINGLE_FLAG`) and the float ``row_tol``,
#: ``step_tol`` of `TOLERANCES`, and the stage-wise RTI step with rqp (an
#: active set: its float tolerances are `ocp.mpc.riccati_qp.RQP_TOL` and
#: ``qp_kkt_tol``). Not the sqpmethod steps (their tolerances, tol_pr
#: 1e-9 and tol_du 1e-7, are not reachable in float), nor
#: ``mpc_cond_step``: its float closed loop (host driver) turns NaN, nor
#: the stage-wise interior point (its ``ipm_tol`` 1e-9).
SINGLE_MPC_VARIANTS: tuple[str, ...] = ("mpc_cond_rti_step",
                                        "mpc_sw_rti_step")

#: The define that makes DAQP's ``c_float`` a float (``daqp/types.h``):
#: every object of a single-precision export that calls DAQP is compiled
#: with it (the export's Makefile, CMakeLists.txt, host and target builds;
#: the ``daqp/types.h`` copied into such an export also defines it).
DAQP_SINGLE_FLAG = "-DDAQP_SINGLE_PRECISION"


def check_single(precision: str, plugins: dict, variants) -> None:
    """Refuse what a single-precision export does not support.

    MPC steps: only `SINGLE_MPC_VARIANTS` (sqpmethod's tolerances are
    not reachable in float), the condensed one with DAQP (qrqp fails its
    certificate, in double already), the stage-wise one with rqp (the
    interior point's tolerance is not reachable in float).
    """
    if check_precision(precision) == "double":
        return
    bad = [v for v in variants if v not in SINGLE_MPC_VARIANTS]
    if bad:
        raise InvalidValueError(
            f"precision='single' exports only {SINGLE_MPC_VARIANTS}; got "
            f"{bad} (sqpmethod's tolerances are not reachable in float)")
    if "mpc_cond_rti_step" in variants and \
            plugins.get("condensed_qp_plugin") == "qrqp":
        raise InvalidValueError(
            "precision='single' MPC steps need DAQP: qrqp fails the "
            "condensed QP's certificate")
    if "mpc_sw_rti_step" in variants and \
            plugins.get("stagewise_qp_plugin") != "rqp":
        raise InvalidValueError(
            "precision='single' exports mpc_sw_rti_step with "
            "stagewise_qp_plugin='rqp' only: the interior point's "
            "tolerance (1e-9) is not reachable in float")


#: What the README of a single-precision export says.
README_SINGLE = """
## Single precision

Exported with `precision="single"` (`adcs export --precision single`):
`casadi_real` is `float`, every literal is a float literal (`1.5f`;
double constants beyond float's range are mapped to `FLT_MAX` or
`FLT_MIN`) and the math calls are the float ones (`sqrtf`, `fabsf`,
`fminf`, …; `nm -u adcs_codegen.o` lists no double math symbol), so a
single-precision FPU (Cortex-M4F) runs it without software double
routines. The QPs use tolerances chosen for float
(`ocp.codegen.precision.TOLERANCES`). DAQP (in `daqp/`, for
`wheel_qp`, `duty_qp` and the MPC step) is its single-precision build:
`daqp/types.h` here defines `DAQP_SINGLE_PRECISION` (`c_float` is
`float`) and the Makefile and CMakeLists.txt pass
`-DDAQP_SINGLE_PRECISION` too; a build of your own must not undefine
it. The MPC step is the condensed RTI step (`mpc_cond_rti_step`) with
float tolerances (row test 1e-6, step 1e-5); check its `qp_kkt` against
1e-4 rather than 1e-6, and its `first_violation` against 1e-4 (scaled;
4.7e-5 measured over the driver's closed loop of 80 steps, 1e-13 in
double; the driver fails its check above 1e-4, `ocp.codegen.checks`).
The stage-wise RTI step (`mpc_sw_rti_step`) is exported in float with
rqp only (`--stagewise-qp rqp`): rqp.c is compiled with
`RQP_SINGLE_PRECISION` (its step and sign tolerance 1e-4 in box widths,
its rank and bound tests 1e-5) and the step's `qp_kkt` threshold is
1e-4 too; the interior point's tolerance is not reachable in float.
The QP outputs equal the double export's within float rounding: check
`violation` against 1e-5 (scaled) rather than 1e-6. Build with
`-Wdouble-promotion` to see any double left.
"""


_QRQP_ABORT = """  if (d.status == QP_SUCCESS) {;
    return 0;
  } else if (d.status == QP_NO_SEARCH_DIR) {
    return 4;
  } else {
    return -1;
  }"""
_QRQP_CHECKED = """  /* the caller checks the point (violation, KKT): a failed
   * solve returns it, as the Functions with error_on_fail=False do in
   * Python (ocp.codegen.precision.patch_qrqp_failure) */
  return 0;"""


def patch_qrqp_failure(source: str) -> tuple[str, int]:
    """Let generated qrqp conics return their point when a solve fails.

    The qrqp analogue of `ocp.codegen.patch_daqp_failure`: a failed qrqp
    solve (iteration limit, no search direction) would return nonzero
    from the whole call and leave its outputs unwritten; every caller of
    the toolbox checks the point itself (``wheel_qp``'s violation,
    ``duty_qp``'s certificate and status, the condensed MPC's ``qp_kkt``
    and ``violation``). A single-precision export, whose conics are all
    qrqp, applies it. Returns the text and the number of conics edited.
    """
    count = source.count(_QRQP_ABORT)
    return source.replace(_QRQP_ABORT, _QRQP_CHECKED), count
