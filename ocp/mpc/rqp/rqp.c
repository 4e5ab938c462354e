/* SPDX-License-Identifier: BSD-3-Clause (LICENSE beside this file) */
/* Primal active set (Nocedal & Wright, Numerical Optimization, 2nd ed.,
 * algorithm 16.3) on the stage-wise QP of rqp.h. A working set's
 * equality QP is one backward recursion: at stage k the working boxes of
 * the stage and the rows passed back to x_{k+1}, each an equality row on
 * (x_k, u_k) through the dynamics, are split by Gram-Schmidt on their
 * u-parts (rows that constrain u_k eliminate a direction of it; the
 * others, less their kept parts, are rows on x_k alone, passed back:
 * Laine & Tomlin, Efficient computation of feedback control for
 * equality-constrained LQR, ICRA 2019), the free directions of u_k
 * minimise the cost-to-go, and u_k = K_k x_k + k_k. A change at stage k
 * refactors stages k…0; the multipliers come from one forward sweep. */
#include "rqp.h"

#include <math.h>

#ifdef RQP_SINGLE_PRECISION
#define RQP_SQRT sqrtf
#define RQP_FABS fabsf
#define RQP_RANK 1e-5f /* a row's u-part below this of its norm: none */
#define RQP_DEP 1e-5f  /* a row on x below this of its norm: dependent */
#define RQP_MOVE 1e-5f /* the ratio test skips boxes moved less */
#define RQP_AT_BOUND 1e-5f /* a warm box this near its bound: at it */
#else
#define RQP_SQRT sqrt
#define RQP_FABS fabs
#define RQP_RANK 1e-9
#define RQP_DEP 1e-9
#define RQP_MOVE 1e-9
#define RQP_AT_BOUND 1e-9
#endif

#define RQP_DEPENDENT (-1)
#define RQP_FULL (-2) /* the rows passed back would overflow their pool */

/* the rows passed back to the stages' states share one pool of this
 * many rows (the Monte Carlo's QPs pass at most one a stage) */
#ifndef RQP_POOL_ROWS
#define RQP_POOL_ROWS(N, nx) ((N) + (nx))
#endif

#ifdef RQP_PRODUCTS
/* the stage's products, generated for the craft's patterns: from P
 * (nx × nx, row-major, symmetric) and the stage's A, B (nonzeros) and d,
 * AᵀPA (nx × nx), BᵀPA (nu × nx), BᵀPB (nu × nu), P B (nx × nu) and P d;
 * PB has room for nx × nx (the generated products keep P A there first) */
void RQP_PRODUCTS(const rqp_real *P, const rqp_real *A, const rqp_real *B,
                  const rqp_real *d, rqp_real *AtPA, rqp_real *BtPA,
                  rqp_real *BtPB, rqp_real *PB, rqp_real *Pd);
#endif

/* sizes known when compiled (-DRQP_NX=…, -DRQP_NU=…) let the compiler
 * unroll the stage's loops; rqp_solve then refuses other sizes */
#ifdef RQP_NX
#define NX_OF(qp) RQP_NX
#else
#define NX_OF(qp) ((qp)->nx)
#endif
#ifdef RQP_NU
#define NU_OF(qp) RQP_NU
#else
#define NU_OF(qp) ((qp)->nu)
#endif

/* the work arrays (caller's w and iw), carved in rqp_solve */
typedef struct {
  rqp_real *P, *p, *K, *k, *H, *h;      /* per stage (P: triangles) */
  rqp_real *Us, *Xs, *V, *dV;          /* per stage: iterate, boxes */
  rqp_real *Cx, *Cu, *c, *Qa, *Ra, *beta, *Hb, *hb, *M; /* one stage */
  rqp_real *Fx, *f0, *V2, *Muu, *Mux, *mu, *red, *T1, *T2, *v1, *v2, *nu_;
  rqp_real *PA, *PB; /* a stage's cost-to-go in and out, dense */
  int *nH, *oH, *acc, *dep, *rowbox, *xrow; /* oH: a stage's rows' first */
  int pool;
} work;

#include "rqp_kernels.h"

/* the cost-to-go P_k is kept as its upper triangle, row by row */
#define NP_OF(n) ((n) * ((n) + 1) / 2)

