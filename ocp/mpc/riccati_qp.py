"""The stage-wise step's QP by the Riccati active set in C
(``solver="stagewise", qp_solver="rqp"``).

`ocp.mpc.stagewise` poses each SQP iteration's QP stage by stage (δu_k,
δx_{k+1}; A_k, B_k and Q_k as CasADi nonzeros). With ``"rqp"`` it goes
to ``rqp/rqp.c`` instead of the Riccati interior point: a primal active
set (Nocedal & Wright, Numerical Optimization, 2nd ed., algorithm 16.3)
whose every working set's equality QP is one backward Riccati recursion
with the working boxes eliminated stage by stage (Laine & Tomlin, ICRA
2019), started where the step starts (the shifted plan, dynamics kept)
from the shifted multipliers' signs, in C99 without heap, double or
float. Its memory is O(N) and so is each iteration's work; its
iteration limit bounds a step by construction (a capped point keeps
every box and lowers the cost).

The solver enters the step's graph as a CasADi external Function: a C
wrapper in CasADi's calling convention (`wrapper_source`, which compiles
rqp.c for the QP's sizes in its own translation unit, its public names
prefixed, with its stage products generated as straight-line code for
the step's patterns of A and B, `products_source`), compiled into a
shared library for Python (`qp_external`; needs a C compiler) and
written into the export folder beside rqp.c for generated C
(`copy_sources`). rqp.c has no phase one: where the start
breaks a box it answers the start, flagged ``infeasible``, and the
step's certificate fails; the step then returns the shifted plan, as
every failed QP does (`ocp.mpc.condensed.sqp_step_functions`). With a
rate bound, whose starts the linearisation's defects break, the
wrapper runs a phase one of its own first (`wrapper_source`'s
``phase_one``: rqp on the QP with the broken boxes widened to the start
and pulled to their bound by a penalty, over the stages from the first
broken one).

The wrapper keeps no state (its memory is the caller's work), so a
controller with this QP may be stepped from several threads.
"""

from __future__ import annotations

import re
from functools import partial
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

from .condensed_qp import QP_ITER_LIMIT
from .external_c import copy_solver, shared_external
from .stagewise_boxes import BoxLayout

#: The C solver's folder (rqp.c, rqp.h, its kernels and LICENSE).
RQP_SOURCES = Path(__file__).with_name("rqp")
#: The export folder's subfolder of rqp's sources (`copy_sources`).
RQP_DIR = "rqp"
#: The solver's step and sign tolerance (in box widths), by casadi_real.
RQP_TOL = {"double": 1e-10, "single": 1e-4}
_FILES = ("rqp.c", "rqp.h", "rqp_kernels.h", "rqp_rows.h", "LICENSE")
_NAME = re.compile(r"\b(adcs_rqp_\d+x\d+x\d+x\d+(?:_cap\d+)?(?:_p1)?)\(")
#: Each external built in this process: its `wrapper_source` arguments.
_BUILT: dict[str, tuple] = {}


def external_name(N: int, nx: int, nu: int, nb: int,
                  max_iter: int = QP_ITER_LIMIT,
                  phase_one: bool = False) -> str:
    """The external Function's C name for N stages of n_x states, n_u
    inputs and n_b boxes, with ``_cap<max_iter>`` when capped below
    `QP_ITER_LIMIT` and ``_p1`` with the phase one (`wrapper_source`)."""
    cap = f"_cap{max_iter}" if max_iter < QP_ITER_LIMIT else ""
    return f"adcs_rqp_{N}x{nx}x{nu}x{nb}{cap}{'_p1' if phase_one else ''}"


def max_iter_of(name: str) -> int:
    """The iteration limit of the external ``name`` built in this process."""
    return int(_BUILT[name][5])


def _ints(values) -> str:
    return ", ".join(str(int(v)) for v in values)


def boxes(lay: BoxLayout, nu: int) -> tuple[list[int], np.ndarray]:
    """``(box, scale)`` of rqp.h: each box's component of (u, x) (inputs
    first) and its scale, the inverse of its width, in ``lay``'s order."""
    box = [*lay.bu, *(nu + i for i in lay.bx)]
    return box, 1.0 / np.asarray(lay.width, dtype=float)


