/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* Primal active set (Nocedal & Wright, Numerical Optimization, 2nd ed.,
 * algorithm 16.3) for the QP of Hessian I: the working set's step is
 * p = -(r - C_Wᵀ t), M t = C_W r, r = y + f, with the Cholesky factor
 * L of M = C_W C_Wᵀ kept by a row added (one forward solve) or dropped
 * (Givens rotations). The warm working set's factor comes from
 * Householder reflections of its rows instead (warm_factor). See pqp.h. */
#include "pqp.h"

#include <math.h>

#ifdef PQP_SINGLE_PRECISION
#define PQP_SQRT sqrtf
#define PQP_FABS fabsf
/* a row joins only if its pivot is above PQP_DEP of its norm; the
 * ratio test skips rows moved less than PQP_MOVE of |p||c|, phase one's
 * multipliers moved less than PQP_MOVE of the largest move */
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

int pqp_work_size(int n, int m) { return PQP_WORK_SIZE(n, m); }

int pqp_iwork_size(int n, int m) { return PQP_IWORK_SIZE(n, m); }

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

/* Lᵀ t = t in place, two columns of L a pass (the same operations, in
 * the same order, as one at a time: half the loads and stores of t) */
static void back_solve(int k, const pqp_real* L, pqp_real* t) {
  int i, j;
  for (i = k - 1; i >= 1; i -= 2) {
    const pqp_real *a = LROW(L, i), *b = LROW(L, i - 1);
    const pqp_real ta = t[i] / a[i];
    const pqp_real tb = (t[i - 1] - a[i - 1] * ta) / b[i - 1];
    t[i] = ta;
    t[i - 1] = tb;
    for (j = 0; j < i - 1; ++j) t[j] = t[j] - a[j] * ta - b[j] * tb;
  }
  if (i == 0) t[0] /= L[0];
}

/* p += C_Wᵀ t (the k rows in ws), two rows a pass, likewise */
static void add_rows(const pqp_real* C, const int* start, const int* len,
                     const int* ws, int k, const pqp_real* t, pqp_real* p) {
  int i, j;
  for (i = 0; i < k; i += 2) {
    const pqp_real *a = C + start[ws[i]], ta = t[i];
    const int la = len[ws[i]];
    if (i + 1 < k) {
      const pqp_real *b = C + start[ws[i + 1]], tb = t[i + 1];
      const int lb = len[ws[i + 1]], l = la < lb ? la : lb;
      for (j = 0; j < l; ++j) p[j] = p[j] + ta * a[j] + tb * b[j];
      for (; j < la; ++j) p[j] += ta * a[j];
      for (j = l; j < lb; ++j) p[j] += tb * b[j];
    } else {
      for (j = 0; j < la; ++j) p[j] += ta * a[j];
    }
  }
}

/* Add row j to the factor of the k rows in ws; 0, or 1 if it depends on
 * them (relative to its norm). Row i of C: len[i] entries at C +
 * start[i] (its nonzero prefix). */
