"""The condensed step's QP by a primal active set in C (``qp_solver="pqp"``).

`ocp.mpc.condensed_qp.routed_qp` hands DAQP the QP in y (Hessian I, the
rows ``G`` stage by stage). With ``"pqp"`` it goes instead to
``pqp/pqp.c``: a primal active set (Nocedal & Wright, Numerical
Optimization, 2nd ed., algorithm 16.3) started where the step starts (y =
0, δu = 0 on the shifted plan) from the shifted multipliers' signs, in
C99 without heap, double or float. It reaches the optimum the DAQP QP
has (the QP is strictly convex) along a path that stays near the warm
start, and its iteration limit bounds a step by construction.

The solver enters the step's graph as a CasADi external Function: a C
wrapper in CasADi's calling convention (`wrapper_source`), compiled here
into a shared library for Python (`qp_external`; needs a C compiler) and
written into the export folder beside ``pqp.c`` for generated C
(`copy_sources`). Where y = 0 breaks a bound (a defect the linearisation
carries, or a rate beyond its bound) the solver's phase one first moves
the start to the nearest point that keeps every bound (a dual active
set, Goldfarb & Idnani 1983, at most the iteration limit), and the
primal phase starts there; where it finds none (inconsistent bounds, or
the limit reached) the wrapper answers y = 0, flagged, and the step's
certificate fails. No other QP solver is linked.

Its iteration limit (`AttitudeMPC` ``solver_options={"qp_max_iter":
k}``, default `QP_ITER_LIMIT`) can cap the QP: every iterate keeps every
bound and lowers the cost from the shifted plan, so a capped point is a
feasible descent step, not the optimum. The step takes it, certified by
`condensed_qp.capped_residual` (feasibility and descent) instead of the
KKT residual, and says so (its output ``qp_capped``, status
``":qp_capped"``); the next step starts from its working set. On the
demo craft at horizons 10–20, capped at 8 iterations, closed loops from
random attitudes settle within 2.5 s of the uncapped ones; capped at 5,
at horizon 20, 4 of 20 do not settle in 60 s (docs/benchmarks.md,
`benchmarks.capped_step`).

The wrapper keeps no state (its memory is the caller's work), so a
controller with this QP may be stepped from several threads; the
library is compiled once per QP size, each process and thread into a
file of its own renamed into place (tested).
"""

from __future__ import annotations

import re
from functools import partial
from itertools import accumulate
from pathlib import Path

import casadi as ca

from .condensed_qp import QP_ITER_LIMIT
from .external_c import copy_solver, shared_external

#: The C solver's folder (pqp.c, pqp.h).
PQP_SOURCES = Path(__file__).with_name("pqp")
#: The solver's step and sign tolerances (relative), by casadi_real.
PQP_TOL = {"double": 1e-10, "single": 1e-4}
#: The export folder's subfolder of pqp's sources (`copy_sources`).
PQP_DIR = "pqp"
#: pqp's float build (a single-precision export: casadi_real float).
PQP_SINGLE_FLAG = "-DPQP_SINGLE_PRECISION"
_NAME = re.compile(r"\b(adcs_pqp_\d+x\d+(?:_cap\d+)?)\(")
#: Each external built in this process: its `wrapper_source` arguments.
_BUILT: dict[str, tuple[int, int, int, ca.Sparsity, int]] = {}


def external_name(n: int, m: int, max_iter: int = QP_ITER_LIMIT) -> str:
    """The external Function's C name for n variables and m rows, and
    ``max_iter`` iterations when capped below `QP_ITER_LIMIT`
    (``adcs_pqp_<n>x<m>`` or ``adcs_pqp_<n>x<m>_cap<max_iter>``)."""
    cap = f"_cap{max_iter}" if max_iter < QP_ITER_LIMIT else ""
    return f"adcs_pqp_{n}x{m}{cap}"


def max_iter_of(name: str) -> int:
    """The iteration limit of the external ``name`` built in this process."""
    return _BUILT[name][4]


def _ints(values) -> str:
    return ", ".join(str(int(v)) for v in values)


def _row_order(N: int, nu: int, nw: int, h: int, sp_g: ca.Sparsity
               ) -> tuple[list[int], list[int], list[int]]:
    """``(order, at, length)`` of the wrapper's rows (wrapper.c.in): its
    columns are G's reversed within each stage, its rows G's sorted stage
    by stage by where they end once the diagonal blocks' zeros (W⁻¹'s are
    upper triangular) are counted: bound row i and the momentum row of
    wheel i (the torque of wheel i is control i) end n_u − i columns into
    their stage, the rate rows at its end. ``order[r]``: the G row of the
    wrapper's row r; ``at``: its inverse; ``length``: the wrapper's rows'
    lengths in G's pattern (the last column, reversed, + 1)."""
    colind, row = sp_g.get_ccs()

    def key(r: int) -> tuple[int, int, int]:
        s, i = divmod(r, h)
        if i < nu:
            return s, nu - i, 0
        if i < nu + nw:
            return s, nu - (i - nu), 1
        return s, nu + 1, 2
    order = sorted(range(sp_g.size1()), key=key)
    at = [0] * len(order)
    for r, g_row in enumerate(order):
        at[g_row] = r
    length = [0] * len(order)
    for c in range(sp_g.size2()):
        col = c // nu * nu + nu - 1 - c % nu
        for r in row[colind[c]:colind[c + 1]]:
            length[at[r]] = max(length[at[r]], col + 1)
    return order, at, length


