"""CasADi ``conic`` backend, wrapped as one Function of the parameters."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..problem import INF, DutyCycleQP

#: Options set per plugin (printing off, no exception on failure: the
#: allocator checks residuals itself, since qrqp can report success on a
#: violated point, SOLVER_NOTES).
DEFAULTS = {
    "qrqp": {"print_iter": False, "print_header": False,
             "print_info": False, "error_on_fail": False},

    "osqp": {"osqp": {"eps_abs": 1e-6, "eps_rel": 1e-6, "polishing": True,
                      "max_iter": 20000, "verbose": False},
             "error_on_fail": False},
}


def _inf(v: np.ndarray) -> np.ndarray:
    out = v.astype(float).copy()
    out[out >= INF / 2] = np.inf
    out[out <= -INF / 2] = -np.inf
    return out


def conic_function(qp: DutyCycleQP, plugin: str,
                   options: dict | None = None) -> ca.Function:
    """``duty_qp(theta[9], kmax[n]) -> (x[n+1], violation)``, casadi.

    ``q, l, u`` are formed from ``theta`` inside the Function, so one call
    (or one `casadi.Function.buffer` trigger, or generated C) solves a
    cycle; ``kmax`` are the variables' upper bounds (ones at the build
    pressure); ``violation`` is the largest constraint violation of ``x``.
    """
    opts = {**DEFAULTS.get(plugin, {"error_on_fail": False}),
            **(options or {})}
    H = ca.DM(qp.P)
    Asp = ca.DM(qp.A)
    solver = ca.conic("duty_conic", plugin,
                      {"h": H.sparsity(), "a": Asp.sparsity()}, opts)
    theta = ca.MX.sym("theta", qp.Lm.shape[1])
    q = ca.DM(qp.q0) + ca.DM(qp.Q) @ theta
    l = ca.DM(_inf(qp.l0)) + ca.DM(qp.Lm) @ theta
    u = ca.DM(_inf(qp.u0)) + ca.DM(qp.Um) @ theta
    n = qp.nx - 1
    kmax = ca.MX.sym("kmax", n)
    lbx = ca.DM(qp.lb)
    ubx = ca.vertcat(kmax, ca.DM(qp.ub[n]))
    sol = solver(h=H, g=q, a=Asp, lba=l, uba=u, lbx=lbx, ubx=ubx)
    x = sol["x"]
    Ax = Asp @ x
    viol = ca.mmax(ca.vertcat(ca.fmax(l - Ax, 0), ca.fmax(Ax - u, 0),
                              ca.fmax(lbx - x, 0), ca.fmax(x - ubx, 0)))
    return ca.Function("duty_qp", [theta, kmax], [x, viol],
                       ["theta", "kmax"], ["x", "violation"])


class Backend:
    """CasADi conic called through ``Function.buffer()`` (no conversion)."""

    def __init__(self, qp: DutyCycleQP, plugin: str, options: dict) -> None:
        self.qp = qp
        self.function = conic_function(qp, plugin, options)
        self._bind()

    def _bind(self) -> None:
        """Bind numpy work arrays to the Function's buffer."""
        qp = self.qp
        self._theta = np.zeros(qp.Lm.shape[1])
        self._kmax = np.array(qp.ub[:-1], dtype=float)
        self._x = np.zeros(qp.nx)
        self._viol = np.zeros(1)
        self._buf, self._trigger = self.function.buffer()
        self._buf.set_arg(0, memoryview(self._theta))
        self._buf.set_arg(1, memoryview(self._kmax))
        self._buf.set_res(0, memoryview(self._x))
        self._buf.set_res(1, memoryview(self._viol))

    def set_upper(self, ub: np.ndarray) -> None:
        """Change the duties' upper bounds for the next solves."""
        self._kmax[:] = ub[:-1]

    def solve(self, theta: np.ndarray):
        """Return ``(x, status, violation)``; residuals decide success."""
        self._theta[:] = theta
        # a failed evaluation (generated C returns an error code) leaves
        # the outputs untouched: NaN marks it instead of a stale point
        self._viol[0] = np.nan
        self._trigger()
        x = self._x.copy()
        viol = float(self._viol[0])
        if not np.isfinite(viol):
            return None, "failed", None
        return x, "solved", viol


def compiler() -> str | None:
    """A C compiler on PATH (``cc``, ``gcc`` or ``clang``), or None."""
    import shutil

    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


class CodegenBackend(Backend):
    """The conic Function exported to C, compiled, loaded as external.

    ``casadi.Function.generate`` writes self-contained C for code-
    generatable plugins (qrqp); it is compiled once with the system C
    compiler (``-O2 -shared -fPIC``) in a temporary folder (removed once
    the library is loaded) and called through ``Function.buffer()``.
    """

    def __init__(self, qp: DutyCycleQP, plugin: str, options: dict) -> None:
        import os
        import subprocess
        import tempfile

        self.qp = qp
        fn = conic_function(qp, plugin, options)
        folder = tempfile.mkdtemp(prefix="thrusters_qp_")
        cwd = os.getcwd()
        try:
            os.chdir(folder)
            fn.generate("duty_qp.c")
        finally:
            os.chdir(cwd)
        src = os.path.join(folder, "duty_qp.c")
        lib = os.path.join(folder, "duty_qp.so")
        subprocess.run([compiler(), "-O2", "-shared", "-fPIC", src, "-o",
                        lib, "-lm"], check=True, capture_output=True)
        self.function = ca.external("duty_qp", lib)
        self._bind()
        # the library is loaded (dlopen): the temporary folder can go
        import shutil

        shutil.rmtree(folder, ignore_errors=True)