static void pack(int n, const rqp_real *F, rqp_real *T) {
  int i, j;
  for (i = 0; i < n; ++i)
    for (j = i; j < n; ++j) *T++ = F[i * n + j];
}

static void unpack(int n, const rqp_real *T, rqp_real *F) {
  int i, j;
  for (i = 0; i < n; ++i)
    for (j = i; j < n; ++j) F[i * n + j] = F[j * n + i] = *T++;
}

/* box b's value at (u, x): s_b (u, x)[i_b] */
static rqp_real box_value(const rqp_problem *qp, int b, const rqp_real *u,
                          const rqp_real *x) {
  const int i = qp->box[b];
  return qp->scale[b] * (i < NU_OF(qp) ? u[i] : x[i - NU_OF(qp)]);
}

#include "rqp_rows.h"

/* Stage k of the recursion: from the cost-to-go (Pin, pin) at x_{k+1}
 * and the rows passed back there, the law u_k = K x_k + k, the
 * cost-to-go at x_k and the rows passed back to it (stored at k). */
static int stage_factor(const rqp_problem *qp, int k, const signed char *side,
                        const rqp_real *u, const rqp_real *Pin,
                        const rqp_real *pin, const rqp_real *Hin,
                        const rqp_real *hin, int nHin, rqp_real *P,
                        work *ws) {
  const int nx = NX_OF(qp), nu = NU_OF(qp);
  const sparse A = stage_A(qp, k), B = stage_B(qp, k);
  const rqp_real *d = qp->d + k * nx, *g = qp->g + k * nu;
  rqp_real *K = ws->K + k * nu * nx, *kk = ws->k + k * nu,
           *p = ws->p + k * nx;
  const int r = stage_rows(qp, k, side, u, Hin, hin, nHin, ws);
  int na, nd, nf = 0, i, j, t;
  split(r, nu, ws, &na, &nd);
  if (nd > nx) return RQP_DEPENDENT;
  /* Raᵀ Z = rows' x-parts and c (forward substitution), Fx = -Qa Z */
  for (j = 0; j <= nx; ++j) {
    for (t = 0; t < na; ++t) {
      rqp_real s = j < nx ? ws->Cx[ws->acc[t] * nx + j] : ws->c[ws->acc[t]];
      for (i = 0; i < t; ++i) s -= ws->Ra[i * nu + t] * ws->v2[i];
      ws->v2[t] = s / ws->Ra[t * nu + t];
    }
    for (i = 0; i < nu; ++i) {
      rqp_real s = 0;
      for (t = 0; t < na; ++t) s += ws->Qa[t * nu + i] * ws->v2[t];
      if (j < nx)
        ws->Fx[i * nx + j] = -s;
      else
        ws->f0[i] = s;
    }
  }
  /* the free directions: unit vectors less their parts on Qa and on
   * the directions taken before them (kept where ≥ 1/2 is left) */
  for (j = 0; j < nu && na + nf < nu; ++j) {
    for (i = 0; i < nu; ++i) ws->v1[i] = i == j;
    for (t = 0; t < na; ++t) {
      const rqp_real s = ws->Qa[t * nu + j];
      for (i = 0; i < nu; ++i) ws->v1[i] -= s * ws->Qa[t * nu + i];
    }
    for (t = 0; t < nf; ++t) {
      const rqp_real s = ws->V2[t * nu + j];
      for (i = 0; i < nu; ++i) ws->v1[i] -= s * ws->V2[t * nu + i];
    }
    {
      const rqp_real n = RQP_SQRT(dot(nu, ws->v1, ws->v1));
      if (n > (rqp_real)0.5) {
        for (i = 0; i < nu; ++i) ws->V2[nf * nu + i] = ws->v1[i] / n;
        ++nf;
      }
    }
  }
  /* Muu = R + BᵀPB, Mux = BᵀPA, mu = g + Bᵀ(Pd + p); T2 = AᵀPA */
#ifdef RQP_PRODUCTS
  RQP_PRODUCTS(Pin, A.v, B.v, d, ws->T2, ws->Mux, ws->Muu, ws->T1, ws->hb);
#else
  mul_sparse(nx, nx, Pin, A, ws->T1);              /* P A (nx × nx) */
  tmul_sparse(A, nx, ws->T1, ws->T2);           /* AᵀPA */
  tmul_sparse(B, nx, ws->T1, ws->Mux);          /* BᵀPA */
  mul_sparse(nx, nx, Pin, B, ws->T1);              /* P B (nx × nu) */
  tmul_sparse(B, nu, ws->T1, ws->Muu);          /* BᵀPB */
  matvec(nx, nx, Pin, d, ws->hb);                  /* P d, kept */
#endif
  for (i = 0; i < nu; ++i) ws->Muu[i * nu + i] += qp->R[i];
  for (i = 0; i < nx; ++i) ws->v1[i] = ws->hb[i] + pin[i];
  tvec_sparse(B, ws->v1, ws->mu);
  for (i = 0; i < nu; ++i) ws->mu[i] += g[i];
  if (!r) {
    free_stage(nx, nu, ws, K, kk, P);
  } else {
    for (i = 0; i < nu * nx; ++i) K[i] = ws->Fx[i];
    for (i = 0; i < nu; ++i) kk[i] = ws->f0[i];
    if (nf) {
      /* red = V2ᵀ Muu V2 = L Lᵀ; K -= V2 red⁻¹ V2ᵀ(Muu Fx + Mux), k likewise */
      rqp_real *L = ws->red;
      for (i = 0; i < nf; ++i)
        for (j = 0; j <= i; ++j) {
          rqp_real s = 0;
          int a, b;
          for (a = 0; a < nu; ++a)
            for (b = 0; b < nu; ++b)
              s += ws->V2[i * nu + a] * ws->Muu[a * nu + b] * ws->V2[j * nu + b];
          for (t = 0; t < j; ++t) s -= L[i * nu + t] * L[j * nu + t];
          L[i * nu + j] = i == j ? RQP_SQRT(s) : s / L[j * nu + j];
        }
      for (j = 0; j <= nx; ++j) {
        /* v1 = Muu col + Mux col (or Muu f0 + mu), v2 = V2ᵀ v1, solved */
        for (i = 0; i < nu; ++i) {
          rqp_real s = j < nx ? ws->Mux[i * nx + j] : ws->mu[i];
          for (t = 0; t < nu; ++t)
            s += ws->Muu[i * nu + t] * (j < nx ? ws->Fx[t * nx + j] : ws->f0[t]);
          ws->v1[i] = s;
        }
        for (i = 0; i < nf; ++i) {
          rqp_real s = dot(nu, ws->V2 + i * nu, ws->v1);
          for (t = 0; t < i; ++t) s -= L[i * nu + t] * ws->v2[t];
          ws->v2[i] = s / L[i * nu + i];
        }
        for (i = nf - 1; i >= 0; --i) {
          rqp_real s = ws->v2[i];
          for (t = i + 1; t < nf; ++t) s -= L[t * nu + i] * ws->v2[t];
          ws->v2[i] = s / L[i * nu + i];
        }
        for (i = 0; i < nu; ++i) {
          rqp_real s = 0;
          for (t = 0; t < nf; ++t) s += ws->V2[t * nu + i] * ws->v2[t];
          if (j < nx)
            K[i * nx + j] -= s;
          else
            kk[i] -= s;
        }
      }
    }
    /* P = AᵀPA + KᵀZ + ZᵀK, Z = Mux + ½ Muu K (= Aclᵀ Pin Acl + KᵀRK,
     * Acl = A + BK) (+ Q_{k-1}): Fx takes Z */
    matmul(nu, nu, nx, ws->Muu, K, ws->Fx);
    for (i = 0; i < nu * nx; ++i)
      ws->Fx[i] = ws->Mux[i] + (rqp_real)0.5 * ws->Fx[i];
    for (i = 0; i < nx; ++i)
      for (j = i; j < nx; ++j) {
        rqp_real s = ws->T2[i * nx + j];
        for (t = 0; t < nu; ++t)
          s += K[t * nx + i] * ws->Fx[t * nx + j] +
               ws->Fx[t * nx + i] * K[t * nx + j];
        P[i * nx + j] = P[j * nx + i] = s;
      }
  }
  /* p = Aᵀv + Kᵀ(Muu k + mu), v = P (B k + d) + pin = PB k + Pd + pin */
  matvec(nx, nu, ws->T1, kk, ws->v1);
  for (i = 0; i < nx; ++i) ws->v1[i] += ws->hb[i] + pin[i];
  tvec_sparse(A, ws->v1, p);
  matvec(nu, nu, ws->Muu, kk, ws->v2);
  for (i = 0; i < nu; ++i) ws->v2[i] += ws->mu[i];
  for (j = 0; j < nx; ++j) {
    rqp_real s = 0;
    for (t = 0; t < nu; ++t) s += K[t * nx + j] * ws->v2[t];
    p[j] += s;
  }
  if (k > 0) {
    add_sparse(stage_Q(qp, k - 1), nx, P);
    for (i = 0; i < nx; ++i) p[i] += qp->q[(k - 1) * nx + i];
  }
  pack(nx, P, ws->P + k * NP_OF(nx));
  {
    /* stage k's rows follow those of the stages after it in the pool */
    const int at = k == qp->N - 1 ? 0 : ws->oH[k + 1] + ws->nH[k + 1];
    if (at + nd > ws->pool) return RQP_FULL;
    ws->oH[k] = at;
    ws->nH[k] = nd;
    return pass_back(k, nx, nu, na, nd, ws, ws->H + at * nx, ws->h + at);
  }
}

