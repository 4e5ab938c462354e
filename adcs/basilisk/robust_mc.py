"""Monte Carlo draws of the robust-MPC study flown in Basilisk.

Each draw of `adcs.robust_mc.draw_plant` (inertia, products, wheel-axis
tilts) becomes a Basilisk craft: its hub (`convert.hub_inertia` of the
drawn inertia and the tilted axes), a reactionWheelStateEffector on the
tilted axes and simpleNav, integrated by RK4 at ``dt_dynamics``. The
nominal and the robust MPC (both on the nominal craft) fly it through
`AttitudeMPCModule`, which forms the wheel momenta with the nominal axes
(the controller does not know the tilts). The same draw flown by
`ocp.mpc.simulate_mpc` (CVODES, the controller given the plant's exact
state) is the reference each Basilisk run is compared with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from adcs_common.quaternion import quat_from_axis_angle
from adcs_common.results import ResultMixin
from allocation import WheelArray

from . import require_basilisk
from .convert import mrp_to_quaternion, rotor_momenta
from .mpc_scenario import _angle, mpc_task

__all__ = ["BasiliskDraw", "basilisk_robust_mc", "fly_in_basilisk"]


@dataclass(frozen=True, eq=False, repr=False)
class BasiliskDraw(ResultMixin):
    """One controller on one drawn plant, in Basilisk and in ours.

    Attributes
    ----------
    draw : int
        The draw (`adcs.robust_mc.draw_plant`).
    controller : str
        ``"nominal"`` or ``"robust"``.
    final_error_basilisk, final_error_ours : float
        Attitude error at the end [rad].
    max_error_difference : float
        Largest difference of the error angle along the run [rad].
    max_torque_difference : float
        Largest difference of a commanded wheel torque [N·m].
    momentum_excess, torque_excess : float
        Largest excess of ``|H_w|`` (true rotor momenta) and of the
        commanded ``|m|`` over their bounds in Basilisk (<= 0: none)
        [N·m·s], [N·m].
    energy_basilisk : float
        ``Σ_i ∫ m_i² dt`` of the commands [N²·m²·s].
    faults : int
        Steps where the module wrote zero torques (the MPC raised).
    """

    draw: int
    controller: str
    final_error_basilisk: float
    final_error_ours: float
    max_error_difference: float
    max_torque_difference: float
    momentum_excess: float
    torque_excess: float
    energy_basilisk: float
    faults: int


def _basilisk_run(mpc: Any, inertia: np.ndarray, wheels: WheelArray,
                  qf: np.ndarray, t_final: float, dt_dynamics: float,
                  Js: float) -> tuple:
    """Fly ``mpc`` on the plant in Basilisk.

    Returns ``(q (K+1, 4), H_w (K+1, N) true rotor momenta, commands
    (K, N), faults)``, sampled at the MPC's period.
    """
    from Basilisk.utilities import SimulationBaseClass, macros

    from .scenarios import run_recorded, spacecraft_task

    sim = SimulationBaseClass.SimBaseClass()
    _, rw, nav = spacecraft_task(sim, inertia, wheels, Js, dt_dynamics)
    ctl = mpc_task(sim, mpc, qf, Js, nav, rw)
    recs = run_recorded(sim, [nav.attOutMsg, rw.rwSpeedOutMsg,
                              ctl.rwMotorTorqueOutMsg],
                        macros.sec2nano(mpc.dt), t_final)
    n = wheels.n_wheels
    k = int(np.ceil(t_final / mpc.dt - 1e-9)) + 1
    sigma = np.asarray(recs[0].sigma_BN)[:k]
    omega = np.asarray(recs[0].omega_BN_B)[:k]
    speeds = np.asarray(recs[1].wheelSpeeds)[:k, :n]
    u = np.asarray(recs[2].motorTorque)[:k - 1, :n]
    q = np.array([mrp_to_quaternion(s) for s in sigma])
    h = np.array([rotor_momenta(wheels, Js, sp, w)
                  for sp, w in zip(speeds, omega)])
    return q, h, u, int(ctl.faults)


def fly_in_basilisk(draw: int, controller: str, mpc: Any, *, seed: int = 0,
                    angle: float = np.deg2rad(90.0), t_final: float = 30.0,
                    dt_dynamics: float = 0.1, Js: float = 1e-3
                    ) -> BasiliskDraw:
    """Fly draw ``draw`` of ``seed`` by ``mpc`` in Basilisk and in ours.

    Parameters
    ----------
    draw, seed : int
        The plant (`adcs.robust_mc.draw_plant` of ``mpc``'s model).
    controller : str
        Its label (``"nominal"``, ``"robust"``).
    mpc : ocp.mpc.AttitudeMPC
        The controller (e.g. `ocp.mpc.RobustMPC`), on the nominal craft.
    angle : float
        Slew about (1, 1, 0) from rest [rad].
    t_final, dt_dynamics : float
        Run length and Basilisk's RK4 step [s].
    Js : float
        Rotor spin inertia [kg·m²].
    """
    require_basilisk()
    from ocp import rigid_spacecraft
    from ocp.mpc import simulate_mpc

    from adcs.robust_mc import draw_plant

    model = mpc.model
    d = draw_plant(model.inertia, model.wheels, seed, draw)
    qf = quat_from_axis_angle([1.0, 1.0, 0.0], angle)
    ours = simulate_mpc(mpc, [1.0, 0.0, 0.0, 0.0], qf, t_final=t_final,
                        plant=rigid_spacecraft(d.inertia, d.wheels))
    q, h, u, faults = _basilisk_run(mpc, d.inertia, d.wheels, qf, t_final,
                                    dt_dynamics, Js)
    err_b = np.array([_angle(x, qf) for x in q])
    err_o = ours.trajectory.error_angle()
    wh = model.wheels
    return BasiliskDraw(
        draw=int(draw), controller=controller,
        final_error_basilisk=float(err_b[-1]),
        final_error_ours=float(err_o[-1]),
        max_error_difference=float(np.abs(err_b - err_o).max()),
        max_torque_difference=float(np.abs(
            u - ours.trajectory.wheel_torque).max()),
        momentum_excess=float(np.max(np.abs(h) - wh.h_max)),
        torque_excess=float(np.max(np.abs(u) - wh.m_max)),
        energy_basilisk=float(np.sum(u ** 2) * mpc.dt), faults=faults)


def basilisk_robust_mc(draws: int = 3, *, seed: int = 0,
                       t_final: float = 30.0, spread: float = 0.2,
                       **options: Any) -> list[BasiliskDraw]:
    """Draws ``0..draws-1`` flown by the nominal and the robust MPC.

    The demo craft (J = diag(3.0, 2.5, 3.5) kg·m², the pyramid of
    0.2 N·m·s, 0.05 N·m wheels); both MPCs stage-wise RTI, horizon 20,
    0.5 s, the robust one over `ocp.mpc.inertia_corners` (``spread``).
    ``options``: `fly_in_basilisk`'s (angle, dt_dynamics, Js).
    """
    require_basilisk()
    from ocp import rigid_spacecraft
    from ocp.mpc import AttitudeMPC, RobustMPC, inertia_corners

    model = rigid_spacecraft(np.diag([3.0, 2.5, 3.5]),
                             WheelArray.pyramid(h_max=0.2, m_max=0.05))
    mpcs = {"nominal": AttitudeMPC(model, solver="stagewise", rti=True),
            "robust": RobustMPC(model, inertia_corners(model.inertia,
                                                       spread), rti=True)}
    return [fly_in_basilisk(k, name, mpc, seed=seed, t_final=t_final,
                            **options)
            for k in range(draws) for name, mpc in mpcs.items()]
