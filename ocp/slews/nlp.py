"""Rest-to-rest slews as NLPs: time-optimal and minimum-energy (theory §4).

The NLP is built with CasADi ``nlpsol`` on ``N`` intervals of length
``T/N`` with piecewise-constant controls, by multiple shooting (one RK4
step per interval, ``substeps`` stages) or direct collocation (Legendre
points of degree 3). Limits are wheel-level, through the array —
``|m_i| <= m_max_i`` and ``|H_i| <= h_max_i`` — or a per-axis body torque
box. Decision variables are scaled by the limits and the eigenaxis time.

The time-optimal problem has a stationary point at the eigenaxis slew
(SOLVER_NOTES): started exactly there, IPOPT stops at the eigenaxis time.
The perturbed guess is the eigenaxis slew plus a smooth off-axis rate and
torque, which lets the solver leave it; the default with IPOPT solves
that first on about N/5 intervals and refines (``initial_guess``).

Built solvers are kept per problem shape (`SOLVER_CACHE`): the target, initial
state and scales are NLP parameters, so another slew of the same
spacecraft reuses the solver. ``jit=True`` compiles the NLP (all data as
parameters) to a C library cached on disk. ``solver="fatrop"`` uses a
stage-wise layout with the final time as a state of every stage.
"""

from __future__ import annotations

from typing import Sequence

from numpy.typing import ArrayLike



from adcs_common.exceptions import (
    SolverError,
    InvalidValueError,
)
from adcs_common.validation import as_finite_scalar
from allocation import WheelArray


from ocp.models.trajectory import SlewTrajectory
from ocp.spacecraft.definition import Spacecraft
from .build import clear_solver_cache
from .setup import KeepOut, check_common, setup_slew
from .keepout import solve_clear_of_cones
from .solve import solve_slew
from .solvers import NLP_SOLVERS, solver_entry, available_nlp_solvers
from .transcription import TRANSCRIPTIONS


__all__ = [
    "KeepOut",
    "NLP_SOLVERS",
    "TRANSCRIPTIONS",
    "available_nlp_solvers",
    "clear_solver_cache",
    "min_energy_slew",
    "time_optimal_slew",
]


#: Longest slew a minimum-energy problem may ask for [s] (a year).
MAX_DURATION = 3.2e7


def _guarded(s, solver: str, **kwargs) -> SlewTrajectory:
    """`solve_slew`, its numerical breakdowns as the toolbox's error."""
    try:
        return solve_clear_of_cones(solve_slew, s, solver=solver, **kwargs)
    except (RuntimeError, OverflowError, ZeroDivisionError) as exc:
        raise SolverError(
            f"the slew NLP broke down numerically ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0][:200]}); check the limits and "
            "the time scale", solver=solver) from None


