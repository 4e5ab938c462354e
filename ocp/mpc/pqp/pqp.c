/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* Primal active set (Nocedal & Wright, Numerical Optimization, 2nd ed.,
 * algorithm 16.3) for the QP of Hessian I: the working set's step is
 * p = -(r - C_Wᵀ t), M t = C_W r, r = y + f, with the Cholesky factor
 * L of M = C_W C_Wᵀ kept by a row added (one forward solve) or dropped
 * (Givens rotations). See pqp.h. */
#include "pqp.h"

#include <math.h>

#ifdef PQP_SINGLE_PRECISION
#define PQP_SQRT sqrtf
#define PQP_FABS fabsf
/* a row joins only if its pivot is above PQP_DEP of its norm; the
 * ratio test skips rows moved less than PQP_MOVE of |p||c| */
#define PQP_DEP 1e-4f
#define PQP_MOVE 1e-4f
#else
#define PQP_SQRT sqrt
#define PQP_FABS fabs
/* the pivot comes from the Gram matrix (its square): below about
 * sqrt(DBL_EPSILON) of the norm it is rounding, so a row nearer than
 * 1e-6 to the working set's span counts as dependent */
#define PQP_DEP 1e-6
#define PQP_MOVE 1e-9
#endif

/* row i of the packed lower factor (rows of length i + 1) */
#define LROW(L, i) ((L) + (i) * ((i) + 1) / 2)

int pqp_work_size(int n, int m) { return n * (n + 1) / 2 + 4 * n + 3 * m; }

int pqp_iwork_size(int n, int m) { return n + m; }

/* four partial sums: the loop the solver spends its time in, unrolled
 * by hand so that any compiler keeps the FPU busy */
static pqp_real dot(int n, const pqp_real* a, const pqp_real* b) {
  pqp_real s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  int i;
  for (i = 0; i + 3 < n; i += 4) {
    s0 += a[i] * b[i];
    s1 += a[i + 1] * b[i + 1];
    s2 += a[i + 2] * b[i + 2];
    s3 += a[i + 3] * b[i + 3];
  }
  for (; i < n; ++i) s0 += a[i] * b[i];
  return (s0 + s1) + (s2 + s3);
}

/* Add row j to the factor of the k rows in ws; 0, or 1 if it depends on
 * them (relative to its norm). len: each row's nonzero prefix. */
static int factor_add(int n, const pqp_real* C, const int* len,
                      const int* ws, int k, int j, pqp_real norm2,
                      pqp_real* L) {
  pqp_real* row = LROW(L, k);
  const pqp_real* c = C + (long)j * n;
  pqp_real d = norm2;
  int i;
  for (i = 0; i < k; ++i) {
    const int l = len[ws[i]] < len[j] ? len[ws[i]] : len[j];
    pqp_real v = dot(l, C + (long)ws[i] * n, c);
    v -= dot(i, LROW(L, i), row);
    row[i] = v / LROW(L, i)[i];
    d -= row[i] * row[i];
  }
  if (d <= PQP_DEP * PQP_DEP * norm2) return 1;
  row[k] = PQP_SQRT(d);
  return 0;
}

/* Drop row q of the factor of k rows: rotate columns (i, i+1) to zero
 * the factor's new superdiagonal, then close the gap. v (k), the
 * solution of L v = b, is rotated with them: its first k - 1 entries
 * solve the new factor's system with b's entry q left out. */
static void factor_drop(int k, int q, pqp_real* L, pqp_real* v) {
  int i, t;
  for (i = q; i < k - 1; ++i) {
    pqp_real a = LROW(L, i + 1)[i], b = LROW(L, i + 1)[i + 1];
    pqp_real r = PQP_SQRT(a * a + b * b), c = a / r, s = b / r;
    pqp_real vi = v[i];
    v[i] = c * vi + s * v[i + 1];
    v[i + 1] = -s * vi + c * v[i + 1];
    LROW(L, i + 1)[i] = r;
    LROW(L, i + 1)[i + 1] = 0;
    for (t = i + 2; t < k; ++t) {
      pqp_real x = LROW(L, t)[i], z = LROW(L, t)[i + 1];
      LROW(L, t)[i] = c * x + s * z;
      LROW(L, t)[i + 1] = -s * x + c * z;
    }
  }
  for (i = q; i < k - 1; ++i) {
    pqp_real* dst = LROW(L, i);
    const pqp_real* src = LROW(L, i + 1);
    for (t = 0; t <= i; ++t) dst[t] = src[t];
  }
}

/* rows parked at their bound (side ±2) back out of the working set */
static void unpark(int m, signed char* side) {
  int j;
  for (j = 0; j < m; ++j)
    if (side[j] == 2 || side[j] == -2) side[j] = 0;
}

