"""What the condensed RTI step's QPs ask of a QP method, by horizon.

Run from the repository root::

    python -m benchmarks.horizon_qps [--spacecraft demo]
                                     [--horizon 20] [--draws 20]
                                     [--steps 120] [--seed 0]
                                     [--admm-caps 25,50,100,200]
                                     [--primal-caps 10,20,40]

Flies the condensed RTI step (`AttitudeMPC`, ``solver="condensed"``,
``rti=True``; the demo craft or ``--spacecraft``, dt 0.5 s) in Python from the random starts
of `benchmarks.mpc_worst_case` (same seed, same states; the craft's rate
bound if it has one, as `adcs export` poses the step) and keeps every
step's QP as the step poses it (`ocp.mpc.condensed.qp_factor_function`:
the QP in y, Hessian I, gradient W⁻ᵀg, rows ``[W⁻¹; momenta]`` of
8·N, and the rates' 3·N with a rate bound). Each QP is solved again by:

* DAQP (dual active set, the step's own solver), cold, and warm-started
  as the step starts it (the signs of the last QP's multipliers, moved
  one stage ahead), from those signs where they were (not moved), or
  from the last QP's active rows (by value) moved one stage ahead;
* OSQP (ADMM, its Ruiz scaling, σ 1e-6, α 1.6, no polish) to 1e-6,
  warm-started at δu = 0 (the last plan moved one stage ahead, as the
  step starts) with the last multipliers moved one stage ahead: with its
  adaptive ρ, and with ρ fixed (one factorisation a QP, as flight ADMM
  solvers such as TinyMPC keep it);
* the same fixed-ρ ADMM stopped after a fixed number of iterations
  (``--admm-caps``): how far its answer is from the step's;
* a primal active set (`benchmarks.primal_active_set`) in δu started
  where the step starts: at δu = 0, the last plan moved one stage ahead
  (feasible on every QP but a loop's first and those a defect moves),
  with the shifted signs that hold there; run to its optimum and
  stopped after ``--primal-caps`` iterations (its point is feasible:
  how far from the step's, and the share of the step's cost decrease
  it misses).

Prints what the QPs hold at their optimum (DAQP's: the active bounds
and rows, its working set, and that set's distance from the step's warm
start: the changes a method walking straight there makes), iterations
per method (median, 99th percentile and worst over the QPs with a
constraint active) with the largest difference of the answer from the
step's (δu over the torque bound m_max), and the capped
ADMM's distance and bound violation (scaled: torques over m_max,
momenta over h_max, rates over the rate bound).
"""

from __future__ import annotations

import argparse

import daqp
import numpy as np
import osqp
from scipy import sparse
from tqdm.auto import tqdm

from benchmarks import primal_active_set
from benchmarks.riccati_active_set import stage_qp_function
from benchmarks.mpc_worst_case import random_states
from ocp.models.rigid import rigid_spacecraft
from ocp.mpc import AttitudeMPC
from ocp.mpc.condensed import qp_factor_function
from ocp.spacecraft import load_spacecraft

#: A constraint is active at the optimum within this (scaled).
ACTIVE_TOL = 1e-7
#: OSQP's absolute and relative tolerance.
OSQP_TOL = 1e-6
#: ADMM's step size ρ: OSQP's default, kept fixed (or its first, adaptive).
FIXED_RHO = 0.1


def study_setup(horizon: int, spacecraft: str = "demo") -> tuple:
    """``(spacecraft, model, mpc, qp)``: the craft's condensed RTI MPC (a
    built-in name or a TOML file, `load_spacecraft`; dt 0.5 s) and its QP
    (`qp_factor_function`)."""
    sc = load_spacecraft(spacecraft)
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    mpc = AttitudeMPC(model, horizon=horizon, dt=0.5, solver="condensed",
                      rti=True, rate_max=sc.rate_max)
    return sc, model, mpc, qp_factor_function(mpc)


def plan_controls(mpc) -> list[int]:
    """The controls u_0…u_{N−1} in ``mpc``'s plan (indices)."""
    return [i for s in mpc._us for i in range(s.start, s.stop)]


