"""Closed-loop runs of the MPC and its comparison with the closed forms."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, TYPE_CHECKING
import numpy as np
from numpy.typing import ArrayLike
from adcs_common.results import ResultMixin
from adcs_common.exceptions import (
    InvalidValueError,
)
from adcs_common.validation import (
    as_finite_scalar,
    as_vector,
    check_positive,
    check_items,
)
from ocp.models.rigid import SpacecraftModel
from ocp.models.trajectory import SlewTrajectory
from .controller import AttitudeMPC, MPCWeights

if TYPE_CHECKING:
    import pandas as pd


__all__ = [
    "ClosedLoopResult",
    "closed_loop_table",
    "compare_slew",
    "keep_out_margin",
    "settle_time",
    "simulate_mpc",
]


# ---------------------------------------------------------------- closed loop
@dataclass(frozen=True, eq=False, repr=False)
class ClosedLoopResult(ResultMixin):
    """Metrics of a simulated slew-and-hold (or of an open-loop NLP).

    Attributes
    ----------
    name : str
        Controller label.
    trajectory : SlewTrajectory
        The simulated trajectory (plant integrated by CVODES).
    settle_time : float
        First time after which the error angle stays below
        ``settle_angle`` [s] (NaN: never).
    settle_angle : float
        Threshold of ``settle_time`` [rad].
    energy : float
        :math:`\\sum_i\\int m_i^2 dt` [N²·m²·s].
    peak_torque : float
        Largest ``|m_i|`` [N·m].
    peak_momentum : float
        Largest ``|H_i|`` [N·m·s].
    torque_violation : float
        Largest excess of ``|m_i|`` over ``m_max_i`` [N·m] (0: none).
    momentum_violation : float
        Largest excess of ``|H_i|`` over ``h_max_i`` [N·m·s] (0: none).
    final_error : float
        Error angle at the end [rad].
    hold_error : float
        Largest error angle over the last ``hold`` seconds [rad].
    step_time_median, step_time_max : float
        Per-step controller time [s] (NaN for closed forms).
    extras : dict
        Anything else (solver status counts, NLP solve time...).
    hold : float
        Length of the final window of ``hold_error`` [s] (0: the last
        sample only, so ``hold_error`` is ``final_error``).

    Notes
    -----
    `settled` is the one verdict the reports use: the error stays below
    ``settle_angle`` from ``settle_time`` to the end *and* over the whole
    hold window (``hold_error < settle_angle``). A run that enters the
    band only inside the hold window has a finite ``settle_time`` but a
    hold error above the band: it has not settled.
    """

    name: str
    trajectory: SlewTrajectory
    settle_time: float
    settle_angle: float
    energy: float
    peak_torque: float
    peak_momentum: float
    torque_violation: float
    momentum_violation: float
    final_error: float
    hold_error: float
    step_time_median: float = float("nan")
    step_time_max: float = float("nan")
    extras: dict[str, Any] = field(default_factory=dict)
    hold: float = 0.0

    @property
    def settled(self) -> bool:
        """Whether the run settled (see Notes of the class).

        True when ``settle_time`` is finite and ``hold_error <
        settle_angle``: within the band from ``settle_time`` on and over
        the whole hold window.
        """
        return bool(np.isfinite(self.settle_time)
                    and self.hold_error < self.settle_angle)


def settle_time(t: np.ndarray, err: np.ndarray, angle: float) -> float:
    """First sample time from which ``err`` (K,) [rad] stays below
    ``angle`` [rad] to the end of ``t`` (K,) [s]; NaN if the last sample
    is not below it (`ClosedLoopResult.settle_time`)."""
    outside = np.flatnonzero(err >= angle)
    if len(outside) == 0:
        return 0.0
    if outside[-1] < len(t) - 1:
        return float(t[outside[-1] + 1])
    return float("nan")


def _result_from_trajectory(name: str, traj: SlewTrajectory, wheels,
                            settle_angle: float, hold: float,
                            step_times=None, extras=None
                            ) -> ClosedLoopResult:
    err = traj.error_angle()
    m = traj.wheel_torque
    h = traj.wheel_momentum
    tv = float(np.max(np.abs(m) - wheels.m_max)) if m is not None else 0.0
    hv = float(np.max(np.abs(h) - wheels.h_max)) if h is not None else 0.0
    in_hold = traj.t >= traj.t[-1] - hold - 1e-12
    st = np.asarray(step_times if step_times is not None else [np.nan])
    return ClosedLoopResult(
        name=name, trajectory=traj,
        settle_time=settle_time(traj.t, err, settle_angle),
        settle_angle=settle_angle, energy=traj.energy,
        peak_torque=traj.peak_wheel_torque,
        peak_momentum=traj.peak_wheel_momentum,
        torque_violation=max(tv, 0.0), momentum_violation=max(hv, 0.0),
        final_error=float(err[-1]), hold_error=float(np.max(err[in_hold])),
        step_time_median=float(np.median(st)),
        step_time_max=float(np.max(st)), extras=dict(extras or {}),
        hold=float(hold))


def simulate_mpc(mpc: AttitudeMPC, q0: ArrayLike, qf: ArrayLike, *,
                 t_final: float, w0: ArrayLike | None = None,
                 h0: ArrayLike | None = None,
                 disturbance: Callable[[float], Any] | Any = None,
                 estimate_disturbance: bool = False,
                 settle_angle: float = np.deg2rad(0.1), hold: float = 0.0,
                 progress: Callable[[int, int], None] | None = None,
                 plant: SpacecraftModel | None = None
                 ) -> ClosedLoopResult:
    """Closed-loop simulation of ``mpc`` on the plant (CVODES, ZOH).

    Each sample the controller gets the exact plant state, the command is
    held over ``mpc.dt`` and the plant (the model's dynamics with the
    disturbance torque) is integrated by CVODES to 1e-10.

    Parameters
    ----------
    mpc : AttitudeMPC
        The controller (its warm start is reset first).
    q0, qf : array_like (4,)
        Initial and target attitude (scalar-first).
    t_final : float
        Simulated time [s].
    w0 : array_like (3,), optional
        Initial body rate [rad/s] (default zero).
    h0 : array_like (N,), optional
        Initial wheel momenta [N·m·s] (default zero).
    disturbance : callable or array_like (3,), optional
        External torque on the body [N·m], constant or ``f(t) -> (3,)``.
    estimate_disturbance : bool
        Give the controller the true disturbance at each sample (an ideal
        estimator); otherwise it plans with zero disturbance.
    settle_angle : float
        Threshold of the settling time [rad].
    hold : float
        Length of the final hold window of ``hold_error`` [s].
    progress : callable, optional
        ``progress(k, K)`` after each step.
    plant : SpacecraftModel, optional
        The craft flown, when it is not the one the MPC plans with (a
        Monte Carlo draw of inertia or misalignment; the same states and
        controls as ``mpc.model``). Default: ``mpc.model``.

    Returns
    -------
    ClosedLoopResult
    """
    model = mpc.model
    if plant is not None:
        if not isinstance(plant, SpacecraftModel) or (
                plant.nx, plant.nu) != (model.nx, model.nu):
            raise InvalidValueError(
                "plant must be a SpacecraftModel with the MPC model's "
                f"states and controls ({model.nx}, {model.nu})")
    t_final = as_finite_scalar(t_final, "t_final")
    check_positive(t_final, "t_final")
    x = model.state(q0, w0, h0)
    qf = as_vector(qf, 4, "qf")
    qf = qf / np.linalg.norm(qf)
    if disturbance is None:
        def dist(_t):
            return np.zeros(3)
    elif callable(disturbance):
        def dist(t):
            return as_vector(disturbance(t), 3, "disturbance")
    else:
        d = as_vector(disturbance, 3, "disturbance")

        def dist(_t):
            return d
    K = int(np.ceil(t_final / mpc.dt - 1e-9))
    F = (plant or model).integrator(mpc.dt)
    X = np.empty((K + 1, model.nx))
    U = np.empty((K, model.nu))
    X[0] = x
    times, calls, iters = [], [], []
    statuses: dict[str, int] = {}
    mpc.reset()
    for k in range(K):
        tk = k * mpc.dt
        tau = dist(tk)
        t0 = time.perf_counter()
        s = mpc.step(X[k], qf, tau if estimate_disturbance else None)
        calls.append(time.perf_counter() - t0)
        times.append(s.solve_time)
        iters.append(s.iterations)
        statuses[s.status] = statuses.get(s.status, 0) + 1
        U[k] = s.u
        xf = F(x0=X[k], p=np.r_[s.u, tau])["xf"]
        X[k + 1] = np.asarray(xf).ravel()
        if progress is not None:
            progress(k + 1, K)
    t = mpc.dt * np.arange(K + 1)
    nw = model.n_wheels
    extras: dict[str, Any] = {"solver": mpc.name, "horizon": mpc.horizon,
                              "dt": mpc.dt}
    loop = {"statuses": statuses, "mean_iterations": float(np.mean(iters)),
            # wall time of the whole `step` call (checks included) [s]
            "step_call_median": float(np.median(calls)),
            "step_call_max": float(np.max(calls))}
    if model.thrusters is not None:
        duty = U[:, nw:]
        extras["duty"] = duty
        loop["propellant"] = float(np.sum(
            duty @ model.thrusters.propellant_rate()) * mpc.dt)
        loop["thruster_on_time"] = float(np.sum(duty) * mpc.dt)
    traj = SlewTrajectory(
        method="mpc", T=float("nan"), t=t, q=X[:, :4], w=X[:, 4:7],
        torque=model.body_control_torque(U.T).T, wheel_torque=U[:, :nw],
        wheel_momentum=X[:, 7:], qf=qf, status="simulated", success=True,
        solve_time=float(np.sum(times)), iterations=int(np.sum(iters)),
        extras=extras)
    return _result_from_trajectory(
        f"MPC {mpc.name}", traj, mpc.wheels, settle_angle, hold, times,
        loop)


def keep_out_margin(result: ClosedLoopResult, keep_out: Any,
                    plant: SpacecraftModel, substeps: int = 8,
                    disturbance: ArrayLike | None = None) -> float:
    """Smallest angle [rad] of a closed loop's path from its keep-out cones.

    The path between the samples of ``result`` (`simulate_mpc`) is
    integrated again on ``plant`` (the plant the loop flew, CVODES) with
    each sample's command held, at ``substeps`` points per sample; the
    margin is `ocp.KeepOut.margin`'s over those points and the samples
    (negative: the boresight entered a cone). ``disturbance`` (3,) [N·m]
    is the constant torque the loop flew with (default none).
    """
    from .keepout import as_keep_out, smallest_cone_margin

    cones = as_keep_out(keep_out)
    if not cones:
        raise InvalidValueError("keep_out names no cone")
    if not isinstance(result, ClosedLoopResult):
        raise InvalidValueError(
            f"result must be a ClosedLoopResult, got {type(result).__name__}")
    if not isinstance(plant, SpacecraftModel):
        raise InvalidValueError(
            f"plant must be a SpacecraftModel, got {type(plant).__name__}")
    if isinstance(substeps, bool) or not isinstance(
            substeps, (int, np.integer)) or substeps < 1:
        raise InvalidValueError(
            f"substeps must be a positive int, got {substeps!r}")
    tau = np.zeros(3) if disturbance is None else as_vector(
        disturbance, 3, "disturbance")
    tr = result.trajectory
    if tr.wheel_torque is None or tr.wheel_momentum is None:
        raise InvalidValueError("keep_out_margin needs a wheeled loop")
    U = np.asarray(tr.wheel_torque, dtype=float)
    if "duty" in tr.extras:
        U = np.c_[U, tr.extras["duty"]]
    if U.shape[1] != plant.nu or len(tr.t) < 2:
        raise InvalidValueError(
            "plant must have the loop's controls, and the loop a sample")
    F = plant.integrator(float(tr.t[1] - tr.t[0]) / int(substeps))
    X = np.c_[tr.q, tr.w, tr.wheel_momentum]
    qs = [tr.q]
    for k in range(len(U)):
        x = X[k]
        for _ in range(int(substeps) - 1):
            x = np.asarray(F(x0=x, p=np.r_[U[k], tau])["xf"]).ravel()
            qs.append(x[None, :4])
    q = np.concatenate(qs)
    return smallest_cone_margin(cones, q)


def compare_slew(model: SpacecraftModel, q0: ArrayLike, qf: ArrayLike, *,
                 t_final: float,
                 solvers: Any = ("sqpmethod", "sqpmethod-rti", "ipopt"),
                 horizon: int = 20, dt: float = 0.5,
                 weights: MPCWeights | None = None,
                 natural_frequency: float | None = None,
                 damping: float = 0.9, time_optimal: bool = True,
                 settle_angle: float = np.deg2rad(0.1), hold: float = 0.0,
                 disturbance: Any | None = None) -> list[ClosedLoopResult]:
    """Slew and hold by MPC, quaternion feedback and the time-optimal NLP.

    Parameters
    ----------
    model : SpacecraftModel
        Spacecraft with wheels.
    q0, qf : array_like (4,)
        Initial and target attitude.
    t_final : float
        Simulated time [s] (the slew and the hold after it).
    solvers : sequence of str
        MPC solvers; ``"sqpmethod-rti"`` is sqpmethod with ``rti=True``,
        ``"sqpmethod-daqp"`` sqpmethod with daqp.
    horizon, dt, weights
        MPC settings.
    natural_frequency : float, optional
        ω_n of the quaternion feedback [rad/s]; default ``4 / T_eig``
        with ``T_eig`` the eigenaxis (bang–coast–bang) slew time.
    damping : float
        ζ of the quaternion feedback.
    time_optimal : bool
        Add the time-optimal NLP (`ocp.slews.nlp.time_optimal_slew`) when that
        module is installed; its metrics are those of the open-loop plan.
    settle_angle, hold, disturbance
        As `simulate_mpc` (the disturbance acts on the MPC runs only: the
        closed forms are simulated without one).

    Returns
    -------
    list of ClosedLoopResult
    """
    from ocp.guidance import eigenaxis_slew, quaternion_feedback_slew

    wh = model.wheels
    if wh is None:
        raise InvalidValueError("model must have wheels")
    results = []
    for name in solvers:
        solver, _, variant = name.partition("-")
        kw: dict[str, Any] = {}
        if variant == "rti":
            kw["rti"] = True
        elif variant:
            kw["qp_solver"] = variant
        mpc = AttitudeMPC(model, horizon=horizon, dt=dt, solver=solver,
                          weights=weights, **kw)
        results.append(simulate_mpc(mpc, q0, qf, t_final=t_final,
                                    settle_angle=settle_angle, hold=hold,
                                    disturbance=disturbance))
    eig = eigenaxis_slew(model.inertia, q0, qf, wheels=wh)
    wn = (natural_frequency if natural_frequency is not None
          else 4.0 / max(eig.T, 1e-9))
    fb = quaternion_feedback_slew(
        model.inertia, q0, qf, wheels=wh, natural_frequency=wn,
        damping=damping, t_final=t_final, dt=dt, settle_angle=settle_angle)
    results.append(_result_from_trajectory(
        f"quaternion feedback (ω_n={wn:.3g})", fb, wh, settle_angle, hold))
    if time_optimal:
        slew: Callable[..., Any] | None
        try:
            from ocp.slews.nlp import time_optimal_slew as slew
        except ImportError:
            slew = None
        if slew is not None:
            t0 = time.perf_counter()
            to = slew(model.inertia, q0, qf, wheels=wh, N=100)
            results.append(_result_from_trajectory(
                "time-optimal NLP (open loop)", to, wh, settle_angle, 0.0,
                extras={"solve_time": time.perf_counter() - t0,
                        "T": to.T}))
    return results


def closed_loop_table(results: Any) -> str:
    """Markdown table of `ClosedLoopResult` metrics.

    Columns: settle time [s] ('not settled' unless
    `ClosedLoopResult.settled`), energy [N²·m²·s], peak ``|m|`` [N·m],
    peak ``|H|`` [N·m·s], torque and momentum violations, final and hold
    errors [deg], median / max step time [ms].
    """
    head = ("| controller | settle [s] | energy [N²m²s] | peak abs(m) [Nm] "
            "| peak abs(H) [Nms] | m viol. | H viol. | final err [deg] | "
            "hold err [deg] | step median / max [ms] |")
    lines = [head, "|" + "---|" * 10]
    for r in results:
        st = ("–" if not np.isfinite(r.step_time_median) else
              f"{1e3 * r.step_time_median:.2f} / "
              f"{1e3 * r.step_time_max:.2f}")
        lines.append(
            f"| {r.name} | "
            f"{f'{r.settle_time:.1f}' if r.settled else 'not settled'} | "
            f"{r.energy:.4g} | "
            f"{r.peak_torque:.4g} | {r.peak_momentum:.4g} | "
            f"{r.torque_violation:.1e} | {r.momentum_violation:.1e} | "
            f"{np.rad2deg(r.final_error):.2e} | "
            f"{np.rad2deg(r.hold_error):.2e} | {st} |")
    return "\n".join(lines)


def closed_loop_frame(results: Any) -> pd.DataFrame:
    """`ClosedLoopResult` metrics as a `pandas.DataFrame` (SI, radians)."""
    import pandas as pd

    results = check_items(results, ClosedLoopResult, "results")
    return pd.DataFrame([{
        "controller": r.name, "settle_time": r.settle_time,
        "settled": r.settled,
        "energy": r.energy, "peak_torque": r.peak_torque,
        "peak_momentum": r.peak_momentum,
        "torque_violation": r.torque_violation,
        "momentum_violation": r.momentum_violation,
        "final_error": r.final_error, "hold_error": r.hold_error,
        "step_time_median": r.step_time_median,
        "step_time_max": r.step_time_max} for r in results])