def time_optimal_slew(inertia: ArrayLike | Spacecraft, q0: ArrayLike,
                      qf: ArrayLike, *,
                      torque_max: ArrayLike | None = None,
                      wheels: WheelArray | None = None, N: int = 100,
                      transcription: str = "multiple_shooting",
                      solver: str = "ipopt", expand: bool = True,
                      substeps: int = 1, h0: ArrayLike | None = None,
                      rate_max: float | None = None,
                      initial_guess: str | None = None,
                      perturbation: float = 0.3, seed: int = 0,
                      solver_options: dict | None = None,
                      verify: bool = True,
                      jit: bool | dict = False,
                      keep_out: KeepOut | Sequence[KeepOut] | None = None
                      ) -> SlewTrajectory:
    """Minimum-time rest-to-rest slew from ``q0`` to ``qf`` (free T).

    .. math::
        \\min T \\;\\text{s.t.}\\; \\dot x = f(x, u),\\; q(0) = q_0,\\;
        ω(0) = ω(T) = 0,\\; \\mathrm{vec}(q_f^{*}\\otimes q(T)) = 0,\\;
        |m_i| \\le m_{max,i},\\; |H_i| \\le h_{max,i}

    (or :math:`|u_k| \\le u_{max,k}` for the torque box).

    Parameters
    ----------
    inertia : array_like (3, 3) or (3,), or ocp.spacecraft.Spacecraft
        J [kg·m²], or a `Spacecraft` (its wheels, and its ``rate_max``
        unless given here).
    q0, qf : array_like (4,)
        Initial and final attitude (scalar-first, body to reference).
    torque_max : float or array_like (3,), optional
        Per-axis body torque box [N·m] (instead of ``wheels``).
    wheels : WheelArray, optional
        Wheel array: limits ``m_max`` and ``h_max`` per wheel.
    N : int
        Number of control intervals.
    transcription : {"multiple_shooting", "collocation"}
        Transcription of the dynamics.
    solver : {"ipopt", "fatrop", "sqpmethod", "sqpmethod:qrqp"}
        NLP solver (default ``"ipopt"``). ``"fatrop"`` (where CasADi has
        it; multiple shooting only) exploits the stage structure.
        ``"sqpmethod"`` is CasADi's SQP with qpOASES, ``"sqpmethod:qrqp"``
        the same with qrqp (code-generatable, much faster per iteration):
        both converge on minimum-energy slews, slowly (about 100
        iterations), and stall on time-optimal ones (the status then says
        so; set ``solver_options={"max_iter": ...}`` to bound the time).
    expand : bool
        Build the NLP as an SX graph (what ``expand`` gives: faster
        evaluations) instead of an MX graph of Function calls.
    substeps : int
        RK4 stages per interval (multiple shooting).
    h0 : array_like (N_w,), optional
        Initial wheel momenta [N·m·s] (default zero); final ones are free.
    rate_max : float, optional
        Bound on each body-rate component ``|ω_j|`` [rad/s].
    initial_guess : {None, "coarse", "perturbed_eigenaxis", "eigenaxis"}
        None (default): ``"coarse"`` with IPOPT, ``"perturbed_eigenaxis"``
        with the other solvers (fatrop's coarse solve of the
        Bilimoria–Wie slew ends in another local optimum, T = 3.285).
        ``"perturbed_eigenaxis"``: the eigenaxis slew with a smooth
        off-axis perturbation. ``"coarse"``: that guess solved
        first on about N/5 intervals (a divisor of N where one fits;
        tolerance 1e-4, `COARSE_OPTIONS`), its controls held on the N
        intervals and its states re-simulated, then the N-interval NLP
        solved from there (`WARM_START_OPTIONS`); ``solve_time`` includes
        both solves and ``extras`` holds the coarse figures. Below 30
        intervals it is ``"perturbed_eigenaxis"``. ``"eigenaxis"`` is the
        unperturbed closed form: a stationary point.
    perturbation : float
        Off-axis rate amplitude of the perturbed guess, relative to the
        eigenaxis peak rate.
    seed : int
        Seed of the perturbation direction.
    solver_options : dict, optional
        Options for the CasADi solver, merged over the defaults and
        forwarded untouched.
    verify : bool
        Simulate the optimal controls with CVODES and store the final
        attitude error and rate in ``extras`` (outside ``solve_time``);
        ``success`` then also needs that simulated final error within
        1e-3 rad (``ocp.slews.solve.VERIFY_TOL``), else ``status`` says
        by how much the plant missed.
    jit : bool or dict
        Opt-in: compile the NLP's functions to C (MX graph of mapped
        interval Functions, ``expand`` ignored) with all problem data as
        NLP parameters, so one library serves every slew of the same
        shape (N, wheels or torque box, transcription, solver, options).
        The library is cached on disk, named by the SHA-256 of its code:
        the compile (≈ 8–16 s per library at -O1 on the benchmark slews;
        the coarse start needs two) happens once per machine, later
        processes load it in ≈ 1 s. It is not thread-safe (it changes
        the working directory while generating the code). A dict
        sets ``compiler`` (default $CC, gcc, cc or clang), ``flags``
        (default ``["-O1"]``) and ``cache_dir`` (default
        $ADCS_CACHE_DIR or ``~/.cache/adcs_toolbox/slews``).
    keep_out : KeepOut or sequence of KeepOut, optional
        Cones a body axis must stay out of (e.g. a star tracker away from
        the Sun), imposed at every node; ``extras`` then holds
        ``keep_out_node_margin`` and, with ``verify``,
        ``keep_out_margin`` (smallest margin on the simulated trajectory
        at 8 points per interval) [rad]. ``q0`` and ``qf`` must lie
        outside every cone.

    Returns
    -------
    SlewTrajectory
        ``success`` False and ``status`` the solver's message when the
        solver fails; the iterate is then returned for inspection.

    Raises
    ------
    SolverNotFound
        Unknown or missing solver.
    InvalidValueError, ShapeError
        Bad arguments.
    """
    if initial_guess is None:
        initial_guess = ("coarse" if solver == "ipopt"
                         else "perturbed_eigenaxis")
    if initial_guess not in ("perturbed_eigenaxis", "eigenaxis", "coarse"):
        raise InvalidValueError(
            "initial_guess must be 'perturbed_eigenaxis', 'eigenaxis' or "
            f"'coarse', got {initial_guess!r}")
    solver_entry(solver)
    check_common(N, transcription, substeps)
    perturbation = as_finite_scalar(perturbation, "perturbation")
    s = setup_slew(inertia, q0, qf, wheels, torque_max, h0, rate_max, keep_out)
    pert = 0.0 if initial_guess == "eigenaxis" else perturbation
    return _guarded(s, objective="time", T_fixed=None, N=int(N),
                    transcription=transcription, solver=solver,
                    expand=expand, substeps=int(substeps),
                    initial_guess=("coarse" if initial_guess == "coarse"
                                   else "eigenaxis"),
                    perturbation=pert, seed=seed,
                    solver_options=solver_options, verify=verify, jit=jit)