def products_source(sp_a: ca.Sparsity, sp_b: ca.Sparsity,
                    precision: str = "double",
                    name: str = "rqp_products") -> str:
    """C of the stage's products that rqp.c takes from ``RQP_PRODUCTS``
    (AᵀPA, BᵀPA, BᵀPB, P·B, P·d from P and one stage's A, B, d): CasADi
    straight-line code for the patterns ``sp_a`` and ``sp_b`` of A and B,
    the symmetric results formed once and mirrored, no work array; the
    function ``name(P, A, B, d, AtPA, BtPA, BtPB, PB, Pd)``.

    Three pieces run one after the other, so that few temporaries are
    live at once (one fused piece kept 1,728 bytes of the M7's stack at
    horizon 20): P·A into the P·B output's buffer (n_x × n_x), then AᵀPA
    and BᵀPA from it, then P·B (over it), BᵀPB and P·d."""
    from ocp.codegen.patches import patch_unused_parameters  # no cycle

    nx, nu = sp_b.shape
    pf = ca.SX.sym("P", nx * nx)
    P = ca.SX(nx, nx)
    for i in range(nx):
        for j in range(nx):
            P[i, j] = pf[max(i, j) * nx + min(i, j)]
    a, b = ca.SX.sym("A", sp_a.nnz()), ca.SX.sym("B", sp_b.nnz())
    A, B = ca.SX(sp_a, a), ca.SX(sp_b, b)
    d = ca.SX.sym("d", nx)
    pa = ca.SX.sym("PA", nx * nx)
    PA = ca.reshape(pa, nx, nx).T               # row-major in memory

    def sym(M):
        n = M.shape[0]
        out = ca.SX(n, n)
        for i in range(n):
            for j in range(i + 1):
                out[i, j] = out[j, i] = M[i, j]
        return out

    def rows(M):            # row-major, dense
        return ca.densify(ca.vec(M.T))
    PB = ca.mtimes(P, B)
    pieces = [
        ca.Function(f"{name}_pa", [pf, a], [rows(ca.mtimes(P, A))],
                    {"cse": True}),
        ca.Function(f"{name}_apa", [pa, a, b],
                    [rows(sym(ca.mtimes(A.T, PA))), rows(ca.mtimes(B.T, PA))],
                    {"cse": True}),
        ca.Function(f"{name}_pb", [pf, b, d],
                    [rows(PB), rows(sym(ca.mtimes(B.T, PB))),
                     ca.mtimes(P, d)], {"cse": True})]
    real = "float" if precision == "single" else "double"
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator(f"{name}.c", {"casadi_real": real,
                                            "casadi_int": "int"})
        for f in pieces:
            cg.add(f)
        cg.generate(tmp + "/")
        code, _ = patch_unused_parameters(
            (Path(tmp) / f"{name}.c").read_text())
    if "w[" in code:
        raise RuntimeError("the generated products use a work array")
    return code + f"""
void {name}(const casadi_real* P, const casadi_real* A, const casadi_real* B,
            const casadi_real* d, casadi_real* AtPA, casadi_real* BtPA,
            casadi_real* BtPB, casadi_real* PB, casadi_real* Pd);
void {name}(const casadi_real* P, const casadi_real* A, const casadi_real* B,
            const casadi_real* d, casadi_real* AtPA, casadi_real* BtPA,
            casadi_real* BtPB, casadi_real* PB, casadi_real* Pd) {{
  const casadi_real* arg[3];
  casadi_real* res[3];
  /* straight-line pieces, no work array; P A lives in PB's n_x × n_x
   * buffer until P B overwrites it */
  arg[0] = P; arg[1] = A; res[0] = PB;
  {name}_pa(arg, res, 0, 0, 0);
  arg[0] = PB; arg[1] = A; arg[2] = B; res[0] = AtPA; res[1] = BtPA;
  {name}_apa(arg, res, 0, 0, 0);
  arg[0] = P; arg[1] = B; arg[2] = d; res[0] = PB; res[1] = BtPB;
  res[2] = Pd;
  {name}_pb(arg, res, 0, 0, 0);
}}
"""


