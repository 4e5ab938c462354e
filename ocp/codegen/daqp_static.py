"""DAQP in exported C without the heap: vendored sources, static workspace.

CasADi's generated DAQP runtime (``casadi_daqp_solve``) calls DAQP's
``setup_daqp`` on every solve, which allocates the solver's workspace
with ``malloc``, and ``free_daqp_workspace``/``free_daqp_ldp`` after it.
`patch_daqp_static` edits that runtime so that the workspace's arrays
point into static storage laid out per conic (and per CasADi memory
slot) from the problem dimensions known at generation time;
`copy_daqp_sources` writes DAQP's C sources (MIT, vendored in
``ocp/codegen/vendor/daqp``, ``README.md`` there) beside the export. The
vendored ``api.c`` keeps no allocating function, so any path back to the
heap fails at link time. A small conic (`KEEP_MAX_NNZ`) keeps its setup
from one call to the next while its H and A stay the same (the duty QP's
are constants).
"""

from __future__ import annotations

import re
import shutil
from importlib import resources
from pathlib import Path

from adcs_common.exceptions import AdcsError
from .precision import float_literals

#: The DAQP release vendored: its headers are those the casadi wheel
#: ships under ``casadi/include/daqp`` (the API the generated code calls).
DAQP_VERSION = "0.5.1"

#: The vendored DAQP files copied into each export (folder ``daqp/``).
DAQP_SOURCES = ("api.c", "auxiliary.c", "bnb.c", "daqp.c", "daqp_prox.c",
                "factorization.c", "utils.c")
DAQP_HEADERS = ("api.h", "auxiliary.h", "bnb.h", "constants.h", "daqp.h",
                "daqp_prox.h", "factorization.h", "types.h", "utils.h")
DAQP_FILES = DAQP_SOURCES + DAQP_HEADERS + ("LICENSE", "README.md")

#: Folder of the vendored DAQP inside an export.
DAQP_DIR = "daqp"


def vendored_daqp() -> Path:
    """The folder of the vendored DAQP sources (package data)."""
    return Path(str(resources.files("ocp.codegen") / "vendor" / "daqp"))


#: What ``daqp/types.h`` of a single-precision export starts with: the
#: float build (``c_float`` is float) whatever the flags of the build.
_SINGLE_DEFINE = ("/* single-precision export (ocp.codegen.copy_daqp_sources)"
                  " */\n#ifndef DAQP_SINGLE_PRECISION\n"
                  "#define DAQP_SINGLE_PRECISION\n#endif\n")


def copy_daqp_sources(out: Path, single: bool = False) -> list[Path]:
    """Copy the vendored DAQP sources, headers and licence to ``out/daqp``.

    ``single``: the copied ``types.h`` defines ``DAQP_SINGLE_PRECISION``
    (DAQP's float build, for a single-precision export whose
    ``casadi_real`` is float), so that every file that includes it agrees
    on ``c_float`` even when a build forgets the flag; the copies' literals
    and math calls are made float (`ocp.codegen.precision.float_literals`:
    ``1e-12f``, ``sqrtf``), so that no double arithmetic is left.

    Returns
    -------
    list of pathlib.Path
        The C sources written (to compile beside the generated source).
    """
    src = vendored_daqp()
    dst = Path(out) / DAQP_DIR
    dst.mkdir(exist_ok=True)
    for name in DAQP_FILES:
        shutil.copyfile(src / name, dst / name)
    if single:
        for name in DAQP_SOURCES + DAQP_HEADERS:
            (dst / name).write_text(float_literals((dst / name).read_text()))
        types = dst / "types.h"
        types.write_text(_SINGLE_DEFINE + types.read_text())
    return [dst / name for name in DAQP_SOURCES]