def min_energy_slew(inertia: ArrayLike, q0: ArrayLike, qf: ArrayLike, *,
                    T: float, torque_max: ArrayLike | None = None,
                    wheels: WheelArray | None = None, N: int = 100,
                    transcription: str = "multiple_shooting",
                    solver: str = "ipopt", expand: bool = True,
                    substeps: int = 1, h0: ArrayLike | None = None,
                    rate_max: float | None = None,
                    solver_options: dict | None = None,
                    verify: bool = True,
                    jit: bool | dict = False,
                    keep_out: KeepOut | Sequence[KeepOut] | None = None
                    ) -> SlewTrajectory:
    """Minimum-energy rest-to-rest slew in a fixed time ``T``.

    .. math::
        \\min \\sum_i \\int_0^T m_i^2\\,dt

    (body torque :math:`\\int |u|^2 dt` for the torque box) under the
    constraints of `time_optimal_slew`. The initial guess is a cubic
    rest-to-rest eigenaxis profile over ``T``, allocated by the
    minimum-norm law (with keep-out cones, perturbed off the eigenaxis
    plane as in `time_optimal_slew`).

    Parameters
    ----------
    T : float
        Slew time [s]; infeasible below the time-optimal one (then
        ``success`` is False).
    inertia, q0, qf, torque_max, wheels, N, transcription, solver
        As `time_optimal_slew`.
    expand, substeps, h0, rate_max, solver_options, verify, jit, keep_out
        As `time_optimal_slew`.

    Returns
    -------
    SlewTrajectory
    """
    solver_entry(solver)
    check_common(N, transcription, substeps)
    T = as_finite_scalar(T, "T")
    if not 0.0 < T <= MAX_DURATION:
        raise InvalidValueError(
            f"T must lie in (0, {MAX_DURATION:g}] s, got {T!r}")
    s = setup_slew(inertia, q0, qf, wheels, torque_max, h0, rate_max, keep_out)
    # a cone on the eigenaxis path makes the planar guess a stationary
    # point (escaping to either side is symmetric): perturb it off-plane
    return _guarded(s, objective="energy", T_fixed=T, N=int(N),
                    transcription=transcription, solver=solver,
                    expand=expand, substeps=int(substeps),
                    initial_guess="cubic",
                    perturbation=0.3 if s.keep_out else 0.0, seed=0,
                    solver_options=solver_options, verify=verify, jit=jit)