def stage_parts(N: int, nu: int, nw: int, rate_rows: bool) -> list:
    """The QP's stage-major blocks ``(N, width)`` in order: torques,
    momenta and, with a rate bound, rates (`shift_stages`)."""
    return [(N, nu), (N, nw)] + ([(N, 3)] if rate_rows else [])


def du_form(winv: np.ndarray, rows: np.ndarray) -> tuple:
    """``(W, H, C)`` of the QP in δu: W = (W⁻¹)⁻¹, the Hessian WᵀW and
    the rows ``[I; rows·W]`` (the gradient in δu is Wᵀ times y's)."""
    W = np.linalg.inv(winv)
    return W, W.T @ W, np.vstack([np.eye(W.shape[0]), rows @ W])


def row_scales(sc, mpc) -> np.ndarray:
    """The scale of each of the QP's rows: the torque bounds m_max, the
    momentum bounds h_max and, with a rate bound, the rate bound."""
    N = mpc.horizon
    rate = [] if mpc.rate_max is None else [np.full(3 * N, mpc.rate_max)]
    return np.concatenate([np.tile(sc.wheels.m_max, N),
                           np.tile(sc.wheels.h_max, N), *rate])


def warm_working_set(C: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                     start: np.ndarray, tol: np.ndarray) -> dict[int, int]:
    """The rows of the signs ``start`` (−1 lower, 1 upper) at their bound
    at δu = 0 (within ``tol``), made independent: the primal active
    set's first working set."""
    at = [int(j) for j in np.flatnonzero(start)
          if abs((hi if start[j] > 0 else lo)[j]) <= tol[j]]
    return {j: int(start[j]) for j in primal_active_set.independent(C, at)}


def add_loop_arguments(ap: argparse.ArgumentParser) -> None:
    """The Monte Carlo's options: spacecraft, horizon, draws, steps,
    seed."""
    ap.add_argument("--spacecraft", default="demo",
                    help="a built-in craft or a TOML file (default demo)")
    ap.add_argument("--horizon", type=int, default=20)
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--seed", type=int, default=0)


def collect(horizon: int, draws: int, steps: int, seed: int,
            spacecraft: str = "demo", stagewise: bool = False) -> dict:
    """The QPs of ``draws`` closed loops of ``steps`` steps, with the
    step's answer δu, and the scales of their rows; ``stagewise``: each
    QP also kept stage by stage (``"stage"``,
    `benchmarks.riccati_active_set.stage_qp_function`)."""
    sc, model, mpc, qp = study_setup(horizon, spacecraft)
    pose = stage_qp_function(mpc) if stagewise else None
    N, nu, nw = horizon, model.nu, sc.wheels.n_wheels
    rk4 = model.rk4_step(1)
    qf, tau = np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3)
    controls = plan_controls(mpc)
    starts = random_states(model, draws, np.random.default_rng(seed))
    qps = []
    for d, x0 in enumerate(tqdm(starts, desc="loops", disable=None,
                                leave=False)):
        x = x0.copy()
        z = mpc.initial_guess(x)
        lx, lg = np.zeros(mpc.nz), np.zeros(mpc.ng)
        for s in range(steps):
            z0 = np.array(mpc.shift_function(x, z, lx, lg)[0]).ravel()
            data = [np.array(v) for v in qp(z0, np.r_[x, qf, tau])]
            out = mpc.rti_function(x, qf, tau, z, lx, lg)
            z, lx, lg = (np.array(v).ravel() for v in out[1:4])
            winv, rows, g, lbu, ubu, lba, uba = data
            qps.append({"draw": d, "step": s, "Winv": winv, "rows": rows,
                        "gy": winv.T @ g.ravel(),
                        "lo": np.r_[lbu.ravel(), lba.ravel()],
                        "hi": np.r_[ubu.ravel(), uba.ravel()],
                        "du": z[controls] - z0[controls]})
            if pose is not None:
                qps[-1]["stage"] = pose(z0, np.r_[x, qf, tau])
            x = np.asarray(rk4(x, np.array(out[0]).ravel(), tau,
                               0.5)).ravel()
    return {"qps": qps, "scale": row_scales(sc, mpc), "N": N, "nu": nu,
            "nw": nw, "m_max": np.tile(sc.wheels.m_max, N)}


