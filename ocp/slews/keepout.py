"""Keep-out cones on the continuous path, not only at the nodes.

The NLPs impose each cone at the grid's nodes; between two nodes the
boresight moves on and can dip into a cone (measured: 17 of 18 slews, by
up to 0.147°). The path is therefore checked where it is flown: the
controls run on the plant (CVODES) on a grid 8 times finer, and the
smallest margin there is lowered by the most the margin can dip between
two samples (`path_margin`: its second derivative is bounded by the body
rate and acceleration). When that path margin is negative, the slew is
solved again with every cone widened at the nodes by the entry found
(times 1.25), up to `KEEP_OUT_PASSES` times; a slew that still enters a
cone is not a success, and its status says by how much.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from ocp.models.trajectory import SlewTrajectory

from .setup import KeepOut, SlewSetup

#: Re-solves with widened cones before a slew that enters one is given up.
KEEP_OUT_PASSES = 3
#: Widening of the next pass over the entry found [1].
_WIDEN = 1.25
#: Extra widening of each pass [rad] (1e-5 rad ≈ 0.0006°).
_EXTRA = 1e-5


def path_margin(margin: float, rate_max: float, accel_max: float,
                h_fine: float, half_angle_min: float) -> float:
    """Smallest margin [rad] of the continuous path from sampled margins.

    The boresight ``r = R b`` has ``|r̈| <= |ω̇| + |ω|²``, and its angle θ
    from the avoided direction ``|θ''| <= |r̈| + |ṙ|² |cot θ|``; near a
    cone θ is its half-angle, so between two samples ``h_fine`` apart
    the margin dips below the lower sample by at most ``B h² / 8`` with
    ``B = |ω̇| + |ω|² (1 + |cot α|)`` (the largest rate ``rate_max``
    [rad/s] and acceleration ``accel_max`` [rad/s²] on the samples, 10 %
    over for what lies between them).

    Parameters
    ----------
    margin : float
        Smallest margin at the samples [rad].
    rate_max, accel_max : float
        Largest body rate [rad/s] and acceleration [rad/s²] there.
    h_fine : float
        Sample interval [s].
    half_angle_min : float
        Smallest cone half-angle (or π minus the largest) [rad].
    """
    w, a = 1.1 * rate_max, 1.1 * accel_max
    cot = 1.0 / np.tan(max(half_angle_min, 1e-3))
    bound = a + w * w * (1.0 + abs(cot))
    return float(margin - bound * h_fine ** 2 / 8.0)


def widened(s: SlewSetup, pad: float) -> SlewSetup:
    """The setup with every cone's half-angle widened by ``pad`` [rad]."""
    cones = tuple(KeepOut(k.boresight, k.direction,
                          min(k.half_angle + pad, np.pi - 1e-6))
                  for k in s.keep_out)
    return replace(s, keep_out=cones)


def solve_clear_of_cones(solve: Callable[..., SlewTrajectory],
                         s: SlewSetup, **kwargs) -> SlewTrajectory:
    """``solve(s, **kwargs)``, widened until the path clears every cone.

    Without cones or without ``verify`` it is one solve. Otherwise the
    result's ``extras`` hold ``keep_out_path_margin`` (against the
    original cones, [rad]) and ``keep_out_widening`` (the widening of the
    pass returned, [rad]); ``success`` needs the path margin >= 0.
    """
    traj = solve(s, **kwargs)
    if not s.keep_out or not kwargs.get("verify"):
        return traj
    pad = 0.0
    for _ in range(KEEP_OUT_PASSES):
        margin = _margin(traj, pad)
        if not traj.success or margin >= 0.0:
            break
        pad += _WIDEN * (-margin) + _EXTRA
        traj = solve(widened(s, pad), **kwargs)
    margin = _margin(traj, pad)
    extras = {k: v for k, v in traj.extras.items()
              if k != "keep_out_path_margin_padded"}
    extras.update(keep_out_path_margin=margin, keep_out_widening=pad)
    for key in ("keep_out_margin", "keep_out_node_margin"):
        if key in extras:           # against the cones the user gave
            extras[key] = float(extras[key] + pad)
    success, status = traj.success, traj.status
    if success and not margin >= 0.0:
        success = False
        status = (f"{status}; the path enters a keep-out cone between "
                  f"nodes by {np.rad2deg(-margin):.3g}° after "
                  f"{KEEP_OUT_PASSES} widened solves")
    return replace(traj, success=success, status=status, extras=extras)


def _margin(traj: SlewTrajectory, pad: float) -> float:
    """Path margin against the original cones (``-inf`` if unknown)."""
    m = traj.extras.get("keep_out_path_margin_padded")
    return -np.inf if m is None else float(m + pad)