/* The cost-to-go at x_{k+1}, dense into F: P_{k+1} unpacked, or the
 * last stage's Q */
static void cost_to_go_after(const rqp_problem *qp, int k, const work *ws,
                             rqp_real *F) {
  const int nx = NX_OF(qp);
  int i;
  if (k < qp->N - 1) {
    unpack(nx, ws->P + (k + 1) * NP_OF(nx), F);
    return;
  }
  for (i = 0; i < nx * nx; ++i) F[i] = 0;
  add_sparse(stage_Q(qp, k), nx, F);
}

/* The recursion from stage top down to 0 (stages above keep theirs). */
static int factor(const rqp_problem *qp, const signed char *side,
                  const rqp_real *U, int top, work *ws, long *stages) {
  const int N = qp->N, nx = NX_OF(qp), nu = NU_OF(qp);
  rqp_real *in = ws->PA, *out = ws->PB, *t;
  int k, code;
  cost_to_go_after(qp, top, ws, in);
  for (k = top; k >= 0; --k) {
    const int last = k == N - 1;
    const rqp_real *pin = last ? qp->q + k * nx : ws->p + (k + 1) * nx;
    ++*stages;
    code = stage_factor(qp, k, side, U + k * nu, in, pin,
                        last ? 0 : ws->H + ws->oH[k + 1] * nx,
                        last ? 0 : ws->h + ws->oH[k + 1],
                        last ? 0 : ws->nH[k + 1], out, ws);
    if (code) return code;
    t = in, in = out, out = t; /* stage k's cost-to-go is k − 1's input */
  }
  return 0;
}