def shift_stages(v: np.ndarray, parts: list) -> np.ndarray:
    """A stage-major vector of blocks ``parts`` (each ``(N, width)``),
    moved one stage ahead, its last stage repeated."""
    out, top = [], 0
    for n, w in parts:
        s = v[top:top + n * w].reshape(n, w)
        out.append(np.r_[s[1:], s[-1:]].ravel())
        top += n * w
    return np.concatenate(out)


def _parts(c: dict) -> list:
    N, nw = c["N"], c["nw"]
    return stage_parts(N, c["nu"], nw, c["qps"][0]["rows"].shape[0] > N * nw)


def active_sets(c: dict, sides: list, signs: list) -> np.ndarray:
    """Per QP: the bounds and the rows active at the optimum (``sides``:
    −1 at a row's lower bound, 1 at its upper, 0 between), its working
    set's size (``signs``: the signs of DAQP's multipliers, the same
    convention), and that set's distance from the last QP's moved one
    stage ahead (−1 for a loop's first QP): the constraints to drop plus
    those to add, a row that changes bound counting two. A method that
    walks straight from the step's warm start to the optimum makes that
    many changes."""
    parts, n = _parts(c), c["qps"][0]["Winv"].shape[0]
    out, prev = [], None
    for q, side, sign in zip(c["qps"], sides, signs):
        dist = -1
        if prev is not None and q["step"] > 0:
            dist = int(np.sum(np.abs(sign - shift_stages(prev, parts))))
        out.append((int(np.count_nonzero(side[:n])),
                    int(np.count_nonzero(side[n:])),
                    int(np.count_nonzero(sign)), dist))
        prev = sign
    return np.array(out)


def _senses(side: np.ndarray) -> np.ndarray:
    """DAQP's warm-start senses of −1/0/1 sides: 3 at the lower bound,
    1 at the upper, 0 free."""
    return np.choose(side + 1, [3, 0, 1]).astype(np.int32)


def run_daqp(c: dict) -> dict:
    """DAQP cold, and warm from the last QP's multipliers' signs moved one
    stage ahead (``warm_signs``: the step's warm start) or where they
    were (``warm_unshifted``), or from its active rows by value moved
    one stage ahead (``warm_sides``); the ``sides`` and ``signs`` at each
    optimum (`active_sets`)."""
    parts = _parts(c)
    out: dict = {"cold": [], "warm_sides": [], "warm_signs": [],
                 "warm_unshifted": [], "at_optimum": ([], [])}
    err = {m: 0.0 for m in out if m != "at_optimum"}
    for q in c["qps"]:
        A = np.vstack([q["Winv"], q["rows"]])
        starts = {"cold": np.zeros(A.shape[0], np.int32)}
        last = out["at_optimum"]
        first = not last[0] or q["step"] == 0
        for mode, start in (("warm_sides", lambda: shift_stages(last[0][-1], parts)),
                            ("warm_signs", lambda: shift_stages(last[1][-1], parts)),
                            ("warm_unshifted", lambda: last[1][-1])):
            starts[mode] = starts["cold"] if first else _senses(start())
        for mode, sense in starts.items():
            y, _, flag, info = daqp.solve(np.eye(A.shape[1]), q["gy"], A,
                                          q["hi"].copy(), q["lo"].copy(),
                                          sense.copy())
            if flag < 1:
                raise RuntimeError(f"DAQP failed ({flag}) on a QP")
            out[mode].append(info["iterations"])
            err[mode] = max(err[mode], float(np.max(
                np.abs(q["Winv"] @ y - q["du"]) / c["m_max"])))
            if mode == "cold":
                v, tol = A @ y, ACTIVE_TOL * c["scale"]
                out["at_optimum"][0].append(np.where(
                    np.abs(v - q["lo"]) <= tol, -1,
                    np.where(np.abs(v - q["hi"]) <= tol, 1, 0)))
                # DAQP's multipliers: positive at an upper bound
                out["at_optimum"][1].append(
                    np.sign(info["lam"]).astype(int))
    return {**{m: np.array(out[m]) for m in err}, "error": err,
            "sides": out["at_optimum"][0], "signs": out["at_optimum"][1]}


