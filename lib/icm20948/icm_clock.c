/*
 * icm_clock: when each AK09916 sample was measured (see icm_clock.h).
 */
#include "icm20948/icm_clock.h"

#include <stddef.h>

/* A gap this long between two samples (a sensor not read for a second)
 * starts the estimate afresh: the phase may have drifted by more than a
 * period. */
#define ICM_CLOCK_GAP_US 1000000L

/* The AK09916's period is taken within 5 % of its nominal value. */
#define ICM_CLOCK_PERIOD_MIN (ICM_CLOCK_PERIOD_US - ICM_CLOCK_PERIOD_US / 20u)
#define ICM_CLOCK_PERIOD_MAX (ICM_CLOCK_PERIOD_US + ICM_CLOCK_PERIOD_US / 20u)

#define HAVE_LINE   1u
#define HAVE_PERIOD 2u

void icm_clock_reset(icm_clock_t *c)
{
    c->have = 0;
}

uint32_t icm_clock_seen(icm_clock_t *c, uint32_t seen_us)
{
    uint32_t at = c->at_us + c->period_us;
    int32_t lag = (int32_t)(seen_us - at);
    if (!(c->have & HAVE_LINE) || lag >= ICM_CLOCK_GAP_US || lag <= -ICM_CLOCK_GAP_US) {
        c->have = HAVE_LINE;
        c->period_us = ICM_CLOCK_PERIOD_US;
        c->k = ICM_CLOCK_WINDOW; /* the next sample starts a window */
        c->low_us = 0;
        c->lowered_us = 0;
        at = seen_us; /* an upper bound: the next reads lower it */
        lag = 0;
    }
    if (c->k >= ICM_CLOCK_WINDOW) {
        c->k = 0;
        c->low_us = 0xFFFFu;
        c->lowered_us = 0;
    }
    c->k++;
    while (lag >= (int32_t)ICM_CLOCK_LAG_MAX_US) {
        /* a sample the reads missed */
        c->k++;
        at += c->period_us;
        lag -= (int32_t)c->period_us;
    }
    if (lag < 0) {
        /* read before the line says it was measured: the line comes down */
        uint32_t d = (uint32_t)c->lowered_us + (uint32_t)-lag;
        c->lowered_us = (uint16_t)(d > 0xFFFFu ? 0xFFFFu : d);
        at = seen_us;
        lag = 0;
    }
    if ((uint32_t)lag < c->low_us) {
        c->low_us = (uint16_t)lag;
    }
    if (c->k >= ICM_CLOCK_WINDOW) {
        /* up to the window's lowest read; the period takes a quarter of
         * what the line moved over the window (one window's lowest read is
         * noisy) */
        int16_t p = (int16_t)c->period_us;
        if (c->have & HAVE_PERIOD) {
            p = (int16_t)(p + ((int16_t)(c->low_us >> 1) - (int16_t)(c->lowered_us >> 1)) /
                                  (int16_t)(2u * ICM_CLOCK_WINDOW));
        }
        c->have |= HAVE_PERIOD;
        at += c->low_us;
        c->period_us = (uint16_t)(p < (int16_t)ICM_CLOCK_PERIOD_MIN   ? ICM_CLOCK_PERIOD_MIN
                                  : p > (int16_t)ICM_CLOCK_PERIOD_MAX ? ICM_CLOCK_PERIOD_MAX
                                                                      : (uint16_t)p);
    }
    c->at_us = at;
    return at;
}
