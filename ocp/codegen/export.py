"""C code export of the allocation laws, QPs, dynamics and MPC step.

`export_c` writes one self-contained C source (CasADi ``CodeGenerator``,
no CasADi at run time) with its header, a test driver ``main.c`` that
calls every function on sample inputs and times it with
``clock_gettime``, a ``Makefile`` and a README. The wheel QP is solved
exactly in closed form for 3 or 4 working wheels (no solver in its C,
``wheel_qp_fast_path``); otherwise, and for the other QPs, every QP inside
is a code-generatable conic. A wheel-QP conic is daqp when its header and
the static ``libdaqpstat.a`` of the casadi wheel are found (≈ 4x faster
than qrqp; the build then adds ``-I<casadi>/include
<casadi>/libdaqpstat.a``, see
`allocation.qp.conic_function.conic_c_flags`), otherwise qrqp; with
``wheel_qp_plugin="qrqp"`` the C is self-contained and ``gcc`` and
``libm`` are all the build needs. Builds use ``-O3``. The generated
qrqp is edited to reuse its KKT factorization while the active set does
not change (`patch_qrqp`, bit-identical results).

Exported functions (names are the C symbols):

* ``min_norm(M[3]) -> m[N]``: seed 001 eq. (5), the closed form;
* ``wheel_qp(M[3], h[N]) -> (m[N], alpha, violation)``: the bounded wheel
  QP (`allocation.conic_allocator_function`, torque and momentum bounds;
  closed form, or daqp / qrqp, ``wheel_qp_plugin``);
* ``duty_qp(theta[9], kmax[6]) -> (x[7], violation)``: the thruster
  duty-cycle QP
  (`thrusters.build_qp` data; ``theta = (P_T, M_X, M_Z, H[3], τ[3])``);
* ``dynamics(x, u, tau) -> xdot`` and ``rk4(x, u, tau, dt) -> xf``: the
  spacecraft model (`ocp.rigid_spacecraft`);
* ``mpc_step(x, qf, tau, z_prev, lam_x_prev, lam_g_prev) -> (u, z, lam_x,
  lam_g, cost, violation, first_violation, defect)``: one MPC step
  (`ocp.mpc.AttitudeMPC`, sqpmethod + qrqp), and ``mpc_rti_step`` (its
  real-time-iteration variant).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from adcs_common.exceptions import AdcsError, InvalidValueError
from adcs_common.paths import output_folder
from adcs_common.validation import as_finite_scalar, check_positive
from allocation import WheelArray, conic_allocator_function, min_norm_function
from allocation.qp.conic_function import conic_c_flags, wheel_qp_method

from ocp.models.rigid import SpacecraftModel, rigid_spacecraft
from ocp.spacecraft import load_spacecraft

__all__ = [
    "CompilerNotFound",
    "ExportResult",
    "build_exported",
    "compile_shared",
    "daqp_available",
    "default_functions",
    "duty_qp_function",
    "export_c",
    "patch_qrqp",
    "run_driver",
]

#: Base name of the generated source and header.
SOURCE = "adcs_codegen"
#: Optimisation flags of the builds (driver, object, shared library).
OPT_FLAGS = ("-O3",)
#: Wheel-QP conic plugins `export_c` accepts.
WHEEL_QP_PLUGINS = ("daqp", "qrqp")


def daqp_available() -> bool:
    """Return True when generated C with daqp can be built here.

    Needs the CasADi conic plugin, ``daqp/api.h`` under the casadi
    package's ``include`` and its static ``libdaqpstat.a``.
    """
    root = Path(ca.__file__).parent
    try:
        ok = ca.has_conic("daqp")
    except RuntimeError:
        ok = False
    return (ok and (root / "include" / "daqp" / "api.h").is_file()
            and (root / "libdaqpstat.a").is_file())


def _resolve_wheel_qp_plugin(plugin: str | None) -> str:
    if plugin is None:
        return "daqp" if daqp_available() else "qrqp"
    if plugin not in WHEEL_QP_PLUGINS:
        raise InvalidValueError(
            f"wheel_qp_plugin must be one of {WHEEL_QP_PLUGINS} or None, "
            f"got {plugin!r}")
    if plugin == "daqp" and not daqp_available():
        raise InvalidValueError(
            "wheel_qp_plugin='daqp' needs the casadi daqp plugin, "
            "include/daqp/api.h and libdaqpstat.a in the casadi package; "
            "use 'qrqp' (self-contained C)")
    return plugin


def c_flags(plugin: str) -> tuple[list[str], list[str]]:
    """Compile flags and link arguments for generated C with ``plugin``.

    Returns ``([], ["-lm"])`` for qrqp (self-contained C).
    """
    if plugin != "daqp":
        return [], ["-lm"]
    flags = conic_c_flags("daqp")
    inc = [f for f in flags if f.startswith("-I")]
    return inc, [f for f in flags if not f.startswith("-I")]


class CompilerNotFound(AdcsError, RuntimeError):
    """No C compiler to build the generated code.

    Attributes
    ----------
    compiler : str
        The compiler that was asked for.
    """

    def __init__(self, compiler: str) -> None:
        super().__init__(
            f"C compiler {compiler!r} not found on PATH: install gcc (e.g. "
            "apt-get install gcc) or pass cc= the compiler to use; the "
            "generated sources were written and can be built elsewhere")
        self.compiler = compiler


@dataclass(frozen=True, eq=False)
class ExportResult:
    """What `export_c` wrote (and built).

    Attributes
    ----------
    out_dir : pathlib.Path
        The output folder.
    functions : dict of str to casadi.Function
        The exported Functions by C name (the Python reference of each).
    samples : dict of str to list of numpy.ndarray
        The sample inputs compiled into the driver (by C name; keys
        ``"name:label"`` are extra cases of ``name`` the driver also times,
        e.g. ``"wheel_qp:saturated"``).
    source, header, driver, makefile, readme : pathlib.Path
        The files written.
    executable : pathlib.Path or None
        The built driver (None unless ``build=True``).
    shared_library : pathlib.Path or None
        The built shared library (None unless ``build=True``).
    extras : dict
        ``wheel_qp_plugin`` (conic of ``wheel_qp``), ``wheel_qp_method``
        (`allocation.qp.conic_function.wheel_qp_method`: ``"closed
        form"``, ``"min-norm check + conic"`` or ``"conic"``), ``cflags``
        and ``ldflags`` (what the build adds for daqp: empty and ``-lm``
        for qrqp or a closed form), ``qrqp_patched`` (`patch_qrqp` was
        applied).
    """

    out_dir: Path
    functions: dict[str, ca.Function]
    samples: dict[str, list[np.ndarray]]
    source: Path
    header: Path
    driver: Path
    makefile: Path
    readme: Path
    executable: Path | None = None
    shared_library: Path | None = None
    extras: dict = field(default_factory=dict)


def duty_qp_function(unit, cycle: float, h_max: float, *,
                     plugin: str = "qrqp", **qp_options) -> ca.Function:
    """Build the thruster duty-cycle QP as one casadi Function.

    Built from `thrusters.build_qp` data by the CasADi conic backend of
    `thrusters` (q, l, u formed from ``theta`` inside the graph).

    Parameters
    ----------
    unit : thrusters.ThrusterSet
        The thrusters.
    cycle : float
        Cycle T_T [s].
    h_max : float
        Momentum bound [N·m·s].
    plugin : str
        CasADi conic plugin (``"qrqp"``: self-contained C).
    **qp_options
        Forwarded to `thrusters.build_qp` (tracking, bound, weights).

    Returns
    -------
    casadi.Function
        ``duty_qp(theta[9], kmax[n]) -> (x[n+1], violation)``: duties and
        slack, and the largest scaled constraint violation (check it: qrqp
        can report success on a violated point); ``kmax`` scales each
        thruster's upper duty (ones at the build pressure, see
        `DutyCycleAllocator.set_pressure`).
    """
    from thrusters import build_qp
    from thrusters.qp.backends.casadi_conic_ import conic_function

    return conic_function(build_qp(unit, cycle, h_max, **qp_options),
                          plugin)


def default_functions(*, wheels: WheelArray, inertia=None,
                      thrusters=None, cycle: float = 2.0,
                      thruster_h_max: float = 0.012, dt: float = 0.5,
                      horizon: int = 20,
                      mpc_variants=("mpc_step", "mpc_rti_step"),
                      wheel_qp_plugin: str | None = "qrqp",
                      wheel_qp_fast_path: bool = True
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
    from ocp.mpc.controller import AttitudeMPC

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
    fns["wheel_qp"] = conic_allocator_function(
        wheels, dt=dt, plugin=_resolve_wheel_qp_plugin(wheel_qp_plugin),
        fast_path=wheel_qp_fast_path)
    h = 0.5 * np.asarray(wheels.h_max) * rng.uniform(-1, 1, n)
    samples["wheel_qp"] = [2.0 * M, h]
    # a demand beyond the attainable set (alpha < 1): the driver times it
    # as "wheel_qp:saturated"
    samples["wheel_qp:saturated"] = [
        4.0 * float(np.sum(wheels.m_max)) * M / np.linalg.norm(M), h]
    if thrusters is not None:
        f = duty_qp_function(thrusters, cycle, thruster_h_max)
        fns["duty_qp"] = f
        samples["duty_qp"] = [np.array([0.0, 0.01, -0.02, 0.004, 0.0,
                                        -0.003, 1e-4, 0.0, 0.0]),
                              np.ones(thrusters.n)]
    fns["dynamics"] = model.dynamics
    x = model.state(quat_from_axis_angle([1, 2, 3], 0.7),
                    0.01 * rng.normal(size=3), 0.3 * h)
    u = np.asarray(wheels.m_max) * rng.uniform(-1, 1, n)
    samples["dynamics"] = [x, u, 1e-3 * rng.normal(size=3)]
    fns["rk4"] = model.rk4_step(1)
    samples["rk4"] = [x, u, np.zeros(3), np.array(dt)]
    if mpc_variants:
        qf = quat_from_axis_angle([1.0, 1.0, 0.0], np.deg2rad(90.0))
        x0 = model.state([1.0, 0.0, 0.0, 0.0])
        for name, rti in (("mpc_step", False), ("mpc_rti_step", True)):
            if name not in mpc_variants:
                continue
            ctl = AttitudeMPC(model, horizon=horizon, dt=dt, rti=rti,
                              expand=False)
            fns[name] = _renamed(ctl.step_function, name)
            samples[name] = [x0, qf, np.zeros(3), ctl.initial_guess(x0),
                             np.zeros(ctl.nz), np.zeros(ctl.ng)]
    return fns, samples, model


def _renamed(f: ca.Function, name: str) -> ca.Function:
    """``f`` wrapped under a new name (C symbol)."""
    args = f.mx_in()
    return ca.Function(name, args, f.call(args), f.name_in(), f.name_out())


def export_c(out_dir, spacecraft=None, *,
             wheels: WheelArray | None = None, thrusters=None,
             inertia=None, cycle: float = 2.0,
             thruster_h_max: float = 0.012, dt: float = 0.5,
             horizon: int = 20,
             mpc_variants=("mpc_step", "mpc_rti_step"),
             wheel_qp_plugin: str | None = None,
             wheel_qp_fast_path: bool = True,
             qrqp_reuse_factorization: bool = True,
             build: bool = False,
             cc: str = "gcc", repeats: int = 1000) -> ExportResult:
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
        J [kg·m²] of the model (default diag(3.0, 2.5, 3.5), SPEC 2).
    cycle : float
        Thruster cycle T_T [s].
    thruster_h_max : float
        Momentum bound of the duty QP [N·m·s] (0.012 in seed 004).
    dt : float
        Sample time of the wheel QP momentum bound, RK4 and MPC [s].
    horizon : int
        MPC horizon (intervals).
    mpc_variants : sequence of str
        MPC steps to export: ``"mpc_step"`` (SQP to convergence) and/or
        ``"mpc_rti_step"`` (one SQP step per sample); empty for none.
        Each adds ~1.2 MB of C (~15 s of gcc -O2) at horizon 20.
    wheel_qp_plugin : {None, "daqp", "qrqp"}
        Conic of ``wheel_qp``: ``"daqp"`` (≈ 4x faster in C; needs the
        casadi wheel's ``include/daqp`` and ``libdaqpstat.a`` at build
        time), ``"qrqp"`` (self-contained C) or None: daqp when
        `daqp_available`, else qrqp.
    wheel_qp_fast_path : bool
        Solve the wheel QP exactly without the conic where possible
        (`allocation.qp.conic_function.conic_allocator_function`: a closed
        form for 3 or 4 working wheels, so ``wheel_qp`` then needs no
        solver library; with more wheels the minimum-norm point when it
        is within the bounds, else the conic).
    qrqp_reuse_factorization : bool
        Edit the generated qrqp to reuse its KKT factorization when the
        active set recurs within a solve (`patch_qrqp`: same results bit
        for bit, ≈ 30 % off an MPC step).
    build : bool
        Compile the driver and a shared library with ``cc``.
    cc : str
        C compiler.
    repeats : int
        Calls per function timed by the driver.

    Returns
    -------
    ExportResult

    Raises
    ------
    CompilerNotFound
        ``build`` is True and ``cc`` is not on PATH (the sources are
        written first).
    """
    if spacecraft is not None:
        if wheels is not None or thrusters is not None or inertia is not None:
            raise InvalidValueError(
                "give spacecraft= or wheels=/thrusters=/inertia=, not both")
        sc = load_spacecraft(spacecraft)
        wheels, thrusters, inertia = sc.wheels, sc.thrusters, sc.inertia
    elif wheels is None:
        raise InvalidValueError("give spacecraft= or wheels= (a WheelArray)")
    out = output_folder(out_dir, "out_dir")
    if int(repeats) < 1:
        raise InvalidValueError(f"repeats must be >= 1, got {repeats!r}")
    plugin = _resolve_wheel_qp_plugin(wheel_qp_plugin)
    method = wheel_qp_method(wheels, wheel_qp_fast_path)
    # a closed-form wheel_qp holds no conic: no solver library to link
    cflags, ldflags = c_flags(plugin if method != "closed form" else "")
    fns, samples, model = default_functions(
        wheels=wheels, inertia=inertia, thrusters=thrusters, cycle=cycle,
        thruster_h_max=thruster_h_max, dt=dt, horizon=horizon,
        mpc_variants=tuple(mpc_variants), wheel_qp_plugin=plugin,
        wheel_qp_fast_path=wheel_qp_fast_path)
    cg = ca.CodeGenerator(f"{SOURCE}.c", {"with_header": True})
    for f in fns.values():
        cg.add(f)
    cg.generate(f"{out}/")
    source = out / f"{SOURCE}.c"
    patched = False
    if qrqp_reuse_factorization:
        text, patched = patch_qrqp(source.read_text())
        if patched:
            source.write_text(text)
    driver = out / "main.c"
    driver.write_text(_driver_source(fns, samples, int(repeats), model,
                                     dt))
    makefile = out / "Makefile"
    makefile.write_text(_MAKEFILE.format(
        src=SOURCE, opt=" ".join(OPT_FLAGS), cflags=" ".join(cflags),
        libs=" ".join(ldflags)))
    readme = out / "README.md"
    readme.write_text(_readme(fns, samples, plugin, cflags, ldflags,
                              method, patched))
    res = ExportResult(out_dir=out, functions=fns, samples=samples,
                       source=out / f"{SOURCE}.c",
                       header=out / f"{SOURCE}.h", driver=driver,
                       makefile=makefile, readme=readme,
                       extras={"wheel_qp_plugin": plugin,
                               "wheel_qp_method": method,
                               "qrqp_patched": patched,
                               "cflags": cflags, "ldflags": ldflags})
    if build:
        return build_exported(res, cc=cc)
    return res


