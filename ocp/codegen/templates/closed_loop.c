/* Closed loop: mpc step -> plant (the generated rk4) -> next state, with
 * the solution fed back as warm start; times every MPC step. The state,
 * plan and multipliers live in static arrays of ADCS_LOOP_N reals.
 * Its check (ocp.codegen.checks): the final error angle within tol_deg,
 * every applied step's scaled bound violation within tol_viol, nothing
 * NaN, every step returning 0; "LOOP" prints the figures, "FAIL" why the
 * check failed, and closed_loop then returns 1 (the driver exits 1). */
static casadi_real cl_x[ADCS_LOOP_N], cl_xn[ADCS_LOOP_N], cl_z[ADCS_LOOP_N],
    cl_lx[ADCS_LOOP_N], cl_lg[ADCS_LOOP_N], cl_u[ADCS_LOOP_N];

static int closed_loop(const char* name, eval_t f, work_t work,
                       checkout_t checkout, release_t release,
                       const casadi_real* x0, const casadi_real* qf,
                       int nx, int nz, int ng, int nu, int nplan,
                       double dt, int steps, double tol_deg,
                       double tol_viol) {
  casadi_real tau[3] = {0, 0, 0}, h = dt, cost, viol, viol1, defect;
  int k, i, mem, pmem, flag = 0, finite = 1, ok;
  double worst = 0.0, dot = 0.0, vn = 0.0, err, tmax = 0.0, twarm = 0.0;
  if (check_work(name, work, 8, 8, steps) || check_work("rk4", rk4_work,
      4, 1, steps) || nx > ADCS_LOOP_N || nz > ADCS_LOOP_N
      || ng > ADCS_LOOP_N || nu > ADCS_LOOP_N) return 1;
  mem = checkout();
  pmem = rk4_checkout();
  if (mem < 0 || pmem < 0) return 1;
  memset(cl_z, 0, sizeof cl_z);
  memset(cl_lx, 0, sizeof cl_lx);
  memset(cl_lg, 0, sizeof cl_lg);
  memset(cl_u, 0, sizeof cl_u);
  memcpy(cl_x, x0, sizeof(casadi_real) * nx);
  /* cold start: x0 at every stage of every plan of nplan reals (a robust
   * step's z holds one plan per scenario) */
  for (i = 0; i + nplan <= nz; i += nplan)
    for (k = 0; k + nx <= nplan; k += nx + nu)
      memcpy(cl_z + i + k, x0, sizeof(casadi_real) * nx);
  for (k = 0; k < ADCS_SZ_RES; ++k) drv_res[k] = 0;  /* outputs not asked */
  for (k = 0; k < ADCS_SZ_ARG; ++k) drv_arg[k] = 0;
  for (k = 0; k < steps; ++k) {
    double t0;
    drv_arg[0] = cl_x; drv_arg[1] = qf; drv_arg[2] = tau; drv_arg[3] = cl_z;
    drv_arg[4] = cl_lx; drv_arg[5] = cl_lg;
    drv_res[0] = cl_u; drv_res[1] = cl_z; drv_res[2] = cl_lx;
    drv_res[3] = cl_lg; drv_res[4] = &cost; drv_res[5] = &viol;
    drv_res[6] = &viol1; drv_res[7] = &defect;
    t0 = clock_now();
    flag |= f(drv_arg, drv_res, drv_iw, drv_w, mem);
    drv_t[k] = clock_now() - t0;
    if (!isfinite((double)viol1)) finite = 0;   /* NaN > worst is false */
    else if (viol1 > worst) worst = viol1;
    drv_arg[0] = cl_x; drv_arg[1] = cl_u; drv_arg[2] = tau; drv_arg[3] = &h;
    drv_res[0] = cl_xn;
    rk4(drv_arg, drv_res, drv_iw, drv_w, pmem);
    memcpy(cl_x, cl_xn, sizeof(casadi_real) * nx);
  }
  release(mem);
  rk4_release(pmem);
  /* the error quaternion qf* ⊗ x in double: 2 atan2(|v|, |w|) resolves
   * what 2 acos(x·qf) cannot (about 0.05° with float quaternions) */
  {
    const double w0 = qf[0], w1 = qf[1], w2 = qf[2], w3 = qf[3];
    const double x0 = cl_x[0], x1 = cl_x[1], x2 = cl_x[2], x3 = cl_x[3];
    const double v1 = w0 * x1 - x0 * w1 - (w2 * x3 - w3 * x2);
    const double v2 = w0 * x2 - x0 * w2 - (w3 * x1 - w1 * x3);
    const double v3 = w0 * x3 - x0 * w3 - (w1 * x2 - w2 * x1);
    dot = w0 * x0 + w1 * x1 + w2 * x2 + w3 * x3;
    vn = sqrt(v1 * v1 + v2 * v2 + v3 * v3);
  }
  for (i = 0; i < nx; ++i) if (!isfinite((double)cl_x[i])) finite = 0;
  err = 2.0 * atan2(vn, fabs(dot)) * 57.295779513082323;
  ok = finite && err <= tol_deg && worst <= tol_viol && flag == 0;
  for (k = 0; k < steps; ++k) if (drv_t[k] > tmax) tmax = drv_t[k];
  /* the first step starts cold (x0 everywhere, no multipliers) */
  for (k = 1; k < steps; ++k) if (drv_t[k] > twarm) twarm = drv_t[k];
  printf("STEPS closed_loop:%s:", name);
  for (k = 0; k < steps; ++k) printf(" %.3f", drv_t[k]);
  printf("\n");
  sort_doubles(drv_t, steps);
  printf("TIME closed_loop:%s median_" TIME_UNIT "=%.3f max_" TIME_UNIT
         "=%.3f calls=%d flag=%d final_error_deg=%.3e max_warm_" TIME_UNIT
         "=%.3f\n", name, drv_t[steps / 2], tmax, steps, flag, err, twarm);
  printf("STATE closed_loop:%s:", name);
  for (i = 0; i < nx; ++i) printf(" %.17g", (double)cl_x[i]);
  printf("\n");
  printf("  closed_loop:%s worst applied-step violation %.3e\n", name,
         (double)worst);
  printf("LOOP closed_loop:%s steps=%d dt=%.17g seconds=%.17g "
         "final_error_deg=%.17g tolerance_deg=%.17g worst_violation=%.17g "
         "violation_tolerance=%.17g finite=%d flag=%d ok=%d\n", name,
         steps, dt, steps * dt, err, tol_deg, worst, tol_viol, finite, flag,
         ok);
  if (!finite)
    printf("FAIL closed_loop:%s goes NaN\n", name);
  if (finite && !(err <= tol_deg))
    printf("FAIL closed_loop:%s ends %.3g deg from the target after %d "
           "steps x %g s = %g s (tolerance %.3g deg)\n", name, err, steps,
           dt, steps * dt, tol_deg);
  if (finite && !(worst <= tol_viol))
    printf("FAIL closed_loop:%s breaks a bound (worst applied-step "
           "violation %.3g > %.3g)\n", name, (double)worst, tol_viol);
  if (flag) printf("FAIL closed_loop:%s has a step returning %d\n", name,
                   flag);
  return !ok;
}