/* (Us, Xs): the working set's optimum, x_0 = 0 rolled forward */
static void forward(const rqp_problem *qp, work *ws) {
  const int nx = NX_OF(qp), nu = NU_OF(qp);
  int k, i;
  for (k = 0; k < qp->N; ++k) {
    const rqp_real *x = k ? ws->Xs + (k - 1) * nx : 0;
    rqp_real *u = ws->Us + k * nu, *xn = ws->Xs + k * nx;
    for (i = 0; i < nu; ++i)
      u[i] = ws->k[k * nu + i] + (x ? dot(nx, ws->K + (k * nu + i) * nx, x) : 0);
    for (i = 0; i < nx; ++i) xn[i] = qp->d[k * nx + i];
    vec_sparse(stage_B(qp, k), u, xn);
    if (x) vec_sparse(stage_A(qp, k), x, xn);
  }
}

/* The working boxes' multipliers at (Us, Xs), the working set's optimum
 * (lam, N × nb; zero off the working set): forward over the stages, the
 * rows' multipliers ν solving C_uᵀν = -(R u_k + g_k + Bᵀ∇V_{k+1}) with
 * those of the rows passed back to x_k (η) fixed by stage k - 1. */
static void multipliers(const rqp_problem *qp, const signed char *side,
                        rqp_real *lam, work *ws) {
  const int N = qp->N, nx = NX_OF(qp), nu = NU_OF(qp), nb = qp->nb;
  rqp_real *eta = ws->v1 + (nx > nu ? nx : nu); /* beside v1's scratch */
  int k, i, t, ne = 0;
  for (i = 0; i < N * nb; ++i) lam[i] = 0;
  for (k = 0; k < N; ++k) {
    const int last = k == N - 1;
    const rqp_real *Pin = ws->PA;
    const rqp_real *pin = last ? qp->q + k * nx : ws->p + (k + 1) * nx;
    const rqp_real *u = ws->Us + k * nu, *x = ws->Xs + k * nx;
    const int r = stage_rows(qp, k, side, u, last ? 0 : ws->H + ws->oH[k + 1] * nx,
                             last ? 0 : ws->h + ws->oH[k + 1],
                             last ? 0 : ws->nH[k + 1], ws);
    int na, nd;
    cost_to_go_after(qp, k, ws, ws->PA);
    split(r, nu, ws, &na, &nd);
    /* the stored rows of x_k are this stage's; pass_back again for M */
    pass_back(k, nx, nu, na, nd, ws, ws->T1, ws->T2);
    /* rho = R u + g + Bᵀ(Pin x + pin), into mu */
    matvec(nx, nx, Pin, x, ws->v2);
    for (i = 0; i < nx; ++i) ws->v2[i] += pin[i];
    tvec_sparse(stage_B(qp, k), ws->v2, ws->mu);
    for (i = 0; i < nu; ++i) ws->mu[i] += qp->R[i] * u[i] + qp->g[k * nu + i];
    for (i = 0; i < r; ++i) ws->nu_[i] = 0;
    /* ν_dep = Mᵀ η */
    for (i = 0; i < nd; ++i) {
      rqp_real s = 0;
      for (t = i; t < nd && t < ne; ++t) s += ws->M[t * nx + i] * eta[t];
      ws->nu_[ws->dep[i]] = s;
    }
    /* ν_acc = Ra⁻¹ Qaᵀ(-rho) - betaᵀ ν_dep (back substitution) */
    for (t = na - 1; t >= 0; --t) {
      rqp_real s = -dot(nu, ws->Qa + t * nu, ws->mu);
      int j;
      for (j = t + 1; j < na; ++j) s -= ws->Ra[t * nu + j] * ws->v2[j];
      ws->v2[t] = s / ws->Ra[t * nu + t];
    }
    for (t = 0; t < na; ++t) {
      rqp_real s = ws->v2[t];
      for (i = 0; i < nd; ++i) s -= ws->beta[i * nu + t] * ws->nu_[ws->dep[i]];
      ws->nu_[ws->acc[t]] = s;
    }
    ne = 0;
    for (i = 0; i < r; ++i) {
      if (ws->rowbox[i] >= 0) lam[k * nb + ws->rowbox[i]] = ws->nu_[i];
      if (ws->rowbox[i] == -2) eta[ne++] = ws->nu_[i];
    }
  }
}

