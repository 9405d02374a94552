/* Tests of the homing API against a scripted bench (servos that reach their
 * goal at once, sensors that return what the test says): argument and table
 * errors, abort on the very next step, preflight naming every missing
 * device, slack never confirmed, the event queue, helpers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>

#include <cmocka.h>

#include "hom_fixture.h"
#include "homing/hom_priv.h"

static plant_cfg_t g_cfg;
static tbl_wide_t g_tab;
static hom_t g_h;

typedef struct {
    hom_in_t in;
    hom_out_t out;
    int32_t pos[TBL_MAX_TENDONS];
    int32_t field[HOM_MAX_SENSORS][3];
    int32_t drift_per_sample; /* added to every field z at each sample */
    int32_t droop;            /* servos stop this many ticks short of their goals */
    uint8_t sensor_status[HOM_MAX_SENSORS];
    uint8_t servo_status[TBL_MAX_TENDONS];
    uint8_t hw_error[TBL_MAX_TENDONS];
} bench_t;

static bench_t g_b;

static int group_setup(void **state)
{
    (void)state;
    return hom_fix_paper(&g_cfg, &g_tab);
}

static void bench_init(bench_t *b, uint32_t t0)
{
    uint8_t k;
    memset(b, 0, sizeof *b);
    b->in.now_ms = t0;
    for (k = 0; k < HOM_MAX_SENSORS; k++) {
        b->field[k][0] = g_tab.sensors[k].b_straight_cuT[0];
        b->field[k][1] = g_tab.sensors[k].b_straight_cuT[1];
        b->field[k][2] = g_tab.sensors[k].b_straight_cuT[2] - 4400;
        b->sensor_status[k] = HOM_SENS_NEW;
    }
}

/* One millisecond: sensors sample at 100 Hz, servos jump to their goals. */
static int bench_step(bench_t *b, hom_t *h)
{
    uint8_t k;
    int rc;
    b->in.now_ms++;
    for (k = 0; k < HOM_MAX_SENSORS; k++) {
        b->in.sensor[k].status = HOM_SENS_NONE;
        if (b->in.now_ms % 10u == 0u) {
            b->field[k][2] += b->drift_per_sample;
            b->in.sensor[k].status = b->sensor_status[k];
            memcpy(b->in.sensor[k].b_cuT, b->field[k], sizeof b->field[k]);
        }
    }
    for (k = 0; k < TBL_MAX_TENDONS; k++) {
        b->in.servo[k].status = b->servo_status[k];
        b->in.servo[k].hw_error = b->hw_error[k];
        b->in.servo[k].pos = b->pos[k];
    }
    rc = hom_step(h, &b->in, &b->out);
    for (k = 0; k < TBL_MAX_TENDONS; k++) {
        if ((b->out.changed >> k) & 1u) {
            b->pos[k] = b->out.goal[k] + (b->out.goal[k] > b->pos[k] ? -b->droop : b->droop);
        }
    }
    return rc;
}

/* The packed form of t as it is now (pack again after editing t). */
static tbl_src_t src_of(const tbl_wide_t *t)
{
    tbl_src_t s;
    s.table = hom_fix_pack(t);
    s.copy = tbl_copy_ram;
    return s;
}

static hom_cmd_t full_cmd(void)
{
    hom_cmd_t c;
    memset(&c, 0, sizeof c);
    c.mode = HOM_MODE_FULL;
    return c;
}

