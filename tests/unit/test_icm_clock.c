/*
 * icm_clock: the estimate of when each AK09916 sample was measured, against
 * a timeline of the three clocks that delay it (the AK09916's own, the
 * ICM-20948 master's copies, the host's reads with a main loop's jitter),
 * with the AK09916's oscillator fast, slow and exact, and reads that stall.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "icm20948/icm_clock.h"
#include "icm20948/icm_set.h"

#define READ_US ICM_SET_PERIOD_US_DEFAULT /* the firmware's reads */

typedef struct {
    uint32_t ak_us;     /* the AK09916's period */
    uint32_t mst_us;    /* the master's copy period */
    uint32_t poll_us;   /* the host's read period */
    uint32_t jitter_us; /* each read up to this much late */
    uint32_t stall_at;  /* a read at this sample stalls for stall_us (0: none) */
    uint32_t stall_us;
    uint32_t warmup; /* samples before the errors count */
    uint32_t seed;
} timeline_t;

typedef struct {
    int32_t late_us;  /* worst estimate after the true measurement */
    int32_t early_us; /* worst estimate before it (negative) */
    uint32_t n;       /* samples seen after the warm-up */
} errs_t;

static uint32_t next_rand(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

/* Runs n samples of the timeline through a fresh clock. */
static errs_t run(const timeline_t *tl, uint32_t n)
{
    icm_clock_t c;
    errs_t e = {0, 0, 0};
    uint32_t s = tl->seed;
    uint32_t ak0 = 1000u + next_rand(&s) % tl->ak_us;
    uint32_t mst = 1000u + next_rand(&s) % tl->mst_us;   /* next copy */
    uint32_t poll = 1000u + next_rand(&s) % tl->poll_us; /* next read, before jitter */
    int32_t reg = -1;                                    /* sample in EXT_SLV_SENS_DATA */
    int32_t last = -1;                                   /* last sample the host saw */
    icm_clock_reset(&c);
    while (last < (int32_t)n) {
        uint32_t read = poll + next_rand(&s) % (tl->jitter_us + 1u);
        if (tl->stall_at != 0u && last == (int32_t)tl->stall_at) {
            read += tl->stall_us;
            poll += tl->stall_us;
        }
        /* the master's copies up to the read */
        while (mst <= read) {
            if (mst >= ak0) {
                reg = (int32_t)((mst - ak0) / tl->ak_us);
            }
            mst += tl->mst_us;
        }
        if (reg > last) {
            uint32_t meas = ak0 + (uint32_t)reg * tl->ak_us;
            int32_t err = (int32_t)(icm_clock_seen(&c, read) - meas);
            last = reg;
            if ((uint32_t)reg >= tl->warmup) {
                e.n++;
                e.late_us = err > e.late_us ? err : e.late_us;
                e.early_us = err < e.early_us ? err : e.early_us;
            }
        }
        poll += tl->poll_us;
    }
    return e;
}

/* Runs seeds 1..seeds of the timeline with this AK09916 period, read
 * lateness and stall, n samples each, and checks every estimate after the
 * warm-up within late_max late and early_max early. */
static void expect_within(uint32_t ak_us, uint32_t jitter_us, uint32_t stall_at, uint32_t warmup,
                          uint32_t seeds, int32_t late_max, int32_t early_max)
{
    uint32_t seed;
    for (seed = 1; seed <= seeds; seed++) {
        timeline_t tl = {ak_us, 7300u, READ_US, jitter_us, stall_at, 35000u, warmup, seed};
        errs_t e = run(&tl, warmup + 260u);
        assert_true(e.n >= 200u);
        assert_in_range(e.late_us, 0, late_max);
        assert_in_range(-e.early_us, 0, early_max);
    }
}

/* The firmware's clocks, reads up to 1 ms late: within 4 ms late and 1 ms
 * early after 40 samples. 4 ms is 8 ticks of a take-up at its top speed;
 * a sample's age read at the read itself is up to 16 ms. */
static void test_nominal(void **state)
{
    (void)state;
    expect_within(ICM_CLOCK_PERIOD_US, 1000u, 0u, 40u, 40u, 4000, 1000);
}

/* Reads up to 3 ms late miss a sample now and then: that sample and the
 * next few look up to a period older than they are, never younger by more
 * than 4.5 ms. */
static void test_late_reads(void **state)
{
    (void)state;
    expect_within(ICM_CLOCK_PERIOD_US, 3000u, 0u, 40u, 40u, 4500, ICM_CLOCK_PERIOD_US + 500);
}

/* The first samples are taken as measured when seen: late, never early. */
static void test_first_samples_late_not_early(void **state)
{
    timeline_t tl = {ICM_CLOCK_PERIOD_US, 7300u, READ_US, 1000u, 0u, 0u, 0u, 7u};
    errs_t e;
    (void)state;
    e = run(&tl, 5u);
    assert_true(e.early_us >= 0);
    assert_true(e.late_us <= (int32_t)ICM_CLOCK_LAG_MAX_US);
}

/* An AK09916 whose oscillator runs 1 or 2 % fast or slow: the period
 * follows, within 5.5 ms late and 1 ms early after 150 samples. */
static void test_oscillator_off(void **state)
{
    static const uint32_t period[] = {9800u, 9900u, 10100u, 10200u};
    uint8_t k;
    (void)state;
    for (k = 0; k < 4u; k++) {
        expect_within(period[k], 1000u, 0u, 150u, 20u, 5500, 1000);
    }
}

/* A read stalled for 35 ms at sample 100 skips samples: the estimate may
 * fall a period early (a sample looks older), never late by more than
 * 5 ms, and 40 samples on it is back within 5 ms late and 1 ms early. */
static void test_stall_skips_samples(void **state)
{
    (void)state;
    expect_within(ICM_CLOCK_PERIOD_US, 1000u, 100u, 40u, 20u, 5000, ICM_CLOCK_PERIOD_US + 1000);
    expect_within(ICM_CLOCK_PERIOD_US, 1000u, 100u, 140u, 20u, 5000, 1000);
}

/* A second without samples starts afresh. */
static void test_long_gap_restarts(void **state)
{
    icm_clock_t c;
    (void)state;
    icm_clock_reset(&c);
    assert_int_equal(icm_clock_seen(&c, 5000u), 5000u);
    assert_int_equal(icm_clock_seen(&c, 9000u), 9000u); /* pinned: seen before the estimate */
    assert_int_equal(icm_clock_seen(&c, 3000000u), 3000000u);

    assert_int_equal(icm_clock_seen(&c, 3014000u), 3010000u); /* 4 ms behind the line */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nominal),
        cmocka_unit_test(test_late_reads),
        cmocka_unit_test(test_first_samples_late_not_early),
        cmocka_unit_test(test_oscillator_off),
        cmocka_unit_test(test_stall_skips_samples),
        cmocka_unit_test(test_long_gap_restarts),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
