/* Startup code of the bare-metal Cortex-M driver (written by
 * ocp.codegen.target; linker script cortex_m.ld). The vector table holds
 * the initial stack pointer, the reset handler and the SysTick handler
 * (the driver counts SysTick wraps); the reset handler enables the FPU
 * (CPACR, full access to CP10 and CP11) before any floating-point
 * instruction, copies .data from flash, clears .bss, runs the C library's
 * constructors, calls main and exits with its status (through
 * semihosting, which ends qemu). C99, clean under -Wall -Wextra. */
#include <stdint.h>
#include <stdlib.h>

extern uint32_t __stack_top, __data_load, __data_start, __data_end,
    __bss_start__, __bss_end__;
extern int main(void);
extern void __libc_init_array(void);
void Reset_Handler(void);
void SysTick_Handler(void);

static void Default_Handler(void) {
  for (;;) {
  }
}

/* weak: a driver without SysTick counting needs no handler */
__attribute__((weak)) void SysTick_Handler(void) {}

typedef void (*vector_t)(void);

__attribute__((section(".isr_vector"), used))
const vector_t vector_table[16] = {
    (vector_t)(uintptr_t)&__stack_top, /* initial stack pointer */
    Reset_Handler,                     /* reset */
    Default_Handler,                   /* NMI */
    Default_Handler,                   /* hard fault */
    Default_Handler,                   /* memory management fault */
    Default_Handler,                   /* bus fault */
    Default_Handler,                   /* usage fault */
    0, 0, 0, 0,                        /* reserved */
    Default_Handler,                   /* SVCall */
    Default_Handler,                   /* debug monitor */
    0,                                 /* reserved */
    Default_Handler,                   /* PendSV */
    SysTick_Handler,                   /* SysTick */
};

/* crti/crtn are not linked (-nostartfiles): the C library's
 * constructor and destructor hooks are empty */
void _init(void);
void _fini(void);
void _init(void) {}
void _fini(void) {}

/* no floating-point instruction may run before the FPU is on: keep this
 * function free of floating point (it is compiled like the rest) */
void Reset_Handler(void) {
  volatile uint32_t* cpacr = (volatile uint32_t*)0xE000ED88u;
  uint32_t *src, *dst;
  *cpacr |= 0xFu << 20; /* CP10, CP11: full access */
  __asm__ volatile("dsb\n\tisb" ::: "memory");
  src = &__data_load;
  for (dst = &__data_start; dst < &__data_end;) *dst++ = *src++;
  for (dst = &__bss_start__; dst < &__bss_end__;) *dst++ = 0u;
  __libc_init_array();
  exit(main());
}