# ------------------------------------------------------------ the C edits
#: DAQP's setup_daqp (api.c) without the heap: the same steps in the same
#: order (allocate_daqp_workspace, setup_daqp_ldp, setup_daqp_bnb with no
#: binary constraint, activate_constraints), the arrays carved from ``w``
#: (``nw`` doubles) and ``iw`` (``niw`` ints).
_SETUP_STATIC = r"""/* (ocp.codegen.patch_daqp_static) DAQP's setup_daqp
 * without the heap: the same steps, the workspace's arrays carved from static
 * storage (w: nw reals, iw: niw ints) sized for this conic at generation
 * time.
 * Soft and binary constraints (which need more storage) are refused. */
static int casadi_daqp_setup_static(DAQPProblem* qp, DAQPWorkspace* work,
    c_float* w, int nw, int* iw, int niw, int diag, int own_m, int same,
    const casadi_real* hdiag) {
  int i, mask = UPDATE_M+UPDATE_d+UPDATE_sense;
  int n = qp->n, m = qp->m, ms = qp->ms;
  for (i=0; i<m; ++i) if (qp->sense[i] & (SOFT|BINARY)) return -100;
  if (5*(n+1) + (n+1)*(n+2)/2 + 2*n + 3*m + (diag && !own_m ? 0 : n*(m-ms))
      + (diag ? n : n*(n+1)/2) + n > nw
      || (n+1) + m > niw) return -101;
  if (same) {
    /* H and A as at this workspace's last setup (casadi_daqp_same_data):
     * its factor of H, M and the rows' scaling hold; DAQP's own partial
     * update (update_ldp's mask) redoes the bounds, the sense and v */
    work->qp = qp;
    reset_daqp_workspace(work);
    i = update_ldp(UPDATE_d+UPDATE_sense+(work->v ? UPDATE_v : 0), work);
    if (i < 0) return i;
    return activate_constraints(work);
  }
  /* allocate_daqp_workspace(work, n, 0) */
  work->n = n;
  work->Rinv = NULL; work->v = NULL; work->scaling = NULL;
  work->lam = w; w += n+1;
  work->lam_star = w; w += n+1;
  work->WS = iw; iw += n+1;
  work->D = w; w += n+1;
  work->xldl = w; w += n+1;
  work->zldl = w; w += n+1;
  work->L = w; w += (n+1)*(n+2)/2;
  work->u = w; w += n;
  work->x = work->u;
  work->xold = w; w += n;
  work->bnb = NULL;
  reset_daqp_workspace(work);
  /* setup_daqp_ldp(work, qp) */
  work->n = n; work->m = m; work->ms = ms; work->qp = qp;
  work->scaling = w; w += m;
  for (i=0; i<ms; ++i) work->scaling[i] = 1;
  /* a diagonal H (by its sparsity): DAQP scales A by H's diagonal
   * element by element (update_M), so M may be A itself, and H's factor
   * is its diagonal (update_Rinv's RinvD); a conic that keeps its setup
   * holds M in its own storage (own_m) */
  if (diag && !own_m) work->M = qp->A;
  else { work->M = w; w += n*(m-ms); }
  work->dupper = w; w += m;
  work->dlower = w; w += m;
  work->sense = iw; iw += m;
  work->RinvD = NULL;
  if (qp->H != NULL) {
    work->Rinv = w; w += diag ? n : n*(n+1)/2;
    if (diag) {
      /* update_Rinv's branch for a diagonal H, read from H's nonzeros
       * (hdiag: its sparsity is the diagonal): no dense H to fill and
       * scan for off-diagonal entries */
      work->RinvD = work->Rinv;
      work->Rinv = NULL;
      for (i=0; i<n; ++i) {
        c_float hi = (hdiag ? hdiag[i] : 0) + work->settings->eps_prox;
        if (hi <= 0) return EXIT_NONCONVEX;
        hi = sqrt(hi);
        work->RinvD[i] = 1/hi;
        if (i < ms) work->scaling[i] = hi;
      }
    } else {
      mask += UPDATE_Rinv;
    }
  } else {
    work->Rinv = NULL;
  }
  if (qp->f != NULL || work->settings->eps_prox != 0) {
    work->v = w;
    mask += UPDATE_v;
  } else {
    work->v = NULL;
  }
  i = update_ldp(mask, work);
  if (i < 0) return i;
  /* setup_daqp_bnb(work, 0, 0): nothing; then the initial working set */
  return activate_constraints(work);
}

/* (ocp.codegen.patch_daqp_static) A conic with few nonzeros in H and A
 * keeps its setup: 1 when this memory slot's last setup succeeded with the
 * same H and A (compared value by value; a NaN never compares equal). The
 * values are copied for the next call; kept is set again only when this
 * call's setup succeeds (casadi_daqp_mark_kept). */
static int casadi_daqp_same_data(struct casadi_daqp_data* d) {
  int i, same = d->kept;
  if (!d->keep || !d->qp->h || !d->qp->a) return d->kept = 0;
  for (i=0; i<d->nkh; ++i) {
    if (d->keep[i] != d->qp->h[i]) same = 0;
    d->keep[i] = d->qp->h[i];
  }
  for (i=0; i<d->nka; ++i) {
    if (d->keep[d->nkh+i] != d->qp->a[i]) same = 0;
    d->keep[d->nkh+i] = d->qp->a[i];
  }
  d->kept = 0;
  return same;
}

/* After a setup that succeeded: keep it unless DAQP found a zero row of
 * M (normalize_M marks it immutable in the workspace, which a partial
 * update would not redo) */
static void casadi_daqp_mark_kept(struct casadi_daqp_data* d) {
  int i;
  if (!d->keep) return;
  for (i=d->daqp.ms; i<d->daqp.m; ++i)
    if ((d->work.sense[i] & IMMUTABLE) && !(d->daqp.sense[i] & IMMUTABLE))
      return;
  d->kept = 1;
}

"""