def run_primal(c: dict, signs: list, caps: list[int]) -> dict:
    """A primal active set (`benchmarks.primal_active_set`) on the QP in
    δu, started where the step starts: at δu = 0 (the last plan moved
    one stage ahead) with the last optimum's multipliers' signs moved
    one stage ahead that hold there (made independent). QPs where δu = 0
    breaks a bound (a loop's first, or a defect) are left out. Per cap
    of ``caps`` its point after that many iterations (feasible by
    construction): the torques' distance from the step's and the share
    of the step's cost decrease it misses."""
    parts = _parts(c)
    out: dict = {"iters": [], "error": 0.0, "infeasible_start": 0,
                 "kept": [], **{cap: ([], []) for cap in caps}}
    for i, q in enumerate(c["qps"]):
        if q["step"] == 0:
            continue
        Wm, H, C = du_form(q["Winv"], q["rows"])
        g = Wm.T @ q["gy"]
        tol = 1e-9 * c["scale"]
        if np.any(q["lo"] > tol) or np.any(q["hi"] < -tol):
            out["infeasible_start"] += 1
            continue
        W = warm_working_set(C, q["lo"], q["hi"],
                             shift_stages(signs[i - 1], parts), tol)
        x0 = np.zeros(H.shape[0])
        r = primal_active_set.solve(H, g, C, q["lo"], q["hi"], x0, W)
        if not r["optimal"]:
            raise RuntimeError("the primal active set did not finish a QP")
        out["kept"].append(i)
        out["iters"].append(r["iterations"])
        out["error"] = max(out["error"], float(np.max(
            np.abs(r["x"] - q["du"]) / c["m_max"])))
        f_opt = 0.5 * r["x"] @ H @ r["x"] + g @ r["x"]
        for cap in caps:
            xc = r["path"][min(cap, r["iterations"]) - 1]
            missed = 0.0 if f_opt >= 0 else float(
                (0.5 * xc @ H @ xc + g @ xc - f_opt) / -f_opt)
            out[cap][0].append(float(np.max(np.abs(xc - q["du"])
                                            / c["m_max"])))
            out[cap][1].append(missed)
    out["iters"] = np.array(out["iters"])
    return out


def run_osqp(c: dict, adaptive: bool, cap: int | None = None) -> dict:
    """OSQP warm-started at δu = 0 with the last multipliers one stage
    ahead: iterations to `OSQP_TOL`, or its answer after ``cap`` iterations."""
    parts = _parts(c)
    iters, err, viol, prev = [], [], [], None
    for q in c["qps"]:
        A = np.vstack([q["Winv"], q["rows"]])
        n = A.shape[1]
        solver = osqp.OSQP()
        solver.setup(sparse.identity(n, format="csc"), q["gy"],
                     sparse.csc_matrix(A), q["lo"], q["hi"], verbose=False,
                     rho=FIXED_RHO, adaptive_rho=adaptive, polishing=False,
                     eps_abs=OSQP_TOL, eps_rel=OSQP_TOL,
                     max_iter=cap or 20000,
                     check_termination=0 if cap else 1,
                     scaled_termination=False)
        if prev is not None and q["step"] > 0:
            # the shifted plan is the last answer moved ahead: δu = 0
            solver.warm_start(x=np.zeros(n), y=shift_stages(prev, parts))
        r = solver.solve(raise_error=False)
        if not cap and r.info.status_val != 1:
            raise RuntimeError(f"OSQP: {r.info.status} on a QP")
        prev = r.y
        iters.append(r.info.iter)
        err.append(float(np.max(np.abs(q["Winv"] @ r.x - q["du"])
                                / c["m_max"])))
        v = A @ r.x
        viol.append(float(np.max(np.r_[q["lo"] - v, v - q["hi"], 0.0]
                                 / np.r_[c["scale"], c["scale"], 1.0])))
    return {"iters": np.array(iters), "error": np.array(err),
            "violation": np.array(viol)}


def _pct(a: np.ndarray) -> tuple:
    return (float(np.median(a)), float(np.percentile(a, 99)), float(a.max()))