#: qrqp's test of a singular KKT factorization (one line of its C).
_QRQP_SINGULAR = ("d->sing = casadi_qr_singular(&d->mina, &d->imina, "
                  "d->nz_r, p->sp_r, p->pc, 1e-12);")
#: qrqp's KKT assembly and factorization (its C).
_QRQP_FACTOR = """  casadi_qrqp_kkt(d);
  casadi_qr(p->sp_kkt, d->nz_kkt, d->w, p->sp_v, d->nz_v, p->sp_r,
            d->nz_r, d->beta, p->prinv, p->pc);
"""
_QRQP_FACTORIZE_HEAD = ("void casadi_qrqp_factorize("
                        "struct casadi_qrqp_data* d) {\n" + """\
  const struct casadi_qrqp_prob* p = d->prob;
  if (d->has_search_dir) {
    d->sing = 1;
    return;
  }
""")
#: Exact text edits of CasADi's generated qrqp (see `patch_qrqp`).
_QRQP_EDITS = (
    ("  casadi_int r_index, r_sign;\n  casadi_int iter;\n};",
     "  casadi_int r_index, r_sign;\n  casadi_int iter;\n"
     "  int fact_valid;\n};"),
    ("  d->iter = 0;\n  return 0;\n}",
     "  d->iter = 0;\n  d->fact_valid = 0;\n  return 0;\n}"),
    ("  for (i = 0; i < p->qp->nz; ++i) d->lincomb[i] = 0;\n",
     "  d->fact_valid = 0;\n"
     "  for (i = 0; i < p->qp->nz; ++i) d->lincomb[i] = 0;\n"),
    (_QRQP_FACTORIZE_HEAD + _QRQP_FACTOR + f"  {_QRQP_SINGULAR}\n}}",
     _QRQP_FACTORIZE_HEAD.replace(
         "  const struct", "  casadi_int i;\n  const struct", 1)
     + """  /* (ocp.codegen.patch_qrqp) The KKT matrix depends on H, A and the
   * set of zero multipliers only; H and A are fixed within one solve,
   * so the factorization of an unchanged set is reused (the same bits).
   * The set of the last factorization is kept in lincomb, which only
   * singular_step uses (and it invalidates the cache). */
  if (d->fact_valid) {
    for (i=0; i<p->qp->nz; ++i)
      if ((d->lam[i]==0) != d->lincomb[i]) break;
    if (i==p->qp->nz) {
      casadi_clear(d->w, p->qp->nz);
"""
     + f"      {_QRQP_SINGULAR}\n      return;\n    }}\n  }}\n"
     + _QRQP_FACTOR
     + "  for (i=0; i<p->qp->nz; ++i) d->lincomb[i] = d->lam[i]==0;\n"
     + "  d->fact_valid = 1;\n"
     + f"  {_QRQP_SINGULAR}\n}}"),
)