static void test_start_errors(void **state)
{
    static tbl_wide_t bad;
    tbl_src_t src = src_of(&g_tab);
    tbl_src_t bsrc = src_of(&bad);
    hom_cmd_t c = full_cmd();
    (void)state;
    hom_init(&g_h, NULL);
    assert_int_equal(hom_start(NULL, &src, &c), HOM_E_ARG);
    assert_int_equal(hom_start(&g_h, NULL, &c), HOM_E_ARG);
    assert_int_equal(hom_start(&g_h, &src, NULL), HOM_E_ARG);
    c.mode = (hom_mode_t)7;
    assert_int_equal(hom_start(&g_h, &src, &c), HOM_E_ARG);
    c = full_cmd();
    bad = g_tab;
    bad.magic ^= 1u;
    bsrc = src_of(&bad);
    assert_int_equal(hom_start(&g_h, &bsrc, &c), HOM_E_TABLE);
    bad = g_tab;
    bad.format_version++;
    bsrc = src_of(&bad);
    assert_int_equal(hom_start(&g_h, &bsrc, &c), HOM_E_TABLE);
    c.tension_mN = 100;
    assert_int_equal(hom_start(&g_h, &src, &c), HOM_E_TENSION);
    c.tension_mN = 1600;
    assert_int_equal(hom_start(&g_h, &src, &c), HOM_E_TENSION);
    c = full_cmd();
    c.mode = HOM_MODE_SINGLE;
    c.tendon = 6;
    assert_int_equal(hom_start(&g_h, &src, &c), HOM_E_ARG);
    c = full_cmd();
    c.mode = HOM_MODE_QUICK;
    assert_int_equal(hom_start(&g_h, &src, &c), HOM_E_HOMES);
    c = full_cmd();
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    assert_int_equal(hom_start(&g_h, &src, &c), HOM_E_BUSY);
    assert_int_equal(hom_step(&g_h, NULL, &g_b.out), HOM_E_ARG);
}

static void test_idle_step_does_nothing(void **state)
{
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0);
    assert_int_equal(bench_step(&g_b, &g_h), 0);
    assert_int_equal(g_b.out.changed, 0);
    assert_int_equal(hom_abort(&g_h), 0); /* no effect when idle, and it says so */
    assert_int_equal(bench_step(&g_b, &g_h), 0);
}

static void test_abort_before_motion_moves_nothing(void **state)
{
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0);
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    assert_int_equal(bench_step(&g_b, &g_h), HOM_RUNNING); /* preflight, no sample yet */
    assert_int_equal(hom_abort(&g_h), 1);
    assert_int_equal(bench_step(&g_b, &g_h), -HOM_F_ABORTED);
    assert_int_equal(hom_abort(&g_h), 0); /* the run has ended: the caller releases */
    assert_int_equal(g_b.out.changed, 0);
    assert_int_equal(g_h.fault, HOM_F_ABORTED);
    /* a new run may start after a fault */
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
}

static void test_abort_releases_on_next_step(void **state)
{
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    hom_event_t ev;
    int32_t before[TBL_MAX_TENDONS];
    uint8_t i;
    int n;
    int released = 0;
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 1000);
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 100 && g_h.moved == 0u; n++) {
        assert_int_equal(bench_step(&g_b, &g_h), HOM_RUNNING);
    }
    assert_true(g_h.moved);
    memcpy(before, g_b.pos, sizeof before);
    hom_abort(&g_h);
    assert_int_equal(bench_step(&g_b, &g_h), -HOM_F_ABORTED);
    assert_int_equal(g_b.out.changed, (1u << g_tab.n_tendons) - 1u);
    for (i = 0; i < g_tab.n_tendons; i++) {
        /* pull_dir +1: a release never raises the position, and goes no
         * further than the margin before the engagement window (the
         * release the run had already made) */
        assert_true(g_b.out.goal[i] <= before[i]);
        assert_int_equal(g_b.out.goal[i], g_h.tendon[i].eng_lo - g_h.tendon[i].margin_ticks);
        assert_int_equal(g_b.out.vel[i], g_h.cfg.v_release);
        assert_int_equal(g_b.out.torque[i], 1);
    }
    while (hom_event_pop(&g_h, &ev)) {
        if (ev.type == HOM_EV_RELEASED) {
            released = 1;
            assert_int_equal(ev.a, HOM_F_ABORTED);
        }
    }
    assert_true(released);
    /* the fault stays until the next start, and nothing more is commanded */
    assert_int_equal(bench_step(&g_b, &g_h), -HOM_F_ABORTED);
    assert_int_equal(g_b.out.changed, 0);
}

