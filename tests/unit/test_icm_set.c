/*
 * icm_set: the round-robin sensor scheduler with three (and sixteen) modelled
 * sensors behind a modelled TCA9548A, polled like the firmware main loop.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "devices/icm20948_model.h"
#include "devices/tca9548a_model.h"
#include "icm20948/icm20948.h"
#include "icm20948/icm_set.h"
#include "icm_fake_bus.h"

#define MAXS 16

typedef struct {
    tcam_t mux;
    icmm_t icm[MAXS];
    icm_fake_bus_t fb;
    icm_set_t set;
    icm_set_slot_t slots[MAXS];
    uint8_t n;
    uint64_t busy_ns; /* bus time spent inside icm_set_poll */
} bench_t;

/* n sensors: channel i % 8, address 0x69 for the first eight, then 0x68. */
static void bench_setup(bench_t *b, uint8_t n)
{
    uint8_t i;
    memset(b, 0, sizeof(*b));
    tcam_init(&b->mux, 0x70);
    for (i = 0; i < n; i++) {
        uint8_t addr = i < 8u ? 0x69 : 0x68;
        icmm_init(&b->icm[i], addr, 100u + i);
        icmm_set_noise(&b->icm[i], 60, 200u + i);
        icmm_set_field_cuT(&b->icm[i], 1000 * (i + 1), -500, 3000);
        assert_int_equal(tcam_attach(&b->mux, (uint8_t)(i % 8u), icmm_slave(&b->icm[i])), 0);
    }
    icm_fake_bus_setup(&b->fb, tcam_slave(&b->mux));
    assert_int_equal(icm_set_setup(&b->set, &b->fb.bus, 0x70, b->slots, MAXS), 0);
    for (i = 0; i < n; i++) {
        assert_int_equal(icm_set_add(&b->set, (uint8_t)(i % 8u), i < 8u ? 0x69 : 0x68), i);
    }
    b->n = n;
}

/* The main loop: poll, then 50 us of other work. */
static void bench_run(bench_t *b, uint32_t us)
{
    uint64_t end = b->fb.now_ns + (uint64_t)us * 1000u;
    while (b->fb.now_ns < end) {
        uint64_t t0 = b->fb.now_ns;
        assert_int_equal(icm_set_poll(&b->set, icm_fake_bus_now_us(&b->fb)), 0);
        b->busy_ns += b->fb.now_ns - t0;
        icm_fake_bus_sleep_us(&b->fb, 50);
    }
}

static void test_set_args(void **state)
{
    icm_set_t set;
    icm_set_slot_t slots[2];
    icm_bus_t bus = {0};
    icm_sample_t s;
    icm_diag_t d;
    (void)state;
    assert_int_equal(icm_set_setup(NULL, &bus, 0x70, slots, 2), ICM_E_ARG);
    assert_int_equal(icm_set_setup(&set, &bus, 0x60, slots, 2), ICM_E_ARG);
    assert_int_equal(icm_set_setup(&set, &bus, 0x70, NULL, 2), ICM_E_ARG);
    assert_int_equal(icm_set_setup(&set, &bus, 0x70, slots, 0), ICM_E_ARG);
    assert_int_equal(icm_set_setup(&set, &bus, 0x70, slots, ICM_SET_MAX + 1u), ICM_E_ARG);
    assert_int_equal(icm_set_setup(&set, &bus, ICM_NO_MUX, slots, 2), 0);
    assert_int_equal(icm_set_begin(&set, 0), ICM_E_ARG); /* empty */
    assert_int_equal(icm_set_poll(&set, 0), ICM_E_STATE);
    assert_int_equal(icm_set_take(&set, 0, &s), ICM_E_ARG);
    assert_int_equal(icm_set_diag(&set, 0, &d), ICM_E_ARG);
    assert_int_equal(icm_set_period_us(&set, 999), ICM_E_ARG);
    assert_int_equal(icm_set_stale_limit_us(&set, 0), ICM_E_ARG);
}