def patch_qrqp(source: str) -> tuple[str, bool]:
    """Let CasADi's generated qrqp skip repeated KKT factorizations.

    qrqp factorizes its KKT matrix (a sparse QR, most of an MPC step's
    time) at every iteration, also when the active set has not changed
    since the last factorization, e.g. the final iteration that confirms
    convergence. The KKT matrix is a function of the QP's ``H``, ``A``
    (fixed during one solve) and of which multipliers are zero, so this
    edit keeps that zero pattern of the last factorization and reuses the
    factors when it recurs within the solve: the results are bit for bit
    those of the unedited code. Invalidated at every solve and by qrqp's
    singular-KKT path (which refactorizes the transpose).

    Parameters
    ----------
    source : str
        Generated C text.

    Returns
    -------
    text : str
        The edited text (``source`` unchanged if it holds no qrqp or the
        qrqp text differs from the CasADi version this edit was written
        for, 3.7/3.8).
    applied : bool
        Whether the edit was made.
    """
    if any(source.count(old) != 1 for old, _ in _QRQP_EDITS):
        return source, False
    for old, new in _QRQP_EDITS:
        source = source.replace(old, new)
    return source, True


def _check_cc(cc: str) -> str:
    path = shutil.which(cc)
    if path is None:
        raise CompilerNotFound(cc)
    return path


