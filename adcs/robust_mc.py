"""Monte Carlo of closed loops: nominal against robust (multi-stage) MPC.

Each draw is a plant from the uncertainty set of a craft: its principal
moments scaled by ``1 + U(-spread, spread)`` each, its products of
inertia each ``U(-products, products)`` times the largest moment, and
every wheel axis tilted by two angles ``U(-misalignment, misalignment)``
(the accuracy study's mounting model, `allocation.tilted_axes`, ±0.5°).
The same plant is flown twice, slew and hold from rest: by the nominal
stage-wise MPC (RTI) and by `ocp.mpc.RobustMPC` (RTI) over the craft's
nominal inertia and the 8 corners of ``1 ± spread``
(`ocp.mpc.inertia_corners`). Both plan with the nominal wheel axes.

Per draw and controller: whether the loop broke (the MPC raised: no
plan met its bounds from the measured state, or its QP failed its
certificate), the largest excess of the wheel momentum, wheel torque and
body rate over their bounds, the entry into a keep-out cone (with
``keep_out_deg``: a cone across the slew, `slew_keep_out`, held by both
MPCs; the path between samples checked, `ocp.mpc.keep_out_margin`), the
settling time, the final error and the energy. Draw ``k`` of seed ``s``
uses the random stream
``SeedSequence(s, spawn_key=(k,))`` alone, so a draw is the same
whatever the chunking or the worker that flies it; `run_robust_mc`
runs the draws on a Dask client (`adcs.sweep.run_sweep`) or serially.
"""

from __future__ import annotations

import functools
import threading
from dataclasses import dataclass
from typing import Any, TYPE_CHECKING

import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError
from adcs_common.validation import as_finite_scalar
from allocation import WheelArray, tilted_axes

if TYPE_CHECKING:
    import xarray as xr

__all__ = ["CONTROLLERS", "ControllerSummary", "PlantDraw", "draw_plant",
           "robust_mc_case", "robust_mc_params", "robust_mc_table",
           "robust_scenarios", "run_robust_mc", "summarise"]

#: Spread of each principal moment, as a fraction of it [1].
INERTIA_SPREAD = 0.2
#: Bound of each product of inertia, as a fraction of the largest moment.
PRODUCTS = 0.05
#: Bound of each wheel-axis tilt [rad]: the accuracy study's mounting
#: tolerance (`adcs.studies.accuracy.MOUNT_TOL`, 0.5°).
MISALIGNMENT = float(np.deg2rad(0.5))
#: Default rate bound of the Monte Carlo [rad/s]: none (0). Without one
#: the wheel momentum and torque cannot exceed their bounds whatever the
#: plant (dH/dt = m exactly, the applied m and H_1 are bounded in every
#: plan): a bound violation needs a rate bound (``rate_max``, e.g. 0.04),
#: where the plant's inertia matters.
RATE_MAX = 0.0
#: A bound counts as violated above this fraction of the bound [1].
VIOLATION_TOL = 1e-6
#: The two controllers, in the order of the outputs.
CONTROLLERS = ("nominal", "robust")
#: Per-controller outputs of `robust_mc_case` (prefixed by the name).
METRICS = ("failed", "momentum_violation", "torque_violation",
           "rate_violation", "keep_out_violation", "settle_time",
           "final_error", "energy", "step_time")
#: How far the keep-out cone's direction lies off the slew's path, toward
#: the slew axis [rad] (`slew_keep_out`): a cone centred on the path
#: leaves the MPC a saddle to pass it by.
KEEP_OUT_OFFSET = float(np.deg2rad(5.0))


@dataclass(frozen=True)
class PlantDraw:
    """One plant of the uncertainty set.

    Attributes
    ----------
    inertia : ndarray (3, 3)
        Drawn inertia [kg·m²].
    wheels : WheelArray
        The craft's wheels with the drawn axes.
    factors : ndarray (3,)
        Scale factors of the principal moments, in ascending order of
        the nominal moments (`numpy.linalg.eigh`) [1].
    products : ndarray (3,)
        Products (J_xy, J_xz, J_yz) added, over the largest moment [1].
    tilt_a, tilt_b : ndarray (N,)
        Tilts of each wheel axis [rad].
    """

    inertia: np.ndarray
    wheels: WheelArray
    factors: np.ndarray
    products: np.ndarray
    tilt_a: np.ndarray
    tilt_b: np.ndarray