static void test_add_rules(void **state)
{
    bench_t b;
    uint8_t i;
    (void)state;
    bench_setup(&b, 0);
    assert_int_equal(icm_set_add(&b.set, ICM_NO_MUX, 0x69), ICM_E_ARG); /* mux needs a channel */
    assert_int_equal(icm_set_add(&b.set, 8, 0x69), ICM_E_ARG);
    assert_int_equal(icm_set_add(&b.set, 0, 0x6A), ICM_E_ARG);
    for (i = 0; i < 16u; i++) {
        assert_int_equal(icm_set_add(&b.set, (uint8_t)(i / 2u), (uint8_t)(0x68u + (i & 1u))), i);
    }
    assert_int_equal(icm_set_add(&b.set, 0, 0x69), ICM_E_ARG); /* full (and duplicate) */
    b.set.n = 15;
    assert_int_equal(icm_set_add(&b.set, 0, 0x69), ICM_E_ARG); /* duplicate */
    /* a small set is full at its capacity */
    {
        icm_set_t small;
        icm_set_slot_t two[2];
        assert_int_equal(icm_set_setup(&small, &b.fb.bus, 0x70, two, 2), 0);
        assert_int_equal(icm_set_add(&small, 0, 0x69), 0);
        assert_int_equal(icm_set_add(&small, 1, 0x69), 1);
        assert_int_equal(icm_set_add(&small, 2, 0x69), ICM_E_ARG);
    }
}

static void test_three_sensors_at_100hz(void **state)
{
    bench_t b;
    icm_sample_t s;
    icm_diag_t d;
    uint8_t i;
    uint32_t got[3] = {0, 0, 0};
    uint64_t busy0;
    uint32_t reads0, t0;
    (void)state;
    bench_setup(&b, 3);
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 250000); /* 100 ms start-up after the reset */
    assert_true(icm_set_settled(&b.set));
    assert_int_equal(icm_set_ready_count(&b.set), 3);
    /* take samples as the homing loop would, for two seconds */
    bench_run(&b, 1000000); /* first full rate window */
    for (i = 0; i < 3u; i++) {
        (void)icm_set_take(&b.set, i, &s);
        b.set.slot[i].missed = 0;
    }
    busy0 = b.busy_ns;
    t0 = icm_fake_bus_now_us(&b.fb);
    reads0 = b.icm[0].ext_reads;
    while (icm_fake_bus_now_us(&b.fb) - t0 < 2000000u) {
        bench_run(&b, 1000);
        for (i = 0; i < 3u; i++) {
            int8_t rc = icm_set_take(&b.set, i, &s);
            assert_true(rc == 0 || rc == 1);
            if (rc == 1) {
                got[i]++;
                assert_true(s.flags & ICM_SAMPLE_NEW);
                /* the field set for sensor i, within noise */
                assert_in_range(s.raw[0] * 15, 1000 * (i + 1) - 400, 1000 * (i + 1) + 400);
            }
        }
    }
    for (i = 0; i < 3u; i++) {
        assert_in_range(got[i], 198, 202); /* 100 Hz for two seconds */
        assert_int_equal(icm_set_diag(&b.set, i, &d), 0);
        assert_in_range(d.rate_dhz, 990, 1010);
        assert_int_equal(d.state, ICM_SET_S_RUN);
        assert_true(d.present);
        assert_int_equal(d.who_am_i, 0xEA);
        assert_true(d.mag_ready);
        assert_int_equal(d.error_count, 0);
        assert_int_equal(b.set.slot[i].missed, 0);
    }
    /* each sensor read every period: 2 s / 4.7 ms = 425.5 reads */
    {
        uint32_t n = 2000000u / ICM_SET_PERIOD_US_DEFAULT;
        assert_in_range(b.icm[0].ext_reads - reads0, n - 2u, n + 2u);
    }
    /* bus occupancy: 3 sensors x reads/s x (mux write + data read) */
    {
        uint64_t per_s = (b.busy_ns - busy0) / 2u;
        uint64_t per_read = per_s / (3u * 1000000u / ICM_SET_PERIOD_US_DEFAULT);
        printf("# 3 sensors: bus busy %llu us per second, %llu us per read\n",
               (unsigned long long)(per_s / 1000u), (unsigned long long)(per_read / 1000u));
        /* mux write 20 bits + data read 111 bits = 131 bits = 327.5 us */
        assert_in_range(per_read, 327000, 328000);
    }
}

