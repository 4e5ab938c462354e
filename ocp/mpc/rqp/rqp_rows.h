/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* rqp.c's stage rows: the equality rows of a stage's working boxes and
 * of the rows passed back to it, their split into the rows that
 * constrain u_k and those passed back to x_k, and the stage without
 * rows (static: included by rqp.c alone, after its work struct). */
#ifndef RQP_ROWS_H
#define RQP_ROWS_H

/* Stage k's rows on (x_k, u_k): the fixed inputs, the working boxes (in
 * box order), the nH rows H x_{k+1} = h passed back to x_{k+1}. */
static int stage_rows(const rqp_problem *qp, int k, const signed char *side,
                      const rqp_real *u, const rqp_real *H,
                      const rqp_real *h, int nH, work *ws) {
  const int nx = NX_OF(qp), nu = NU_OF(qp);
  const sparse A = stage_A(qp, k), B = stage_B(qp, k);
  const rqp_real *d = qp->d + k * nx;
  int r = 0, i, j, b, t, nxb = 0;
  for (i = 0; i < nx; ++i) ws->xrow[i] = -1;
  for (i = 0; i < nu; ++i)
    if (qp->fixed[i]) {
      for (j = 0; j < nx; ++j) ws->Cx[r * nx + j] = 0;
      for (j = 0; j < nu; ++j) ws->Cu[r * nu + j] = j == i;
      ws->c[r] = u[i];
      ws->rowbox[r++] = -1;
    }
  for (b = 0; b < qp->nb; ++b) {
    const int s = side[k * qp->nb + b], ib = qp->box[b];
    const rqp_real sc = qp->scale[b],
                   bound = s > 0 ? qp->hi[k * qp->nb + b] : qp->lo[k * qp->nb + b];
    if (s != 1 && s != -1) continue;
    if (ib < nu) {
      for (j = 0; j < nx; ++j) ws->Cx[r * nx + j] = 0;
      for (j = 0; j < nu; ++j) ws->Cu[r * nu + j] = j == ib ? sc : 0;
      ws->c[r] = bound;
    } else {
      const int ix = ib - nu;
      if (ws->xrow[ix] < 0) { /* filled below, in one pass over A, B */
        ws->xrow[ix] = r;
        ++nxb;
        ws->nu_[r] = sc;
        for (j = 0; j < nx; ++j) ws->Cx[r * nx + j] = 0;
        for (j = 0; j < nu; ++j) ws->Cu[r * nu + j] = 0;
      } else {  /* a second box on the component */
        row_sparse(A, ix, ws->Cx + r * nx);
        row_sparse(B, ix, ws->Cu + r * nu);
        for (j = 0; j < nx; ++j) ws->Cx[r * nx + j] *= sc;
        for (j = 0; j < nu; ++j) ws->Cu[r * nu + j] *= sc;
      }
      ws->c[r] = bound - sc * d[ix];
    }
    ws->rowbox[r++] = b;
  }
  for (j = 0; nxb && j < nx; ++j)
    for (t = A.col[j]; t < A.col[j + 1]; ++t)
      if ((i = ws->xrow[A.row[t]]) >= 0)
        ws->Cx[i * nx + j] = ws->nu_[i] * A.v[t];
  for (j = 0; nxb && j < nu; ++j)
    for (t = B.col[j]; t < B.col[j + 1]; ++t)
      if ((i = ws->xrow[B.row[t]]) >= 0)
        ws->Cu[i * nu + j] = ws->nu_[i] * B.v[t];
  if (nH) {
    mul_sparse(nH, nx, H, A, ws->Cx + r * nx);
    mul_sparse(nH, nx, H, B, ws->Cu + r * nu);
  }
  for (i = 0; i < nH; ++i) {
    ws->c[r] = h[i] - dot(nx, H + i * nx, d);
    ws->rowbox[r++] = -2;
  }
  return r;
}

/* Gram-Schmidt on the rows' u-parts (the twin's _split): *na kept rows
 * (acc), C_u[acc] = RaᵀQaᵀ with Qa's columns (nu × na, stored column by
 * column) orthonormal; *nd others (dep), C_u[dep] = beta C_u[acc]. */
static void split(int r, int nu, work *ws, int *na, int *nd) {
  int i, j, t, a = 0, e = 0;
  for (i = 0; i < r; ++i) {
    const rqp_real *row = ws->Cu + i * nu;
    rqp_real *res = ws->v1, *co = ws->v2, norm, rnorm = RQP_SQRT(
        dot(nu, row, row));
    for (t = 0; t < a; ++t) co[t] = dot(nu, ws->Qa + t * nu, row);
    for (j = 0; j < nu; ++j) {
      res[j] = row[j];
      for (t = 0; t < a; ++t) res[j] -= ws->Qa[t * nu + j] * co[t];
    }
    norm = RQP_SQRT(dot(nu, res, res));
    if (a < nu && norm > RQP_RANK * (rnorm > 1 ? rnorm : 1)) {
      for (t = 0; t < a; ++t) ws->Ra[t * nu + a] = co[t];
      ws->Ra[a * nu + a] = norm;
      for (j = 0; j < nu; ++j) ws->Qa[a * nu + j] = res[j] / norm;
      ws->acc[a++] = i;
    } else {
      /* beta: R beta = co, R upper triangular (a × a, stride nu) */
      for (t = a - 1; t >= 0; --t) {
        rqp_real s = co[t];
        for (j = t + 1; j < a; ++j) s -= ws->Ra[t * nu + j] * co[j];
        co[t] = s / ws->Ra[t * nu + t];
      }
      /* on the rows kept before it: zero on those kept after */
      for (t = 0; t < nu; ++t) ws->beta[e * nu + t] = t < a ? co[t] : 0;
      ws->dep[e++] = i;
    }
  }
  *na = a;
  *nd = e;
}

