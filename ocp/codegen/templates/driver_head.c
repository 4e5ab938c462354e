/* Test driver of the generated ADCS functions (written by
 * ocp.codegen.export_c). Calls each function on sample inputs, prints the
 * outputs and times REPEATS calls with clock_gettime (CLOCK_MONOTONIC).
 * Output lines "TIME <name> first_us=... median_us=... max_us=...
 * calls=... flag=..." are parsed by ocp.codegen.export.run_driver: the
 * first (cold) call, the median and worst of all calls, and the OR of
 * every call's return flag (0: every call succeeded). */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "adcs_codegen.h"
#if defined(__GLIBC__)
#include <malloc.h>
#endif

/* CasADi's DAQP runtime allocates its workspace on every solve and frees
 * it after. As real-time Linux programs do, keep freed memory in the heap
 * (no trimming, no mmap) so that those calls do not fault pages in. */
static void realtime_heap(void) {
#if defined(__GLIBC__)
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
  mallopt(M_TOP_PAD, 16 << 20);
  mallopt(M_MMAP_MAX, 0);
#endif
}

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

static int cmp_double(const void* a, const void* b) {
  double x = *(const double*)a, y = *(const double*)b;
  return (x > y) - (x < y);
}

static void time_call(const char* name, eval_t f, work_t work,
                      checkout_t checkout, release_t release,
                      const casadi_real** arg, int n_in, casadi_real** res,
                      int n_out, int reps,
                      int n_show) {
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  work(&sz_arg, &sz_res, &sz_iw, &sz_w);
  const casadi_real** a = malloc(sizeof(casadi_real*) * (sz_arg + n_in));
  casadi_real** r = malloc(sizeof(casadi_real*) * (sz_res + n_out));
  casadi_int* iw = malloc(sizeof(casadi_int) * (sz_iw + 1));
  casadi_real* w = malloc(sizeof(casadi_real) * (sz_w + 1));
  double* t = malloc(sizeof(double) * reps);
  int i, mem = checkout(), flag = 0;
  double first;
  for (i = 0; i < n_in; ++i) a[i] = arg[i];
  for (i = 0; i < n_out; ++i) r[i] = res[i];
  for (i = 0; i < reps; ++i) {
    double t0 = now_us();
    flag |= f(a, r, iw, w, mem);
    t[i] = now_us() - t0;
  }
  release(mem);
  first = t[0];
  qsort(t, reps, sizeof(double), cmp_double);
  printf("TIME %s first_us=%.3f median_us=%.3f max_us=%.3f calls=%d "
         "flag=%d\n", name, first, t[reps / 2], t[reps - 1], reps, flag);
  printf("  %s first output:", name);
  for (i = 0; i < n_show && i < 4; ++i) printf(" %.10g", (double)res[0][i]);
  printf("\n");
  free(a); free(r); free(iw); free(w); free(t);
}