static void test_sixteen_sensors(void **state)
{
    bench_t b;
    icm_diag_t d;
    uint8_t i;
    (void)state;
    bench_setup(&b, 16);
    assert_int_equal(icm_set_period_us(&b.set, 10000), 0);
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 2500000);
    assert_int_equal(icm_set_ready_count(&b.set), 16);
    for (i = 0; i < 16u; i++) {
        assert_int_equal(icm_set_diag(&b.set, i, &d), 0);
        /* noise-free fields: unchanged samples count only by DRDY, and
         * reads every 10 ms, slower than the master's 7.27 ms, miss many of
         * them (a real sensor's noise changes the data of every
         * sample); the default 5 ms period catches every one */
        assert_in_range(d.rate_dhz, 500, 1010);
        assert_int_equal(d.addr, i < 8u ? 0x69 : 0x68);
        /* each sensor shows its own field: no channel crosstalk */
        assert_in_range(d.field_cuT[0], 1000 * (i + 1) - 400, 1000 * (i + 1) + 400);
        assert_int_equal(b.icm[i].resets, 1);
    }
}

static void test_absent_and_wrong_sensors_reported(void **state)
{
    bench_t b;
    icm_diag_t d;
    icm_sample_t s;
    char line[ICM_DIAG_LINE_MAX];
    (void)state;
    bench_setup(&b, 3);
    b.icm[1].present = 0;
    b.icm[2].ak.present = 0;
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 300000);
    assert_true(icm_set_settled(&b.set));
    assert_int_equal(icm_set_ready_count(&b.set), 1);
    assert_int_equal(icm_set_diag(&b.set, 1, &d), 0);
    assert_int_equal(d.state, ICM_SET_S_FAIL);
    assert_false(d.present);
    assert_int_equal(d.last_err, ICM_E_ABSENT);
    assert_int_equal(icm_set_take(&b.set, 1, &s), ICM_E_ABSENT);
    assert_int_equal(icm_set_diag(&b.set, 2, &d), 0);
    assert_true(d.present);
    assert_false(d.mag_ready);
    assert_int_equal(d.last_err, ICM_E_MAG_ABSENT);
    assert_true(icm_diag_format(&d, line, sizeof(line)) > 0);
    assert_string_equal(line, "ch=2 addr=0x69 state=fail who=0xEA mag=0 rate=0.0 bx=0.00 by=0.00 "
                              "bz=0.00 ovf=0 dor=0 err=1 last=-7");
    /* the working sensor is unaffected */
    assert_int_equal(icm_set_diag(&b.set, 0, &d), 0);
    assert_int_equal(d.state, ICM_SET_S_RUN);
    /* retried every second: plug the sensor in and it comes up */
    b.icm[1].present = 1;
    bench_run(&b, 1100000);
    assert_int_equal(icm_set_diag(&b.set, 1, &d), 0);
    assert_int_equal(d.state, ICM_SET_S_RUN);
    assert_int_equal(d.reinits, 1);
}

/* Three sensors sampling, then sensor k unplugged: it fails as absent. */
static void run_then_unplug(bench_t *b, uint8_t k, icm_diag_t *d)
{
    bench_setup(b, 3);
    assert_int_equal(icm_set_begin(&b->set, 0), 0);
    bench_run(b, 200000);
    assert_int_equal(icm_set_ready_count(&b->set), 3);
    b->icm[k].present = 0; /* unplugged */
    bench_run(b, 100000);
    assert_int_equal(icm_set_diag(&b->set, k, d), 0);
    assert_int_equal(d->state, ICM_SET_S_FAIL);
    assert_int_equal(d->last_err, ICM_E_ABSENT);
}

