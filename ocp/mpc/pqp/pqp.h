/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* A primal active-set solver for the dense QP of Hessian I:
 *
 *   min ½ yᵀy + fᵀy   s.t.   lo ≤ C y ≤ hi,   C (m × n, row-major),
 *
 * started from a warm working set, and stoppable after a fixed number
 * of iterations (every iterate is feasible and lowers the cost). A start
 * that breaks a bound first goes to its projection onto the feasible
 * set (phase one: a dual active set, at most max_iter iterations more).
 * C99, no heap: the caller passes the work arrays (pqp_work_size reals,
 * pqp_iwork_size ints). Double, or float when compiled with
 * -DPQP_SINGLE_PRECISION. */
#ifndef PQP_H
#define PQP_H

#ifdef PQP_SINGLE_PRECISION
typedef float pqp_real;
#else
typedef double pqp_real;
#endif

/* return values of pqp_solve */
#define PQP_OPTIMAL 0
#define PQP_ITERATION_LIMIT 1   /* a feasible point, not yet optimal */
#define PQP_INFEASIBLE 2        /* no point keeps every bound */
#define PQP_INVALID_INPUT 3
#define PQP_NO_FEASIBLE_POINT 4 /* phase one stopped at max_iter */

/* reals and ints of the work arrays for n variables and m rows (the
 * macros size static arrays) */
#define PQP_WORK_SIZE(n, m) ((n) * ((n) + 1) / 2 + 4 * (n) + 3 * (m))
#define PQP_IWORK_SIZE(n, m) ((n) + 2 * (m))
/* phase one's iteration limit in pqp_solve: each broken row joins once
 * and max_iter rows may leave (phase one rarely drops one: starts
 * beyond a rate bound that broke 8 and 20 rows took 8 and 20) */
#define PQP_PHASE_ONE_LIMIT(m, max_iter) ((m) + (max_iter))
int pqp_work_size(int n, int m);
int pqp_iwork_size(int n, int m);

/* Solve from the point y (n; in: the start, out: the last iterate).
 * side (m; in: the warm working set's sides, -1 lower, 1 upper, 0 not
 * in it; rows not at that bound at y, or dependent on those before
 * them, are left out; out: the last working set). Where y breaks a
 * bound (beyond tol relative to 1 + |bound|), phase one first moves it
 * to the nearest point that keeps every bound, the warm rows held at
 * their bound while their multipliers allow (at most
 * PQP_PHASE_ONE_LIMIT(m, max_iter) iterations: PQP_NO_FEASIBLE_POINT
 * after them, PQP_INFEASIBLE where the rows are inconsistent; y is then
 * phase one's last iterate); the primal phase starts there from phase
 * one's working rows. lam (m; out: the multipliers, positive at an
 * upper bound; at PQP_ITERATION_LIMIT, where y is not stationary, the
 * working set's sides instead: ±1 on its rows, to warm start a next
 * call; zero elsewhere and when no feasible point was found). At most
 * max_iter iterations of the primal phase (a KKT solve each: a step, or
 * a row dropped; phase one's likewise); *iterations the number made by
 * both phases. tol: the step below which y is a working set's optimum,
 * and the multipliers' sign tolerance, both relative to 1 + max |y + f|
 * (the gradient's scale). A start, gradient or bound that is NaN:
 * PQP_INVALID_INPUT, y left as it came and lam zero. */
int pqp_solve(int n, int m, const pqp_real* C, const pqp_real* lo,
              const pqp_real* hi, const pqp_real* f, pqp_real* y,
              signed char* side, pqp_real* lam, int max_iter, pqp_real tol,
              pqp_real* w, int* iw, int* iterations);

/* pqp_solve with C's rows laid out by the caller: row j's entries in
 * columns [0, row_len[j]) at C + row_start[j] (m each), its entries
 * beyond taken as zero. row_start NULL: rows of n entries one after the
 * other (C + j n); row_len NULL: found by scanning C, only so (with
 * row_start NULL: else PQP_INVALID_INPUT). max_phase_one: phase one's
 * iteration limit (pqp_solve's: PQP_PHASE_ONE_LIMIT). */
int pqp_solve_rows(int n, int m, const pqp_real* C, const int* row_start,
                   const int* row_len, const pqp_real* lo,
                   const pqp_real* hi, const pqp_real* f, pqp_real* y,
                   signed char* side, pqp_real* lam, int max_iter,
                   int max_phase_one, pqp_real tol, pqp_real* w, int* iw,
                   int* iterations);

#endif
