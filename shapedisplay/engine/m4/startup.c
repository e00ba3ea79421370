/* startup.c -- bare-metal start and I/O of the Cortex-M4F harness under QEMU (mps2-an386).
 *
 * Vector table, reset (FPU on, .bss zeroed), Arm semihosting for file I/O and exit, and the
 * SysTick counter that counts executed instructions when QEMU runs with `-icount shift=S`
 * (each instruction then advances virtual time by 2^S ns and SysTick, clocked by the 25 MHz
 * system clock, by 2^S * 25 / 1000 counts; tests/runtime_vectors.py uses S = 6). No libc
 * start-up files are linked. */
#include <stdint.h>
#include <string.h>
#include "m4.h"

extern uint32_t __bss_start__, __bss_end__, __stack_top;
int main(void);

static void fault(void)
{
    m4_exit(3);
}

void Reset_Handler(void)
{
    uint32_t *p;
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;      /* CPACR: CP10, CP11 full access (FPU) */
    __asm volatile("dsb\n isb");
    for (p = &__bss_start__; p < &__bss_end__; p++) *p = 0;
    m4_exit(main());
}

__attribute__((section(".vectors"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))(uintptr_t)&__stack_top, Reset_Handler, fault, fault, fault, fault, fault, 0, 0, 0, 0,
    fault, fault, 0, fault, fault,
};

/* ------------------------------------------------------------------ semihosting */
static int32_t semi(int32_t op, const void *arg)
{
    register int32_t r0 __asm("r0") = op;
    register const void *r1 __asm("r1") = arg;
    __asm volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

int32_t m4_open(const char *path, int write)
{
    uint32_t a[3];
    a[0] = (uint32_t)(uintptr_t)path;
    a[1] = write ? 6u : 1u;        /* "wb" : "rb" */
    a[2] = (uint32_t)strlen(path);
    return semi(0x01, a);
}

int32_t m4_read(int32_t fd, void *buf, uint32_t n)
{
    uint32_t a[3];
    a[0] = (uint32_t)fd;
    a[1] = (uint32_t)(uintptr_t)buf;
    a[2] = n;
    return (int32_t)n - semi(0x06, a);     /* bytes read */
}

int32_t m4_write(int32_t fd, const void *buf, uint32_t n)
{
    uint32_t a[3];
    a[0] = (uint32_t)fd;
    a[1] = (uint32_t)(uintptr_t)buf;
    a[2] = n;
    return semi(0x05, a);                  /* bytes not written */
}

void m4_close(int32_t fd)
{
    uint32_t a = (uint32_t)fd;
    semi(0x02, &a);
}

int32_t m4_cmdline(char *buf, uint32_t n)
{
    uint32_t a[2];
    a[0] = (uint32_t)(uintptr_t)buf;
    a[1] = n;
    return semi(0x15, a);
}

void m4_exit(int code)
{
    uint32_t a[2];
    a[0] = 0x20026u;                       /* ADP_Stopped_ApplicationExit */
    a[1] = (uint32_t)code;
    for (;;) semi(0x20, a);               /* SYS_EXIT_EXTENDED: reason and exit code */
}

/* ------------------------------------------------------------------ SysTick */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)

void m4_count_start(void)
{
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0;                          /* any write reloads */
    SYST_CSR = 5u;                         /* enable, processor clock, no interrupt */
}

uint32_t m4_count_read(void)
{
    return 0xFFFFFFu - SYST_CVR;
}
