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

/* the clock of time_call and closed_loop (driver_body.c) and its unit */
#define TIME_UNIT "us"
static double clock_now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return 1e6 * (double)t.tv_sec + 1e-3 * (double)t.tv_nsec;
}

/* no stack painting on the host */
static void stack_paint(void) {}
static long stack_used(void) { return -1; }

static void driver_init(void) { realtime_heap(); }

