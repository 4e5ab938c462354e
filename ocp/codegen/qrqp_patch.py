"""Edit CasADi's generated qrqp to reuse its KKT factorization (same bits)."""

from __future__ import annotations



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