static int factor_add(const pqp_real* C, const int* start, const int* len,
                      const int* ws, int k, int j, pqp_real norm2,
                      pqp_real* L) {
  pqp_real* row = LROW(L, k);
  const pqp_real* c = C + start[j];
  pqp_real d = norm2;
  int i;
  for (i = 0; i < k; ++i) {
    const int l = len[ws[i]] < len[j] ? len[ws[i]] : len[j];
    pqp_real v = dot(l, C + start[ws[i]], c);
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

/* Reflect x by the reflections in store[0, used): each is a header
 * (its first index i times n + 1, plus its length l: an integer, exact
 * in float for n < 4096), beta, then the l - 1 entries of its vector
 * after the first (which is 1); it acts on x[i, i + l). */
static void reflect(int n, const pqp_real* store, long used, pqp_real* x) {
  const pqp_real* end = store + used;
  while (store < end) {
    const int head = (int)store[0], i = head / (n + 1), l = head % (n + 1);
    const pqp_real* u = store + 2;
    pqp_real* xi = x + i;
    pqp_real s = xi[0];
    int t;
    for (t = 1; t < l; ++t) s += u[t - 1] * xi[t];
    s *= store[1];
    xi[0] -= s;
    for (t = 1; t < l; ++t) xi[t] -= s * u[t - 1];
    store += l + 1;
  }
}

/* The factor of the warm working set: each row at its bound (in order)
 * reflected by its predecessors' Householder reflections (Golub & Van
 * Loan, Matrix Computations, 4th ed., algorithms 5.1.1 and 5.2.1, on
 * C_Wᵀ): L = R of C_Wᵀ = QR, R's column k the reflected row's first k
 * entries and the norm of the rest (the entry itself, of either sign,
 * where the rest is that one entry: no reflection). The rows of the
 * step's QP are stage by stage, each row's nonzeros a prefix no longer
 * than the next's by more than a stage, so the reflections are a few
 * entries long and few: this costs a small share of forming the Gram
 * matrix (factor_add). They are stored in [store, store + *used);
 * when they fill it, the rest of the rows go through factor_add. x: n
 * reals of scratch. Returns the number of rows in ws; *used: the reals
 * the reflections take, or -1 if they did not reach every row. */
static int warm_factor(int n, int m, const pqp_real* C, const int* start,
                       const int* len, const pqp_real* lo,
                       const pqp_real* hi, const pqp_real* Cy,
                       const pqp_real* norm, pqp_real tol, signed char* side,
                       int* ws, pqp_real* L, pqp_real* store,
                       long* used_out, pqp_real* x) {
  const long cap = *used_out;
  int i, j, k = 0, e = 0, reflecting = 1;
  long used = 0;
  for (j = 0; j < m; ++j) {
    const pqp_real* c = C + start[j];
    pqp_real b, sigma, x0, mu;
    int top;
    if (!side[j]) continue;
    b = side[j] > 0 ? hi[j] : lo[j];
    if (k == n || PQP_FABS(Cy[j] - b) > tol * (1 + PQP_FABS(b))) {
      side[j] = 0;
      continue;
    }
    if (!reflecting) {
      if (factor_add(C, start, len, ws, k, j, norm[j], L))
        side[j] = 0;
      else
        ws[k++] = j;
      continue;
    }
    top = len[j] > e ? len[j] : e;
    for (i = 0; i < len[j]; ++i) x[i] = c[i];
    for (; i < top; ++i) x[i] = 0;
    reflect(n, store, used, x);
    sigma = top > k + 1 ? dot(top - k - 1, x + k + 1, x + k + 1) : 0;
    x0 = top > k ? x[k] : 0;
    mu = PQP_SQRT(x0 * x0 + sigma);
    if (mu <= PQP_DEP * PQP_SQRT(norm[j])) {
      side[j] = 0; /* it depends on the rows before it */
      continue;
    }
    for (i = 0; i < k; ++i) LROW(L, k)[i] = x[i];
    e = top;
    if (sigma == 0) {
      LROW(L, k)[k] = x0; /* nothing to reflect */
    } else if (used + (top - k) + 1 > cap) {
      LROW(L, k)[k] = mu; /* no room for its reflection: the rest */
      reflecting = 0;      /* of the rows through factor_add */
    } else {
      /* v = (1, x[k+1, top) / v0) maps x[k, top) to (mu, 0, ...) */
      const pqp_real v0 = x0 <= 0 ? x0 - mu : -sigma / (x0 + mu);
      store[used] = (pqp_real)(k * (n + 1) + (top - k));
      store[used + 1] = 2 * v0 * v0 / (sigma + v0 * v0);
      for (i = k + 1; i < top; ++i) store[used + 1 + i - k] = x[i] / v0;
      used += top - k + 1;
      LROW(L, k)[k] = mu;
    }
    ws[k++] = j;
  }
  *used_out = reflecting ? used : -1;
  return k;
}

/* Phase one: the start's projection onto the feasible set, min ½|y -
 * y0|² s.t. lo ≤ C y ≤ hi, by the dual active set of Goldfarb & Idnani
 * (A numerically stable dual method for solving strictly convex
 * quadratic programs, Math. Programming 27, 1983) for Hessian I: the
 * most violated row q joins at its broken side s, its multiplier
 * growing from 0 while y moves along z, c_q's part normal to the
 * working rows (which stay at their bound); a working row whose
 * multiplier would change sign leaves first. Starts from the k rows in
 * ws (at their bound at y0, multipliers 0) and their factor L; rows
 * join by a forward solve and leave by factor_drop, as in the primal
 * phase. u, x, r, z: n reals of scratch each; Cz: m. Returns 0 (y
 * feasible, *k its working rows), PQP_INFEASIBLE (q depends on the
 * working rows and none can leave: no point keeps every bound) or
 * PQP_NO_FEASIBLE_POINT (max_iter KKT solves made). */
static int phase_one(int n, int m, const pqp_real* C, const int* start,
                     const int* len, const pqp_real* lo, const pqp_real* hi,
                     const pqp_real* norm, pqp_real tol, pqp_real* y,
                     pqp_real* Cy, signed char* side, int* ws, int* k_io,
                     pqp_real* L, pqp_real* u, pqp_real* x, pqp_real* r,
                     pqp_real* z, pqp_real* Cz, int max_iter, int* its) {
  int i, j, k = *k_io;
  for (i = 0; i < k; ++i) u[i] = 0; /* the warm rows' multipliers */
  for (;;) {
    pqp_real worst = 0, b = 0, lam = 0;
    int q = -1, s = 0;
    for (j = 0; j < m; ++j) { /* the row farthest beyond its bound */
      pqp_real over;
      int sj = 0;
      if (side[j]) continue;
      if (Cy[j] > hi[j] + tol * (1 + PQP_FABS(hi[j])))
        over = Cy[j] - hi[j], sj = 1;
      else if (Cy[j] < lo[j] - tol * (1 + PQP_FABS(lo[j])))
        over = lo[j] - Cy[j], sj = -1;
      else
        continue;
      if (norm[j] == 0) { /* 0 beyond a bound */
        *k_io = k;
        return PQP_INFEASIBLE;
      }
      over /= PQP_SQRT(norm[j]);
      if (over > worst) worst = over, q = j, s = sj;
    }
    if (q < 0) break;
    b = s > 0 ? hi[q] : lo[q];
    for (;;) {
      const pqp_real* c = C + start[q];
      pqp_real d = norm[q], step, room = 0, rmax = 0;
      int block = -1, dep;
      if (*its >= max_iter) {
        *k_io = k;
        return PQP_NO_FEASIBLE_POINT;
      }
      ++*its;
      /* x = L⁻¹ C_W c_q, d = |c_q|² - |x|² = |z|²; r = L⁻ᵀ x */
      for (i = 0; i < k; ++i) {
        const int l = len[ws[i]] < len[q] ? len[ws[i]] : len[q];
        x[i] = (dot(l, C + start[ws[i]], c) - dot(i, LROW(L, i), x)) /
               LROW(L, i)[i];
        d -= x[i] * x[i];
      }
      for (i = 0; i < k; ++i) r[i] = x[i];
      back_solve(k, L, r);
      dep = k == n || d <= PQP_DEP * PQP_DEP * norm[q];
      for (i = 0; i < k; ++i)
        if (PQP_FABS(r[i]) > rmax) rmax = PQP_FABS(r[i]);
      for (i = 0; i < k; ++i) /* multipliers that reach 0 first (a */
        if (s * r[i] * side[ws[i]] > PQP_MOVE * rmax) { /* moved one) */
          const pqp_real ti = u[i] / (s * r[i]);
          if (block < 0 || ti < room) room = ti, block = i;
        }
      if (dep && block < 0) {
        *k_io = k;
        return PQP_INFEASIBLE;
      }
      step = dep ? room : s * (Cy[q] - b) / d; /* q reaches b */
      if (block >= 0 && (dep || room < step)) step = room;
      else block = -1;
      if (!dep) { /* y += step s z, z = C_Wᵀ r - c_q */
        for (j = 0; j < n; ++j) z[j] = j < len[q] ? -c[j] : 0;
        add_rows(C, start, len, ws, k, r, z);
        for (j = 0; j < n; ++j) y[j] += step * s * z[j];
        for (j = 0; j < m; ++j)
          if (!side[j] && j != q) {
            Cz[j] = dot(len[j], C + start[j], z);
            Cy[j] += step * s * Cz[j];
          }
        Cy[q] -= step * s * d;
      }
      for (i = 0; i < k; ++i) u[i] -= step * s * r[i];
      lam += step * s;
      if (block < 0) { /* q reaches its bound: it joins */
        for (i = 0; i < k; ++i) LROW(L, k)[i] = x[i];
        LROW(L, k)[k] = PQP_SQRT(d);
        Cy[q] = b;
        side[q] = (signed char)s;
        u[k] = lam;
        ws[k++] = q;
        break;
      }
      side[ws[block]] = 0; /* a multiplier reached 0: its row leaves */
      factor_drop(k, block, L, x);
      for (i = block; i < k - 1; ++i) ws[i] = ws[i + 1], u[i] = u[i + 1];
      --k;
    }
  }
  *k_io = k;
  return 0;
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
  return pqp_solve_rows(n, m, C, 0, 0, lo, hi, f, y, side, lam, max_iter,
                        PQP_PHASE_ONE_LIMIT(m, max_iter), tol, w, iw,
                        iterations);
}

int pqp_solve_rows(int n, int m, const pqp_real* C, const int* row_start,
                   const int* row_len, const pqp_real* lo,
                   const pqp_real* hi, const pqp_real* f, pqp_real* y,
                   signed char* side, pqp_real* lam, int max_iter,
                   int max_phase_one, pqp_real tol, pqp_real* w, int* iw,
                   int* iterations) {
  /* r, p, v and Cp follow L: the warm start's reflections are stored
   * there, beyond the rows its factor can take, before they are used */
  pqp_real *L = w, *r = L + n * (n + 1) / 2, *p = r + n, *v = p + n,
           *Cp = v + n, *t = Cp + m, *Cy = t + n, *norm = Cy + m;
  int *ws = iw, *len = iw + n, *start = len + m;
  int i, j, k = 0, it, at_zero = 1, warm = 0, feasible = 1, first = 0;
  int crossed = 0, nan = 0;
  long reflected;
  *iterations = 0;
  if (row_start && !row_len) return PQP_INVALID_INPUT;
  for (i = 0; i < n; ++i) {
    at_zero = at_zero && y[i] == 0;
    nan = nan || y[i] != y[i] || f[i] != f[i];
  }
  for (j = 0; j < m; ++j) {
    const pqp_real* c;
    start[j] = row_start ? row_start[j] : j * n;
    c = C + start[j];
    if (row_len)
      len[j] = row_len[j];
    else
      for (len[j] = n; len[j] > 0 && c[len[j] - 1] == 0; --len[j]) {
      }
    lam[j] = 0;
    norm[j] = dot(len[j], c, c);
    Cy[j] = at_zero ? 0 : dot(len[j], c, y);
    nan = nan || lo[j] != lo[j] || hi[j] != hi[j];
    crossed = crossed || lo[j] > hi[j] + tol * (1 + PQP_FABS(hi[j]));
    feasible = feasible && Cy[j] >= lo[j] - tol * (1 + PQP_FABS(lo[j])) &&
               Cy[j] <= hi[j] + tol * (1 + PQP_FABS(hi[j]));
  }
  if (nan) return PQP_INVALID_INPUT; /* lam is 0, y as it came */
  if (crossed) return PQP_INFEASIBLE; /* a row's bounds cross */
  /* the warm rows at their bound, independent ones in order */
  for (j = 0; j < m; ++j) warm += side[j] != 0;
  if (warm > n) warm = n;
  reflected = (long)(Cp + m - LROW(L, warm));
  k = warm_factor(n, m, C, start, len, lo, hi, Cy, norm, tol, side, ws, L,
                  LROW(L, warm), &reflected, t);
  if (!feasible) {
    /* phase one to the start's projection, whose working rows (at
     * their bound there) are then the primal phase's warm start */
    const int status = phase_one(n, m, C, start, len, lo, hi, norm, tol,
                                 y, Cy, side, ws, &k, L, v, t, r, p, Cp,
                                 max_phase_one, &first);
    *iterations = first;
    if (status) {
      unpark(m, side);
      return status;
    }
    for (j = 0; j < m; ++j) Cy[j] = dot(len[j], C + start[j], y);
    warm = k;
    reflected = (long)(Cp + m - LROW(L, warm));
    k = warm_factor(n, m, C, start, len, lo, hi, Cy, norm, tol, side, ws, L,
                    LROW(L, warm), &reflected, t);
  }
  /* v = L⁻¹ C_W r, kept from here on: a step leaves C_W r unchanged
   * (C_W p = 0), a row added appends one entry, one dropped rotates v.
   * C_W = L Qᵀ (the first k columns of warm_factor's Q), so v is the
   * first k entries of Qᵀ r where every warm row was reflected. */
  for (i = 0; i < n; ++i) t[i] = y[i] + f[i];
  if (reflected >= 0) {
    reflect(n, LROW(L, warm), reflected, t);
    for (i = 0; i < k; ++i) v[i] = t[i];
  } else {
    for (i = 0; i < k; ++i) {
      v[i] = dot(len[ws[i]], C + start[ws[i]], t) -
             dot(i, LROW(L, i), v);
      v[i] /= LROW(L, i)[i];
    }
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
    back_solve(k, L, t);
    if (k < n) { /* n independent rows leave no step: p = 0 */
      for (i = 0; i < n; ++i) p[i] = -r[i];
      add_rows(C, start, len, ws, k, t, p);
      for (i = 0; i < n; ++i) {
        pqp_real a = PQP_FABS(p[i]);
        if (a > pmax) pmax = a;
        pnorm += p[i] * p[i];
      }
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
        *iterations = first + it;
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
      Cp[j] = dot(len[j], C + start[j], p);
      if (PQP_FABS(Cp[j]) <= PQP_MOVE * pnorm * PQP_SQRT(norm[j])) continue;
      room = ((Cp[j] > 0 ? hi[j] : lo[j]) - Cy[j]) / Cp[j];
      if (room < alpha) alpha = room > 0 ? room : 0, block = j;
    }
    for (i = 0; i < n; ++i) y[i] += alpha * p[i];
    for (j = 0; j < m; ++j) Cy[j] += alpha * Cp[j];
    if (block >= 0) {
      if (k == n || factor_add(C, start, len, ws, k, block, norm[block], L)) {
        /* a row the working set already holds at its bound (in exact
         * arithmetic it could not block): parked, out of the ratio test
         * until a row leaves */
        side[block] = Cp[block] > 0 ? 2 : -2;
        continue;
      }
      side[block] = Cp[block] > 0 ? 1 : -1;
      /* the new entry of v, from c·(y + f) = c·y + c·f */
      v[k] = Cy[block] + dot(len[block], C + start[block], f) -
             dot(k, LROW(L, k), v);
      v[k] /= LROW(L, k)[k];
      ws[k++] = block;
    }
  }
  /* stopped at a feasible point that is not stationary: no multipliers,
   * the working set's sides instead (±1, the next call's warm start) */
  for (i = 0; i < k; ++i) lam[ws[i]] = side[ws[i]];
  unpark(m, side);
  *iterations = first + max_iter;
  return PQP_ITERATION_LIMIT;
}