def draw_plant(inertia: Any, wheels: WheelArray, seed: int, draw: int, *,
               spread: float = INERTIA_SPREAD, products: float = PRODUCTS,
               misalignment: float = MISALIGNMENT) -> PlantDraw:
    """Draw ``draw`` of seed ``seed`` from the uncertainty set (uniform).

    Parameters
    ----------
    inertia : array_like (3, 3)
        Nominal inertia [kg·m²].
    wheels : WheelArray
        Nominal wheels (axes tilted in the draw, limits kept).
    seed, draw : int
        The stream ``SeedSequence(seed, spawn_key=(draw,))``.
    spread, products : float
        Bounds of the principal-moment scale and of the products [1].
    misalignment : float
        Bound of each of the two tilts of each axis [rad].

    Raises
    ------
    InvalidValueError
        A negative seed, draw or bound, or a drawn inertia that is not
        positive definite (products too large for the craft).
    """
    from adcs_common.rigid_body import check_inertia

    for name, v in (("seed", seed), ("draw", draw)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) \
                or v < 0:
            raise InvalidValueError(
                f"{name} must be a non-negative int, got {v!r}")
    for name, v in (("spread", spread), ("products", products),
                    ("misalignment", misalignment)):
        _fraction(v, name)
    J = check_inertia(inertia)
    rng = np.random.default_rng(
        np.random.SeedSequence(int(seed), spawn_key=(int(draw),)))
    n = wheels.n_wheels
    factors = 1.0 + spread * rng.uniform(-1.0, 1.0, 3)
    prods = products * rng.uniform(-1.0, 1.0, 3)
    ta = misalignment * rng.uniform(-1.0, 1.0, n)
    tb = misalignment * rng.uniform(-1.0, 1.0, n)
    lam, V = np.linalg.eigh(J)
    Jd = V @ np.diag(lam * factors) @ V.T
    off = np.zeros((3, 3))
    off[0, 1], off[0, 2], off[1, 2] = prods * float(np.max(np.diag(J)))
    Jd = check_inertia(Jd + off + off.T, "drawn inertia")
    axes = tilted_axes(np.array(wheels.axes), ta, tb)
    return PlantDraw(Jd, wheels.with_axes(axes), factors, prods, ta, tb)


def _fraction(value: Any, name: str) -> float:
    """``value`` as a float in [0, 1), else `InvalidValueError`."""
    v = as_finite_scalar(value, name)
    if not 0.0 <= v < 1.0:
        raise InvalidValueError(f"{name} must be in [0, 1), got {value!r}")
    return v


def slew_keep_out(angle: float, half_angle: float) -> Any:
    """A keep-out cone across the Monte Carlo's slew (`ocp.KeepOut`).

    The slew turns ``angle`` [rad] about (1, 1, 0) from rest at the
    identity; the boresight (1, −1, 0)/√2, normal to that axis, sweeps a
    great circle. The cone of ``half_angle`` [rad] is centred at the
    boresight's direction half-way, moved `KEEP_OUT_OFFSET` toward the
    axis: without a keep-out the slew passes through it.
    """
    from ocp import KeepOut

    a = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    b = np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0)
    half = 0.5 * float(angle)
    mid = np.cos(half) * b + np.sin(half) * np.cross(a, b)
    s = np.cos(KEEP_OUT_OFFSET) * mid + np.sin(KEEP_OUT_OFFSET) * a
    return KeepOut(b, s, float(half_angle))


def _slew_cones(angle_deg: float, keep_out_deg: float) -> tuple:
    """The Monte Carlo's cones: none, or `slew_keep_out`'s."""
    if keep_out_deg == 0.0:
        return ()
    return (slew_keep_out(np.deg2rad(angle_deg), np.deg2rad(keep_out_deg)),)


def rate_excess(w: np.ndarray, rate_max: float) -> float:
    """Largest excess of the body rates ``w`` (K, 3) [rad/s] over
    ``rate_max`` [rad/s] (0 below it, or without a bound: 0)."""
    if rate_max <= 0.0:
        return 0.0
    return max(float(np.abs(w).max()) - rate_max, 0.0)