/* The slack a calibrated tendon is released to: at least the margin, scaled
 * with the tension above 1 N, and at least the tendon's own travel at the
 * tension plus a quarter of the margin (another tendon's pull lengthens its
 * path by about that much). */
static void test_slack_margin_covers_the_pull_of_other_tendons(void **state)
{
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    static const uint16_t tension[4] = {300, 800, 1000, 1500};
    uint8_t k;
    uint8_t i;
    int n;
    (void)state;
    for (k = 0; k < 4u; k++) {
        hom_init(&g_h, NULL);
        bench_init(&g_b, 1000);
        c.tension_mN = tension[k];
        assert_int_equal(hom_start(&g_h, &src, &c), 0);
        for (n = 0; n < 100 && g_h.moved == 0u; n++) {
            assert_int_equal(bench_step(&g_b, &g_h), HOM_RUNNING);
        }
        for (i = 0; i < g_tab.n_tendons; i++) {
            const hom_tendon_t *t = &g_h.tendon[i];
            uint32_t scaled = tension[k] > 1000u ? 600u * tension[k] / 1000u : 600u;
            int32_t a = hom_um_to_ticks(scaled, t->nm_per_tick);
            int32_t b = t->travel_ticks + hom_um_to_ticks(150u, t->nm_per_tick);
            int32_t want = a > b ? a : b;
            assert_in_range(t->margin_ticks, want - 1, want + 1);
        }
    }
    /* at 1.5 N the margin is half as large again as at 1 N or more */
    assert_true(g_h.tendon[0].margin_ticks >= hom_um_to_ticks(900u, g_h.tendon[0].nm_per_tick));
}

static void test_preflight_names_every_missing_device(void **state)
{
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    hom_event_t ev;
    int rc = HOM_RUNNING;
    int n;
    int missing = 0;
    int fault = 0;
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0);
    g_b.sensor_status[0] = HOM_SENS_ABSENT;
    g_b.sensor_status[2] = HOM_SENS_ERROR;
    g_b.servo_status[1] = HOM_SERVO_NOREPLY;
    g_b.hw_error[4] = 0x04; /* overheating */
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 1000 && rc == HOM_RUNNING; n++) {
        rc = bench_step(&g_b, &g_h);
        assert_int_equal(g_b.out.changed, 0); /* never any motion */
    }
    assert_int_equal(rc, -HOM_F_PREFLIGHT);
    while (hom_event_pop(&g_h, &ev)) {
        if (ev.type == HOM_EV_MISSING) {
            missing++;
            if (ev.code == HOM_DEV_SENSOR) {
                assert_true(ev.index == 0 || ev.index == 2);
                assert_int_equal(ev.a, ev.index == 0 ? 1 : 3);
            } else {
                assert_int_equal(ev.code, HOM_DEV_SERVO);
                assert_true(ev.index == 1 || ev.index == 4);
                assert_int_equal(ev.a, ev.index == 1 ? 2 : 4);
                if (ev.index == 4) {
                    assert_int_equal(ev.b, 0x04);
                }
            }
        } else if (ev.type == HOM_EV_FAULT) {
            fault = 1;
            assert_int_equal(ev.code, HOM_F_PREFLIGHT);
            assert_int_equal(ev.b, 4);
        }
    }
    assert_int_equal(missing, 4);
    assert_true(fault);
}

static void test_slack_never_confirmed(void **state)
{
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    int rc = HOM_RUNNING;
    int n;
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0xFFFFFF00u); /* the clock wraps during the run */
    g_b.drift_per_sample = 300;    /* the field keeps moving */
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 20000 && rc == HOM_RUNNING; n++) {
        rc = bench_step(&g_b, &g_h);
    }
    assert_int_equal(rc, -HOM_F_SLACK);
    assert_int_equal(g_h.steps, g_h.cfg.slack_max_steps);
}

