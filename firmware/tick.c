#include "tick.h"

#include "board_io.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

/* 16 MHz / 64 = 250 kHz; 250 counts = 1 ms. */
#define TICK_PRESCALE  64u
#define TICK_TOP       249u
#define TICK_US_PER_CT 4u

static volatile uint32_t tick_count_ms;

ISR(TIMER0_COMPA_vect)
{
    tick_count_ms++;
    if (((uint8_t)tick_count_ms & 3u) == 0u) {
        board_io_sample();
    }
}

void tick_init(void)
{
    TCCR0A = _BV(WGM01); /* CTC, TOP = OCR0A */
    TCCR0B = _BV(CS01) | _BV(CS00);
    OCR0A = TICK_TOP;
    TCNT0 = 0;
    TIMSK0 = _BV(OCIE0A);
}

uint32_t tick_ms(void)
{
    uint32_t ms;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        ms = tick_count_ms;
    }
    return ms;
}

/* The compare flag may be pending with interrupts off: then the counter has
 * already wrapped and the millisecond count is one behind. */
uint32_t tick_us(void)
{
    uint32_t ms;
    uint8_t ct;
    uint8_t pending;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        ms = tick_count_ms;
        ct = TCNT0;
        pending = (uint8_t)(TIFR0 & _BV(OCF0A));
        if (pending) {
            ct = TCNT0;
        }
    }
    if (pending) {
        ms++;
    }
    return ms * 1000u + (uint32_t)ct * TICK_US_PER_CT;
}