@functools.lru_cache(maxsize=8)
def _controllers(text: str, source: str, horizon: int, dt: float,
                 rate_max: float, spread: float, thread: int,
                 tree_products: float = 0.0, cones: tuple = ()) -> tuple:
    """(craft, nominal MPC, robust MPC), built once per worker thread.

    ``text`` (the craft's TOML) keys the cache, so an edited file gets
    new controllers; ``thread`` keeps one pair per thread (an MPC follows
    one trajectory at a time).
    """
    from ocp import rigid_spacecraft
    from ocp.mpc import AttitudeMPC, RobustMPC
    from .sweep.builtin import _craft_of

    del thread
    sc = _craft_of(text, source)
    model = rigid_spacecraft(sc.inertia, sc.wheels)
    rate = None if rate_max <= 0.0 else rate_max
    nominal = AttitudeMPC(model, horizon=horizon, dt=dt, solver="stagewise",
                          rti=True, rate_max=rate, keep_out=cones)
    robust = RobustMPC(model, robust_scenarios(sc.inertia, spread,
                                               tree_products),
                       horizon=horizon, dt=dt, rti=True, rate_max=rate,
                       keep_out=cones)
    return sc, nominal, robust


def robust_scenarios(inertia: Any, spread: float = INERTIA_SPREAD,
                     tree_products: float = 0.0) -> list:
    """The robust MPC's scenarios: the nominal craft and the 8 corners of
    ``1 ± spread`` principal moments (`ocp.mpc.inertia_corners`); with
    ``tree_products`` > 0, the nominal craft and those 8 corners each
    with the products ``±tree_products`` of the largest moment
    (`ocp.mpc.scenario_grid`: 17 scenarios) [1]."""
    from ocp.mpc import inertia_corners, scenario_grid

    corners = inertia_corners(inertia, spread)
    tree_products = _fraction(tree_products, "tree_products")
    if tree_products == 0.0:
        return corners
    return corners[:1] + scenario_grid(
        inertia, inertia_scale=(1.0 - spread, 1.0 + spread),
        products=(-tree_products, tree_products))


def _fly(name: str, mpc: Any, plant: Any, qf: np.ndarray, t_final: float,
         rate_max: float) -> dict:
    """One closed loop from rest: the metrics, prefixed by ``name``."""
    from ocp.mpc import keep_out_margin, simulate_mpc

    out = {f"{name}_{k}": float("nan") for k in METRICS}
    try:
        r = simulate_mpc(mpc, [1.0, 0.0, 0.0, 0.0], qf, t_final=t_final,
                         plant=plant)
    except AdcsError:
        out[f"{name}_failed"] = 1.0
        return out
    out.update({
        f"{name}_failed": 0.0,
        f"{name}_momentum_violation": r.momentum_violation,
        f"{name}_torque_violation": r.torque_violation,
        f"{name}_rate_violation": rate_excess(r.trajectory.w, rate_max),
        f"{name}_keep_out_violation": max(0.0, -keep_out_margin(
            r, mpc.keep_out, plant)) if mpc.keep_out else 0.0,
        f"{name}_settle_time": r.settle_time,
        f"{name}_final_error": r.final_error,
        f"{name}_energy": r.energy,
        f"{name}_step_time": r.step_time_median})
    return out