static void test_steady_field_reaches_tendon_phase_across_wrap(void **state)
{
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    hom_event_t ev;
    int n;
    int tendon_phase = 0;
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0xFFFFFF00u);
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 3000 && !tendon_phase; n++) {
        assert_int_equal(bench_step(&g_b, &g_h), HOM_RUNNING);
        while (hom_event_pop(&g_h, &ev)) {
            if (ev.type == HOM_EV_PHASE && ev.code == HOM_PH_TENDON) {
                tendon_phase = 1;
            }
        }
    }
    assert_true(tendon_phase);
    /* the field never changes here: the take-up finds no engagement */
    for (n = 0; n < 20000 && g_h.fault == HOM_F_NONE; n++) {
        (void)bench_step(&g_b, &g_h);
    }
    assert_int_equal(g_h.fault, HOM_F_NO_ENGAGEMENT);
}

static void test_servo_droop_counts_as_arrived(void **state)
{
    /* position control without integral action stops short under load: a
     * servo still for 100 ms within a few ticks of its goal has arrived */
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    hom_event_t ev;
    int n;
    int tendon_phase = 0;
    (void)state;
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0);
    g_b.droop = 3;
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 5000 && !tendon_phase; n++) {
        assert_int_equal(bench_step(&g_b, &g_h), HOM_RUNNING);
        while (hom_event_pop(&g_h, &ev)) {
            tendon_phase |= ev.type == HOM_EV_PHASE && ev.code == HOM_PH_TENDON;
        }
    }
    assert_true(tendon_phase);
    assert_true(n > 200); /* it did wait for the servos to stand still */
    /* 20 ticks short is not arrived: the release never completes */
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0);
    g_b.droop = 20;
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 10000 && g_h.fault == HOM_F_NONE; n++) {
        (void)bench_step(&g_b, &g_h);
    }
    assert_int_equal(g_h.fault, HOM_F_SERVO_STALL);
}

static void test_preflight_from_any_start_time(void **state)
{
    /* the preflight clock starts at the first step, even or odd, wrapping or
     * not: a healthy bench never fails it */
    static const uint32_t starts[] = {0u, 1u, 1000u, 1001u, 0xFFFFFFFEu, 0xFFFFFFF0u};
    tbl_src_t src = src_of(&g_tab);
    hom_cmd_t c = full_cmd();
    unsigned k;
    int n;
    (void)state;
    for (k = 0; k < sizeof starts / sizeof starts[0]; k++) {
        hom_init(&g_h, NULL);
        bench_init(&g_b, starts[k]);
        assert_int_equal(hom_start(&g_h, &src, &c), 0);
        for (n = 0; n < 50 && g_h.moved == 0u; n++) {
            assert_int_equal(bench_step(&g_b, &g_h), HOM_RUNNING);
        }
        assert_true(g_h.moved);
        assert_int_equal(g_h.fault, HOM_F_NONE);
    }
}