def _column_runs(sp: ca.Sparsity) -> tuple[list[int], list[int]]:
    """``(colrun, runs)``: each column's nonzeros as runs of consecutive
    rows, ``runs`` flat (first row, count) pairs, column c's from pair
    ``colrun[c]`` to ``colrun[c + 1]`` (one run a column for G's stage
    blocks)."""
    colind, row = sp.get_ccs()
    colrun: list[int] = [0]
    runs: list[int] = []
    for c in range(sp.size2()):
        for r in row[colind[c]:colind[c + 1]]:
            if runs and len(runs) // 2 > colrun[-1] and \
                    runs[-2] + runs[-1] == r:
                runs[-1] += 1
            else:
                runs += [r, 1]
        colrun.append(len(runs) // 2)
    return colrun, runs


def wrapper_source(N: int, nu: int, nw: int, sp_g: ca.Sparsity,
                   max_iter: int, precision: str = "double",
                   in_export: bool = False) -> str:
    """C text of the external ``adcs_pqp_<n>x<m>(g, G, lbu, ubu, lba,
    uba, lam_u0, lam_a0) -> (y, lam_u, lam_a, lam, infeasible, capped,
    moved)`` (`external_name`; ``infeasible``: 1 where no point keeps
    every bound, phase one reached ``max_iter`` first, or an input is
    NaN, and then y = 0 and the multipliers 0; ``moved``: 1 where y = 0
    breaks a bound and phase one ran (pqp.h); ``capped``: 1 where the
    solver stopped at ``max_iter`` iterations, at a point that keeps
    every bound and lowers the cost, with its working set's sides, ±1,
    in place of the multipliers, pqp.h).

    ``G`` (m × n, ``sp_g``) holds the QP's rows stage by stage, h = m / N
    a stage: the bounds on δu_k (n_u), the momenta of δx_{k+1} (n_w),
    then its rates (`condensed_qp.RowLayout`). The wrapper unpacks G
    into rows in its work, each up to its last column in ``sp_g`` and
    packed one after the other (`pqp.h`'s ``pqp_solve_rows``), spreads
    the bounds and the warm signs in G's order, solves from y = 0 (at
    most ``max_iter`` iterations) and picks the multipliers back. ``in_export``: it includes the
    generated header (casadi_real, casadi_int of the export).
    """
    n, m = sp_g.size2(), sp_g.size1()
    h = m // N
    name = external_name(n, m, max_iter)
    colind, row = sp_g.get_ccs()
    order, at, length = _row_order(N, nu, nw, h, sp_g)
    start = list(accumulate(length, initial=0))[:m]
    colrun, runs = _column_runs(sp_g)
    tol = PQP_TOL[precision]
    head = ('#include "../adcs_codegen.h"\n' if in_export else
            "#define casadi_real double\n#define casadi_int long long int\n")
    values = {"NAME": name, "HEAD": head, "N": N, "NU": nu, "NW": nw,
              "H": h, "NVAR": n, "M": m, "NA": m - n,
              "COLIND": _ints(colind), "ROW": _ints(row),
              "ORDER": _ints(order), "LEN": _ints(length),
              "PACKED": sum(length), "START": _ints(start),
              "GOES": _ints(start[at[i]] for i in range(m)),
              "COLRUN": _ints(colrun), "RUNS": _ints(runs),
              "HOLES": int(sum(length) != sp_g.nnz()),
              "MAXITER": max_iter, "TOL": repr(tol)}
    text = (PQP_SOURCES / "wrapper.c.in").read_text()
    return re.sub(r"@([A-Z]+)@", lambda k: str(values[k[1]]), text)


def qp_external(N: int, nu: int, nw: int, sp_g: ca.Sparsity,
                max_iter: int) -> ca.Function:
    """The external Function of `wrapper_source`, built as a shared
    library (double) in the user's temporary folder, once per text.

    Raises
    ------
    CompilerNotFound
        No C compiler: ``qp_solver="pqp"`` needs one.
    """
    n, m = sp_g.size2(), sp_g.size1()
    name = external_name(n, m, max_iter)
    _BUILT[name] = (N, nu, nw, sp_g, max_iter)
    text = wrapper_source(N, nu, nw, sp_g, max_iter)
    return shared_external(name, text, [PQP_SOURCES / "pqp.c"],
                           [f"-I{PQP_SOURCES}"], "pqp")


def copy_sources(out: Path, source_text: str, precision: str = "double"
                 ) -> list[Path]:
    """Write pqp.c, pqp.h and the wrapper of every pqp external that the
    generated ``source_text`` calls into ``out/pqp`` (a stale folder of an
    earlier export is emptied when it calls none).

    Returns
    -------
    list of pathlib.Path
        The C sources written (to compile beside the generated source).
    """
    return copy_solver(Path(out) / PQP_DIR, PQP_SOURCES,
                       ("pqp.c", "pqp.h", "LICENSE"), ("pqp.c",), _NAME,
                       source_text, _BUILT,
                       partial(wrapper_source, precision=precision,
                               in_export=True))
