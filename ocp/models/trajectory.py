"""The slew trajectory returned by every slew law and NLP of `ocp`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from adcs_common.results import ResultMixin

from adcs_common.quaternion import quat_error_angle

__all__ = ["SlewTrajectory"]


@dataclass(frozen=True, eq=False, repr=False)
class SlewTrajectory(ResultMixin):
    """A rest-to-rest slew on a time grid, with ZOH controls.

    Attributes
    ----------
    method : str
        ``"eigenaxis"``, ``"quaternion_feedback"``, ``"time_optimal"`` or
        ``"min_energy"``.
    T : float
        Slew time [s]: the final time of an NLP or of the eigenaxis law, the
        settling time of a feedback law (NaN when it never settles).
    t : numpy.ndarray, shape (K + 1,)
        Time grid [s].
    q : numpy.ndarray, shape (K + 1, 4)
        Attitude quaternions (scalar-first, body to reference).
    w : numpy.ndarray, shape (K + 1, 3)
        Body rates [rad/s].
    torque : numpy.ndarray, shape (K, 3)
        Control torque on the body over each interval [N·m] (``-A m`` with
        wheels).
    wheel_torque : numpy.ndarray (K, N) or None
        Motor torques m [N·m]; None for a torque-box model.
    wheel_momentum : numpy.ndarray (K + 1, N) or None
        Wheel momenta H_w [N·m·s]; None for a torque-box model.
    qf : numpy.ndarray, shape (4,)
        Target attitude.
    status : str
        Solver or law status (``"Solve_Succeeded"``, ``"closed_form"``,
        ``"settled"``, ``"not_settled"``, IPOPT's return status...).
    success : bool
        True when the solver converged / the law reached the target.
    solve_time : float
        Wall time of the solve [s] (0 for closed forms).
    iterations : int
        Solver iterations (0 for closed forms).
    extras : dict
        Method-specific data (objective, transcription, solver, gains...).
    """

    method: str
    T: float
    t: np.ndarray
    q: np.ndarray
    w: np.ndarray
    torque: np.ndarray
    wheel_torque: np.ndarray | None
    wheel_momentum: np.ndarray | None
    qf: np.ndarray
    status: str
    success: bool
    solve_time: float = 0.0
    iterations: int = 0
    extras: dict[str, Any] = field(default_factory=dict)

    # ---------------------------------------------------------------- metrics
    @property
    def dt(self) -> np.ndarray:
        """Interval lengths (K,) [s]."""
        return np.diff(self.t)

    @property
    def energy(self) -> float:
        """Control energy :math:`\\sum_i \\int m_i^2\\,dt` [N²·m²·s].

        Body torque when there are no wheels; exact for the
        piecewise-constant controls.
        """
        u = self.torque if self.wheel_torque is None else self.wheel_torque
        return float(np.sum(np.sum(u ** 2, axis=1) * self.dt))

    @property
    def peak_wheel_torque(self) -> float:
        """Largest ``|m_i|`` [N·m] (largest body-axis torque if no wheels)."""
        u = self.torque if self.wheel_torque is None else self.wheel_torque
        return float(np.max(np.abs(u)))

    @property
    def peak_wheel_momentum(self) -> float:
        """Largest ``|H_i|`` [N·m·s] (NaN if no wheels)."""
        if self.wheel_momentum is None:
            return float("nan")
        return float(np.max(np.abs(self.wheel_momentum)))

    @property
    def final_error(self) -> float:
        """Attitude error angle at the end of the grid [rad]."""
        return float(quat_error_angle(self.q[-1], self.qf))

    def error_angle(self) -> np.ndarray:
        """Attitude error angle to ``qf`` at each grid point (K + 1,) [rad]."""
        return quat_error_angle(self.q, self.qf)

    # ---------------------------------------------------------------- plots
    def plot(self, axes: Any | None = None) -> Any:
        """Plot error angle, body rates, torques and wheel momenta.

        Parameters
        ----------
        axes : sequence of 4 matplotlib Axes, optional
            Where to draw; a new figure is made otherwise.

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        if axes is None:
            fig, axes = plt.subplots(4, 1, sharex=True, figsize=(7, 9))
        else:
            fig = axes[0].figure
        t = self.t
        axes[0].plot(t, np.rad2deg(self.error_angle()))
        axes[0].set_ylabel("error angle [deg]")
        axes[1].plot(t, self.w)
        axes[1].set_ylabel("ω [rad/s]")
        axes[1].legend(["x", "y", "z"], loc="best")
        u = self.torque if self.wheel_torque is None else self.wheel_torque
        n = u.shape[1]
        names = ([f"RW{i + 1}" for i in range(n)]
                 if self.wheel_torque is not None else ["x", "y", "z"])
        axes[2].step(t, np.vstack([u, u[-1:]]), where="post")
        axes[2].set_ylabel("m [N·m]" if self.wheel_torque is not None
                           else "τ [N·m]")
        axes[2].legend(names, loc="best")
        if self.wheel_momentum is not None:
            axes[3].plot(t, self.wheel_momentum)
            axes[3].legend(names, loc="best")
        axes[3].set_ylabel("H_w [N·m·s]")
        axes[3].set_xlabel("t [s]")
        axes[0].set_title(f"{self.method}: T = {self.T:.4g} s "
                          f"({self.status})")
        return fig
