/*
 * tick: the firmware's monotonic clock. Timer0 in CTC mode interrupts every
 * 1 ms; microseconds are the millisecond count plus the timer's count
 * (4 us resolution).
 */
#ifndef HALLHOME_TICK_H
#define HALLHOME_TICK_H

#include <stdint.h>

/* Starts Timer0 (1 ms compare interrupt). Interrupts must be enabled by the caller. */
void tick_init(void);

/* Milliseconds since tick_init(); wraps after 49 days. */
uint32_t tick_ms(void);

/* Microseconds since tick_init() (4 us resolution); wraps after 71 minutes. */
uint32_t tick_us(void);

#endif /* HALLHOME_TICK_H */
