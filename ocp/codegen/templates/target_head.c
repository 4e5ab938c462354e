/* Bare-metal test driver of the generated ADCS functions on a Cortex-M
 * (written by ocp.codegen.target; startup_cortex_m.c, cortex_m.ld). Runs
 * on qemu-system-arm's MPS2 boards with semihosting (printf reaches the
 * host's stdout, exit ends qemu). Times every function with SysTick: run
 * under `-icount shift=0` qemu advances its clock one nanosecond per
 * instruction and SysTick counts one tick per 40 instructions, so the
 * figures are instruction counts (not cycles: no pipeline, cache or
 * memory wait states are modelled). The driver prints ticks
 * (TIME_UNIT); ocp.codegen.target converts them to instructions after
 * checking the rate on a known loop ("CAL" line). The stack is painted
 * before each function's calls and scanned after them ("STACK" line). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "adcs_codegen.h"

extern void initialise_monitor_handles(void);

typedef int (*eval_t)(const casadi_real**, casadi_real**, casadi_int*,
                      casadi_real*, int);
typedef int (*work_t)(casadi_int*, casadi_int*, casadi_int*, casadi_int*);
typedef int (*checkout_t)(void);
typedef void (*release_t)(int);

#define SYST_CSR (*(volatile uint32_t*)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t*)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t*)0xE000E018u)
#define SYST_PERIOD 0x1000000u /* 24-bit counter: RVR + 1 ticks a wrap */

static volatile uint32_t systick_wraps;

/* SysTick interrupt: one more wrap of the 24-bit down-counter */
void SysTick_Handler(void);
void SysTick_Handler(void) { ++systick_wraps; }

/* ticks since systick_start: wraps and counter read until consistent */
static uint64_t ticks_now(void) {
  uint32_t w, v;
  do {
    w = systick_wraps;
    v = SYST_CVR;
  } while (w != systick_wraps);
  return (uint64_t)w * SYST_PERIOD + (uint64_t)(SYST_PERIOD - 1u - v);
}

/* the clock of time_call and closed_loop (driver_body.c) and its unit */
#define TIME_UNIT "ticks"
static double clock_now(void) { return (double)ticks_now(); }

static void systick_start(void) {
  volatile int i;
  SYST_CSR = 0u;
  SYST_RVR = SYST_PERIOD - 1u;
  SYST_CVR = 0u; /* reloads on the next tick */
  SYST_CSR = 7u; /* enable, interrupt, processor clock */
  for (i = 0; i < 200; ++i) {
  } /* wait for the reload before the first reading */
  systick_wraps = 0u;
}

/* a known loop, six instructions an iteration: "CAL ticks=...
 * instructions=..." lets the host check the ticks-to-instructions rate */
static void calibrate(void) {
  uint32_t n = 4000u;
  uint64_t t0 = ticks_now(), t1;
  __asm__ volatile(
      "1:\n\t"
      "add r1, r1, #1\n\t"
      "add r2, r2, #1\n\t"
      "add r3, r3, #1\n\t"
      "nop\n\t"
      "subs %0, %0, #1\n\t"
      "bne 1b\n\t"
      : "+r"(n)
      :
      : "r1", "r2", "r3", "cc");
  t1 = ticks_now();
  printf("CAL ticks=%lu instructions=%lu\n", (unsigned long)(t1 - t0),
         6ul * 4000ul);
}

/* stack painting: the 256 KB below time_call's stack pointer are filled
 * with a pattern before a function's calls; afterwards the lowest word
 * that changed gives the deepest stack the calls used (SysTick's rare
 * exception frame included) */
#define STACK_PAINT_WORDS (64u * 1024u)
#define STACK_PATTERN 0xA5A5A5A5u
static uint32_t* stack_ref;

__attribute__((always_inline)) static inline void stack_paint(void) {
  uint32_t* p;
  uint32_t i;
  __asm__ volatile("mov %0, sp" : "=r"(p));
  stack_ref = p;
  for (i = 1u; i <= STACK_PAINT_WORDS; ++i) {
    volatile uint32_t* q = p - i;
    *q = STACK_PATTERN;
  }
}

static long stack_used(void) {
  const volatile uint32_t* p = stack_ref - STACK_PAINT_WORDS;
  while (p < stack_ref && *p == STACK_PATTERN) ++p;
  return (long)((const char*)stack_ref - (const char*)p);
}

static void driver_init(void) {
  initialise_monitor_handles();
  systick_start();
  calibrate();
}