_INCLUDE = "#include <daqp/api.h>\n"
_INCLUDE_NEW = '#include "daqp/api.h"\n#include "daqp/utils.h"\n'
_DATA_END = "  int nodecount;\n  int bnb_itercount;\n};\n"
_DATA_END_NEW = ("  int nodecount;\n  int bnb_itercount;\n"
                 "  c_float* ws;  /* static workspace "
                 "(ocp.codegen.patch_daqp_static) */\n"
                 "  int* iws;\n  int nws, niws;\n"
                 "  int diag_h;  /* H's sparsity is diagonal */\n"
                 "  casadi_real* keep;  /* H, A of the kept setup, or NULL */\n"
                 "  int nkh, nka, kept;\n};\n")
_SOLVE_HEAD = "int casadi_daqp_solve(struct casadi_daqp_data* d,"
_SETUP_CALL = "setup_daqp(&d->daqp,&d->work,&(d->res.setup_time))"
_SETUP_NEW = ("casadi_daqp_setup_static(&d->daqp,&d->work,"
              "d->ws,d->nws,d->iws,d->niws,d->diag_h,d->keep!=0,same,"
              "d->qp->h)")
_DENSIFY = ("  casadi_densify(d->qp->h, d->prob->qp->sp_h, d->daqp.H, 0);\n"
            "  casadi_densify(d->qp->a, d->prob->qp->sp_a, d->daqp.A, 1);\n")
_DENSIFY_NEW = (
    "  same = casadi_daqp_same_data(d);\n"
    "  if (!same) {\n"
    "    if (!d->diag_h)\n"
    "      casadi_densify(d->qp->h, d->prob->qp->sp_h, d->daqp.H, 0);\n"
    "    casadi_densify(d->qp->a, d->prob->qp->sp_a, d->daqp.A, 1);\n"
    "  }\n")
_SOLVE_CALL = "  daqp_solve(&d->res,&d->work);\n"
_SOLVE_CALL_NEW = "  casadi_daqp_mark_kept(d);\n" + _SOLVE_CALL
_FLAG_DECL = "  int flag;\n  const struct casadi_daqp_prob* p = d->prob;\n"
_FLAG_DECL_NEW = "  int flag, same;\n  const struct casadi_daqp_prob* p = d->prob;\n"