/* the work arrays' layout for these sizes: reals, ints */
static int layout(int N, int nx, int nu, int nb, rqp_real *w, int *iw,
                  work *ws, int *ni) {
  const int rmax = nu + nb + nx, big = nx > nu ? nx : nu;
  const int vlen = 2 * (big > rmax ? big : rmax);
  const int pool = RQP_POOL_ROWS(N, nx);
  rqp_real *at = w;
  int *it = iw;
  ws->pool = pool;
#define TAKE(f, n) (ws->f = w ? at : 0, at += (n))
  TAKE(P, N * NP_OF(nx)); TAKE(p, N * nx); TAKE(K, N * nu * nx);
  TAKE(k, N * nu); TAKE(H, pool * nx); TAKE(h, pool);
  TAKE(Us, N * nu); TAKE(Xs, N * nx); TAKE(V, N * nb); TAKE(dV, N * nb);
  TAKE(Cx, rmax * nx); TAKE(Cu, rmax * nu); TAKE(c, rmax);
  TAKE(Qa, nu * nu); TAKE(Ra, nu * nu); TAKE(beta, rmax * nu);
  TAKE(Hb, rmax * nx); TAKE(hb, rmax); TAKE(M, nx * nx);
  TAKE(Fx, nu * nx); TAKE(f0, nu); TAKE(V2, nu * nu); TAKE(Muu, nu * nu);
  TAKE(Mux, nu * nx); TAKE(mu, nu); TAKE(red, nu * nu);
  TAKE(T1, nx * nx); TAKE(T2, nx * nx); TAKE(v1, vlen); TAKE(v2, vlen);
  TAKE(nu_, rmax); TAKE(PA, nx * nx); TAKE(PB, nx * nx);
#undef TAKE
  ws->nH = iw ? it : 0; it += N;
  ws->oH = iw ? it : 0; it += N;
  ws->acc = iw ? it : 0; it += nu;
  ws->dep = iw ? it : 0; it += rmax;
  ws->rowbox = iw ? it : 0; it += rmax;
  ws->xrow = iw ? it : 0; it += nx;
  *ni = (int)(it - iw);
  return (int)(at - w);
}