static void test_sensor_lost_and_back(void **state)
{
    bench_t b;
    icm_diag_t d;
    icm_sample_t s;
    (void)state;
    run_then_unplug(&b, 0, &d);
    assert_false(d.present);
    assert_int_equal(d.rate_dhz, 0);
    assert_true(d.error_count >= 2u); /* the failed read and the failed re-init */
    assert_true(icm_set_take(&b.set, 0, &s) < 0);
    assert_int_equal(icm_set_ready_count(&b.set), 2);
    b.icm[0].present = 1;
    bench_run(&b, 1200000);
    assert_int_equal(icm_set_ready_count(&b.set), 3);
    bench_run(&b, 20000);
    assert_int_equal(icm_set_take(&b.set, 0, &s), 1);
}

/* A bring-up (icm_set_retry()) tries a failed sensor again at once, and
 * icm_set_settled() waits for that attempt: a sensor plugged back since its
 * last attempt is running before the bring-up names the missing ones, not a
 * second later (a press right after the plug was refused: chaos seed 1009).
 * One still absent settles as failed again. */
static void test_retry_at_once_and_settled_waits(void **state)
{
    bench_t b;
    icm_diag_t d;
    (void)state;
    bench_setup(&b, 3);
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 200000);
    b.icm[0].present = 0;
    b.icm[1].present = 0;
    bench_run(&b, 100000);
    assert_int_equal(icm_set_ready_count(&b.set), 1);
    b.icm[0].present = 1; /* plugged back; 1 stays away */
    bench_run(&b, 10000);
    assert_int_equal(icm_set_ready_count(&b.set), 1); /* its retry is not due yet */
    icm_set_retry(&b.set, icm_fake_bus_now_us(&b.fb));
    assert_false(icm_set_settled(&b.set));
    bench_run(&b, 50000);
    assert_false(icm_set_settled(&b.set)); /* sensor 0's init takes longer */
    bench_run(&b, 250000);
    assert_true(icm_set_settled(&b.set));
    assert_int_equal(icm_set_ready_count(&b.set), 2);
    assert_int_equal(icm_set_diag(&b.set, 1, &d), 0);
    assert_int_equal(d.state, ICM_SET_S_FAIL);
    assert_int_equal(d.last_err, ICM_E_ABSENT);
}

/* A bring-up that comes while a failed sensor's periodic retry is under way
 * (in its reset wait) waits for that init too: taken as settled, the sensor
 * was named missing and the press refused, found 80 ms later (chaos seed
 * 3195). */
static void test_settled_waits_for_an_init_under_way(void **state)
{
    bench_t b;
    icm_diag_t d;
    uint32_t t;
    (void)state;
    run_then_unplug(&b, 2, &d);
    b.icm[2].present = 1; /* plugged back: its periodic retry finds it */
    for (t = 0; t < 2000000u; t += 1000u) {
        bench_run(&b, 1000);
        assert_int_equal(icm_set_diag(&b.set, 2, &d), 0);
        if (d.state == ICM_SET_S_INIT) {
            break;
        }
    }
    assert_int_equal(d.state, ICM_SET_S_INIT);
    bench_run(&b, 5000); /* into the init */
    icm_set_retry(&b.set, icm_fake_bus_now_us(&b.fb));
    assert_false(icm_set_settled(&b.set));
    while (!icm_set_settled(&b.set)) {
        bench_run(&b, 1000);
    }
    assert_int_equal(icm_set_ready_count(&b.set), 3);
}

static void test_stale_sensor_reinitialised(void **state)
{
    bench_t b;
    icm_diag_t d;
    (void)state;
    bench_setup(&b, 3);
    assert_int_equal(icm_set_stale_limit_us(&b.set, 40000), 0);
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 200000);
    /* the AK09916 of sensor 2 powers down (e.g. a brown-out) */
    b.icm[2].ak.mode = 0;
    b.icm[2].ak.next_meas_us = UINT64_MAX;
    bench_run(&b, 60000);
    assert_int_equal(icm_set_diag(&b.set, 2, &d), 0);
    assert_int_equal(d.last_err, ICM_E_STALE);
    assert_true(d.reinits >= 1u);
    bench_run(&b, 150000); /* its reset's 100 ms and the init's steps */
    assert_int_equal(icm_set_diag(&b.set, 2, &d), 0);
    assert_int_equal(d.state, ICM_SET_S_RUN); /* the init set 100 Hz mode again */
    assert_int_equal(b.icm[2].ak.mode, 0x08);
}

