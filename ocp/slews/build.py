"""Building slew NLP solvers, cached per problem shape (jit: compiled)."""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import time
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from adcs_common.codegen import (
    CompileError,
    CompilerNotFound,
    find_compiler,
    cached_library,
    compile_c,
    generate_c,
    solver_dependencies,
    compile_progress,
)
from adcs_common.exceptions import (
    InvalidValueError,
    SolverError,
)
from adcs_common.quaternion import (
    quat_conj,
    quat_mul,
    quat_to_dcm,
)
from ocp.models.rigid import (
    effective_torque_matrix,
)
from .setup import SlewSetup
from .transcription import (
    Constraints,
    Layout,
    layout,
    param_sizes,
    pick,
    split_parameters,
)


@dataclass(frozen=True, eq=False)
class BuiltSolver:
    """A slew NLP solver and the numeric pieces of its inputs.

    ``lbg``, ``ubg`` are the constraint bounds, with ``rate_rows`` the
    rows of the ``|ω|² <= rate_max²`` bound (set per solve).
    """

    solver: ca.Function
    lay: Layout
    lbg: np.ndarray
    ubg: np.ndarray
    rate_rows: np.ndarray
    build_time: float


#: Built solvers, keyed by problem structure (and folded data).
SOLVER_CACHE: dict[tuple, BuiltSolver] = {}


SOLVER_CACHE_SIZE = 16


def clear_solver_cache() -> None:
    """Forget every built slew solver (the next solve builds afresh)."""
    SOLVER_CACHE.clear()


def slew_data(s: SlewSetup, T_ref: float, x0: np.ndarray) -> np.ndarray:
    """Numeric slew-data vector (layout of `param_sizes`)."""
    model = s.model
    if model.wheels is None:
        A, sfac, hmax = np.zeros((3, 0)), np.zeros(0), np.zeros(0)
    else:
        A, sfac = effective_torque_matrix(model.wheels)
        hmax = s.h_max
    J = model.inertia
    xs = np.r_[np.ones(4), np.full(3, s.w_scale), hmax]
    keep = [np.r_[k.boresight, k.direction, np.cos(k.half_angle)]
            for k in s.keep_out]
    return np.concatenate([J.ravel("F"), np.linalg.inv(J).ravel("F"),
                           A.ravel("F"), sfac, s.u_max, hmax, [s.w_scale],
                           [T_ref], s.qf, x0 / xs, *keep])


def data_symbols(Sym, sizes: dict[str, int], values: np.ndarray,
                 symbolic: tuple[str, ...]):
    """Return (dict of entries, p) of the slew data.

    The ``symbolic`` entries are symbols, stacked in ``p``; the others
    are the constants of ``values``.
    """
    num = split_parameters(values, sizes)
    d, syms = {}, []
    for k, n in sizes.items():
        if k in symbolic:
            d[k] = Sym.sym(k, n)
            syms.append(d[k])
        else:
            d[k] = ca.DM(num[k])
    return d, ca.vertcat(*syms) if syms else Sym(0, 1)


def options_key(opts: dict | None) -> str | None:
    """Hashable form of solver options, None if they hold objects."""
    try:
        return json.dumps(opts, sort_keys=True)
    except TypeError:
        return None


