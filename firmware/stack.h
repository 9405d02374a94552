/*
 * stack: the stack's high-water mark. At boot every byte between the end of
 * the static data (.data, .bss, .noinit) and the stack pointer is painted
 * with a known value; whatever the stack has ever overwritten since is gone,
 * so the painted bytes still intact are the least free RAM there has been.
 */
#ifndef HALLHOME_STACK_H
#define HALLHOME_STACK_H

#include <stdint.h>

#define STACK_PAINT 0xC5u /* unlikely as a run of stack contents */

/* Bytes between the static data and the deepest the stack has reached since
 * boot (the painted bytes still intact above the static data). Scans from the
 * static data upwards, about 2 us per free byte: for the status report, not
 * for the main loop's every pass. */
uint16_t stack_free_min(void);

#endif /* HALLHOME_STACK_H */