def wrapper_source(N: int, lay: BoxLayout, nu: int, fixed: np.ndarray,
                   patterns: tuple[ca.Sparsity, ca.Sparsity, ca.Sparsity],
                   max_iter: int, phase_one: bool = False,
                   precision: str = "double",
                   in_export: bool = False) -> str:
    """C text of the external ``adcs_rqp_<N>x<nx>x<nu>x<nb>(dU0, dX0, D,
    A, B, Q, q, g, r, lo, hi, side0) -> (dU, dX, lam, capped,
    infeasible, costate, moved)`` (`external_name`).

    Inputs, one column per stage: the start (dU0, n_u × N; dX0, n_x × N,
    the states x_1…x_N, dynamics kept), the defects D, the nonzeros of
    A, B and Q in ``patterns`` (the stage-wise kernels' sparsities), q,
    g, the input weight r (its first column is taken), the scaled boxes'
    sides lo, hi (`BoxLayout`, n_b × N) and the warm working set's signs
    side0 (−, + or 0 a box). ``fixed`` (n_u,): the inputs held at their
    start. Outputs: the last iterate, the boxes' multipliers in
    `BoxLayout`'s scaled units (positive at an upper bound); ``capped``
    1 where ``max_iter`` iterations were made, and then ``lam`` holds
    the working set's sides ±1 (the next step's warm start);
    ``infeasible`` 1 where the start breaks a box (or an input is
    invalid), and then the start, with zero multipliers; ``costate``
    the optimum's costates (n_x × N, zero unless optimal).

    ``phase_one``: a start that breaks boxes is first moved to one that
    keeps them (the wrapper's phase one: the broken boxes' bounds
    widened to the start, a penalty of 1e3 (1 + max |q|, |g|) per box
    width pulling each to its bound, solved by rqp over stages j…N−1
    alone, x_j held at the start's and the earlier stages keeping the
    start, in at most n_b (N − j) + ``max_iter`` iterations: j the first
    stage with a broken box, then, where a box stays beyond its bound,
    ever earlier stages, the span doubled, up to 0; then the QP itself
    from there, capped as without it), ``moved`` 1 where it ran;
    ``infeasible`` 1 where a box stayed beyond its bound from stage 0
    too. It keeps 2 n_b N + (2 n_x + n_u) N reals more of work.
    """
    sp_a, sp_b, sp_q = patterns
    nx = sp_a.size1()
    name = external_name(N, nx, nu, lay.nb, max_iter, phase_one)
    box, scale = boxes(lay, nu)
    head = ('#include "../adcs_codegen.h"\n' if in_export else
            "#define casadi_real double\n#define casadi_int long long int\n")
    single = "#define RQP_SINGLE_PRECISION\n" if precision == "single" else ""
    (acol, arow), (bcol, brow), (qcol, qrow) = (sp.get_ccs() for sp in
                                                (sp_a, sp_b, sp_q))
    values = {"NAME": name, "HEAD": head, "SINGLE": single, "N": N,
              "NX": nx, "NU": nu, "NB": lay.nb, "NNZA": sp_a.nnz(),
              "NNZB": sp_b.nnz(), "NNZQ": sp_q.nnz(), "ACOL": _ints(acol),
              "AROW": _ints(arow), "BCOL": _ints(bcol), "BROW": _ints(brow),
              "QCOL": _ints(qcol), "QROW": _ints(qrow), "BOX": _ints(box),
              "SCALE": ", ".join(repr(float(s)) for s in scale),
              "FIXED": _ints(np.asarray(fixed, dtype=bool)),
              "MAXITER": max_iter, "TOL": repr(RQP_TOL[precision]),
              "PHASEONE": int(bool(phase_one)),
              "PRODUCTS": products_source(sp_a, sp_b, precision,
                                          f"{name}_products")}
    text = (RQP_SOURCES / "wrapper.c.in").read_text()
    return re.sub(r"@([A-Z]+)@", lambda k: str(values[k[1]]), text)


def qp_external(N: int, lay: BoxLayout, nu: int, fixed: np.ndarray,
                patterns: tuple[ca.Sparsity, ca.Sparsity, ca.Sparsity],
                max_iter: int, phase_one: bool = False) -> ca.Function:
    """The external Function of `wrapper_source`, built as a shared
    library (double) in the user's temporary folder, once per text.

    Raises
    ------
    CompilerNotFound
        No C compiler: ``qp_solver="rqp"`` needs one.
    """
    name = external_name(N, patterns[0].size1(), nu, lay.nb, max_iter,
                         phase_one)
    _BUILT[name] = (N, lay, nu, np.asarray(fixed, dtype=bool).copy(),
                    patterns, max_iter, phase_one)
    text = wrapper_source(N, lay, nu, fixed, patterns, max_iter, phase_one)
    return shared_external(name, text, [], [f"-I{RQP_SOURCES}"], "rqp",
                           [RQP_SOURCES / f for f in _FILES[:4]])


def copy_sources(out: Path, source_text: str, precision: str = "double"
                 ) -> list[Path]:
    """Write rqp's sources, its LICENSE and the wrapper of every rqp
    external that the generated ``source_text`` calls into ``out/rqp``
    (a stale folder of an earlier export is emptied when it calls none).

    Returns
    -------
    list of pathlib.Path
        The C sources to compile beside the generated source: the
        wrappers (each includes rqp.c).
    """
    return copy_solver(Path(out) / RQP_DIR, RQP_SOURCES, _FILES, (), _NAME,
                       source_text, _BUILT,
                       partial(wrapper_source, precision=precision,
                               in_export=True))