def robust_mc_case(spacecraft: str, seed: int, draw: int, t_final: float,
                   rate_max: float, spread: float, angle_deg: float,
                   horizon: int = 20, dt: float = 0.5,
                   rate_margin: float = 0.0,
                   tree_products: float = 0.0,
                   keep_out_deg: float = 0.0) -> dict:
    """Fly draw ``draw`` by the nominal and the robust MPC.

    Parameters
    ----------
    spacecraft : str
        Built-in name or TOML file (its wheels; thrusters are not used).
    seed, draw : int
        The draw (`draw_plant`, default bounds).
    t_final : float
        Length of each closed loop (slew and hold) [s].
    rate_max : float
        Body-rate bound of both MPCs [rad/s]; 0: none.
    spread : float
        The robust MPC's corners ``1 ± spread`` [1].
    angle_deg : float
        Slew angle about (1, 1, 0) from rest [deg].
    horizon, dt
        Both MPCs' horizon and sample time [s].
    rate_margin : float
        Both MPCs plan with the rate bound ``rate_max·(1 − rate_margin)``;
        the violations are counted against ``rate_max`` [1].
    tree_products : float
        The robust MPC's tree also spans the products of inertia
        ``±tree_products`` of the largest moment (`robust_scenarios`) [1].
    keep_out_deg : float
        Half-angle of a keep-out cone across the slew (`slew_keep_out`),
        held by both MPCs [deg]; 0: none.

    Returns
    -------
    dict
        The drawn factors, products and largest tilt [rad], then for
        ``nominal`` and ``robust``: ``failed`` (1: the loop broke),
        ``momentum_violation`` [N·m·s], ``torque_violation`` [N·m],
        ``rate_violation`` [rad/s], ``keep_out_violation`` (how deep
        the path, sampled 8 times per sample, entered the cone) [rad],
        ``settle_time`` [s],
        ``final_error`` [rad], ``energy`` [N²·m²·s], ``step_time``
        (median, [s]; the only output that varies between runs).
    """
    from ocp import rigid_spacecraft

    pair, d, qf, out = draw_case(spacecraft, seed, draw, rate_max, spread,
                                 angle_deg, horizon, dt, rate_margin,
                                 tree_products, keep_out_deg)
    plant = rigid_spacecraft(d.inertia, d.wheels)
    for name, mpc in zip(CONTROLLERS, pair):
        out.update(_fly(name, mpc, plant, qf, t_final, float(rate_max)))
    return out


def draw_case(spacecraft: str, seed: int, draw: int, rate_max: float,
              spread: float, angle_deg: float, horizon: int, dt: float,
              rate_margin: float, tree_products: float = 0.0,
              keep_out_deg: float = 0.0) -> tuple:
    """What a case of the Monte Carlo flies (`robust_mc_case`'s inputs).

    Returns ``((nominal, robust), draw, qf, outputs)``: the two MPCs of
    this thread (planning ``rate_max·(1 − rate_margin)``), the
    `PlantDraw`, the target quaternion and the draw's own outputs (scale
    factors, products, largest tilt [rad]).
    """
    from ocp import quat_from_axis_angle
    from .sweep.builtin import _craft_text

    text = _craft_text(spacecraft)
    sc, nominal, robust = _controllers(
        text, str(spacecraft), int(horizon), float(dt),
        float(rate_max) * (1.0 - float(rate_margin)), float(spread),
        threading.get_ident(), float(tree_products),
        _slew_cones(float(angle_deg), float(keep_out_deg)))
    d = draw_plant(sc.inertia, sc.wheels, seed, draw)
    qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(angle_deg))
    out = {f"factor_{i + 1}": float(f) for i, f in enumerate(d.factors)}
    out.update({f"product_{k}": float(p) for k, p in
                zip(("xy", "xz", "yz"), d.products)})
    out["tilt_max"] = float(np.max(np.abs(np.r_[d.tilt_a, d.tilt_b])))
    return (nominal, robust), d, qf, out


def _craft_inputs(row: dict) -> dict:
    from .sweep.builtin import craft_inputs

    return craft_inputs(row)


robust_mc_case.sweep_inputs = _craft_inputs  # type: ignore[attr-defined]


