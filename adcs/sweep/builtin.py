"""The built-in sweeps of ``adcs sweep``: studies and their parameter sets.

Each study is a module-level function (picklable: it runs on Dask
workers) of one case's parameters returning a dict of numbers; solvers it
builds are cached per worker process (the slews' solver cache, the
functions' own caches), not rebuilt per case.

A spacecraft parameter (a built-in name or a TOML file) is read again for
every case and the cached craft and MPC are keyed by its text, so a
worker never reuses the craft of an edited file; the studies that take
one carry ``sweep_inputs`` (the SHA-256 of that text), which keys their
saved chunks (`adcs.sweep.chunks`).
"""

from __future__ import annotations

import functools
import hashlib
from typing import Callable

import numpy as np

from allocation import WheelArray, envelope, torque_reach
from allocation import min_norm_law

from adcs.basilisk.robust_mc import basilisk_mc_case
from adcs.robust_mc import robust_mc_case, robust_mc_params

__all__ = ["SWEEPS", "accuracy_case", "agility_case", "craft_inputs",
           "failure_case", "geometry_case"]


def geometry_case(delta_deg: float, gamma_deg: float,
                  failed: int) -> dict:
    """Pyramid (δ, γ) with one wheel failed (0: none): envelopes, reach."""
    arr = WheelArray.pyramid(np.deg2rad(delta_deg), np.deg2rad(gamma_deg),
                             h_max=1.0, m_max=1.0)
    if failed:
        arr = arr.with_failed(failed - 1)
    env = envelope(arr, "torque")
    reach = torque_reach(arr, min_norm_law(arr), n_directions=200)
    return {"inscribed_radius": env.inscribed_radius,
            "utilisation": env.utilisation,
            "min_norm_mean_reach": reach.mean_direction_fraction,
            "min_norm_worst_reach": reach.min_direction_fraction}


def accuracy_case(seed: int, n_samples: int, mount_tol_deg: float,
                  scale_tol: float) -> dict:
    """One Monte Carlo block of mounting and scale-factor errors."""
    from allocation import monte_carlo_accuracy

    tol = np.deg2rad(mount_tol_deg)
    r = monte_carlo_accuracy(d_delta_tol=tol, d_gamma_tol=tol,
                             scale_tol=scale_tol, n_samples=n_samples,
                             seed=seed)
    angle = np.rad2deg(r.angle)
    return {"samples": n_samples, "angle_mean_deg": float(angle.mean()),
            "angle_p95_deg": float(np.percentile(angle, 95)),
            "angle_max_deg": float(angle.max()),
            "magnitude_p95": float(np.percentile(
                np.abs(r.magnitude_error), 95))}


def _craft_text(spacecraft: str) -> str:
    """Return the TOML text of a built-in name or a file, read now."""
    from ocp.spacecraft import spacecraft_toml

    return spacecraft_toml(spacecraft)


def _craft(spacecraft: str):
    """Return the `Spacecraft` of a built-in name or a TOML file now."""
    return _craft_of(_craft_text(spacecraft), str(spacecraft))


@functools.lru_cache(maxsize=8)
def _craft_of(text: str, source: str):
    from ocp.spacecraft import spacecraft_from_toml

    return spacecraft_from_toml(text, source)


def craft_inputs(row: dict) -> dict:
    """``{"spacecraft": SHA-256 of its TOML text}``: keys saved chunks."""
    text = _craft_text(row["spacecraft"])
    return {"spacecraft": hashlib.sha256(text.encode()).hexdigest()}


def agility_case(spacecraft: str, axis: int, angle_deg: float,
                 N: int) -> dict:
    """Eigenaxis and time-optimal slew times about a body axis.

    ``axis``: index (0-based) of `fibonacci_axes`; the case also returns
    that axis's direction (``axis_x``, ``axis_y``, ``axis_z``). Times in
    seconds.
    """
    from ocp import eigenaxis_slew, quat_from_axis_angle, time_optimal_slew

    sc = _craft(spacecraft)
    directions = fibonacci_axes()
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    qf = quat_from_axis_angle(directions[axis], np.deg2rad(angle_deg))
    eig = eigenaxis_slew(sc, q0, qf)
    opt = time_optimal_slew(sc, q0, qf, N=N)
    x, y, z = (float(v) for v in directions[axis])
    return {"axis_x": x, "axis_y": y, "axis_z": z,
            "eigenaxis_T": eig.T, "time_optimal_T": opt.T,
            "saving": 1.0 - opt.T / eig.T, "success": float(opt.success)}


def fibonacci_axes(n: int = 12) -> np.ndarray:
    """``n`` unit axes spread over the sphere, (n, 3)."""
    from allocation import fibonacci_directions

    return fibonacci_directions(n).T


def failure_setup(spacecraft: str, angle_deg: float,
                  text: str | None = None) -> tuple:
    """``(q0, qf, T [s], dt [s])`` of the failure sweep's slew.

    ``angle_deg`` about (1, 1, 1) from rest; ``T`` the craft's eigenaxis
    slew time (its wheels and rate limit), ``dt = T/30`` clipped to
    [0.1, 10] s the MPC's sample time. ``text``: the craft's TOML text,
    when the caller has read it already.
    """
    from ocp import eigenaxis_slew, quat_from_axis_angle

    text = _craft_text(spacecraft) if text is None else text
    sc = _craft_of(text, str(spacecraft))
    qf = quat_from_axis_angle([1.0, 1.0, 1.0], np.deg2rad(angle_deg))
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    T = eigenaxis_slew(sc, q0, qf).T
    return q0, qf, T, float(np.clip(T / 30.0, 0.1, 10.0))


