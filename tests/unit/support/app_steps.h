/*
 * app_steps: the steps the lib/app tests share, on one bench (g_b) with one
 * line buffer (g_line: the last line a step waited for).
 */
#ifndef HALLHOME_APP_STEPS_H
#define HALLHOME_APP_STEPS_H

#include <stdint.h>

#include "app_bench.h"

#define APP_STEPS_LINE 512

extern app_bench_t g_b;
extern char g_line[APP_STEPS_LINE];

/* Initialises the bench and waits for <boot> and <ready>. */
void boot(app_bench_t *b, uint8_t with_table);
/* Waits up to ms for the final reply of a command line: it must be expect. */
void reply(app_bench_t *b, const char *expect, uint32_t ms);
/* Sends a command line and checks its final reply. */
void cmd(app_bench_t *b, const char *line, const char *expect);
/* Holds the button ms, lets it go, runs 50 ms. */
void press(app_bench_t *b, uint32_t ms);

#endif /* HALLHOME_APP_STEPS_H */