#: A DAQP conic whose H and A hold at most this many nonzeros together
#: keeps its setup (H's factor, M = A R⁻¹ and the rows' scaling) from one
#: call to the next while H and A stay the same: the duty QP's conic is
#: called with constant H and A, and its setup was a fifth of its
#: instructions. The comparison costs a few per nonzero, and the copy a
#: real each; a large conic (the condensed MPC QP, whose H and A change
#: every step) keeps nothing.
KEEP_MAX_NNZ = 64
_FREES = re.compile(r"^[ \t]*free_daqp_(?:workspace|ldp)\(&d->work\);\n",
                    re.M)
_CONIC = re.compile(
    r"^static int (casadi_f\d+)\(const casadi_real\*\* arg, "
    r"casadi_real\*\* res, casadi_int\* iw, casadi_real\* w, int mem\) "
    r"\{\n(?:(?!^\}).*\n)*?  struct casadi_daqp_data\* d=&\1_mem\[mem\];\n"
    r"(?P<body>(?:(?!^\}).*\n)*?)"
    r"  casadi_daqp_set_work\(d, &arg, &res, &iw, &w\);\n", re.M)
_SPARSITY = re.compile(r"static const casadi_int (casadi_s\d+)\[\d+\] = "
                       r"\s*\{([\d,\s]*)\}")


