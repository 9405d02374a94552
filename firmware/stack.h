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

/* Bytes between the static data and the deepest the stack has reached, as
 * the last complete sweep found it (the painted bytes still intact above the
 * static data); before the first sweep ends, a whole scan. */
uint16_t stack_free_min(void);

/* One step of the sweep that stack_free_min() reports: up to
 * STACK_SWEEP_BYTES painted bytes, from the static data upwards, about 25 us
 * (the main loop's every pass). Scanned at once, the 3 KB took 2.3 ms of the
 * pass that wrote a `status`. */
#define STACK_SWEEP_BYTES 64u
void stack_sweep(void);

#endif /* HALLHOME_STACK_H */
