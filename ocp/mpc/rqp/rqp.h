/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* A primal active set for the MPC's QP kept stage by stage, each working
 * set's equality QP solved by one backward Riccati recursion in which
 * the working boxes are eliminated (the rows a stage's inputs cannot
 * meet passed back to its state):
 *
 *   min Σ_k ½x_{k+1}ᵀQ_k x_{k+1} + q_kᵀx_{k+1} + ½u_kᵀdiag(R)u_k + g_kᵀu_k
 *   s.t. x_{k+1} = A_k x_k + B_k u_k + d_k, x_0 = 0,
 *        lo_kb ≤ s_b · (u_k, x_{k+1})[i_b] ≤ hi_kb   (box b of stage k),
 *
 * k = 0…N−1, started from a feasible (U, X) and a warm working set,
 * stoppable after a fixed number of iterations (every iterate keeps the
 * boxes and lowers the cost). The numpy twin that makes the same
 * decisions is benchmarks/riccati_active_set.py. C99, no heap: the
 * caller passes the work arrays (rqp_work_size reals, rqp_iwork_size
 * ints). Double, or float when compiled with -DRQP_SINGLE_PRECISION. */
#ifndef RQP_H
#define RQP_H

#ifdef RQP_SINGLE_PRECISION
typedef float rqp_real;
#else
typedef double rqp_real;
#endif

/* return values of rqp_solve */
#define RQP_OPTIMAL 0
#define RQP_ITERATION_LIMIT 1 /* a feasible point, not yet optimal */
#define RQP_INFEASIBLE_START 2 /* the start breaks a box: no phase one */
#define RQP_INVALID_INPUT 3
#define RQP_ROWS_FULL 4 /* a feasible point, not yet optimal: the rows
                         * passed back filled their pool (rqp.c,
                         * RQP_POOL_ROWS(N, nx), default N + nx rows) */

/* the problem, stage after stage: A, B and Q as the nonzeros of one
 * compressed-column pattern each (CasADi's: column j's entries at
 * [col[j], col[j+1]), their rows in row[]; Q's pattern symmetric), the
 * vectors dense */
typedef struct {
  int N, nx, nu, nb;
  const int *a_col, *a_row; /* A's pattern: nx + 1 and a_col[nx] */
  const int *b_col, *b_row; /* B's pattern: nu + 1 and b_col[nu] */
  const int *q_col, *q_row; /* Q's pattern: nx + 1 and q_col[nx] */
  const rqp_real *A;     /* N × a_col[nx] */
  const rqp_real *B;     /* N × b_col[nu] */
  const rqp_real *d;     /* N × nx */
  const rqp_real *Q;     /* N × q_col[nx]: the cost of x_{k+1} */
  const rqp_real *q;     /* N × nx */
  const rqp_real *R;     /* nu: the input weight's diagonal */
  const rqp_real *g;     /* N × nu */
  const int *box;        /* nb: i_b, an input (< nu) or nu + a state */
  const rqp_real *scale; /* nb: s_b */
  const rqp_real *lo;    /* N × nb */
  const rqp_real *hi;    /* N × nb */
  const int *fixed;      /* nu: 1 where the input is held at its start */
} rqp_problem;

int rqp_work_size(int N, int nx, int nu, int nb);
int rqp_iwork_size(int N, int nx, int nu, int nb);

/* Solve from (U, X) (N × nu and N × nx: in, a start that keeps every
 * box, beyond tol relative to 1 + |bound| RQP_INFEASIBLE_START, and the
 * dynamics; out, the last iterate; a start or bound that is NaN:
 * RQP_INVALID_INPUT). side (N × nb; in: the
 * warm working set's sides, -1 lower, 1 upper, 0 not in it: boxes not
 * at their bound at the start are
 * left out, and a warm set whose boxes are dependent is left out
 * whole; out: the last working set). lam (N × nb; out: the
 * multipliers, positive at an upper bound, zero elsewhere and unless
 * optimal). At most max_iter iterations (one recursion and one forward
 * sweep each); tol: the step, in box widths, below which the iterate is
 * the working set's optimum, and the multipliers' sign tolerance.
 * *iterations: made; *stages: stages factored by every recursion (N a
 * whole one). */
int rqp_solve(const rqp_problem *qp, rqp_real *U, rqp_real *X,
              signed char *side, rqp_real *lam, int max_iter, rqp_real tol,
              rqp_real *w, int *iw, int *iterations, long *stages);

#endif
