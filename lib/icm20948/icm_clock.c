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

void icm_clock_reset(icm_clock_t *c)
{
    c->have = 0;
}

static void window_start(icm_clock_t *c)
{
    c->k = 0;
    c->low_us = 0xFFFFu;
    c->lowered_us = 0;
}

uint32_t icm_clock_seen(icm_clock_t *c, uint32_t seen_us)
{
    uint32_t at;
    int32_t lag;
    if (!c->have) {
        c->have = 1;
        c->base_us = seen_us; /* an upper bound: the next reads lower it */
        c->period_us = ICM_CLOCK_PERIOD_US;
        c->settled = 0;
        window_start(c);
        return seen_us;
    }
    c->k++;
    at = c->base_us + (uint32_t)c->k * c->period_us;
    lag = (int32_t)(seen_us - at);
    if (lag >= ICM_CLOCK_GAP_US) {
        c->have = 0;
        return icm_clock_seen(c, seen_us);
    }
    while (lag >= (int32_t)ICM_CLOCK_LAG_MAX_US) {
        /* a sample the reads missed (at most a second's worth) */
        c->k++;
        at += c->period_us;
        lag -= (int32_t)c->period_us;
    }
    if (lag < 0) {
        /* read before the line says it was measured: the line comes down */
        c->base_us -= (uint32_t)-lag;
        c->lowered_us =
            (uint16_t)(c->lowered_us + (uint32_t)-lag > 0xFFFFu ? 0xFFFFu
                                                                : c->lowered_us + (uint32_t)-lag);
        at = seen_us;
        lag = 0;
    }
    if ((uint32_t)lag < c->low_us) {
        c->low_us = (uint16_t)lag;
    }
    if (c->k >= ICM_CLOCK_WINDOW) {
        /* up to the window's lowest read; the period takes what the line
         * moved over the window */
        int32_t p = (int32_t)c->period_us;
        if (c->settled) {
            /* a quarter of the drift: one window's lowest read is noisy */
            p += ((int32_t)c->low_us - (int32_t)c->lowered_us) / (int32_t)(4u * ICM_CLOCK_WINDOW);
        }
        c->settled = 1; /* the first window finds the phase, not the period */
        at += c->low_us;
        c->base_us = at;
        p = p < (int32_t)ICM_CLOCK_PERIOD_MIN ? (int32_t)ICM_CLOCK_PERIOD_MIN : p;
        c->period_us =
            (uint16_t)(p > (int32_t)ICM_CLOCK_PERIOD_MAX ? (int32_t)ICM_CLOCK_PERIOD_MAX : p);
        window_start(c);
    }
    return at;
}