def robust_mc_params(draws: int, *, seed: int = 0,
                     spacecraft: str = "demo", t_final: float = 50.0,
                     rate_max: float = RATE_MAX,
                     spread: float = INERTIA_SPREAD,
                     angle_deg: float = 90.0, horizon: int = 20,
                     dt: float = 0.5, rate_margin: float = 0.0,
                     tree_products: float = 0.0,
                     keep_out_deg: float = 0.0) -> list[dict]:
    """One parameter row per draw (`robust_mc_case`'s arguments)."""
    if isinstance(draws, bool) or not isinstance(draws, (int, np.integer)) \
            or draws < 1:
        raise InvalidValueError(
            f"draws must be a positive int, got {draws!r}")
    if not t_final > 0:
        raise InvalidValueError(f"t_final must be > 0 s, got {t_final!r}")
    if not rate_max >= 0:
        raise InvalidValueError(
            f"rate_max must be >= 0 rad/s (0: none), got {rate_max!r}")
    rate_margin = _fraction(rate_margin, "rate_margin")
    tree_products = _fraction(tree_products, "tree_products")
    keep_out_deg = as_finite_scalar(keep_out_deg, "keep_out_deg")
    if keep_out_deg < 0.0:
        raise InvalidValueError(
            f"keep_out_deg must be >= 0 (0: none), got {keep_out_deg!r}")
    from ocp import quat_from_axis_angle

    for cone in _slew_cones(float(angle_deg), keep_out_deg):
        qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(angle_deg))
        if min(cone.margin([1.0, 0.0, 0.0, 0.0]), cone.margin(qf)) <= 0.0:
            raise InvalidValueError(
                f"a keep-out cone of {keep_out_deg:g}° covers the slew's "
                "start or end: take a smaller half-angle")
    return [{"spacecraft": spacecraft, "seed": int(seed), "draw": k,
             "t_final": float(t_final), "rate_max": float(rate_max),
             "spread": float(spread), "angle_deg": float(angle_deg),
             "horizon": int(horizon), "dt": float(dt),
             "rate_margin": float(rate_margin),
             "tree_products": float(tree_products),
             "keep_out_deg": float(keep_out_deg)}
            for k in range(int(draws))]


def run_robust_mc(draws: int, *, client: Any = None,
                  progress: bool = False, out: Any = None,
                  **options: Any) -> xr.Dataset:
    """Run the Monte Carlo on ``client`` (a `distributed.Client`) or here.

    Parameters
    ----------
    draws : int
        Number of plants drawn.
    client : distributed.Client, optional
        Where the draws run (None: in this process, in order).
    progress : bool
        A tqdm bar.
    out : path, optional
        Folder of the finished chunks (a rerun resumes;
        `adcs.sweep.run_sweep`).
    **options
        `robust_mc_params`' keywords (seed, spacecraft, t_final,
        rate_max, spread, angle_deg, horizon, dt).

    Returns
    -------
    xarray.Dataset
        One ``case`` per draw (`robust_mc_case`'s outputs).
    """
    from .sweep import run_sweep

    return run_sweep(robust_mc_case, robust_mc_params(draws, **options),
                     client=client, progress=progress, out=out)


@dataclass(frozen=True)
class ControllerSummary:
    """Counts and statistics of one controller over the draws.

    Attributes
    ----------
    controller : str
        ``"nominal"`` or ``"robust"``.
    draws : int
        Draws flown.
    failed : int
        Loops that broke (the MPC raised).
    momentum, torque, rate : int
        Loops whose wheel momentum, wheel torque or body rate exceeded
        its bound by more than ``VIOLATION_TOL`` of the bound.
    settled : int
        Loops settled within 0.1° before the end.
    settle_median, settle_worst : float
        Settling time over the settled loops [s] (NaN: none).
    final_error_max : float
        Largest final error over the loops that ran [rad].
    energy_median : float
        Median energy [N²·m²·s].
    step_time_median : float
        Median over the loops of their median step time [s].
    rate_over_median, rate_over_max : float
        Median and largest rate overshoot over the loops that ran, as a
        fraction of the rate bound [1] (0 without a bound).
    keep_out : int
        Loops whose path entered the keep-out cone by more than
        ``VIOLATION_TOL`` of its half-angle (0 without a cone).
    """

    controller: str
    draws: int
    failed: int
    momentum: int
    torque: int
    rate: int
    settled: int
    settle_median: float
    settle_worst: float
    final_error_max: float
    energy_median: float
    step_time_median: float
    rate_over_median: float = 0.0
    rate_over_max: float = 0.0
    keep_out: int = 0


def _nan_stat(f: Any, v: np.ndarray) -> float:
    v = v[np.isfinite(v)]
    return float(f(v)) if v.size else float("nan")