int rqp_work_size(int N, int nx, int nu, int nb) {
  work ws;
  int ni;
  return layout(N, nx, nu, nb, 0, 0, &ws, &ni);
}

int rqp_iwork_size(int N, int nx, int nu, int nb) {
  work ws;
  int ni;
  layout(N, nx, nu, nb, 0, 0, &ws, &ni);
  return ni;
}

/* the boxes' values at (U, X) into V (N × nb) */
static void values(const rqp_problem *qp, const rqp_real *U,
                   const rqp_real *X, rqp_real *V) {
  int k, b;
  for (k = 0; k < qp->N; ++k)
    for (b = 0; b < qp->nb; ++b)
      V[k * qp->nb + b] = box_value(qp, b, U + k * NU_OF(qp), X + k * NX_OF(qp));
}

/* the warm boxes at their bound at the start, factored together; a
 * dependent warm set is left out whole (one recursion more: tried one
 * box at a time, a recursion each, it made the worst step) */
static void warm_start(const rqp_problem *qp, const rqp_real *U,
                       signed char *side, work *ws, long *stages) {
  const int N = qp->N, nb = qp->nb;
  int i;
  for (i = 0; i < N * nb; ++i) {
    const rqp_real bound = side[i] > 0 ? qp->hi[i] : qp->lo[i];
    if (side[i] != 1 && side[i] != -1) {
      side[i] = 0;
      continue;
    }
    if (RQP_FABS(ws->V[i] - bound) > RQP_AT_BOUND * (1 + RQP_FABS(bound)))
      side[i] = 0;
  }
  if (!factor(qp, side, U, N - 1, ws, stages)) return;
  for (i = 0; i < N * nb; ++i) side[i] = 0;
  factor(qp, side, U, N - 1, ws, stages);
}

