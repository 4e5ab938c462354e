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
 * run time, driver_body.c), and stdout writes through a static buffer. */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include "adcs_codegen.h"

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

static char drv_stdout[1 << 14];
static void driver_init(void) {
  setvbuf(stdout, drv_stdout, _IOFBF, sizeof drv_stdout);
}