static void test_event_queue_overflow(void **state)
{
    static tbl_wide_t big;
    tbl_src_t src = src_of(&big);
    hom_cmd_t c = full_cmd();
    hom_event_t ev;
    uint8_t i;
    int n;
    int popped = 0;
    (void)state;
    big = g_tab;
    big.n_tendons = TBL_MAX_TENDONS;
    big.n_sensors = HOM_MAX_SENSORS;
    for (i = 0; i < TBL_MAX_TENDONS; i++) {
        big.tendons[i] = g_tab.tendons[i % 6u];
    }
    hom_init(&g_h, NULL);
    bench_init(&g_b, 0);
    for (i = 0; i < TBL_MAX_TENDONS; i++) {
        g_b.servo_status[i] = HOM_SERVO_ABSENT;
    }
    src = src_of(&big);
    assert_int_equal(hom_start(&g_h, &src, &c), 0);
    for (n = 0; n < 1000 && g_h.fault == HOM_F_NONE; n++) {
        (void)bench_step(&g_b, &g_h);
    }
    assert_int_equal(g_h.fault, HOM_F_PREFLIGHT);
    while (hom_event_pop(&g_h, &ev)) {
        popped++;
    }
    assert_int_equal(popped, HOM_EV_CAP);
    assert_true(g_h.ev_dropped > 0u);
    assert_int_equal(hom_event_pop(&g_h, &ev), 0);
    assert_int_equal(hom_event_pop(NULL, &ev), 0);
}

static void test_helpers(void **state)
{
    const int32_t v1[3] = {3, 4, 0};
    const int32_t v2[3] = {491200, -491200, 491200};
    const int32_t v3[3] = {0, 0, 0};
    int32_t home;
    int f;
    (void)state;
    assert_int_equal(hom_norm3(v1), 5);
    /* floor(491200 * sqrt 3) = 850783; scaled by 16 beyond 37837 per axis */
    assert_in_range(hom_norm3(v2), 850783 - 32, 850783);
    assert_int_equal(hom_norm3(v3), 0);
    {
        /* seeded random vectors against the exact floor root: exact while
         * every axis is within 37837, else short by less than three scaled units */
        uint32_t x = 12345u;
        int n;
        for (n = 0; n < 20000; n++) {
            int32_t v[3];
            double sum = 0.0;
            uint32_t top = 0, got, want;
            int a, sh = 0;
            for (a = 0; a < 3; a++) {
                x = x * 1103515245u + 12345u;
                v[a] = (int32_t)((x >> 8) % 1000001u) - 500000;
                if (n % 2 == 0) {
                    v[a] /= 16; /* the exact range */
                }
                sum += (double)v[a] * v[a];
                top |= (uint32_t)(v[a] < 0 ? -v[a] : v[a]);
            }
            while ((top >> sh) > 37837u) {
                sh++;
            }
            want = (uint32_t)floor(sqrt(sum));
            got = hom_norm3(v);
            if (sh == 0) {
                assert_int_equal(got, want);
            } else {
                assert_in_range(got, want > (3u << sh) ? want - (3u << sh) : 0u, want);
            }
        }
    }
    for (f = 0; f < HOM_F_COUNT; f++) {
        assert_string_not_equal(hom_fault_name(f), "unknown");
    }
    assert_string_equal(hom_fault_name(HOM_F_TRAVEL_LIMIT), "travel_limit");
    assert_string_equal(hom_fault_name(-1), "unknown");
    assert_string_equal(hom_fault_name(HOM_F_COUNT), "unknown");
    hom_init(&g_h, NULL);
    assert_int_equal(hom_home(&g_h, 0, &home), HOM_E_ARG);
    assert_int_equal(hom_home(NULL, 0, &home), HOM_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_start_errors),
        cmocka_unit_test(test_idle_step_does_nothing),
        cmocka_unit_test(test_abort_before_motion_moves_nothing),
        cmocka_unit_test(test_abort_releases_on_next_step),
        cmocka_unit_test(test_preflight_names_every_missing_device),
        cmocka_unit_test(test_slack_never_confirmed),
        cmocka_unit_test(test_steady_field_reaches_tendon_phase_across_wrap),
        cmocka_unit_test(test_servo_droop_counts_as_arrived),
        cmocka_unit_test(test_preflight_from_any_start_time),
        cmocka_unit_test(test_event_queue_overflow),
        cmocka_unit_test(test_helpers),
        cmocka_unit_test(test_slack_margin_covers_the_pull_of_other_tendons),
    };
    return cmocka_run_group_tests(tests, group_setup, NULL);
}