static void test_transient_errors_counted_not_fatal(void **state)
{
    bench_t b;
    icm_diag_t d;
    (void)state;
    bench_setup(&b, 3);
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 200000);
    b.fb.timeouts = 1;
    bench_run(&b, 20000);
    b.fb.stuck_sda = 1;
    b.fb.stuck_recoverable = 1;
    bench_run(&b, 20000);
    assert_int_equal(icm_set_ready_count(&b.set), 3);
    assert_int_equal(b.fb.recoveries, 2);
    {
        uint16_t errs = 0;
        uint8_t i;
        for (i = 0; i < 3u; i++) {
            assert_int_equal(icm_set_diag(&b.set, i, &d), 0);
            errs = (uint16_t)(errs + d.error_count);
            assert_int_equal(d.reinits, 0);
        }
        assert_int_equal(errs, 2);
    }
}

static void test_overflow_counted(void **state)
{
    bench_t b;
    icm_diag_t d;
    icm_sample_t s;
    (void)state;
    bench_setup(&b, 3);
    assert_int_equal(icm_set_begin(&b.set, 0), 0);
    bench_run(&b, 200000);
    icmm_set_field_cuT(&b.icm[1], 600000, 0, 0);
    bench_run(&b, 50000);
    assert_int_equal(icm_set_take(&b.set, 1, &s), 1);
    assert_true(s.flags & ICM_SAMPLE_OVERFLOW);
    assert_int_equal(icm_set_diag(&b.set, 1, &d), 0);
    assert_in_range(d.overflow_count, 4, 6);
    assert_int_equal(d.field_cuT[0], 491280);
}

static void test_diag_format_longest(void **state)
{
    icm_diag_t d;
    char line[ICM_DIAG_LINE_MAX];
    char small[10];
    int16_t n;
    (void)state;
    memset(&d, 0, sizeof(d));
    d.channel = 7;
    d.addr = 0x68;
    d.state = ICM_SET_S_INIT;
    d.who_am_i = 0xEA;
    d.mag_ready = 1;
    d.rate_dhz = 65535;
    d.field_cuT[0] = d.field_cuT[1] = d.field_cuT[2] = -491520;
    d.overflow_count = d.overrun_count = d.error_count = 65535;
    d.last_err = -11;
    n = icm_diag_format(&d, line, sizeof(line));
    assert_true(n > 0 && n < (int16_t)sizeof(line));
    assert_string_equal(line, "ch=7 addr=0x68 state=init who=0xEA mag=1 rate=6553.5 bx=-4915.20 "
                              "by=-4915.20 bz=-4915.20 ovf=65535 dor=65535 err=65535 last=-11");
    assert_int_equal(icm_diag_format(&d, small, sizeof(small)), ICM_E_ARG);
    d.field_cuT[0] = 5;
    d.field_cuT[1] = -5;
    d.channel = ICM_NO_MUX;
    n = icm_diag_format(&d, line, sizeof(line));
    assert_non_null(strstr(line, "ch=- "));
    assert_non_null(strstr(line, "bx=0.05 by=-0.05 "));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_set_args),
        cmocka_unit_test(test_add_rules),
        cmocka_unit_test(test_three_sensors_at_100hz),
        cmocka_unit_test(test_sixteen_sensors),
        cmocka_unit_test(test_absent_and_wrong_sensors_reported),
        cmocka_unit_test(test_sensor_lost_and_back),
        cmocka_unit_test(test_retry_at_once_and_settled_waits),
        cmocka_unit_test(test_settled_waits_for_an_init_under_way),
        cmocka_unit_test(test_stale_sensor_reinitialised),
        cmocka_unit_test(test_transient_errors_counted_not_fatal),
        cmocka_unit_test(test_overflow_counted),
        cmocka_unit_test(test_diag_format_longest),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
