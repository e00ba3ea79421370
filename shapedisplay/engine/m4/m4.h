/* m4.h -- the bare-metal services of the Cortex-M4F harness (startup.c). */
#ifndef SD_M4_H
#define SD_M4_H
#include <stdint.h>
int32_t m4_open(const char *path, int write);
int32_t m4_read(int32_t fd, void *buf, uint32_t n);
int32_t m4_write(int32_t fd, const void *buf, uint32_t n);
void m4_close(int32_t fd);
int32_t m4_cmdline(char *buf, uint32_t n);
void m4_exit(int code) __attribute__((noreturn));
void m4_count_start(void);
uint32_t m4_count_read(void);
#endif
