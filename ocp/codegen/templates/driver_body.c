/* Shared body of the host and target drivers: time_call times REPEATS
 * calls of a function with clock_now (the head's clock, in TIME_UNIT) and
 * prints "TIME <name> first_<unit>=... median_<unit>=... max_<unit>=...
 * calls=... flag=... total_<unit>=...", then every output of the last
 * call ("OUT <name> <j>: ..." with %.17g), the work sizes ("WORK <name>
 * sz_arg sz_res sz_iw sz_w bytes_iw bytes_w") and, where the head paints
 * the stack, the deepest stack the calls used ("STACK <name> <bytes>"). */
static int cmp_double(const void* a, const void* b) {
  double x = *(const double*)a, y = *(const double*)b;
  return (x > y) - (x < y);
}

static void time_call(const char* name, eval_t f, work_t work,
                      checkout_t checkout, release_t release,
                      const casadi_real** arg, int n_in, casadi_real** res,
                      int n_out, const int* nnz_out, int reps,
                      int n_show) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const casadi_real** a = malloc(sizeof(casadi_real*) * (sz_arg + n_in));
  casadi_real** r = malloc(sizeof(casadi_real*) * (sz_res + n_out));
  casadi_int* iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
  casadi_real* w = malloc(sizeof(casadi_real) * (sz_w + 1));
  double* t = malloc(sizeof(double) * reps);
  int i, mem = checkout(), flag = 0;
  double first, total = 0.0;
  long stack;
  int j;
  for (i = 0; i < n_in; ++i) a[i] = arg[i];
  for (i = 0; i < n_out; ++i) r[i] = res[i];
  stack_paint();
  for (i = 0; i < reps; ++i) {
    double t0 = clock_now();
    flag |= f(a, r, iw, w, mem);
    t[i] = clock_now() - t0;
  }
  stack = stack_used();
  release(mem);
  for (i = 0; i < reps; ++i) total += t[i];
  first = t[0];
  qsort(t, reps, sizeof(double), cmp_double);
  printf("TIME %s first_" TIME_UNIT "=%.3f median_" TIME_UNIT "=%.3f max_"
         TIME_UNIT "=%.3f calls=%d flag=%d total_" TIME_UNIT "=%.3f\n",
         name, first, t[reps / 2], t[reps - 1], reps, flag, total);
  printf("  %s first output:", name);
  for (i = 0; i < n_show && i < 4; ++i) printf(" %.10g", res[0][i]);
  printf("\n");
  for (j = 0; j < n_out; ++j) {
    printf("OUT %s %d:", name, j);
    for (i = 0; i < nnz_out[j]; ++i) printf(" %.17g", res[j][i]);
    printf("\n");
  }
  printf("WORK %s %ld %ld %ld %ld %d %d\n", name, (long)sz_arg,
         (long)sz_res, (long)sz_iw, (long)sz_w, (int)sizeof(casadi_int),
         (int)sizeof(casadi_real));
  if (stack >= 0) printf("STACK %s %ld\n", name, stack);
  free(a); free(r); free(iw); free(w); free(t);
}
