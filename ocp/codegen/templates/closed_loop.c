
/* Closed loop: mpc step -> plant (the generated rk4) -> next state, with
 * the solution fed back as warm start; times every MPC step. */
static void closed_loop(const char* name, eval_t f, work_t work,
                        checkout_t checkout, release_t release,
                        const casadi_real* x0, const casadi_real* qf,
                        int nx, int nz, int ng, int nu, double dt,
                        int steps) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w, p_arg, p_res, p_iw, p_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  rk4_work(&p_arg, &p_res, &p_iw, &p_w);
  if (p_arg > sz_arg) sz_arg = p_arg;
  if (p_res > sz_res) sz_res = p_res;
  if (p_iw > sz_iw) sz_iw = p_iw;
  if (p_w > sz_w) sz_w = p_w;
  const casadi_real** a = malloc(sizeof(casadi_real*) * (sz_arg + 8));
  casadi_real** r = malloc(sizeof(casadi_real*) * (sz_res + 8));
  casadi_int* iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
  casadi_real* w = malloc(sizeof(casadi_real) * (sz_w + 1));
  casadi_real *x = calloc(nx, sizeof(casadi_real)),
              *xn = calloc(nx, sizeof(casadi_real)),
              *z = calloc(nz, sizeof(casadi_real)),
              *lx = calloc(nz, sizeof(casadi_real)),
              *lg = calloc(ng, sizeof(casadi_real)),
              *u = calloc(nu, sizeof(casadi_real));
  casadi_real tau[3] = {0, 0, 0}, h = (casadi_real)dt, cost, viol, viol1, defect;
  double* t = malloc(sizeof(double) * steps);
  int k, i, mem = checkout(), pmem = rk4_checkout();
  memcpy(x, x0, sizeof(casadi_real) * nx);
  for (k = 0; k + nx <= nz; k += nx + nu)  /* cold start: x0 everywhere */
    memcpy(z + k, x0, sizeof(casadi_real) * nx);
  double worst = 0.0;
  for (k = 0; k < sz_res + 8; ++k) r[k] = 0;  /* outputs not asked for */
  for (k = 0; k < steps; ++k) {
    a[0] = x; a[1] = qf; a[2] = tau; a[3] = z; a[4] = lx; a[5] = lg;
    r[0] = u; r[1] = z; r[2] = lx; r[3] = lg; r[4] = &cost; r[5] = &viol;
    r[6] = &viol1; r[7] = &defect;
    double t0 = now_us();
    f(a, r, iw, w, mem);
    t[k] = now_us() - t0;
    if ((double)viol1 > worst) worst = (double)viol1;
    a[0] = x; a[1] = u; a[2] = tau; a[3] = &h;
    r[0] = xn;
    rk4(a, r, iw, w, pmem);
    memcpy(x, xn, sizeof(casadi_real) * nx);
  }
  release(mem);
  rk4_release(pmem);
  double dot = 0.0, nq = 0.0;
  for (i = 0; i < 4; ++i) {
    dot += (double)x[i] * (double)qf[i];
    nq += (double)x[i] * (double)x[i];
  }
  dot = fabs(dot) / sqrt(nq);
  if (dot > 1.0) dot = 1.0;
  double err = 2.0 * acos(dot) * 57.295779513082323;
  double tmax = 0.0, twarm = 0.0;
  for (k = 0; k < steps; ++k) if (t[k] > tmax) tmax = t[k];
  /* the first step starts cold (x0 everywhere, no multipliers) */
  for (k = 1; k < steps; ++k) if (t[k] > twarm) twarm = t[k];
  qsort(t, steps, sizeof(double), cmp_double);
  printf("TIME closed_loop:%s median_us=%.3f max_us=%.3f calls=%d "
         "final_error_deg=%.3e max_warm_us=%.3f\n", name, t[steps / 2],
         tmax, steps, err, twarm);
  printf("  closed_loop:%s worst applied-step violation %.3e\n", name,
         worst);
  free(a); free(r); free(iw); free(w); free(t);
  free(x); free(xn); free(z); free(lx); free(lg); free(u);
}