def report(c: dict, admm_caps: list[int], primal_caps: list[int]) -> str:
    d = run_daqp(c)
    act = active_sets(c, d["sides"], d["signs"])
    con = act[:, :2].sum(axis=1) > 0
    warm = con & (act[:, 3] >= 0)
    n = c["qps"][0]["Winv"].shape[0]
    m = n + c["qps"][0]["rows"].shape[0]
    lines = [
        f"horizon {c['N']}: {len(c['qps'])} QPs of {n} variables and "
        f"{m} rows, {int(con.sum())} with a constraint active at the "
        "optimum",
        "at the optimum (constrained QPs): median / p99 / max",
        "  active          {:.0f} / {:.0f} / {:.0f}".format(
            *_pct(act[con, :2].sum(1))),
        "  active bounds   {:.0f} / {:.0f} / {:.0f}".format(
            *_pct(act[con, 0])),
        "  active rows     {:.0f} / {:.0f} / {:.0f}".format(
            *_pct(act[con, 1])),
        "  working set     {:.0f} / {:.0f} / {:.0f}".format(
            *_pct(act[con, 2])),
        f"  free variables, median {np.median(n - act[con, 0]):.0f}",
        "working set's distance from the step's warm start (the last "
        "one a stage ahead): {:.0f} / {:.0f} / {:.0f}".format(
            *_pct(act[warm, 3])),
        "",
        "| method | iterations, median | p99 | worst | max |δu − step's| "
        "/ m_max |",
        "|---|---:|---:|---:|---:|"]
    for name, mode in (
            ("DAQP, cold", "cold"),
            ("DAQP, warm: last multipliers' signs a stage ahead (the "
             "step's)", "warm_signs"),
            ("DAQP, warm: last multipliers' signs where they were",
             "warm_unshifted"),
            ("DAQP, warm: last active rows a stage ahead", "warm_sides")):
        lines.append("| {} | {:.0f} | {:.0f} | {:.0f} | {:.1e} |".format(
            name, *_pct(d[mode][con]), d["error"][mode]))
    pas = run_primal(c, d["signs"], primal_caps)
    kept = np.zeros(len(con), bool)
    kept[pas["kept"]] = True
    lines.append("| primal active set from the step's start (δu = 0 and "
                 "the signs that hold there) | {:.0f} | {:.0f} | {:.0f} | "
                 "{:.1e} |".format(*_pct(pas["iters"][con[kept]]),
                                   pas["error"]))
    for name, adaptive in (("OSQP to 1e-6, adaptive ρ", True),
                           (f"OSQP to 1e-6, fixed ρ = {FIXED_RHO}", False)):
        o = run_osqp(c, adaptive)
        lines.append("| {} | {:.0f} | {:.0f} | {:.0f} | {:.1e} |".format(
            name, *_pct(o["iters"][con]), o["error"].max()))
    lines += ["", "(the primal active set leaves out "
              f"{pas['infeasible_start']} QPs where δu = 0 breaks a bound, "
              "and each loop's first, which has no warm start)", "",
              "Stopped after a fixed number of iterations, constrained "
              "QPs:", "",
              "| method, iterations | |δu − step's| / m_max, median | p99 "
              "| worst | violation (scaled) or cost decrease missed, p99 | "
              "worst |",
              "|---|---:|---:|---:|---:|---:|"]
    for cap in admm_caps:
        o = run_osqp(c, False, cap)
        e, v = o["error"][con], o["violation"][con]
        lines.append("| ADMM, fixed ρ, {} | {:.1e} | {:.1e} | {:.1e} | "
                     "violation {:.1e} | {:.1e} |".format(
                         cap, *_pct(e), *_pct(v)[1:]))
    for cap in primal_caps:
        e, m = (np.array(v)[con[kept]] for v in pas[cap])
        lines.append("| primal active set, {} | {:.1e} | {:.1e} | {:.1e} | "
                     "missed {:.1e} | {:.1e} |".format(
                         cap, *_pct(e), *_pct(m)[1:]))
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_loop_arguments(ap)
    ap.add_argument("--admm-caps", default="25,50,100,200")
    ap.add_argument("--primal-caps", default="10,20,40")
    a = ap.parse_args(argv)
    caps = [[int(v) for v in arg.split(",") if v]
            for arg in (a.admm_caps, a.primal_caps)]
    print(report(collect(a.horizon, a.draws, a.steps, a.seed,
                         a.spacecraft), *caps))


if __name__ == "__main__":
    main()