int rqp_solve(const rqp_problem *qp, rqp_real *U, rqp_real *X,
              signed char *side, rqp_real *lam, int max_iter, rqp_real tol,
              rqp_real *w, int *iw, int *iterations, long *stages) {
  const int N = qp->N, nx = NX_OF(qp), nu = NU_OF(qp), nb = qp->nb;
  const int nv = N * nb;
  work ws;
  int it, i, ni, code, full = 0;
  *iterations = 0;
  *stages = 0;
  if (N < 1 || nx < 1 || nu < 1 || nb < 0 || max_iter < 0 ||
      qp->nx != nx || qp->nu != nu)
    return RQP_INVALID_INPUT;
  for (i = 0; i < nb; ++i)
    if (qp->box[i] < 0 || qp->box[i] >= nu + nx) return RQP_INVALID_INPUT;
  layout(N, nx, nu, nb, w, iw, &ws, &ni);
  for (i = 0; i < nv; ++i) lam[i] = 0;
  values(qp, U, X, ws.V);
  for (i = 0; i < nv; ++i) {
    const rqp_real v = ws.V[i], lo = qp->lo[i], hi = qp->hi[i];
    if (v != v || lo != lo || hi != hi) return RQP_INVALID_INPUT;
    if (v > hi + tol * (1 + RQP_FABS(hi)) || v < lo - tol * (1 + RQP_FABS(lo)))
      return RQP_INFEASIBLE_START;
  }
  warm_start(qp, U, side, &ws, stages);
  for (it = 1; it <= max_iter; ++it) {
    rqp_real dmax = 0, vmax = 0, alpha = 1;
    int block = -1, s = 0;
    forward(qp, &ws);
    for (i = 0; i < N * nu; ++i) ws.Us[i] -= U[i]; /* the step, for now */
    for (i = 0; i < N * nx; ++i) ws.Xs[i] -= X[i];
    values(qp, ws.Us, ws.Xs, ws.dV);
    for (i = 0; i < nv; ++i) {
      if (RQP_FABS(ws.dV[i]) > dmax) dmax = RQP_FABS(ws.dV[i]);
      if (RQP_FABS(ws.V[i]) > vmax) vmax = RQP_FABS(ws.V[i]);
    }
    if (dmax <= tol * (1 + vmax)) {
      /* the working set's optimum: its multipliers; drop the most
       * wrong-signed (negative at an upper bound, positive at a lower) */
      rqp_real worst = 0, lmax = 0;
      int q = -1;
      for (i = 0; i < N * nu; ++i) ws.Us[i] += U[i];
      for (i = 0; i < N * nx; ++i) ws.Xs[i] += X[i];
      multipliers(qp, side, lam, &ws);
      for (i = 0; i < nv; ++i)
        if (RQP_FABS(lam[i]) > lmax) lmax = RQP_FABS(lam[i]);
      for (i = 0; i < nv; ++i)
        if ((side[i] == 1 || side[i] == -1) && -lam[i] * side[i] > worst)
          worst = -lam[i] * side[i], q = i;
      if (q < 0 || worst <= tol * (1 + lmax)) {
        for (i = 0; i < N * nu; ++i) U[i] = ws.Us[i];
        for (i = 0; i < N * nx; ++i) X[i] = ws.Xs[i];
        for (i = 0; i < nv; ++i)
          if (side[i] == 2 || side[i] == -2) side[i] = 0;
        *iterations = it;
        return RQP_OPTIMAL;
      }
      side[q] = 0;
      for (i = 0; i < nv; ++i) /* a box left: the parked ones back */
        if (side[i] == 2 || side[i] == -2) side[i] = 0;
      if (factor(qp, side, U, q / nb, &ws, stages) == RQP_FULL) {
        full = 1;
        break;
      }
      for (i = 0; i < nv; ++i) lam[i] = 0;
      continue;
    }
    /* the ratio test over the boxes outside the working set */
    for (i = 0; i < nv; ++i) {
      rqp_real room;
      if (side[i] || RQP_FABS(ws.dV[i]) <= RQP_MOVE * dmax) continue;
      room = ((ws.dV[i] > 0 ? qp->hi[i] : qp->lo[i]) - ws.V[i]) / ws.dV[i];
      if (room < alpha) {
        alpha = room > 0 ? room : 0;
        block = i;
        s = ws.dV[i] > 0 ? 1 : -1;
      }
    }
    for (i = 0; i < N * nu; ++i) U[i] += alpha * ws.Us[i];
    for (i = 0; i < N * nx; ++i) X[i] += alpha * ws.Xs[i];
    for (i = 0; i < nv; ++i) ws.V[i] += alpha * ws.dV[i];
    if (block < 0) continue;
    side[block] = (signed char)s;
    code = factor(qp, side, U, block / nb, &ws, stages);
    if (code == RQP_FULL) { /* the pool: stop at this feasible point */
      side[block] = 0;
      full = 1;
      break;
    }
    if (code) {
      /* at its bound already, held there by the set: parked */
      side[block] = (signed char)(2 * s);
      factor(qp, side, U, block / nb, &ws, stages);
    }
  }
  for (i = 0; i < nv; ++i)
    if (side[i] == 2 || side[i] == -2) side[i] = 0;
  *iterations = full ? it : max_iter;
  return full ? RQP_ROWS_FULL : RQP_ITERATION_LIMIT;
}
