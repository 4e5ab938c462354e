"""Slew comparisons: NLP vs eigenaxis vs quaternion feedback (theory §4)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array, check_items
from adcs_common.validation import as_finite_scalar, as_vector, check_positive
from allocation import WheelArray

from adcs_common.quaternion import quat_from_axis_angle, quat_mul
from ocp.guidance import eigenaxis_slew, quaternion_feedback_slew
from ocp.models.rigid import check_inertia
from ocp.missions.four_wheel_lagrange import four_wheel_craft
from ocp.slews.nlp import min_energy_slew, time_optimal_slew
from ocp.models.trajectory import SlewTrajectory

if TYPE_CHECKING:
    import pandas as pd


__all__ = [
    "METEOR_M_INERTIA",
    "SlewComparisonRow",
    "compare_slews",
    "comparison_table",
    "meteor_m_spacecraft",
    "four_wheel_slew_spacecraft",
]

#: ASSUMED inertia of Meteor-M No. 2 [kg·m²]: [1] gives the wheel
#: pyramid but no inertia; a 2.7 t spacecraft of about 5 x 2.5 x 2.5 m.
METEOR_M_INERTIA = np.diag([3000.0, 2700.0, 2000.0])


def meteor_m_spacecraft(h_max: float = 25.0, m_max: float = 0.2
                        ) -> tuple[np.ndarray, WheelArray]:
    """Assumed Meteor-M No. 2 inertia and its δ=55°, γ=45° pyramid.

    Parameters
    ----------
    h_max, m_max : float
        Wheel momentum [N·m·s] and torque [N·m] capacity (assumed).

    Returns
    -------
    inertia : numpy.ndarray (3, 3)
        `METEOR_M_INERTIA`.
    wheels : WheelArray
    """
    return METEOR_M_INERTIA.copy(), WheelArray.pyramid(h_max=h_max,
                                                       m_max=m_max)


def four_wheel_slew_spacecraft() -> tuple[np.ndarray, WheelArray]:
    """Newton–Euler inertia and 17M71 wheels of the [3] spacecraft."""
    sc = four_wheel_craft()
    return sc.inertia, sc.wheels


@dataclass(frozen=True)
class SlewComparisonRow:
    """One line of the comparison table.

    Attributes
    ----------
    case : str
        Spacecraft / manoeuvre label.
    angle_deg : float
        Slew angle [deg].
    method : str
        ``eigenaxis``, ``time_optimal``, ``min_energy`` (at the eigenaxis
        time) or ``quaternion_feedback``.
    T : float
        Slew (or settling) time [s].
    energy : float
        :math:`\\sum_i \\int m_i^2 dt` [N²·m²·s].
    peak_wheel_torque : float
        max ``|m_i|`` [N·m].
    peak_wheel_momentum : float
        max ``|H_i|`` [N·m·s].
    success : bool
        Solver converged / law settled.
    solve_time : float
        Wall time of the NLP solve [s] (0 for closed forms).
    """

    case: str
    angle_deg: float
    method: str
    T: float
    energy: float
    peak_wheel_torque: float
    peak_wheel_momentum: float
    success: bool
    solve_time: float

    @classmethod
    def from_trajectory(cls, case: str, angle_deg: float,
                        traj: SlewTrajectory) -> "SlewComparisonRow":
        """Summarise a `SlewTrajectory`."""
        return cls(case, float(angle_deg), traj.method, float(traj.T),
                   traj.energy, traj.peak_wheel_torque,
                   traj.peak_wheel_momentum, bool(traj.success),
                   float(traj.solve_time))


def compare_slews(inertia: ArrayLike, wheels: WheelArray, axis: ArrayLike,
                  angles_deg: ArrayLike, *,
                  case: str = "", q0: ArrayLike | None = None, N: int = 60,
                  feedback_frequency: float | None = None,
                  settle_angle: float = np.deg2rad(0.1),
                  ) -> tuple[list[SlewComparisonRow],
                  list[SlewTrajectory]]:
    """Compare slew laws on one spacecraft for several angles.

    For each angle about the body ``axis``: the eigenaxis bang–coast–bang
    law, the time-optimal NLP, the minimum-energy NLP at the eigenaxis
    time, and the quaternion PD feedback (settling time to
    ``settle_angle``), all with the same wheel limits.

    Parameters
    ----------
    inertia : array_like (3, 3)
        J [kg·m²].
    wheels : WheelArray
        Wheel array (limits ``m_max``, ``h_max``).
    axis : array_like (3,)
        Body eigenaxis of the slews.
    angles_deg : sequence of float
        Slew angles [deg].
    case : str
        Label for the table.
    q0 : array_like (4,), optional
        Initial attitude (identity by default).
    N : int
        NLP intervals.
    feedback_frequency : float, optional
        ω_n of the PD [rad/s]; default ``4 / T_eigenaxis`` per angle.
    settle_angle : float
        Settling threshold of the PD [rad].

    Returns
    -------
    rows : list of SlewComparisonRow
    trajectories : list of SlewTrajectory
        In the same order.
    """
    J = check_inertia(inertia)
    axis = as_vector(axis, 3, "axis")
    q0 = (np.array([1.0, 0.0, 0.0, 0.0]) if q0 is None
          else as_vector(q0, 4, "q0"))
    angles = np.atleast_1d(as_finite_array(angles_deg, "angles_deg"))
    if angles.ndim != 1 or len(angles) == 0:
        raise InvalidValueError("angles_deg must be a non-empty sequence")
    check_positive(angles, "angles_deg")
    rows: list[SlewComparisonRow] = []
    trajs: list[SlewTrajectory] = []
    for ang in angles:
        qf = quat_mul(q0, quat_from_axis_angle(axis, np.deg2rad(ang)))
        eig = eigenaxis_slew(J, q0, qf, wheels=wheels)
        wn = (4.0 / eig.T if feedback_frequency is None
              else as_finite_scalar(feedback_frequency,
                                    "feedback_frequency"))
        runs = [
            eig.trajectory(4 * N),
            time_optimal_slew(J, q0, qf, wheels=wheels, N=N),
            min_energy_slew(J, q0, qf, wheels=wheels, N=N, T=eig.T),
            quaternion_feedback_slew(
                J, q0, qf, wheels=wheels, natural_frequency=wn,
                t_final=6.0 * eig.T, dt=eig.T / (4 * N),
                settle_angle=settle_angle),
        ]
        for tr in runs:
            rows.append(SlewComparisonRow.from_trajectory(case, ang, tr))
            trajs.append(tr)
    return rows, trajs


def comparison_table(rows: list[SlewComparisonRow]) -> str:
    """Markdown table of comparison rows (times [s], energy [N²·m²·s])."""
    head = ("| case | angle [deg] | method | T [s] | Σ∫m² dt [N²m²s] | "
            "peak m [N·m] | peak H [N·m·s] | ok |\n"
            "|---|---:|---|---:|---:|---:|---:|---|\n")
    lines = [
        f"| {r.case} | {r.angle_deg:g} | {r.method} | {r.T:.2f} | "
        f"{r.energy:.4g} | {r.peak_wheel_torque:.4f} | "
        f"{r.peak_wheel_momentum:.3f} | {'yes' if r.success else 'no'} |"
        for r in rows]
    return head + "\n".join(lines) + "\n"


def comparison_frame(rows: list[SlewComparisonRow]) -> pd.DataFrame:
    """Comparison rows as a `pandas.DataFrame` (one row per method)."""
    import dataclasses

    import pandas as pd

    rows = check_items(rows, SlewComparisonRow, "rows")
    return pd.DataFrame([dataclasses.asdict(r) for r in rows])
