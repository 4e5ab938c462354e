/* Test driver of the generated ADCS functions (written by
 * ocp.codegen.export_c). Calls each function on sample inputs, prints the
 * outputs and times REPEATS calls with clock_gettime (CLOCK_MONOTONIC).
 * Output lines "TIME <name> first_us=... median_us=... max_us=...
 * calls=... flag=..." are parsed by ocp.codegen.export.run_driver: the
 * first (cold) call, the median and worst of all calls, and the OR of
 * every call's return flag (0: every call succeeded).
 *
 * No heap, as in a flight build: the functions' arg/res/iw/w arrays are
 * static, sized at generation time from their *_work sizes (checked at
 * run time), and stdout writes through a static buffer. */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include "adcs_codegen.h"

/* @SIZES@ */

static const casadi_real* drv_arg[ADCS_SZ_ARG];
static casadi_real* drv_res[ADCS_SZ_RES];
static casadi_int drv_iw[ADCS_SZ_IW];
static casadi_real drv_w[ADCS_SZ_W];
static double drv_t[ADCS_MAX_CALLS];
static char drv_stdout[1 << 14];

typedef int (*eval_t)(const casadi_real**, casadi_real**, casadi_int*,
                      casadi_real*, int);
typedef int (*work_t)(casadi_int*, casadi_int*, casadi_int*, casadi_int*);
typedef int (*checkout_t)(void);
typedef void (*release_t)(int);

static double now_us(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return 1e6 * (double)t.tv_sec + 1e-3 * (double)t.tv_nsec;
}

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
                     int n_out, int reps, int n_show) {
  int i, mem, flag = 0;
  double first;
  if (check_work(name, work, n_in, n_out, reps)) return 1;
  mem = checkout();
  if (mem < 0) return 1;
  for (i = 0; i < ADCS_SZ_ARG; ++i) drv_arg[i] = i < n_in ? arg[i] : 0;
  for (i = 0; i < ADCS_SZ_RES; ++i) drv_res[i] = i < n_out ? res[i] : 0;
  for (i = 0; i < reps; ++i) {
    double t0 = now_us();
    flag |= f(drv_arg, drv_res, drv_iw, drv_w, mem);
    drv_t[i] = now_us() - t0;
  }
  release(mem);
  first = drv_t[0];
  sort_doubles(drv_t, reps);
  printf("TIME %s first_us=%.3f median_us=%.3f max_us=%.3f calls=%d "
         "flag=%d\n", name, first, drv_t[reps / 2], drv_t[reps - 1], reps,
         flag);
  printf("  %s first output:", name);
  for (i = 0; i < n_show && i < 4; ++i) printf(" %.10g", res[0][i]);
  printf("\n");
  return 0;
}

