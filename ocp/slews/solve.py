"""Solving a slew NLP: start points, coarse start, bounds, verification."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from adcs_common.exceptions import (
    InvalidValueError,
    SolverError,
)
from adcs_common.quaternion import (
    quat_conj,
    quat_mul,
)
from ocp.models.rigid import (
    SpacecraftModel,
)
from ocp.models.trajectory import SlewTrajectory
from .build import (
    BuiltSolver,
    SOLVER_CACHE,
    SOLVER_CACHE_SIZE,
    build_solver,
    jit_settings,
    options_key,
    slew_data,
)
from adcs_common.options import merge_options

from .keepout import path_margin
from .setup import SlewSetup, initial_guess_states
from .solvers import (
    COARSE_OPTIONS,
    WARM_START_OPTIONS,
    solver_entry,
    with_user_options,
)
from .transcription import (
    Layout,
    transcription_named,
    SLEW_PARAMETERS,
    param_sizes,
    split_parameters,
)


#: Largest final attitude error [rad] of the controls simulated on the
#: plant (CVODES) for a slew to count as a success (0.057°).
VERIFY_TOL = 1e-3


@dataclass(frozen=True, eq=False)
class PreparedSolve:
    """A built solver with the numeric inputs of one slew."""

    built: BuiltSolver
    cached: bool
    p: np.ndarray
    lbw: np.ndarray
    ubw: np.ndarray
    ubg: np.ndarray
    xs: np.ndarray


def prepare_solve(s: SlewSetup, *, solver: str, N: int, T_fixed: float | None,
                  transcription: str, expand: bool, substeps: int,
                  opts: dict, jit_cfg: dict | None) -> PreparedSolve:
    """Fetch (or build) the solver and set the numeric inputs."""
    plugin, _ = solver_entry(solver)
    model = s.model
    nx, nw = model.nx, model.n_wheels
    tr = transcription_named(transcription, substeps)
    free_T = T_fixed is None
    T_ref = s.T_eig if T_fixed is None else float(T_fixed)
    x0 = np.r_[s.q0, np.zeros(3), s.h0]
    xs = np.r_[np.ones(4), s.w_scale * np.ones(3),
               s.h_max if s.h_max is not None else np.zeros(0)]
    values = slew_data(s, T_ref, x0)
    sizes = param_sizes(nx, model.nu, nw, len(s.keep_out))
    # compiled: every entry is a parameter (one library per shape);
    # otherwise the spacecraft data are folded into the SX graph
    symbolic = tuple(sizes) if jit_cfg else SLEW_PARAMETERS
    folded = np.concatenate([np.zeros(0)] + [
        v for k, v in split_parameters(values, sizes).items()
        if k not in symbolic])
    okey = options_key(opts)
    key = (solver, transcription, N, nx, model.nu, nw, substeps, free_T,
           s.rate_max is not None, len(s.keep_out), bool(expand),
           options_key(jit_cfg),
           okey, folded.tobytes())
    built = SOLVER_CACHE.get(key) if okey is not None else None
    cached = built is not None
    if built is None:
        built = build_solver(s, plugin=plugin, opts=opts, N=N,
                             free_T=free_T, transcription=tr, expand=expand,
                             symbolic=symbolic, values=values, jit=jit_cfg)
        if okey is not None:
            while len(SOLVER_CACHE) >= SOLVER_CACHE_SIZE:
                SOLVER_CACHE.pop(next(iter(SOLVER_CACHE)))
            SOLVER_CACHE[key] = built
    p = np.concatenate([v for k, v in split_parameters(values, sizes).items()
                        if k in symbolic])
    ubg = built.ubg.copy()
    if s.rate_max is not None:
        ubg[built.rate_rows] = (s.rate_max / s.w_scale) ** 2
    lbw, ubw = _bounds(s, built.lay, N, xs, x0,
                       fix=plugin != "fatrop")
    return PreparedSolve(built, cached, p, lbw, ubw, ubg, xs)


def run_solver(prep: PreparedSolve, solver: str,
               w0: np.ndarray) -> tuple[dict, dict, float]:
    """Solve; return (solution as arrays, stats, wall time [s])."""
    S = prep.built.solver
    args = dict(x0=w0, p=prep.p, lbx=prep.lbw, ubx=prep.ubw,
                lbg=prep.built.lbg, ubg=prep.ubg)
    t0 = time.perf_counter()
    try:
        sol = S(**args)
    except RuntimeError as exc:
        raise SolverError(f"solver {solver!r} failed with an error: "
                          f"{str(exc).strip().splitlines()[-1]}",
                          solver=solver) from exc
    solve_time = time.perf_counter() - t0
    sol = {k: np.asarray(v).ravel() for k, v in sol.items()}
    return sol, S.stats(), solve_time


def _coarse_N(N: int) -> int | None:
    """Intervals of the coarse solve for ``initial_guess="coarse"``.

    The divisor of N nearest N/5 within [N/8, N/3] (its piecewise-
    constant controls are then exactly representable on N intervals),
    else round(N/5); None when that is under 6 intervals (then the
    perturbed eigenaxis guess is used directly).
    """
    divs = [n for n in range(max(1, N // 8), N // 3 + 1)
            if N % n == 0 and 8 * n >= N]
    Nc = (min(divs, key=lambda n: abs(5 * n - N)) if divs
          else int(round(N / 5)))
    return Nc if Nc >= 6 else None


def _refined_start(s: SlewSetup, coarse: PreparedSolve, sol: dict,
                   fine: PreparedSolve, N: int, T_fixed: float | None,
                   substeps: int) -> np.ndarray:
    """Scaled guess w0 on N intervals from a coarse solution.

    Controls are held over the fine grid and the states simulated by the
    RK4 of the NLP, so the guess satisfies the continuity rows.
    """
    lc, lf = coarse.built.lay, fine.built.lay
    Nc = lc.iU.shape[1]
    j = np.minimum((np.arange(N) * Nc) // N, Nc - 1)  # coarse interval
    Un = sol["x"][lc.iU][:, j]
    T = (float(sol["x"][lc.iT[0]] * s.T_eig) if T_fixed is None
         else T_fixed)
    U = Un * s.u_max[:, None]
    X = np.empty((s.model.nx, N + 1))
    X[:, 0] = np.r_[s.q0, np.zeros(3), s.h0]
    step = s.model.rk4_step(substeps)  # the shooting step of the NLP
    for k in range(N):
        X[:, k + 1] = np.asarray(step(X[:, k], U[:, k], np.zeros(3),
                                      T / N)).ravel()
    w0 = np.zeros(lf.n)
    w0[lf.iX] = X / fine.xs[:, None]
    w0[lf.iU] = Un
    if lf.iXc.size:  # collocation states: interval midpoints
        d = lf.iXc.shape[1] // N
        mid = 0.5 * (w0[lf.iX][:, :-1] + w0[lf.iX][:, 1:])
        w0[lf.iXc] = np.repeat(mid, d, axis=1)
    if lf.iT.size:
        w0[lf.iT] = sol["x"][lc.iT[0]]
    return w0


def _guess_label(initial_guess: str, Nc: int | None,
                 perturbation: float) -> str:
    """Name of the start actually used, for ``extras["initial_guess"]``."""
    if Nc is not None:
        return "coarse"
    if initial_guess in ("eigenaxis", "coarse"):
        return "perturbed_eigenaxis" if perturbation > 0 else "eigenaxis"
    return initial_guess


def solve_slew(s: SlewSetup, *, objective: str, T_fixed: float | None, N: int,
               transcription: str, solver: str, expand: bool, substeps: int,
               initial_guess: str, perturbation: float, seed: int,
               solver_options: dict | None, verify: bool,
               jit=False) -> SlewTrajectory:
    """Solve one slew NLP (coarse start, refine, verify)."""
    plugin, base_opts = solver_entry(solver)
    model = s.model
    nw = model.n_wheels
    if plugin == "fatrop" and transcription != "multiple_shooting":
        # its structure detection rejects the collocation rows
        raise InvalidValueError(
            "solver 'fatrop' takes transcription='multiple_shooting' only")
    jit_cfg = jit_settings(jit)
    free_T = T_fixed is None
    T_ref = s.T_eig if T_fixed is None else float(T_fixed)
    opts = with_user_options(base_opts, solver_options)
    common: dict[str, Any] = dict(
        solver=solver, T_fixed=T_fixed, transcription=transcription,
        expand=expand, substeps=substeps, jit_cfg=jit_cfg)
    coarse_info: dict = {}
    builds: list[PreparedSolve] = []
    Nc = _coarse_N(N) if initial_guess == "coarse" else None
    sol = None
    if Nc is not None:
        cprep = prepare_solve(s, N=Nc, opts=merge_options(
            opts, COARSE_OPTIONS.get(plugin, {})), **common)
        w0c = _initial_point(s, cprep.built.lay, Nc, cprep.xs, T_ref, free_T,
                             "eigenaxis" if free_T else "cubic",
                             perturbation, seed)
        csol, cstats, ctime = run_solver(cprep, solver, w0c)
        builds.append(cprep)
        coarse_info = {"coarse_N": Nc,
                       "coarse_iterations": int(cstats.get("iter_count", -1)),
                       "coarse_solve_time": ctime,
                       "coarse_status": _status(cstats)}
        if cstats.get("success", False):
            warm = with_user_options(merge_options(base_opts,
                                     WARM_START_OPTIONS.get(plugin, {})),
                              solver_options)
            prep = prepare_solve(s, N=N, opts=warm, **common)
            w0 = _refined_start(s, cprep, csol, prep, N, T_fixed, substeps)
            sol, stats, solve_time = run_solver(prep, solver, w0)
        else:  # start again from the perturbed guess (time included)
            Nc = None
    if sol is None:
        kind = "eigenaxis" if initial_guess == "coarse" else initial_guess
        prep = prepare_solve(s, N=N, opts=opts, **common)
        w0 = _initial_point(s, prep.built.lay, N, prep.xs, T_ref, free_T,
                            kind, perturbation, seed)
        sol, stats, solve_time = run_solver(prep, solver, w0)
    builds.append(prep)
    solve_time += coarse_info.get("coarse_solve_time", 0.0)
    lay, xs = prep.built.lay, prep.xs
    cached = all(b.cached for b in builds)
    build_time = sum(b.built.build_time for b in builds if not b.cached)
    x0 = np.r_[s.q0, np.zeros(3), s.h0]
    wopt = sol["x"]
    Xv = wopt[lay.iX] * xs[:, None]
    Uv = wopt[lay.iU] * s.u_max[:, None]
    Tv = float(wopt[lay.iT[0]] * s.T_eig) if free_T else T_ref
    t = np.linspace(0.0, Tv, N + 1)
    extras = {"objective": objective, "transcription": transcription,
              "solver": solver, "expand": bool(expand), "N": N,
              "jit": jit_cfg is not None, "cached": cached,
              "build_time": build_time,
              "solver_time": float(stats.get("t_wall_total", np.nan)),
              "eigenaxis_T": s.T_eig,
              "initial_guess": _guess_label(initial_guess, Nc,
                                            perturbation),
              "perturbation": perturbation,
              "nlp_objective": float(sol["f"][0]), **coarse_info}
    success, status = _verified(stats, verify and np.isfinite(Tv)
                                and Tv > 0, model, x0, t, Uv, s, extras)
    traj = SlewTrajectory(
        method="time_optimal" if free_T else "min_energy",
        T=Tv, t=t, q=Xv[:4].T, w=Xv[4:7].T,
        torque=model.body_control_torque(Uv).T,
        wheel_torque=Uv.T if nw else None,
        wheel_momentum=Xv[7:].T if nw else None, qf=s.qf,
        status=status, success=success,
        solve_time=solve_time,
        iterations=int(stats.get("iter_count", -1)), extras=extras)
    if s.keep_out:
        extras["keep_out_node_margin"] = float(min(
            np.min(k.margin(traj.q)) for k in s.keep_out))
    return traj


def _verified(stats: dict, verify: bool, model, x0, t, Uv, s: SlewSetup,
              extras: dict) -> tuple[bool, str]:
    """``(success, status)``: the solver's, and the simulated plant's.

    With ``verify`` the controls run on the plant (CVODES); a final
    attitude error beyond `VERIFY_TOL` makes the slew a failure whose
    status says by how much it missed.
    """
    success = bool(stats.get("success", False))
    status = _status(stats)
    if verify:
        verify_trajectory(model, x0, t, Uv, s.qf, extras, s.keep_out)
        err = extras["simulated_final_error"]
        if success and not err <= VERIFY_TOL:
            # the NLP's own model reached the target, the plant did not
            success = False
            status = (f"{status}; simulated final error {err:.3g} rad > "
                      f"{VERIFY_TOL:g}")
    return success, status


def _status(stats: dict) -> str:
    """Return the solver's status message (fatrop's code is an int)."""
    status = stats.get("return_status", "unknown")
    if isinstance(status, str):
        return status
    return f"{stats.get('unified_return_status', 'unknown')} ({status})"


def _bounds(s: SlewSetup, lay: Layout, N: int, xs: np.ndarray,
            x0: np.ndarray, fix: bool):
    """(lbw, ubw) of the scaled variables; ``fix``: x(0), ω(T) by bounds."""
    nx = lay.iX.shape[0]
    nw = s.model.n_wheels
    lbw = np.full(lay.n, -np.inf)
    ubw = np.full(lay.n, np.inf)
    lbX = np.full((nx, N + 1), -np.inf)
    ubX = np.full((nx, N + 1), np.inf)
    if nw:
        lbX[7:, 1:], ubX[7:, 1:] = -1.0, 1.0
    if fix:
        lbX[:, 0] = ubX[:, 0] = x0 / xs
        lbX[4:7, N] = ubX[4:7, N] = 0.0
    lbw[lay.iX], ubw[lay.iX] = lbX, ubX
    active = (np.ones(s.model.nu) if s.model.wheels is None
              else s.model.wheels.active.astype(float))
    lbw[lay.iU] = -active[:, None]
    ubw[lay.iU] = active[:, None]
    if nw and lay.iXc.size:
        lbw[lay.iXc[7:]], ubw[lay.iXc[7:]] = -1.0, 1.0
    lbw[lay.iT] = 1e-3
    return lbw, ubw


def _initial_point(s: SlewSetup, lay: Layout, N: int, xs: np.ndarray,
                   T_guess: float, free_T: bool, kind: str,
                   perturbation: float, seed: int) -> np.ndarray:
    """Scaled initial guess ``w0`` (lay.n,)."""
    Xg, Ug = initial_guess_states(s, N, T_guess, kind, perturbation, seed)
    Xgn = Xg / xs[:, None]
    w0 = np.zeros(lay.n)
    w0[lay.iX] = Xgn
    w0[lay.iU] = Ug / s.u_max[:, None]
    if free_T:
        w0[lay.iT] = T_guess / s.T_eig
    if lay.iXc.size:
        d = lay.iXc.shape[1] // N
        w0[lay.iXc] = np.repeat(0.5 * (Xgn[:, :-1] + Xgn[:, 1:]), d, axis=1)
    return w0


def verify_trajectory(model: SpacecraftModel, x0: np.ndarray, t: np.ndarray,
                      Uv: np.ndarray, qf: np.ndarray, extras: dict,
                      keep_out: tuple = ()) -> None:
    """Simulate the controls with CVODES; store final error and rate.

    With keep-out cones the grid is refined 8 times (controls held) and
    the smallest angular margin on it is stored too [rad], with the
    continuous path's (`keepout.path_margin`).
    """
    opts = {"abstol": 1e-9, "reltol": 1e-9}
    if keep_out:
        sub = 8
        tf = np.linspace(t[0], t[-1], sub * (len(t) - 1) + 1)
        Xf = model.simulate(x0, tf, np.repeat(Uv.T, sub, axis=0),
                            options=opts)
        extras["keep_out_margin"] = float(min(
            np.min(k.margin(Xf[:, :4])) for k in keep_out))
        # how far the margin can dip between two fine samples
        h = float(np.max(np.diff(tf)))
        w = Xf[:, 4:7]
        extras["keep_out_path_margin_padded"] = path_margin(
            extras["keep_out_margin"],
            float(np.linalg.norm(w, axis=1).max()),
            float(np.linalg.norm(np.diff(w, axis=0), axis=1).max()) / h, h,
            min(min(k.half_angle, np.pi - k.half_angle) for k in keep_out))
        Xs = Xf[::sub]
    else:
        Xs = model.simulate(x0, t, Uv.T, options=opts)
    qe = quat_mul(quat_conj(qf), Xs[-1, :4] / np.linalg.norm(Xs[-1, :4]))
    extras["simulated_final_error"] = float(
        2 * np.arcsin(min(1.0, float(np.linalg.norm(qe[1:])))))
    extras["simulated_final_rate"] = float(np.linalg.norm(Xs[-1, 4:7]))