def build_solver(s: SlewSetup, *, plugin: str, opts: dict, N: int,
                 free_T: bool, transcription, expand: bool,
                 symbolic: tuple[str, ...], values: np.ndarray,
                 jit: dict | None) -> BuiltSolver:
    """Build the NLP solver (parameters ``p``: the `symbolic` entries)."""
    t_build = time.perf_counter()
    model = s.model
    nx, nu, nw = model.nx, model.nu, model.n_wheels
    # fatrop needs the stage-wise layout, the final time as a state
    # (T_{k+1} = T_k) and fixed values as constraint rows
    ocp_form = plugin == "fatrop"
    # expand=True builds the NLP in SX directly (what expanding the MX
    # graph gives, without the MX step); expand=False keeps an MX graph
    # of mapped Function calls (what the JIT compiles: loops, not one
    # flat expression).
    Sym = ca.SX if expand and jit is None else ca.MX
    nk = len(s.keep_out)
    sizes = param_sizes(nx, nu, nw, nk)
    lay = layout(nx, nu, N, free_T, transcription.degree, ocp_form)
    w = Sym.sym("w", lay.n)
    d, p = data_symbols(Sym, sizes, values, symbolic)
    inner = data_symbols(ca.SX, sizes, values, symbolic)
    Xn, Un, Xcn = pick(w, lay.iX), pick(w, lay.iU), pick(w, lay.iXc)
    # (N+1,) scaled, SX or MX (None: fixed T)
    Tk: Any = pick(w, lay.iT) if free_T else None
    dt = (d["Tref"] / N * Tk[:N].T if free_T
          else ca.repmat(d["Tref"] / N, 1, N))
    rate = ca.sum1(Xn[4:7, :] ** 2) if s.rate_max is not None else None
    # keep-out cones: s_j^T R(q_k) b_j - cos(half-angle_j) <= 0 per node
    cones = None
    if nk:
        kd = ca.reshape(d["keep"], 7, nk)
        cones = ca.horzcat(*[
            ca.vertcat(*[kd[3:6, j].T @ quat_to_dcm(Xn[:4, k]) @ kd[:3, j]
                         - kd[6, j] for j in range(nk)])
            for k in range(N + 1)])
    # rows stage by stage (fatrop's structure detection reads them so)
    # (rows, lower, upper) blocks
    blocks: list[tuple[Any, float, float]] = [
        (r, 0.0, 0.0) for r in transcription.defects(
            (nx, nu, nw), N, Xn, Xcn, Un, dt, p, inner)]
    if free_T and ocp_form:
        blocks.append((Tk[1:].T - Tk[:N].T, 0.0, 0.0))
    if rate is not None:
        blocks.append((rate[:N], -np.inf, np.nan))
    if cones is not None:
        blocks.append((cones[:, :N], -np.inf, 0.0))
    con = Constraints()
    if ocp_form:
        con.eq(Xn[:, 0] - d["x0"])
    con.add(ca.vertcat(*[r for r, _, _ in blocks]),
            np.concatenate([np.full((r.shape[0], N), a)
                            for r, a, _ in blocks]),
            np.concatenate([np.full((r.shape[0], N), b)
                            for r, _, b in blocks]))
    if rate is not None:
        con.add(rate[N], -np.inf, np.nan)
    if cones is not None:
        con.add(cones[:, N], -np.inf, 0.0)
    if ocp_form:
        con.eq(Xn[4:7, N])
    qe = quat_mul(quat_conj(d["qf"]), Xn[:4, N])  # xs = 1 on q
    con.eq(qe[1:])
    con.add(qe[0], 0.0, np.inf)
    g, lbg, ubg, equality = con.arrays()
    J_obj = Tk[0] if free_T else ca.sumsqr(Un) / N  # ∝ Σ ∫ m² dt
    opts = dict(opts)
    if ocp_form:
        opts["equality"] = equality
    nlp = {"x": w, "p": p, "f": J_obj, "g": g}
    S = (ca.nlpsol("slew", plugin, nlp, opts) if jit is None
         else compiled_nlpsol(plugin, nlp, opts, jit))
    return BuiltSolver(S, lay, lbg, ubg, np.flatnonzero(np.isnan(ubg)),
                  time.perf_counter() - t_build)


def compiled_nlpsol(plugin: str, nlp: dict, opts: dict,
                    jit: dict) -> ca.Function:
    """Return an nlpsol over a C library of the NLP, cached on disk.

    The library is compiled once per generated code (its SHA-256 names
    it) with ``jit["compiler"]`` and ``jit["flags"]`` into
    ``jit["cache_dir"]``.
    """
    S0 = ca.nlpsol("slew", plugin, nlp, opts)
    with tempfile.TemporaryDirectory() as tmp:
        src = generate_c(solver_dependencies(S0), tmp, "slew_nlp")
        flags = list(jit["flags"])
        version = ca.__version__  # type: ignore[attr-defined]  # no stub
        key = hashlib.sha256(src.read_bytes() + " ".join(
            [jit["compiler"], *flags, version]).encode()).hexdigest()
        def build(out):
            with compile_progress("compiling the slew NLP to C (once per "
                                  "problem shape)"):
                return compile_c([src], out, cc=jit["compiler"],
                                 opt=flags[0] if flags else "-O1",
                                 flags=flags[1:])

        try:
            lib = cached_library(jit["cache_dir"], f"slew_{key[:20]}", build)
        except CompileError as exc:
            raise SolverError(f"compiling the slew NLP failed: {exc}",
                              solver=plugin) from None
    return ca.nlpsol("slew", plugin, str(lib), opts)


def jit_settings(jit) -> dict | None:
    """None (no JIT) or the compiler, flags and cache directory."""
    if jit is False or jit is None:
        return None
    try:
        cc = find_compiler()
    except CompilerNotFound:
        cc = None
    cfg: dict[str, Any] = {
        "compiler": cc, "flags": ["-O1"],
        "cache_dir": os.environ.get("ADCS_CACHE_DIR",
                                    "~/.cache/adcs_toolbox/slews")}
    if isinstance(jit, dict):
        unknown = set(jit) - set(cfg)
        if unknown:
            raise InvalidValueError(
                f"jit takes the keys {sorted(cfg)}, got {sorted(unknown)}")
        cfg.update(jit)
    elif jit is not True:
        raise InvalidValueError(f"jit must be a bool or a dict, got {jit!r}")
    if not cfg["compiler"]:
        raise InvalidValueError("jit needs a C compiler (gcc, cc or clang "
                                "on PATH, or $CC)")
    cfg["flags"] = list(cfg["flags"])
    return cfg