def build_exported(res: ExportResult, cc: str = "gcc") -> ExportResult:
    """Compile the driver and a shared library of an export.

    Raises
    ------
    CompilerNotFound
        ``cc`` is not on PATH.
    AdcsError
        The compiler failed (its output is in the message).
    """
    _check_cc(cc)
    cflags = list(res.extras.get("cflags", []))
    ldflags = list(res.extras.get("ldflags", ["-lm"]))
    opt = list(OPT_FLAGS)
    exe = res.out_dir / "adcs_driver"
    obj = res.out_dir / f"{SOURCE}.o"
    _run([cc, *opt, "-fPIC", *cflags, "-c", str(res.source), "-o",
          str(obj)])
    lib = res.out_dir / f"{SOURCE}.so"
    _run([cc, "-shared", str(obj), "-o", str(lib), *ldflags])
    _run([cc, *opt, *cflags, "-o", str(exe), str(res.driver), str(obj),
          *ldflags])
    return ExportResult(**{**res.__dict__, "executable": exe,
                           "shared_library": lib})


def compile_shared(source, library, cc: str = "gcc",
                   plugin: str = "qrqp") -> Path:
    """Build ``source`` into the shared library ``library`` (-O3 -fPIC).

    ``plugin="daqp"`` adds the daqp include and static library.
    """
    _check_cc(cc)
    cflags, ldflags = c_flags(plugin)
    _run([cc, *OPT_FLAGS, "-fPIC", "-shared", *cflags, str(source), "-o",
          str(library), *ldflags])
    return Path(library)