int pqp_solve(int n, int m, const pqp_real* C, const pqp_real* lo,
              const pqp_real* hi, const pqp_real* f, pqp_real* y,
              signed char* side, pqp_real* lam, int max_iter, pqp_real tol,
              pqp_real* w, int* iw, int* iterations) {
  pqp_real *L = w, *r = L + n * (n + 1) / 2, *p = r + n, *t = p + n,
           *v = t + n, *Cy = v + n, *Cp = Cy + m, *norm = Cp + m;
  int *ws = iw, *len = iw + n;
  int i, j, k = 0, it, at_zero = 1;
  for (i = 0; i < n; ++i) at_zero = at_zero && y[i] == 0;
  for (j = 0; j < m; ++j) {
    const pqp_real* c = C + (long)j * n;
    for (len[j] = n; len[j] > 0 && c[len[j] - 1] == 0; --len[j]) {
    }
    lam[j] = 0;
    norm[j] = dot(len[j], c, c);
    Cy[j] = at_zero ? 0 : dot(len[j], c, y);
    if (Cy[j] < lo[j] - tol * (1 + PQP_FABS(lo[j])) ||
        Cy[j] > hi[j] + tol * (1 + PQP_FABS(hi[j])))
      return PQP_INFEASIBLE_START;
  }
  /* the warm rows at their bound, independent ones in order */
  for (j = 0; j < m; ++j) {
    pqp_real b;
    if (!side[j]) continue;
    b = side[j] > 0 ? hi[j] : lo[j];
    if (k == n || PQP_FABS(Cy[j] - b) > tol * (1 + PQP_FABS(b)) ||
        factor_add(n, C, len, ws, k, j, norm[j], L)) {
      side[j] = 0;
      continue;
    }
    ws[k++] = j;
  }
  /* v = L⁻¹ C_W r, kept from here on: a step leaves C_W r unchanged
   * (C_W p = 0), a row added appends one entry, one dropped rotates v */
  for (i = 0; i < n; ++i) r[i] = y[i] + f[i];
  for (i = 0; i < k; ++i) {
    v[i] = dot(len[ws[i]], C + (long)ws[i] * n, r) - dot(i, LROW(L, i), v);
    v[i] /= LROW(L, i)[i];
  }
  for (it = 1; it <= max_iter; ++it) {
    pqp_real pmax = 0, pnorm = 0, alpha = 1, rmax = 0;
    int block = -1;
    /* t = M⁻¹ C_W r, p = C_Wᵀ t - r */
    for (i = 0; i < n; ++i) {
      r[i] = y[i] + f[i];
      if (PQP_FABS(r[i]) > rmax) rmax = PQP_FABS(r[i]);
    }
    for (i = 0; i < k; ++i) t[i] = v[i];
    for (i = k - 1; i >= 0; --i) {
      const pqp_real* row = LROW(L, i);
      t[i] /= row[i];
      for (j = 0; j < i; ++j) t[j] -= row[j] * t[i];
    }
    for (i = 0; i < n; ++i) p[i] = -r[i];
    for (i = 0; i < k; ++i) {
      const pqp_real* c = C + (long)ws[i] * n;
      for (j = 0; j < len[ws[i]]; ++j) p[j] += t[i] * c[j];
    }
    for (i = 0; i < n; ++i) {
      pqp_real a = PQP_FABS(p[i]);
      if (a > pmax) pmax = a;
      pnorm += p[i] * p[i];
    }
    if (pmax <= tol * (1 + rmax)) {
      /* multipliers ν = -t; drop the most wrong-signed */
      pqp_real worst = tol * (1 + rmax);
      int q = -1;
      for (i = 0; i < k; ++i) {
        pqp_real wrong = t[i] * side[ws[i]];
        if (wrong > worst) worst = wrong, q = i;
      }
      if (q < 0) {
        for (i = 0; i < k; ++i) lam[ws[i]] = -t[i];
        unpark(m, side);
        *iterations = it;
        return PQP_OPTIMAL;
      }
      side[ws[q]] = 0;
      unpark(m, side);
      factor_drop(k, q, L, v);
      for (i = q; i < k - 1; ++i) ws[i] = ws[i + 1];
      --k;
      continue;
    }
    /* ratio test over the rows the step moves along */
    pnorm = PQP_SQRT(pnorm);
    for (j = 0; j < m; ++j) {
      pqp_real room;
      if (side[j]) {
        Cp[j] = 0; /* C_W p = 0: the working rows stay at their bound */
        continue;
      }
      Cp[j] = dot(len[j], C + (long)j * n, p);
      if (PQP_FABS(Cp[j]) <= PQP_MOVE * pnorm * PQP_SQRT(norm[j])) continue;
      room = ((Cp[j] > 0 ? hi[j] : lo[j]) - Cy[j]) / Cp[j];
      if (room < alpha) alpha = room > 0 ? room : 0, block = j;
    }
    for (i = 0; i < n; ++i) y[i] += alpha * p[i];
    for (j = 0; j < m; ++j) Cy[j] += alpha * Cp[j];
    if (block >= 0) {
      if (k == n || factor_add(n, C, len, ws, k, block, norm[block], L)) {
        /* a row the working set already holds at its bound (in exact
         * arithmetic it could not block): parked, out of the ratio test
         * until a row leaves */
        side[block] = Cp[block] > 0 ? 2 : -2;
        continue;
      }
      side[block] = Cp[block] > 0 ? 1 : -1;
      /* the new entry of v, from c·(y + f) = c·y + c·f */
      v[k] = Cy[block] + dot(len[block], C + (long)block * n, f) -
             dot(k, LROW(L, k), v);
      v[k] /= LROW(L, k)[k];
      ws[k++] = block;
    }
  }
  /* stopped at a feasible point that is not stationary: no multipliers,
   * the working set's sides instead (±1, the next call's warm start) */
  for (i = 0; i < k; ++i) lam[ws[i]] = side[ws[i]];
  unpark(m, side);
  *iterations = max_iter;
  return PQP_ITERATION_LIMIT;
}
