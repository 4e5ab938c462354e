"""C code export of the allocation laws, QPs, dynamics and MPC step.

`export_c` writes a self-contained folder: one C source (CasADi
``CodeGenerator``, no CasADi at run time) with its header, the C sources
of every solver it calls (DAQP, MIT, in ``daqp/`` with its licence:
`ocp.codegen.daqp_static`), a test driver ``main.c`` that calls every
function on sample inputs and times it with ``clock_gettime``, a
``Makefile``, a ``CMakeLists.txt`` and a README. A C99 compiler and libm
are all the build needs; nothing in the folder names a path outside it.
No exported function allocates: the memory is the caller's ``w``/``iw``
arrays or static (DAQP's workspace, laid out at generation time by
`patch_daqp_static`). The wheel QP is solved
exactly in closed form for 3 or 4 working wheels (no solver in its C,
``wheel_qp_fast_path``); otherwise, and for the other QPs, every QP inside
is a code-generatable conic: daqp (≈ 4x faster than qrqp) when the casadi
daqp plugin is there, else qrqp. Builds use ``-O3``. The generated
qrqp is edited to reuse its KKT factorization while the active set does
not change (`patch_qrqp`, bit-identical results); a generated DAQP conic
returns its point on a failed solve instead of aborting the call
(`patch_daqp_failure`: the Functions check their points themselves);
``casadi_fmax``/``casadi_fmin`` are written so that the compiler inlines
them (`patch_minmax`, the same NaN rules).

Exported functions (names are the C symbols):

* ``min_norm(M[3]) -> m[N]``: [1] eq. (5), the closed form;
* ``wheel_qp(M[3], h[N]) -> (m[N], alpha, violation)``: the bounded wheel
  QP (`allocation.conic_allocator_function`, torque and momentum bounds;
  closed form, or daqp / qrqp, ``wheel_qp_plugin``);
* ``duty_qp(theta[9], kmax[6]) -> (duty[6], slack, violation, status)``:
  the thruster duty-cycle QP (`thrusters.build_qp` data; ``theta = (P_T,
  M_X, M_Z, H[3], τ[3])``; `duty_qp_function`: an attainability test,
  DAQP on the reduced QP, a KKT certificate; ``status`` 0 optimal, 1
  bound relaxed, 2 infeasible, 3 invalid input, 4 solver failed);
* ``dynamics(x, u, tau) -> xdot`` and ``rk4(x, u, tau, dt) -> xf``: the
  spacecraft model (`ocp.rigid_spacecraft`);
* ``mpc_step(x, qf, tau, z_prev, lam_x_prev, lam_g_prev) -> (u, z, lam_x,
  lam_g, cost, violation, first_violation, defect)``: one MPC step
  (`ocp.mpc.AttitudeMPC`, sqpmethod + qrqp), and ``mpc_rti_step`` (its
  real-time-iteration variant).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Sequence


import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from adcs_common.codegen import CompileError, CompilerNotFound
from adcs_common.exceptions import InvalidValueError
from adcs_common.paths import output_folder
from adcs_common.validation import as_finite_scalar, check_positive
from allocation import WheelArray, conic_allocator_function, min_norm_function
from allocation.qp.conic_function import wheel_qp_method
from thrusters import ThrusterSet

from ocp.models.rigid import SpacecraftModel, rigid_spacecraft
from ocp.mpc.primal_qp import PQP_DIR, PQP_SINGLE_FLAG
from ocp.mpc.primal_qp import copy_sources as copy_pqp_sources
from ocp.mpc.riccati_qp import copy_sources as copy_rqp_sources
from ocp.spacecraft import load_spacecraft
from .build import build_exported, run_driver
from .checks import check_loop_steps, loop_plan
from .daqp_static import (
    DAQP_DIR,
    DAQP_SOURCES,
    copy_daqp_sources,
    patch_daqp_static,
)
from .driver import _driver_source, _readme, write_build_files
from .patches import (
    patch_braces,
    patch_daqp_failure,
    patch_daqp_warm_start,
    patch_minmax,
    patch_unused_parameters,
    patch_zeros,
)
from .precision import (DAQP_SINGLE_FLAG,
                        check_precision, check_single,
                        patch_qrqp_failure, to_single,
                        wheel_qp_options)
from .plugins import daqp_available, duty_qp_function, resolve_qp_plugin
from .mpc_variants import MPC_VARIANTS, check_variants as _check_variants
from .mpc_variants import check_variant_options, mpc_functions
from .qrqp_patch import patch_qrqp
from .result import ExportResult, SOURCE
from .linux_target import LINUX_TARGETS
from .target import (CORES, build_target, check_target, daqp_c_sources,
                     target_head, write_target_files)


__all__ = [
    "CompileError",
    "CompilerNotFound",
    "ExportResult",
    "build_exported",
    "daqp_available",
    "default_functions",
    "duty_qp_function",
    "export_c",
    "patch_daqp_failure",
    "patch_daqp_static",
    "patch_daqp_warm_start",
    "patch_minmax",
    "patch_qrqp",
    "run_driver",
]


def default_functions(*, wheels: WheelArray, inertia: ArrayLike | None = None,
                      thrusters: ThrusterSet | None = None,
                      cycle: float = 2.0,
                      thruster_h_max: float = 0.012, dt: float = 0.5,
                      horizon: int = 20, mpc_max_iter: int = 50,
                      mpc_variants: Sequence[str] = (
                          "mpc_step", "mpc_rti_step", "mpc_cond_rti_step"),
                      wheel_qp_plugin: str | None = "qrqp",
                      wheel_qp_fast_path: bool = True,
                      duty_qp_plugin: str | None = "qrqp",
                      rate_max: float | None = None,
                      condensed_qp_plugin: str | None = None,
                      condensed_qp_max_iter: int | None = None,
                      stagewise_qp_plugin: str | None = None,
                      stagewise_qp_max_iter: int | None = None,
                      precision: str = "double",
                      mpc_move_blocks: Any = None,
                      mpc_scenarios: Any = None, mpc_keep_out: Any = None
                      ) -> tuple[dict[str, ca.Function],
                                 dict[str, list[np.ndarray]],
                                 SpacecraftModel]:
    """Return the Functions `export_c` exports and a sample input each.

    Parameters are those of `export_c`.

    Returns
    -------
    functions : dict
        C name -> casadi.Function.
    samples : dict
        C name -> list of input arrays (the driver's inputs); keys
        ``"name:label"`` are extra timed cases of ``name``.
    model : SpacecraftModel
    """
    from adcs_common.quaternion import quat_from_axis_angle

    if not isinstance(wheels, WheelArray):
        raise InvalidValueError(
            f"wheels must be a WheelArray, got {type(wheels).__name__}")
    dt = as_finite_scalar(dt, "dt")
    check_positive(dt, "dt")
    J = np.diag([3.0, 2.5, 3.5]) if inertia is None else inertia
    model = rigid_spacecraft(J, wheels)
    n = wheels.n_wheels
    rng = np.random.default_rng(1)
    fns: dict[str, ca.Function] = {}
    samples: dict[str, list[np.ndarray]] = {}

    fns["min_norm"] = min_norm_function(wheels)
    M = 0.5 * float(np.min(wheels.m_max)) * rng.normal(size=3)
    samples["min_norm"] = [M]
    plugin = resolve_qp_plugin(wheel_qp_plugin)
    fns["wheel_qp"] = conic_allocator_function(
        wheels, dt=dt, plugin=plugin, fast_path=wheel_qp_fast_path,
        **wheel_qp_options(precision, plugin))
    h = 0.5 * np.asarray(wheels.h_max) * rng.uniform(-1, 1, n)
    samples["wheel_qp"] = [2.0 * M, h]
    # a demand beyond the attainable set (alpha < 1): the driver times it
    # as "wheel_qp:saturated"
    samples["wheel_qp:saturated"] = [
        4.0 * float(np.sum(wheels.m_max)) * M / np.linalg.norm(M), h]
    if thrusters is not None:
        fns["duty_qp"] = duty_qp_function(thrusters, cycle, thruster_h_max,
                                          plugin=duty_qp_plugin,
                                          precision=precision)
        samples["duty_qp"] = [np.array([0.0, 0.01, -0.02, 0.004, 0.0,
                                        -0.003, 1e-4, 0.0, 0.0]),
                              np.ones(thrusters.n)]
        # a burn (thrust demanded) and a hold whose demand relaxes the
        # momentum bound: timed as "duty_qp:burn", "duty_qp:relaxed"
        samples["duty_qp:burn"] = [np.array([0.5, 0.002, -0.001, 0.004,
                                             0.0, -0.003, 0.0, 0.0, 0.0]),
                                   np.ones(thrusters.n)]
        samples["duty_qp:relaxed"] = [np.array([0.0, 0.02, -0.008, 0.01,
                                                0.0, -0.01, 0.0, 0.0,
                                                0.0]),
                                      np.ones(thrusters.n)]
    fns["dynamics"] = model.dynamics
    x = model.state(quat_from_axis_angle([1, 2, 3], 0.7),
                    0.01 * rng.normal(size=3), 0.3 * h)
    u = np.asarray(wheels.m_max) * rng.uniform(-1, 1, n)
    samples["dynamics"] = [x, u, 1e-3 * rng.normal(size=3)]
    fns["rk4"] = model.rk4_step(1)
    samples["rk4"] = [x, u, np.zeros(3), np.array(dt)]
    if mpc_variants:
        condensed = resolve_qp_plugin(condensed_qp_plugin,
                                             "condensed_qp_plugin")
        mpc_fns, mpc_samples = mpc_functions(
            model, mpc_variants, horizon=horizon, dt=dt,
            max_iter=mpc_max_iter, rate_max=rate_max,
            condensed_plugin=condensed, precision=precision,
            move_blocks=mpc_move_blocks, scenarios=mpc_scenarios,
            keep_out=mpc_keep_out, condensed_max_iter=condensed_qp_max_iter,
            stagewise=(stagewise_qp_plugin, stagewise_qp_max_iter))
        fns.update({k: _renamed(f, k) for k, f in mpc_fns.items()})
        samples.update(mpc_samples)
    return fns, samples, model


def _target_plugins(target: str, out: Path, wheel: str | None,
                    duty: str | None
                    ) -> tuple[str | None, str | None, str | None]:
    """QP plugins of an export: a Cortex-M target takes the host's, since
    the folder carries DAQP's C sources (`copy_daqp_sources`) whenever a
    function calls DAQP."""
    return wheel, duty, None


def _craft_parts(spacecraft, wheels, thrusters, inertia, rate_max
                 ) -> tuple[WheelArray, ThrusterSet | None, Any,
                            float | None]:
    """``(wheels, thrusters, inertia, rate_max)`` of `export_c`'s
    arguments: those of ``spacecraft`` (a `Spacecraft`, a catalogue name
    or a TOML file), or those given; checked."""
    if spacecraft is not None:
        if wheels is not None or thrusters is not None or inertia is not None:
            raise InvalidValueError(
                "give spacecraft= or wheels=/thrusters=/inertia=, not both")
        sc = load_spacecraft(spacecraft)
        wheels, thrusters, inertia = sc.wheels, sc.thrusters, sc.inertia
        if rate_max is None:
            rate_max = sc.rate_max
    elif not isinstance(wheels, WheelArray):
        raise InvalidValueError(
            f"give spacecraft= or wheels= (a WheelArray), got wheels of "
            f"type {type(wheels).__name__}")
    if thrusters is not None and not isinstance(thrusters, ThrusterSet):
        raise InvalidValueError(
            f"thrusters must be a ThrusterSet, got {type(thrusters).__name__}")
    return wheels, thrusters, inertia, rate_max


def _renamed(f: ca.Function, name: str) -> ca.Function:
    """``f`` wrapped under a new name (C symbol)."""
    args = f.mx_in()
    return ca.Function(name, args, f.call(args), f.name_in(), f.name_out())


def _write_source(fns: dict, out: Path, reuse_factorization: bool,
                  precision: str = "double", int_type: str = "long long"
                  ) -> tuple[int, bool, dict[str, tuple[int, int]],
                             list[Path]]:
    """Generate ``adcs_codegen.c`` and edit it for flight.

    ``int_type`` is ``casadi_int``'s C type: a Cortex-M export's is
    ``int`` (its sparsity patterns and index arrays, in flash, halve;
    `casadi.external` needs a host export, ``long long``).
    Returns ``(daqp_patched, qrqp_patched, daqp_conics, solver_sources)``:
    the DAQP failure patch's edit count, the qrqp reuse patch applied, each
    DAQP conic's static workspace and the DAQP C sources copied beside
    the source (none without a DAQP conic).
    """
    cg = ca.CodeGenerator(f"{SOURCE}.c", {"with_header": True, **(
        {"casadi_real": "float"} if precision == "single" else {}), **(
        {"casadi_int": int_type} if int_type != "long long" else {})})
    for f in fns.values():
        cg.add(f)
    cg.generate(f"{out}/")
    source = out / f"{SOURCE}.c"
    patched = False
    text, daqp_patched = patch_daqp_failure(source.read_text())
    text, _ = patch_minmax(text)
    text, _ = patch_zeros(text, max(f.nnz_in(i) for f in fns.values()
                                    for i in range(f.n_in())))
    text, _ = patch_daqp_warm_start(text)
    # DAQP's workspace in static storage, its sources beside the source
    text, daqp_conics = patch_daqp_static(text)
    if reuse_factorization:
        text, patched = patch_qrqp(text)
    text, _ = patch_unused_parameters(text)       # last: the others
    if precision == "single":                    # match CasADi's text
        text, _ = to_single(patch_qrqp_failure(text)[0])
    text, _ = patch_braces(text)                 # the compile's time
    source.write_text(text)
    solver_sources = (copy_daqp_sources(out, precision == "single")
                      if daqp_conics else [])
    solver_sources += copy_pqp_sources(out, text, precision)
    solver_sources += copy_rqp_sources(out, text, precision)
    if not daqp_conics and (out / DAQP_DIR / "api.c").is_file():
        for name in DAQP_SOURCES:                # stale from an earlier
            (out / DAQP_DIR / name).unlink(missing_ok=True)   # export
    return daqp_patched, patched, daqp_conics, solver_sources


def export_c(out_dir: str | os.PathLike[str], spacecraft: Any | None = None, *,
             wheels: WheelArray | None = None,
             thrusters: ArrayLike | None = None,
             inertia: ArrayLike | None = None, cycle: float = 2.0,
             thruster_h_max: float = 0.012, dt: float = 0.5,
             horizon: int = 20, mpc_max_iter: int = 50,
             mpc_variants: ArrayLike = ("mpc_step", "mpc_rti_step",
                                          "mpc_cond_rti_step"),
             mpc_move_blocks: Any = None,
             mpc_scenarios: Any = None, mpc_keep_out: Any = None,
             wheel_qp_plugin: str | None = None,
             wheel_qp_fast_path: bool = True,
             duty_qp_plugin: str | None = None,
             condensed_qp_plugin: str | None = None,
             condensed_qp_max_iter: int | None = None,
             stagewise_qp_plugin: str | None = None,
             stagewise_qp_max_iter: int | None = None,
             qrqp_reuse_factorization: bool = True,
             rate_max: float | None = None,
             target: str = "host", precision: str = "double",
             build: bool = False,
             cc: str = "gcc", repeats: int = 1000,
             loop_steps: int | None = None,
             progress: bool = False) -> ExportResult:
    """Generate C for the toolbox's laws, QPs, model and MPC step.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Output folder (created).
    spacecraft : ocp.spacecraft.Spacecraft, str or pathlib.Path, optional
        The craft (a `Spacecraft`, a catalogue name or a TOML file): its
        wheels, thrusters and inertia. Give it or ``wheels`` (with the
        optional ``thrusters`` and ``inertia``), not both.
    wheels : WheelArray, optional
        Wheel array of the allocation laws, model and MPC.
    thrusters : thrusters.ThrusterSet, optional
        Thruster set of the duty-cycle QP (skipped when None).
    inertia : array_like (3, 3) or (3,), optional
        J [kg·m²] of the model (default diag(3.0, 2.5, 3.5), theory §2).
    cycle : float
        Thruster cycle T_T [s].
    thruster_h_max : float
        Momentum bound of the duty QP [N·m·s] (0.012 in [4]).
    dt : float
        Sample time of the wheel QP momentum bound, RK4 and MPC [s].
    horizon : int
        MPC horizon (intervals).
    mpc_max_iter : int
        SQP iteration limit of ``mpc_step`` and ``mpc_cond_step`` (and of
        ``mpc_rti_step``'s fallback).
    mpc_move_blocks : int or sequence of int, optional
        Move blocking of the stage-wise steps (`AttitudeMPC` ``move_blocks``).
    mpc_scenarios : sequence of Scenario, optional
        Scenarios of the robust steps (`ocp.mpc.RobustMPC`); default the
        nominal craft and the 8 corners of ±20 % principal inertia.
    mpc_keep_out : KeepOut or sequence of KeepOut, optional
        Keep-out cones of the stage-wise and robust steps (`AttitudeMPC`
        ``keep_out``).
    mpc_variants : sequence of str
        MPC steps to export (`MPC_VARIANTS`): ``"mpc_step"`` (sqpmethod +
        qrqp to convergence), ``"mpc_rti_step"`` (one SQP step per
        sample), each ~1.2 MB of C at horizon 20; ``"mpc_cond_step"``,
        ``"mpc_cond_rti_step"``: the condensed SQP
        (`ocp.mpc.condensed`; DAQP where `daqp_available`, else qrqp),
        ~0.8 MB; empty for none.
        Default: both sqpmethod steps and the condensed RTI step.
    wheel_qp_plugin : {None, "daqp", "qrqp"}
        Conic of ``wheel_qp``: ``"daqp"`` (≈ 4x faster in C),
        ``"qrqp"`` or None: daqp when `daqp_available`, else qrqp.
    wheel_qp_fast_path : bool
        Solve the wheel QP exactly without the conic where possible
        (`allocation.qp.conic_function.conic_allocator_function`: a closed
        form for 3 or 4 working wheels, so ``wheel_qp`` then needs no
        solver library; with more wheels the minimum-norm point when it
        is within the bounds, else the conic).
    condensed_qp_plugin : {None, "daqp", "pqp"}
        QP of the condensed steps: DAQP (None, where `daqp_available`) or
        ``"pqp"``, the toolbox's primal active set in C started where
        the step starts, with a phase one where δu = 0 breaks a bound
        (`ocp.mpc.primal_qp`; its sources and wrapper go to ``pqp/``).
    condensed_qp_max_iter : int, optional
        With ``"pqp"``: its iteration cap (`AttitudeMPC`
        ``solver_options`` ``qp_max_iter``; default 1000). A capped QP's
        point keeps every bound and lowers the cost; the step applies it
        and its output ``qp_capped`` says so.
    stagewise_qp_plugin : {None, "rqp"}
        QP of the stage-wise steps (``mpc_sw_step``, ``mpc_sw_rti_step``):
        their Riccati interior point (None) or ``"rqp"``, the toolbox's
        Riccati active set in C, memory linear in the horizon
        (`ocp.mpc.riccati_qp`; its sources and wrapper go to ``rqp/``).
    stagewise_qp_max_iter : int, optional
        With ``"rqp"``: its iteration cap, as ``condensed_qp_max_iter``.
    duty_qp_plugin : {None, "daqp", "qrqp"}
        Conic of ``duty_qp``'s fast path (`duty_qp_function`): daqp
        (sub-microsecond), qrqp or None: daqp when `daqp_available`.
    qrqp_reuse_factorization : bool
        Edit the generated qrqp to reuse its KKT factorization when the
        active set recurs within a solve (`patch_qrqp`: same results bit
        for bit, ≈ 30 % off an MPC step).
    rate_max : float, optional
        Body-rate limit [rad/s] of the MPC steps (``|ω_i| <= rate_max``
        on every planned state, as `ocp.mpc.AttitudeMPC`); default: the
        spacecraft's ``rate_max`` (none without a spacecraft).
    target : {"host", "cortex-m7", "cortex-m4f", "aarch64"}
        Where the driver runs (`ocp.codegen.target`): the host (``cc``),
        an aarch64 Linux computer (the host's driver, built static with
        ``aarch64-linux-gnu-gcc`` and run by `run_driver` under
        ``qemu-aarch64``, `ocp.codegen.linux_target`; no shared
        library), or a Cortex-M7 (double-precision FPU) / Cortex-M4F (single
        precision: double in software) on qemu: a bare-metal driver,
        startup code and linker script are written too, built with
        ``arm-none-eabi-gcc`` (``-Wall -Wextra -Werror``) and a memory
        report is written. A target export's ``casadi_int`` is ``int``
        (half the flash of its sparsity patterns; `casadi.external`
        needs a host export). Without DAQP's C sources in the folder
        (`ocp.codegen.target.daqp_c_sources`) every QP of a target export
        is solved by qrqp (``"daqp"`` asked for is an error).
    precision : {"double", "single"}
        ``"single"``: ``casadi_real`` is float, with float literals and
        float math (`ocp.codegen.precision.to_single`), the QP and SQP
        tolerances of `ocp.codegen.precision.TOLERANCES`, DAQP in its
        float build (``-DDAQP_SINGLE_PRECISION``) where double uses it
        (``duty_qp``'s with its proximal iterations, which float needs:
        `ocp.codegen.precision.TOLERANCES` ``duty_daqp_eps_prox``);
        MPC steps: the condensed RTI one, and the stage-wise RTI one
        with ``stagewise_qp_plugin="rqp"`` (`SINGLE_MPC_VARIANTS`).
    build : bool
        Compile the driver and a shared library with ``cc`` (a target:
        the ELF with ``arm-none-eabi-gcc``, `build_target`).
    cc : str
        C compiler.
    repeats : int
        Calls per function timed by the driver (a Cortex-M driver: a
        tenth, at least 3; instruction counts do not vary between calls
        on the same input).
    loop_steps : int, optional
        Steps of the driver's closed loops (default: sized from the craft,
        `ocp.codegen.checks.loop_plan`: 2.5 times its eigenaxis slew
        time). The driver fails its check, and `run_driver` raises
        `ocp.codegen.checks.DriverCheckError`, when a loop ends beyond
        its tolerance of the target, breaks a bound or goes NaN.
    progress : bool
        Show a progress bar during the build.

    Returns
    -------
    ExportResult

    Raises
    ------
    CompilerNotFound
        ``build`` is True and ``cc`` is not on PATH (the sources are
        written first).
    """
    wheels, thrusters, inertia, rate_max = _craft_parts(
        spacecraft, wheels, thrusters, inertia, rate_max)
    out = output_folder(out_dir, "out_dir")
    if int(repeats) < 1:
        raise InvalidValueError(f"repeats must be >= 1, got {repeats!r}")
    check_loop_steps(loop_steps)
    mpc_variants = _check_variants(mpc_variants)
    cortex_m = check_target(target) in CORES
    wheel_qp_plugin, duty_qp_plugin, condensed = _target_plugins(
        target, out, wheel_qp_plugin, duty_qp_plugin)
    condensed = condensed_qp_plugin if condensed is None else condensed
    plugin = resolve_qp_plugin(wheel_qp_plugin)
    method = wheel_qp_method(wheels, wheel_qp_fast_path)
    duty_plugin = resolve_qp_plugin(duty_qp_plugin, "duty_qp_plugin")
    condensed = resolve_qp_plugin(condensed, "condensed_qp_plugin")
    check_single(check_precision(precision), {
        "condensed_qp_plugin": condensed,
        "stagewise_qp_plugin": stagewise_qp_plugin}, mpc_variants)
    check_variant_options(mpc_variants, move_blocks=mpc_move_blocks,
                          scenarios=mpc_scenarios, keep_out=mpc_keep_out,
                          qp_cap=(condensed, condensed_qp_max_iter),
                          stagewise=(stagewise_qp_plugin,
                                     stagewise_qp_max_iter))
    fns, samples, model = default_functions(
        wheels=wheels, inertia=inertia, thrusters=thrusters, cycle=cycle,
        thruster_h_max=thruster_h_max, dt=dt, horizon=horizon,
        mpc_max_iter=mpc_max_iter, mpc_move_blocks=mpc_move_blocks,
        mpc_scenarios=mpc_scenarios, mpc_keep_out=mpc_keep_out,
        mpc_variants=tuple(mpc_variants), wheel_qp_plugin=plugin,
        wheel_qp_fast_path=wheel_qp_fast_path, duty_qp_plugin=duty_plugin,
        rate_max=rate_max, condensed_qp_plugin=condensed,
        condensed_qp_max_iter=condensed_qp_max_iter,
        stagewise_qp_plugin=stagewise_qp_plugin,
        stagewise_qp_max_iter=stagewise_qp_max_iter, precision=precision)
    daqp_patched, patched, daqp_conics, solver_sources = _write_source(
        fns, out, qrqp_reuse_factorization, precision,
        "int" if cortex_m else "long long")
    loop = loop_plan(model, samples, dt, rate_max=rate_max,
                     horizon=horizon, steps=loop_steps, precision=precision)
    driver = out / "main.c"
    driver.write_text(_driver_source(fns, samples, int(repeats), model,
                                     dt, precision, loop=loop))
    # DAQP's float build with float casadi_real (c_float: 4 bytes)
    cflags = [DAQP_SINGLE_FLAG] if precision == "single" and daqp_conics \
        else []
    if precision == "single" and (out / PQP_DIR / "pqp.c").is_file():
        cflags.append(PQP_SINGLE_FLAG)
    write_build_files(out, solver_sources, cflags)
    real = 4 if precision == "single" else 8
    static_bytes = sum(real * nw + 4 * niw for nw, niw in daqp_conics.values())
    readme = out / "README.md"
    readme.write_text(_readme(
        fns, samples, plugin, [p.relative_to(out).as_posix()
                               for p in solver_sources],
        method, patched, duty_plugin, static_bytes, precision))
    res = ExportResult(out_dir=out, functions=fns, samples=samples,
                       source=out / f"{SOURCE}.c",
                       header=out / f"{SOURCE}.h", driver=driver,
                       makefile=out / "Makefile", readme=readme,
                       extras={
                           "wheel_qp_plugin": plugin, "rate_max": rate_max,
                           "duty_qp_plugin": duty_plugin, "cflags": cflags,
                           "wheel_qp_method": method, "qrqp_patched": patched,
                           "daqp_patched": daqp_patched, "closed_loop": loop,
                           "condensed_qp_plugin": condensed,
                           "stagewise_qp_plugin": stagewise_qp_plugin,
                           "solver_sources": solver_sources,
                           "daqp_static": daqp_conics, "ldflags": ["-lm"],
                           "daqp_static_bytes": static_bytes,
                           "precision": precision,
                           "casadi_int_bytes": 4 if cortex_m else 8})
    if cortex_m:
        res = write_target_files(res, target, _driver_source(
            fns, samples, max(int(repeats) // 10, 3), model, dt,
            precision, head=target_head(), loop=loop))
        return build_target(res) if build else res
    return _build_host_like(res, target, build, cc, progress)


def _build_host_like(res: ExportResult, target: str, build: bool, cc: str,
                     progress: bool) -> ExportResult:
    """The host export or a Linux target's (`linux_target`), built."""
    if target in LINUX_TARGETS:
        tcc, runner, link = LINUX_TARGETS[target]
        res = ExportResult(**{**res.__dict__, "extras": {
            **res.extras, "target": target, "runner": list(runner)}})
        return build_exported(res, cc=tcc, progress=progress, shared=False,
                              link_flags=link) if build else res
    if build:
        return build_exported(res, cc=cc, progress=progress)
    return res