def _run(cmd: list[str]) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise AdcsError(f"compilation failed: {' '.join(cmd)}\n"
                        f"{proc.stderr[-2000:]}")


def run_driver(res: ExportResult, timeout: float = 300.0
               ) -> dict[str, dict[str, float]]:
    """Run the built driver; return its timings per function.

    Returns
    -------
    dict
        C name -> ``{"median_us": ..., "max_us": ..., "calls": ...}``
        (for ``closed_loop:<name>``, the per-step times of the closed loop
        the driver runs with the generated RK4 as plant, and its final
        error angle ``final_error_deg``).
    """
    if res.executable is None:
        raise InvalidValueError(
            "res has no executable: call export_c(..., build=True)")
    proc = subprocess.run([str(res.executable)], capture_output=True,
                          text=True, timeout=timeout)
    if proc.returncode != 0:
        raise AdcsError(f"driver failed ({proc.returncode}): "
                        f"{proc.stderr[-2000:]}")
    out: dict[str, dict[str, float]] = {}
    pat = re.compile(r"^TIME (\S+) median_us=(\S+) max_us=(\S+) "
                     r"calls=(\d+)(?: final_error_deg=(\S+))?")
    for line in proc.stdout.splitlines():
        m = pat.match(line)
        if m:
            rec = {"median_us": float(m[2]), "max_us": float(m[3]),
                   "calls": int(m[4])}
            if m[5] is not None:
                rec["final_error_deg"] = float(m[5])
            out[m[1]] = rec
    out["_stdout"] = {"text": proc.stdout}  # type: ignore[dict-item]
    return out


