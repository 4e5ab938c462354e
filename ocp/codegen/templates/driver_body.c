/* Shared body of the host and target drivers: time_call times REPEATS
 * calls of a function with clock_now (the head's clock, in TIME_UNIT) and
 * prints "TIME <name> first_<unit>=... median_<unit>=... max_<unit>=...
 * calls=... flag=... total_<unit>=...", then every output of the last
 * call ("OUT <name> <j>: ..." with %.17g), the work sizes ("WORK <name>
 * sz_arg sz_res sz_iw sz_w bytes_iw bytes_w") and, where the head paints
 * the stack, the deepest stack the calls used ("STACK <name> <bytes>").
 * No heap: the work arrays are static, sized at generation time. */

/* @SIZES@ */

static const casadi_real* drv_arg[ADCS_SZ_ARG];
static casadi_real* drv_res[ADCS_SZ_RES];
static casadi_int drv_iw[ADCS_SZ_IW];
static casadi_real drv_w[ADCS_SZ_W];
static double drv_t[ADCS_MAX_CALLS];

/* insertion sort (the C library's qsort may allocate) */
static void sort_doubles(double* t, int n) {
  int i, j;
  for (i = 1; i < n; ++i) {
    double v = t[i];
    for (j = i; j > 0 && t[j - 1] > v; --j) t[j] = t[j - 1];
    t[j] = v;
  }
}

/* 0 when the static arrays hold what work() asks for */
static int check_work(const char* name, work_t work, int n_in, int n_out,
                      int reps) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  if (sz_arg < n_in) sz_arg = n_in;
  if (sz_res < n_out) sz_res = n_out;
  if (sz_arg > ADCS_SZ_ARG || sz_res > ADCS_SZ_RES || sz_iw > ADCS_SZ_IW
      || sz_w > ADCS_SZ_W || reps > ADCS_MAX_CALLS) {
    printf("ERROR %s: work sizes beyond the driver's static arrays\n",
           name);
    return 1;
  }
  return 0;
}

static int time_call(const char* name, eval_t f, work_t work,
                     checkout_t checkout, release_t release,
                     const casadi_real** arg, int n_in, casadi_real** res,
                     int n_out, const int* nnz_out, int reps, int n_show) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  int i, j, mem, flag = 0;
  double first, total = 0.0;
  long stack;
  if (check_work(name, work, n_in, n_out, reps)) return 1;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  mem = checkout();
  if (mem < 0) return 1;
  for (i = 0; i < ADCS_SZ_ARG; ++i) drv_arg[i] = i < n_in ? arg[i] : 0;
  for (i = 0; i < ADCS_SZ_RES; ++i) drv_res[i] = i < n_out ? res[i] : 0;
  stack_paint();
  for (i = 0; i < reps; ++i) {
    double t0 = clock_now();
    flag |= f(drv_arg, drv_res, drv_iw, drv_w, mem);
    drv_t[i] = clock_now() - t0;
  }
  stack = stack_used();
  release(mem);
  for (i = 0; i < reps; ++i) total += drv_t[i];
  first = drv_t[0];
  sort_doubles(drv_t, reps);
  printf("TIME %s first_" TIME_UNIT "=%.3f median_" TIME_UNIT "=%.3f max_"
         TIME_UNIT "=%.3f calls=%d flag=%d total_" TIME_UNIT "=%.3f\n",
         name, first, drv_t[reps / 2], drv_t[reps - 1], reps, flag, total);
  printf("  %s first output:", name);
  for (i = 0; i < n_show && i < 4; ++i) printf(" %.10g", (double)res[0][i]);
  printf("\n");
  for (j = 0; j < n_out; ++j) {
    printf("OUT %s %d:", name, j);
    for (i = 0; i < nnz_out[j]; ++i) printf(" %.17g", (double)res[j][i]);
    printf("\n");
  }
  printf("WORK %s %ld %ld %ld %ld %d %d\n", name, (long)sz_arg,
         (long)sz_res, (long)sz_iw, (long)sz_w, (int)sizeof(casadi_int),
         (int)sizeof(casadi_real));
  if (stack >= 0) printf("STACK %s %ld\n", name, stack);
  return 0;
}