def summarise(ds: Any, wheels: WheelArray | None = None
              ) -> list[ControllerSummary]:
    """`ControllerSummary` of each controller of a Monte Carlo dataset.

    ``wheels`` gives the bounds that scale the violations (default: the
    demo craft's 0.2 N·m·s and 0.05 N·m per wheel).
    """
    h_max = 0.2 if wheels is None else float(np.min(wheels.h_max))
    m_max = 0.05 if wheels is None else float(np.min(wheels.m_max))
    rate = np.asarray(ds["rate_max"], float)
    cone = np.deg2rad(np.asarray(ds["keep_out_deg"], float)
                      if "keep_out_deg" in ds else np.zeros_like(rate))
    out = []
    for c in CONTROLLERS:
        def col(k: str) -> np.ndarray:
            return np.asarray(ds[f"{c}_{k}"], float)

        ran = col("failed") == 0
        settle = col("settle_time")[ran]
        scaled_rate = np.where(rate > 0, col("rate_violation")
                               / np.where(rate > 0, rate, 1.0), 0.0)
        keep = (np.where(cone > 0, col("keep_out_violation")
                         / np.where(cone > 0, cone, 1.0), 0.0)
                if f"{c}_keep_out_violation" in ds else np.zeros_like(rate))
        out.append(ControllerSummary(
            controller=c, draws=int(col("failed").size),
            failed=int(np.sum(~ran)),
            momentum=int(np.sum(col("momentum_violation")[ran]
                                > VIOLATION_TOL * h_max)),
            torque=int(np.sum(col("torque_violation")[ran]
                              > VIOLATION_TOL * m_max)),
            rate=int(np.sum(scaled_rate[ran] > VIOLATION_TOL)),
            settled=int(np.sum(np.isfinite(settle))),
            settle_median=_nan_stat(np.median, settle),
            settle_worst=_nan_stat(np.max, settle),
            final_error_max=_nan_stat(np.max, col("final_error")[ran]),
            energy_median=_nan_stat(np.median, col("energy")[ran]),
            step_time_median=_nan_stat(np.median, col("step_time")[ran]),
            rate_over_median=_nan_stat(np.median, scaled_rate[ran]),
            rate_over_max=_nan_stat(np.max, scaled_rate[ran]),
            keep_out=int(np.sum(keep[ran] > VIOLATION_TOL))))
    return out


def robust_mc_table(ds: Any, wheels: WheelArray | None = None) -> str:
    """Markdown table: nominal and robust side by side, with ratios.

    Rows: draws, loops broken, momentum / torque / rate / keep-out
    violations,
    the rate overshoot's median and largest [% of the bound], settled
    loops, settling time median and worst [s], largest final
    error [deg], median energy [N²·m²·s], median step time [ms]; the
    last column is robust over nominal (the cost of robustness).
    """
    nom, rob = summarise(ds, wheels)
    rows = [("draws", "draws", "{:d}"), ("loops broken", "failed", "{:d}"),
            ("momentum violations", "momentum", "{:d}"),
            ("torque violations", "torque", "{:d}"),
            ("rate violations", "rate", "{:d}"),
            ("keep-out violations", "keep_out", "{:d}"),
            ("rate overshoot, median [% of bound]", "rate_over_median",
             "{:.3f}"),
            ("rate overshoot, largest [% of bound]", "rate_over_max",
             "{:.3f}"),
            ("settled (0.1°)", "settled", "{:d}"),
            ("settling time, median [s]", "settle_median", "{:.1f}"),
            ("settling time, worst [s]", "settle_worst", "{:.1f}"),
            ("final error, largest [deg]", "final_error_max", "{:.2e}"),
            ("energy, median [N²m²s]", "energy_median", "{:.4g}"),
            ("step time, median [ms]", "step_time_median", "{:.2f}")]
    lines = ["| | nominal MPC | robust MPC | robust / nominal |",
             "|---|---|---|---|"]
    for label, key, fmt in rows:
        a, b = getattr(nom, key), getattr(rob, key)
        if key == "final_error_max":
            a, b = np.rad2deg(a), np.rad2deg(b)
        elif key == "step_time_median":
            a, b = 1e3 * a, 1e3 * b
        elif key.startswith("rate_over"):
            a, b = 100.0 * a, 100.0 * b
        ratio = ("–" if isinstance(a, int) or not a > 0
                 else f"{b / a:.2f}")
        lines.append(f"| {label} | {fmt.format(a)} | {fmt.format(b)} | "
                     f"{ratio} |")
    return "\n".join(lines)
