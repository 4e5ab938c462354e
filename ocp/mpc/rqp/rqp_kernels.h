/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* rqp.c's small dense and compressed-column kernels (static: included
 * by rqp.c alone, so that the compiler inlines them). */
#ifndef RQP_KERNELS_H
#define RQP_KERNELS_H

static rqp_real dot(int n, const rqp_real *a, const rqp_real *b) {
  rqp_real s = 0;
  int i;
  for (i = 0; i < n; ++i) s += a[i] * b[i];
  return s;
}

/* y (m) = M (m × n, row-major) x */
static void matvec(int m, int n, const rqp_real *M, const rqp_real *x,
                   rqp_real *y) {
  int i;
  for (i = 0; i < m; ++i) y[i] = dot(n, M + i * n, x);
}

/* C (m × n) = A (m × l) B (l × n), row-major */
static void matmul(int m, int l, int n, const rqp_real *A, const rqp_real *B,
                   rqp_real *C) {
  int i, j, t;
  for (i = 0; i < m; ++i)
    for (j = 0; j < n; ++j) {
      rqp_real s = 0;
      for (t = 0; t < l; ++t) s += A[i * l + t] * B[t * n + j];
      C[i * n + j] = s;
    }
}

/* a compressed-column matrix: pattern and one stage's values */
typedef struct {
  const int *col, *row;
  const rqp_real *v;
  int ncol;
} sparse;

/* stage k's matrix of the pattern (col, row; ncol columns) */
static sparse stage_sparse(const int *col, const int *row,
                           const rqp_real *values, int ncol, int k) {
  sparse S;
  S.col = col;
  S.row = row;
  S.v = values + (long)k * col[ncol];
  S.ncol = ncol;
  return S;
}

#define stage_A(qp, k) stage_sparse((qp)->a_col, (qp)->a_row, (qp)->A, (qp)->nx, k)
#define stage_B(qp, k) stage_sparse((qp)->b_col, (qp)->b_row, (qp)->B, (qp)->nu, k)
#define stage_Q(qp, k) stage_sparse((qp)->q_col, (qp)->q_row, (qp)->Q, (qp)->nx, k)

/* P (n × n, row-major) += S (compressed columns) */
static void add_sparse(sparse S, int n, rqp_real *P) {
  int j, t;
  for (j = 0; j < S.ncol; ++j)
    for (t = S.col[j]; t < S.col[j + 1]; ++t) P[S.row[t] * n + j] += S.v[t];
}

/* out (m × S.ncol) = M (m × n, row-major) S: a column of M scaled per
 * nonzero (loops of m, fixed when the sizes are) */
static void mul_sparse(int m, int n, const rqp_real *M, sparse S,
                       rqp_real *out) {
  int i, j, t;
  for (i = 0; i < m * S.ncol; ++i) out[i] = 0;
  for (j = 0; j < S.ncol; ++j)
    for (t = S.col[j]; t < S.col[j + 1]; ++t) {
      const rqp_real *Mr = M + S.row[t], v = S.v[t];
      for (i = 0; i < m; ++i) out[i * S.ncol + j] += Mr[i * n] * v;
    }
}

#ifndef RQP_PRODUCTS /* else generated for the craft */
/* out (S.ncol × n) = Sᵀ M (M: S's rows × n): a row of M scaled per
 * nonzero */
static void tmul_sparse(sparse S, int n, const rqp_real *M, rqp_real *out) {
  int i, j, t;
  for (j = 0; j < S.ncol; ++j) {
    rqp_real *o = out + j * n;
    for (i = 0; i < n; ++i) o[i] = 0;
    for (t = S.col[j]; t < S.col[j + 1]; ++t) {
      const rqp_real *Mr = M + S.row[t] * n, v = S.v[t];
      for (i = 0; i < n; ++i) o[i] += v * Mr[i];
    }
  }
}
#endif

/* y (S.ncol) = Sᵀ x */
static void tvec_sparse(sparse S, const rqp_real *x, rqp_real *y) {
  int j, t;
  for (j = 0; j < S.ncol; ++j) {
    rqp_real s = 0;
    for (t = S.col[j]; t < S.col[j + 1]; ++t) s += S.v[t] * x[S.row[t]];
    y[j] = s;
  }
}

/* y += S x */
static void vec_sparse(sparse S, const rqp_real *x, rqp_real *y) {
  int j, t;
  for (j = 0; j < S.ncol; ++j)
    for (t = S.col[j]; t < S.col[j + 1]; ++t) y[S.row[t]] += S.v[t] * x[j];
}

/* row i of S into out (S.ncol) */
static void row_sparse(sparse S, int i, rqp_real *out) {
  int j, t;
  for (j = 0; j < S.ncol; ++j) {
    out[j] = 0;
    for (t = S.col[j]; t < S.col[j + 1]; ++t)
      if (S.row[t] == i) out[j] = S.v[t];
  }
}

#endif
