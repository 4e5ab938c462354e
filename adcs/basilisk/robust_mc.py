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
from typing import Any, TYPE_CHECKING

import numpy as np

from adcs_common.quaternion import quat_from_axis_angle
from adcs_common.results import ResultMixin
from allocation import WheelArray
from ocp.mpc.keepout import smallest_cone_margin

from . import require_basilisk
from .convert import mrp_to_quaternion, rotor_momenta
from .mpc_scenario import _angle, mpc_task

if TYPE_CHECKING:
    import xarray as xr

__all__ = ["BasiliskDraw", "basilisk_mc_case", "basilisk_robust_mc",
           "fly_in_basilisk", "run_basilisk_mc"]


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

    Returns ``(q (K+1, 4), ω (K+1, 3) [rad/s], H_w (K+1, N) true rotor
    momenta, commands (K, N), the module, q_path)``, sampled at the MPC's
    period; ``q_path`` the hub's attitude at every dynamics step.
    """
    from Basilisk.utilities import SimulationBaseClass, macros

    from .scenarios import run_recorded, spacecraft_task

    sim = SimulationBaseClass.SimBaseClass()
    hub, rw, nav = spacecraft_task(sim, inertia, wheels, Js, dt_dynamics)
    ctl = mpc_task(sim, mpc, qf, Js, nav, rw)
    path = hub.scStateOutMsg.recorder(macros.sec2nano(dt_dynamics))
    sim.AddModelToTask("dyn", path)
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
    q_path = np.array([mrp_to_quaternion(s)
                       for s in np.asarray(path.sigma_BN)])
    return q, omega, h, u, ctl, q_path


def _loop_figures(q: np.ndarray, h: np.ndarray, u: np.ndarray,
                  qf: np.ndarray, wheels: WheelArray, dt: float) -> tuple:
    """``(error (K+1,) [rad], momentum excess [N·m·s], torque excess
    [N·m], energy [N²·m²·s])`` of a Basilisk loop (`_basilisk_run`'s
    samples; an excess <= 0 is none)."""
    return (np.array([_angle(x, qf) for x in q]),
            float(np.max(np.abs(h) - wheels.h_max)),
            float(np.max(np.abs(u) - wheels.m_max)),
            float(np.sum(u ** 2) * dt))


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
    q, _, h, u, ctl, _ = _basilisk_run(mpc, d.inertia, d.wheels, qf, t_final,
                                    dt_dynamics, Js)
    err_b, h_excess, m_excess, energy = _loop_figures(q, h, u, qf,
                                                      model.wheels, mpc.dt)
    err_o = ours.trajectory.error_angle()
    return BasiliskDraw(
        draw=int(draw), controller=controller,
        final_error_basilisk=float(err_b[-1]),
        final_error_ours=float(err_o[-1]),
        max_error_difference=float(np.abs(err_b - err_o).max()),
        max_torque_difference=float(np.abs(
            u - ours.trajectory.wheel_torque).max()),
        momentum_excess=h_excess, torque_excess=m_excess,
        energy_basilisk=energy, faults=int(ctl.faults))


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


def _fly_basilisk(name: str, mpc: Any, d: Any, qf: np.ndarray,
                  t_final: float, rate_max: float, dt_dynamics: float,
                  Js: float) -> dict:
    """One loop in Basilisk: `adcs.robust_mc`'s metrics, prefixed."""
    from ocp.mpc.closed_loop import settle_time

    from adcs.robust_mc import rate_excess

    q, w, h, u, ctl, q_path = _basilisk_run(mpc, d.inertia, d.wheels, qf,
                                            t_final, dt_dynamics, Js)
    err, h_excess, m_excess, energy = _loop_figures(q, h, u, qf,
                                                    mpc.model.wheels, mpc.dt)
    solve = [s.solve_time for s in ctl.steps]
    return {
        f"{name}_failed": float(ctl.faults > 0),
        f"{name}_faults": float(ctl.faults),
        f"{name}_momentum_violation": max(h_excess, 0.0),
        f"{name}_torque_violation": max(m_excess, 0.0),
        f"{name}_rate_violation": rate_excess(w, rate_max),
        f"{name}_keep_out_violation": max(
            0.0, -smallest_cone_margin(mpc.keep_out, q_path)),
        f"{name}_settle_time": settle_time(
            mpc.dt * np.arange(len(err)), err, float(np.deg2rad(0.1))),
        f"{name}_final_error": float(err[-1]),
        f"{name}_energy": energy,
        f"{name}_step_time": (float(np.median(solve)) if solve
                              else float("nan"))}


def basilisk_mc_case(spacecraft: str, seed: int, draw: int, t_final: float,
                     rate_max: float, spread: float, angle_deg: float,
                     horizon: int = 20, dt: float = 0.5,
                     rate_margin: float = 0.0, tree_products: float = 0.0,
                     keep_out_deg: float = 0.0, dt_dynamics: float = 0.1,
                     Js: float = 1e-3) -> dict:
    """`adcs.robust_mc.robust_mc_case` flown in Basilisk.

    The same draw, controllers and outputs (so `adcs.robust_mc.summarise`
    and `robust_mc_table` read both), with the craft in Basilisk (RK4 at
    ``dt_dynamics`` [s], rotors of spin inertia ``Js`` [kg·m²]) and each
    MPC in `AttitudeMPCModule`. Differences: the module does not raise,
    it commands zero torques for a refused step and counts it, so
    ``failed`` is 1 when the loop had a fault (``faults``: how many); the
    rate is Basilisk's navigation rate at the MPC's samples, the momenta
    the true rotor momenta on the tilted axes, the keep-out cone's entry
    from the hub's attitude at every dynamics step; ``step_time`` is the
    median of the module's steps' ``solve_time`` [s].
    """
    require_basilisk()
    from adcs.robust_mc import CONTROLLERS, draw_case

    pair, d, qf, out = draw_case(spacecraft, seed, draw, rate_max, spread,
                                 angle_deg, horizon, dt, rate_margin,
                                 tree_products, keep_out_deg)
    for name, mpc in zip(CONTROLLERS, pair):
        out.update(_fly_basilisk(name, mpc, d, qf, float(t_final),
                                 float(rate_max), float(dt_dynamics),
                                 float(Js)))
    return out


def _craft_inputs(row: dict) -> dict:
    from adcs.robust_mc import robust_mc_case

    return robust_mc_case.sweep_inputs(row)  # type: ignore[attr-defined]


basilisk_mc_case.sweep_inputs = _craft_inputs  # type: ignore[attr-defined]


def run_basilisk_mc(draws: int, *, client: Any = None,
                    progress: bool = False, out: Any = None,
                    **options: Any) -> xr.Dataset:
    """`adcs.robust_mc.run_robust_mc`'s Monte Carlo flown in Basilisk.

    Same draws for the same ``seed`` (`adcs.robust_mc.robust_mc_params`'
    keywords in ``options``), on ``client`` (a `distributed.Client`) or
    here; one ``case`` per draw with `basilisk_mc_case`'s outputs.
    """
    require_basilisk()
    from adcs.robust_mc import robust_mc_params
    from adcs.sweep import run_sweep

    return run_sweep(basilisk_mc_case, robust_mc_params(draws, **options),
                     client=client, progress=progress, out=out)