# ------------------------------------------------------------------ C text
def _c_array(name: str, values) -> str:
    v = np.asarray(values, dtype=float).ravel()
    body = ", ".join(f"{x:.17g}" for x in v) if v.size else "0"
    return f"static casadi_real {name}[{max(v.size, 1)}] = {{{body}}};"


def _driver_source(fns: dict[str, ca.Function],
                   samples: dict[str, list[np.ndarray]], repeats: int,
                   model: SpacecraftModel, dt: float) -> str:
    lines = [_DRIVER_HEAD]
    calls = []
    for name, f in fns.items():
        for j in range(f.n_out()):
            lines.append(f"static casadi_real {name}_out{j}"
                         f"[{max(f.nnz_out(j), 1)}];")
        res = ", ".join(f"{name}_out{j}" for j in range(f.n_out()))
        reps = repeats if not name.startswith("mpc") else max(
            repeats // 100, 3)
        # the function's sample, then extra cases "name:label"
        cases = [name] + [k for k in samples if k.startswith(f"{name}:")]
        for case in cases:
            ins = samples[case]
            tag = case.replace(":", "_")
            for i, a in enumerate(ins):
                lines.append(_c_array(f"{tag}_in{i}", a))
            arg = ", ".join(f"{tag}_in{i}" for i in range(len(ins)))
            calls.append(
                f"  {{ const casadi_real* a[] = {{{arg}}};\n"
                f"    casadi_real* r[] = {{{res}}};\n"
                f"    time_call(\"{case}\", {name}, {name}_work, "
                f"{name}_checkout, {name}_release, a, {len(ins)}, r, "
                f"{f.n_out()}, {reps}); }}")
    body = "\n".join(lines)
    loops = []
    for name in fns:
        if name.startswith("mpc"):
            f = fns[name]
            loops.append(
                f"  closed_loop(\"{name}\", {name}, {name}_work, "
                f"{name}_checkout, {name}_release, {name}_in0, {name}_in1,"
                f" {f.nnz_in(0)}, {f.nnz_in(3)}, {f.nnz_in(5)}, "
                f"{model.nu}, {dt!r}, 80);")
    main = ("int main(void) {\n" + "\n".join(calls) + "\n"
            + "\n".join(loops) + "\n  return 0;\n}\n")
    return body + "\n" + (_CLOSED_LOOP if loops else "") + main


_DRIVER_HEAD = r"""/* Test driver of the generated ADCS functions (written by
 * ocp.codegen.export_c). Calls each function on sample inputs, prints the
 * outputs and times REPEATS calls with clock_gettime (CLOCK_MONOTONIC).
 * Output lines "TIME <name> median_us=... max_us=... calls=..." are parsed
 * by ocp.codegen.export.run_driver. */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "adcs_codegen.h"

typedef int (*eval_t)(const casadi_real**, casadi_real**, casadi_int*,
                      casadi_real*, int);
typedef int (*work_t)(casadi_int*, casadi_int*, casadi_int*, casadi_int*);
typedef int (*checkout_t)(void);
typedef void (*release_t)(int);

static double now_us(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return 1e6 * (double)t.tv_sec + 1e-3 * (double)t.tv_nsec;
}

static int cmp_double(const void* a, const void* b) {
  double x = *(const double*)a, y = *(const double*)b;
  return (x > y) - (x < y);
}

static void time_call(const char* name, eval_t f, work_t work,
                      checkout_t checkout, release_t release,
                      const casadi_real** arg, int n_in, casadi_real** res,
                      int n_out, int reps) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const casadi_real** a = malloc(sizeof(casadi_real*) * (sz_arg + n_in));
  casadi_real** r = malloc(sizeof(casadi_real*) * (sz_res + n_out));
  casadi_int* iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
  casadi_real* w = malloc(sizeof(casadi_real) * (sz_w + 1));
  double* t = malloc(sizeof(double) * reps);
  int i, mem = checkout(), flag = 0;
  for (i = 0; i < n_in; ++i) a[i] = arg[i];
  for (i = 0; i < n_out; ++i) r[i] = res[i];
  for (i = 0; i < reps; ++i) {
    double t0 = now_us();
    flag |= f(a, r, iw, w, mem);
    t[i] = now_us() - t0;
  }
  release(mem);
  qsort(t, reps, sizeof(double), cmp_double);
  printf("TIME %s median_us=%.3f max_us=%.3f calls=%d\n", name,
         t[reps / 2], t[reps - 1], reps);
  printf("  %s flag=%d first output:", name, flag);
  for (i = 0; i < 4; ++i) printf(" %.10g", res[0][i]);
  printf("\n");
  free(a); free(r); free(iw); free(w); free(t);
}
"""

_CLOSED_LOOP = r"""
/* Closed loop: mpc step -> plant (the generated rk4) -> next state, with
 * the solution fed back as warm start; times every MPC step. */
static void closed_loop(const char* name, eval_t f, work_t work,
                        checkout_t checkout, release_t release,
                        const casadi_real* x0, const casadi_real* qf,
                        int nx, int nz, int ng, int nu, double dt,
                        int steps) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w, p_arg, p_res, p_iw, p_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  rk4_work(&p_arg, &p_res, &p_iw, &p_w);
  if (p_arg > sz_arg) sz_arg = p_arg;
  if (p_res > sz_res) sz_res = p_res;
  if (p_iw > sz_iw) sz_iw = p_iw;
  if (p_w > sz_w) sz_w = p_w;
  const casadi_real** a = malloc(sizeof(casadi_real*) * (sz_arg + 8));
  casadi_real** r = malloc(sizeof(casadi_real*) * (sz_res + 8));
  casadi_int* iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
  casadi_real* w = malloc(sizeof(casadi_real) * (sz_w + 1));
  casadi_real *x = calloc(nx, sizeof(casadi_real)),
              *xn = calloc(nx, sizeof(casadi_real)),
              *z = calloc(nz, sizeof(casadi_real)),
              *lx = calloc(nz, sizeof(casadi_real)),
              *lg = calloc(ng, sizeof(casadi_real)),
              *u = calloc(nu, sizeof(casadi_real));
  casadi_real tau[3] = {0, 0, 0}, h = dt, cost, viol, viol1, defect;
  double* t = malloc(sizeof(double) * steps);
  int k, i, mem = checkout(), pmem = rk4_checkout();
  memcpy(x, x0, sizeof(casadi_real) * nx);
  for (k = 0; k + nx <= nz; k += nx + nu)  /* cold start: x0 everywhere */
    memcpy(z + k, x0, sizeof(casadi_real) * nx);
  double worst = 0.0;
  for (k = 0; k < steps; ++k) {
    a[0] = x; a[1] = qf; a[2] = tau; a[3] = z; a[4] = lx; a[5] = lg;
    r[0] = u; r[1] = z; r[2] = lx; r[3] = lg; r[4] = &cost; r[5] = &viol;
    r[6] = &viol1; r[7] = &defect;
    double t0 = now_us();
    f(a, r, iw, w, mem);
    t[k] = now_us() - t0;
    if (viol1 > worst) worst = viol1;
    a[0] = x; a[1] = u; a[2] = tau; a[3] = &h;
    r[0] = xn;
    rk4(a, r, iw, w, pmem);
    memcpy(x, xn, sizeof(casadi_real) * nx);
  }
  release(mem);
  rk4_release(pmem);
  double dot = 0.0, nq = 0.0;
  for (i = 0; i < 4; ++i) { dot += x[i] * qf[i]; nq += x[i] * x[i]; }
  dot = fabs(dot) / sqrt(nq);
  if (dot > 1.0) dot = 1.0;
  double err = 2.0 * acos(dot) * 57.295779513082323;
  double tmax = 0.0;
  for (k = 0; k < steps; ++k) if (t[k] > tmax) tmax = t[k];
  qsort(t, steps, sizeof(double), cmp_double);
  printf("TIME closed_loop:%s median_us=%.3f max_us=%.3f calls=%d "
         "final_error_deg=%.3e\n", name, t[steps / 2], tmax, steps, err);
  printf("  closed_loop:%s worst applied-step violation %.3e\n", name,
         worst);
  free(a); free(r); free(iw); free(w); free(t);
  free(x); free(xn); free(z); free(lx); free(lg); free(u);
}

"""

_MAKEFILE = """# Build the generated ADCS functions and their test driver.
# SOLVER_CFLAGS / SOLVER_LIBS: daqp's header folder and static library
# (from the casadi wheel) when wheel_qp uses daqp; empty for qrqp.
CC ?= gcc
CFLAGS ?= {opt}
SOLVER_CFLAGS = {cflags}
SOLVER_LIBS = {libs}

all: adcs_driver {src}.so

adcs_driver: main.c {src}.c {src}.h
\t$(CC) $(CFLAGS) $(SOLVER_CFLAGS) -o $@ main.c {src}.c $(SOLVER_LIBS)

{src}.so: {src}.c
\t$(CC) $(CFLAGS) $(SOLVER_CFLAGS) -fPIC -shared -o $@ {src}.c \\
\t  $(SOLVER_LIBS)

run: adcs_driver
\t./adcs_driver

clean:
\trm -f adcs_driver {src}.so
"""


def _readme(fns: dict[str, ca.Function],
            samples: dict[str, list[np.ndarray]], plugin: str = "qrqp",
            cflags=(), ldflags=("-lm",), method: str = "conic",
            patched: bool = False) -> str:
    rows = []
    for name, f in fns.items():
        ins = ", ".join(f"{f.name_in(i)}[{f.nnz_in(i)}]"
                        for i in range(f.n_in()))
        outs = ", ".join(f"{f.name_out(i)}[{f.nnz_out(i)}]"
                         for i in range(f.n_out()))
        rows.append(f"| `{name}` | {ins} | {outs} |")
    opt = " ".join(OPT_FLAGS)
    build_cmd = " ".join(["gcc", opt, *cflags, "-o adcs_driver main.c",
                          f"{SOURCE}.c", *ldflags])
    if method == "closed form":
        solver_text = ("`wheel_qp` solves its QP exactly in closed form "
                       "(3 or 4 working wheels: the equality leaves a "
                       "point or a segment); the other QPs use CasADi's "
                       "qrqp, generated inline, so only `-lm` is needed.")
    elif plugin == "daqp":
        solver_text = ("`wheel_qp` is solved by DAQP: the source includes "
                       "`daqp/api.h` and links the static `libdaqpstat.a` "
                       "that the casadi wheel ships (paths in the "
                       "Makefile's `SOLVER_CFLAGS` / `SOLVER_LIBS`); the "
                       "other QPs use CasADi's qrqp, generated inline. "
                       "Export with `wheel_qp_plugin=\"qrqp\"` for a "
                       "self-contained source.")
    else:
        solver_text = ("The QPs are solved by CasADi's qrqp, generated "
                       "inline, so only `-lm` is needed.")
    if patched:
        solver_text += (" qrqp is edited to reuse its KKT factorization "
                        "while the active set does not change within a "
                        "solve (`ocp.codegen.patch_qrqp`; same results).")
    return f"""# Generated ADCS C code

Written by `ocp.codegen.export.export_c` (CasADi {ca.__version__} code
generation). `{SOURCE}.c` / `{SOURCE}.h` are C99. {solver_text}

Build and run the driver: `make run` (or
`{build_cmd} && ./adcs_driver`).

Calling convention (CasADi): for a function `f`, query work sizes with
`f_work(&sz_arg, &sz_res, &sz_iw, &sz_w)`, allocate, take a memory slot
with `mem = f_checkout()`, call `f(arg, res, iw, w, mem)` (arg/res arrays
of pointers to dense column vectors) and `f_release(mem)`. `main.c` does
this for every function and times the calls with `clock_gettime`.

Units: SI (N·m, N·m·s, kg·m², rad, s); quaternions scalar-first (w, x,
y, z); wheel torques act on the rotors (the body gets -A m). The QP
outputs `violation` (largest constraint violation of the returned point):
check it, qrqp can report success on a violated point.

| function | inputs | outputs |
|---|---|---|
{chr(10).join(rows)}

The MPC steps shift the previous plan (`z_prev`, multipliers) one
interval, solve by sqpmethod (Gauss–Newton Hessian, qrqp) and return the
command `u` to hold over one sample; feed `z`, `lam_x`, `lam_g` back in
at the next sample. `mpc_rti_step` makes one SQP step per sample.
"""