def failure_case(spacecraft: str, wheel: int, t_fail: float,
                 angle_deg: float) -> dict:
    """MPC slew about (1, 1, 1) with wheel ``wheel`` (1..N) failing.

    The craft's own failed wheels stay failed throughout.
    """
    from ocp.mpc import simulate_mpc

    text = _craft_text(spacecraft)          # read once: one craft per case
    q0, qf, T, dt = failure_setup(spacecraft, angle_deg, text)
    before = simulate_mpc(_mpc(text, str(spacecraft), -1, dt), q0, qf,
                          t_final=t_fail)
    tr = before.trajectory
    assert tr.wheel_momentum is not None      # a wheeled craft's loop
    after = simulate_mpc(_mpc(text, str(spacecraft), wheel - 1, dt),
                         tr.q[-1], qf,
                         t_final=2.0 * T, w0=tr.w[-1],
                         h0=tr.wheel_momentum[-1], hold=0.3 * T)
    return {"settle_time": t_fail + after.settle_time,
            "final_error_deg": float(np.rad2deg(after.final_error)),
            "peak_torque": max(before.peak_torque, after.peak_torque),
            "momentum_violation": max(before.momentum_violation,
                                      after.momentum_violation)}


@functools.lru_cache(maxsize=16)
def _mpc(text: str, source: str, failed: int, dt: float):
    """Build (once per worker) an RTI MPC, wheel ``failed`` out (-1: none).

    The craft's inertia, wheels (its own failed wheels stay failed) and
    rate limit. ``text`` is the craft's TOML text (the cache key: an
    edited file gets a new MPC). Built once per worker process and
    reused: `simulate_mpc` resets it (and so takes it over in the calling
    thread) before every run.
    """
    from ocp import rigid_spacecraft
    from ocp.mpc import AttitudeMPC

    sc = _craft_of(text, source)
    wheels = sc.wheels if failed < 0 else sc.wheels.with_failed(failed)
    return AttitudeMPC(rigid_spacecraft(sc.inertia, wheels), dt=dt,
                       rti=True, rate_max=sc.rate_max)


def _geometry(quick: bool, **_) -> list[dict]:
    deltas = np.arange(40.0, 71.0, 10.0 if quick else 2.5)
    gammas = np.arange(30.0, 61.0, 15.0 if quick else 5.0)
    return [{"delta_deg": float(d), "gamma_deg": float(g), "failed": f}
            for d in deltas for g in gammas for f in range(5)]


def _accuracy(quick: bool, samples: int | None = None, **_) -> list[dict]:
    total = samples or (20_000 if quick else 1_000_000)
    block = min(total, 100_000)
    return [{"seed": k, "n_samples": block, "mount_tol_deg": 0.5,
             "scale_tol": 0.02} for k in range(max(total // block, 1))]


def _agility(quick: bool, spacecraft: str = "demo", **_) -> list[dict]:
    axes = range(2 if quick else 12)
    angles = (30.0, 90.0) if quick else (10.0, 30.0, 60.0, 90.0, 135.0,
                                         180.0)
    return [{"spacecraft": spacecraft, "axis": a, "angle_deg": ang,
             "N": 20 if quick else 60} for a in axes for ang in angles]


def _failures(quick: bool, spacecraft: str = "demo",
              t_fail: float | None = None, **_) -> list[dict]:
    wheels = _craft(spacecraft).wheels
    t_fail = (5.0 if quick else 10.0) if t_fail is None else float(t_fail)
    # a wheel the craft has already lost cannot fail again
    return [{"spacecraft": spacecraft, "wheel": w, "t_fail": t_fail,
             "angle_deg": 30.0 if quick else 90.0}
            for w in range(1, wheels.n_wheels + 1)
            if w - 1 not in wheels.failed]


def _robust(quick: bool, samples: int | None = None,
            spacecraft: str = "demo", rate_max: float = 0.0,
            rate_margin: float = 0.0, tree_products: float = 0.0,
            keep_out_deg: float = 0.0, **_) -> list[dict]:
    # draws of the robust-MPC Monte Carlo (adcs.robust_mc): 200, quick 8;
    # a rate bound's loops run 60 s (the slew is slower)
    return robust_mc_params(
        samples or (8 if quick else 200), spacecraft=spacecraft,
        t_final=30.0 if quick else (60.0 if rate_max > 0 else 50.0),
        rate_max=rate_max, rate_margin=rate_margin,
        tree_products=tree_products, keep_out_deg=keep_out_deg)


# the engine hashes a case's inputs through this hook (`chunk_inputs`)
setattr(agility_case, "sweep_inputs", craft_inputs)
setattr(failure_case, "sweep_inputs", craft_inputs)

#: name -> (study, parameter generator, what it shows)
SWEEPS: dict[str, tuple[Callable[..., dict], Callable[..., list[dict]],
                        str]] = {
    "geometry": (geometry_case, _geometry,
                 "pyramid δ × γ × single failure: envelope and reach"),
    "accuracy": (accuracy_case, _accuracy,
                 "Monte Carlo of mounting and scale errors (1e6 samples)"),
    "agility": (agility_case, _agility,
                "eigenaxis and time-optimal slew times: axes × angles"),
    "failures": (failure_case, _failures,
                 "closed-loop MPC slews with each wheel failing"),
    "robust": (robust_mc_case, _robust,
               "Monte Carlo of plants (inertia ±20 %, products, axis "
               "tilts): nominal against robust MPC"),
    "robust-basilisk": (basilisk_mc_case, _robust,
                        "the robust Monte Carlo's draws flown in Basilisk "
                        "(needs the basilisk extra)"),
}