/* The dependent rows less their kept parts, made orthonormal in order:
 * Hout = M Hb (M lower triangular nd × nd, stride nx), hout = M hb.
 * Returns RQP_DEPENDENT where one vanishes or reaches x_0. */
static int pass_back(int k, int nx, int nu, int na, int nd, work *ws,
                     rqp_real *Hout, rqp_real *hout) {
  int i, j, t;
  for (i = 0; i < nd; ++i) {
    const int di = ws->dep[i];
    rqp_real *hb = ws->Hb + i * nx, *co = ws->v2, norm, big = 1;
    for (j = 0; j < nx; ++j) {
      hb[j] = ws->Cx[di * nx + j];
      for (t = 0; t < na; ++t)
        hb[j] -= ws->beta[i * nu + t] * ws->Cx[ws->acc[t] * nx + j];
      if (RQP_FABS(ws->Cx[di * nx + j]) > big)
        big = RQP_FABS(ws->Cx[di * nx + j]);
    }
    ws->hb[i] = ws->c[di];
    for (t = 0; t < na; ++t) ws->hb[i] -= ws->beta[i * nu + t] * ws->c[ws->acc[t]];
    for (t = 0; t < i; ++t) co[t] = dot(nx, Hout + t * nx, hb);
    for (j = 0; j < nx; ++j) {
      rqp_real s = hb[j];
      for (t = 0; t < i; ++t) s -= co[t] * Hout[t * nx + j];
      ws->v1[j] = s;
    }
    norm = RQP_SQRT(dot(nx, ws->v1, ws->v1));
    if (k == 0 || norm <= RQP_DEP * big) return RQP_DEPENDENT;
    for (j = 0; j < nx; ++j) Hout[i * nx + j] = ws->v1[j] / norm;
    for (j = 0; j < i; ++j) {
      rqp_real s = 0;
      for (t = j; t < i; ++t) s += co[t] * ws->M[t * nx + j];
      ws->M[i * nx + j] = -s / norm;
    }
    ws->M[i * nx + i] = 1 / norm;
    hout[i] = 0;
    for (j = 0; j <= i; ++j) hout[i] += ws->M[i * nx + j] * ws->hb[j];
  }
  return 0;
}

/* A stage without rows: K = -Muu⁻¹Mux, k = -Muu⁻¹mu and P = AᵀPA -
 * GᵀG, G = L⁻¹Mux (Muu = L Lᵀ); T2 holds AᵀPA */
static void free_stage(int nx, int nu, work *ws, rqp_real *K, rqp_real *kk,
                       rqp_real *P) {
  rqp_real *L = ws->red, *G = ws->Fx;
  int i, j, t;
  for (i = 0; i < nu; ++i)
    for (j = 0; j <= i; ++j) {
      rqp_real s = ws->Muu[i * nu + j];
      for (t = 0; t < j; ++t) s -= L[i * nu + t] * L[j * nu + t];
      L[i * nu + j] = i == j ? RQP_SQRT(s) : s / L[j * nu + j];
    }
  for (j = 0; j <= nx; ++j) {
    /* column j of G = L⁻¹[Mux | mu], then of K = -L⁻ᵀG */
    for (i = 0; i < nu; ++i) {
      rqp_real s = j < nx ? ws->Mux[i * nx + j] : ws->mu[i];
      for (t = 0; t < i; ++t) s -= L[i * nu + t] * ws->v2[t];
      ws->v2[i] = s / L[i * nu + i];
      if (j < nx) G[i * nx + j] = ws->v2[i];
    }
    for (i = nu - 1; i >= 0; --i) {
      rqp_real s = ws->v2[i];
      for (t = i + 1; t < nu; ++t) s -= L[t * nu + i] * ws->v2[t];
      ws->v2[i] = s / L[i * nu + i];
      if (j < nx)
        K[i * nx + j] = -ws->v2[i];
      else
        kk[i] = -ws->v2[i];
    }
  }
  for (i = 0; i < nx; ++i)
    for (j = i; j < nx; ++j) {
      rqp_real s = ws->T2[i * nx + j];
      for (t = 0; t < nu; ++t) s -= G[t * nx + i] * G[t * nx + j];
      P[i * nx + j] = P[j * nx + i] = s;
    }
}

#endif