def daqp_static_sizes(n: int, na: int, diag: bool = False,
                      own_m: bool = False) -> tuple[int, int]:
    """Reals and ints of the static workspace of one DAQP conic.

    ``n`` variables, ``na`` general rows (``m = n + na`` constraints, the
    first ``n`` the bounds): what ``setup_daqp`` would allocate. With
    ``diag`` (H's sparsity diagonal) DAQP's M is A itself (scaled in
    place) and H's factor its diagonal: n·na + n(n−1)/2 reals fewer;
    ``own_m`` (a conic that keeps its setup) holds M all the same.
    """
    m = n + na
    nw = (5 * (n + 1) + (n + 1) * (n + 2) // 2 + 2 * n + 3 * m
          + (0 if diag and not own_m else n * na)
          + (n if diag else n * (n + 1) // 2) + n)
    return nw, (n + 1) + m


def _nnz(pattern: list[int]) -> int:
    """Nonzeros of a CasADi sparsity array ``{nrow, ncol, colind…, row…}``."""
    return pattern[2 + pattern[1]]


def _is_diagonal(pattern: list[int]) -> bool:
    """Is a CasADi sparsity array ``{nrow, ncol, colind…, row…}`` the
    full diagonal of a square matrix?"""
    nrow, ncol = pattern[:2]
    colind, row = pattern[2:3 + ncol], pattern[3 + ncol:]
    return (nrow == ncol and colind == list(range(ncol + 1))
            and row == list(range(ncol)))


def patch_daqp_static(source: str) -> tuple[str, dict[str, tuple[int, int]]]:
    """Make CasADi's generated DAQP conics run without the heap.

    Edits (exact text of CasADi 3.7/3.8; run after `patch_daqp_warm_start`):
    the include becomes ``"daqp/api.h"`` (the vendored copy beside the
    source, no ``-I``); ``casadi_daqp_setup_static`` replaces every
    ``setup_daqp`` call; the ``free_daqp_*`` calls go; each conic gets
    static arrays ``casadi_fN_daqp_w``/``_iw`` (one set per CasADi memory
    slot, ``CASADI_MAX_NUM_THREADS``) sized from its ``H`` and ``A``
    sparsities, and points its data at them before each solve. A conic
    whose H and A hold at most `KEEP_MAX_NNZ` nonzeros also keeps its
    setup (H's factor, M, the rows' scaling; M then in its own storage)
    while H and A stay the same from call to call, compared value by
    value: later calls redo only the bounds, the sense and v (DAQP's own
    partial update, ``update_ldp``'s mask).

    Returns
    -------
    text : str
        The edited text (``source`` unchanged when it holds no DAQP).
    conics : dict
        C name of each DAQP conic -> (reals, ints) of its static storage
        (the reals count the kept copy of H and A too).

    Raises
    ------
    AdcsError
        The source holds DAQP but not in the text this edit knows (a
        CasADi version whose runtime differs): the export would allocate.
    """
    if _INCLUDE not in source:
        return source, {}
    sparsity = {m[1]: [int(v) for v in m[2].replace(",", " ").split()]
                for m in _SPARSITY.finditer(source)}
    conics: dict[str, tuple[int, int]] = {}
    layout: dict[str, tuple[int, int, int]] = {}

    def _conic(m: re.Match) -> str:
        sp_a = re.search(r"p_qp\.sp_a = (casadi_s\d+);", m["body"])
        sp_h = re.search(r"p_qp\.sp_h = (casadi_s\d+);", m["body"])
        if not (sp_a and sp_h):
            raise AdcsError(f"DAQP conic {m[1]}: no H/A sparsity found")
        n = sparsity[sp_h[1]][1]
        na = sparsity[sp_a[1]][0]
        diag = _is_diagonal(sparsity[sp_h[1]])
        nkh, nka = _nnz(sparsity[sp_h[1]]), _nnz(sparsity[sp_a[1]])
        keep = nkh + nka <= KEEP_MAX_NNZ
        nw, niw = daqp_static_sizes(n, na, diag, own_m=keep)
        conics[m[1]] = (nw + (nkh + nka if keep else 0), niw)
        layout[m[1]] = (nw, niw, nkh + nka if keep else 0)
        kept = (f"  d->keep = {m[1]}_daqp_k[mem]; d->nkh = {nkh}; "
                f"d->nka = {nka};\n" if keep else "  d->keep = 0;\n")
        return (m[0] + f"  d->ws = {m[1]}_daqp_w[mem]; d->nws = {nw};\n"
                f"  d->iws = {m[1]}_daqp_iw[mem]; d->niws = {niw};\n"
                f"  d->diag_h = {int(diag)};\n" + kept)

    text = _CONIC.sub(_conic, source)
    for name, (nw, niw, nkeep) in layout.items():
        decl = (f"static struct casadi_daqp_data {name}_mem"
                "[CASADI_MAX_NUM_THREADS];\n")
        text = text.replace(
            decl, decl + f"static c_float {name}_daqp_w"
            f"[CASADI_MAX_NUM_THREADS][{nw}];\n"
            f"static int {name}_daqp_iw[CASADI_MAX_NUM_THREADS][{niw}];\n"
            + (f"static casadi_real {name}_daqp_k"
               f"[CASADI_MAX_NUM_THREADS][{nkeep}];\n" if nkeep else ""))
    ok = (bool(conics) and source.count(_DATA_END) == 1
          and source.count(_SOLVE_HEAD) == 1
          and source.count(_DENSIFY) == 1 and source.count(_SOLVE_CALL) == 1
          and source.count(_FLAG_DECL) == 1
          and text.count("casadi_daqp_set_work(d, &arg, &res, &iw, &w);")
          == len(conics))
    if ok:
        text = text.replace(_INCLUDE, _INCLUDE_NEW)
        text = text.replace(_DATA_END, _DATA_END_NEW)
        text = text.replace(_SOLVE_HEAD, _SETUP_STATIC + _SOLVE_HEAD)
        text = text.replace(_SETUP_CALL, _SETUP_NEW)
        text = text.replace(_DENSIFY, _DENSIFY_NEW)
        text = text.replace(_SOLVE_CALL, _SOLVE_CALL_NEW)
        text = text.replace(_FLAG_DECL, _FLAG_DECL_NEW)
        text = _FREES.sub("", text)
    if not ok or "setup_daqp(" in text or "free_daqp_" in text:
        raise AdcsError(
            "the generated DAQP runtime differs from the text "
            "ocp.codegen.patch_daqp_static edits (CasADi "
            "version?): it would allocate on every solve")
    return text, conics
