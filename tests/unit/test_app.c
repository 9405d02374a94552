/*
 * lib/app on a native board: the real modules against the XL430, ICM-20948
 * and TCA9548A models and the robot plant (tests/unit/support/app_bench.h).
 */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "app/app_priv.h"
#include "app_bench.h"
#include "app_steps.h"

static void test_boot_banner_and_ready(void **state)
{
    (void)state;
    boot(&g_b, 1);
    assert_non_null(strstr(g_line, "table=paper_2seg"));
    assert_int_equal(app_bench_field(g_line, "sensors", -1), 3);
    assert_int_equal(app_bench_field(g_line, "servos", -1), 6);
    assert_non_null(strstr(g_line, "homes=none"));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 0);
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
    assert_true(g_b.kicks > 10u);
    cmd(&g_b, "version", "ok");
    cmd(&g_b, "rehome", "error:12 no homes: calibrate first");
    cmd(&g_b, "home", "error:12 no homes: calibrate first");
    cmd(&g_b, "cal 5", "error:16 tension outside the table grid");
    cmd(&g_b, "cal 0.8 6", "error:15 no such tendon");
    /* the servo bus runs: every servo's position is fresh */
    assert_int_equal(g_b.app.bus.seen, 0x3F);
    /* idle LED: a short blip every 2 s */
    assert_int_equal(app_led_pattern(&g_b.app), APP_LED_IDLE);
}

static void test_no_table(void **state)
{
    (void)state;
    boot(&g_b, 0);
    assert_non_null(strstr(g_line, "table=none"));
    cmd(&g_b, "cal", "error:11 no valid lookup table");
    cmd(&g_b, "table", "error:11 no valid lookup table");
    press(&g_b, 200);
    assert_true(app_bench_wait_line(&g_b, "<fault ", g_line, sizeof g_line, 100));
    assert_non_null(strstr(g_line, "reason=refused"));
    assert_int_equal(app_bench_field(g_line, "error", 0), 11);
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
}

/* Press the button: every tendon is homed, stored and reported; then a power
 * cycle offers the quick re-home, which finds the same homes. */
static void test_button_calibrates_and_stores(void **state)
{
    int32_t first[TBL_MAX_TENDONS];
    uint8_t i, results = 0;
    store_homes_t h;
    (void)state;
    boot(&g_b, 1);
    press(&g_b, 100);
    /* the first run of a power cycle with nothing known saves its fresh
     * engagement windows before anything moves */
    assert_int_not_equal(g_b.app.state, APP_ST_CAL);
    assert_true(app_bench_wait_line(&g_b, "<progress state=start", g_line, sizeof g_line, 1000));
    assert_int_equal(g_b.app.state, APP_ST_CAL);
    assert_int_equal(app_led_pattern(&g_b.app), APP_LED_RUN);
    for (;;) {
        assert_true(app_bench_wait_line(&g_b, "<", g_line, sizeof g_line, 20000));
        assert_null(strstr(g_line, "<fault"));
        if (strncmp(g_line, "<result ", 8) == 0) {
            long t = app_bench_field(g_line, "tendon", -1);
            double truth;
            assert_true(t >= 0 && t < 6);
            assert_int_equal(plant_true_home(&g_b.cfg, (uint8_t)t, 800, &truth), 0);
            assert_true(fabs((double)app_bench_field(g_line, "home", 0) - truth) <= 2.0);
            assert_true(app_bench_field(g_line, "travel_um", 0) > 0);
            assert_true(app_bench_field(g_line, "time_ms", 0) > 0);
            assert_non_null(strstr(g_line, "dB_uT="));
            results++;
        }
        if (strncmp(g_line, "<done ", 6) == 0) {
            break;
        }
    }
    assert_int_equal(results, 6);
    assert_non_null(strstr(g_line, "mode=full"));
    assert_int_equal(app_bench_field(g_line, "count", 0), 1);
    assert_int_equal(app_led_pattern(&g_b.app), APP_LED_DONE);
    /* the records reach the EEPROM once idle */
    app_bench_run_ms(&g_b, 2000);
    assert_int_equal(store_homes_load(&g_b.app.rec.store, g_b.table.table_id, &h), 0);
    assert_int_equal(h.valid_mask, 0x3F);
    assert_int_equal(h.cal_count, 1);
    assert_int_equal(h.tension_mN, 800);
    assert_int_equal(store_hist_count(&g_b.app.rec.store), 1);
    for (i = 0; i < 6; i++) {
        first[i] = h.t[i].home_ticks;
        /* every tendon taut at its home (together they load each other) */
        assert_true(app_bench_tension(&g_b, i) > 0.3);
    }
    cmd(&g_b, "history", "ok");
    cmd(&g_b, "status", "ok");

    /* power cycle: the servos forget their turns, the app recovers the homes */
    app_bench_restart(&g_b, 1);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_non_null(strstr(g_line, "homes=stored"));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 1);
    cmd(&g_b, "rehome", "ok");
    assert_true(app_bench_wait_line(&g_b, "<done ", g_line, sizeof g_line, 20000));
    assert_non_null(strstr(g_line, "mode=quick"));
    app_bench_run_ms(&g_b, 2000);
    assert_int_equal(store_homes_load(&g_b.app.rec.store, g_b.table.table_id, &h), 0);
    assert_int_equal(h.cal_count, 2);
    for (i = 0; i < 6; i++) {
        double truth;
        int32_t shaft = (int32_t)lround(xl430_shaft_ticks(&g_b.servo[i]));
        assert_int_equal(plant_true_home(&g_b.cfg, i, 800, &truth), 0);
        /* the servo rests at its home: shaft (plant frame) near the truth */
        assert_true(fabs((double)shaft - truth) <= 2.0);
        (void)first;
    }
    /* a spool turned by hand while the board was off: the homes are not used */
    app_bench_run_ms(&g_b, 1500);
    g_b.shaft0[3] -= 1500.0;
    g_b.servo[3].shaft += 1500.0;
    app_bench_restart(&g_b, 1);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_non_null(strstr(g_line, "homes=moved"));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 0);
    cmd(&g_b, "rehome", "error:22 spool turned while powered off: full calibration needed");
    cmd(&g_b, "home", "error:22 spool turned while powered off: full calibration needed");
}

/* A board that counts presses itself (bits 1-7 of its button byte): a press
 * that came and went between two passes, never seen down by the debounce,
 * starts a run; the count of a release the debounce saw (here the end of a
 * long press that aborted) starts nothing. */
static void test_board_counted_press(void **state)
{
    (void)state;
    boot(&g_b, 1);
    g_b.button = 2; /* one press counted, the level never seen down */
    app_bench_run_ms(&g_b, 50);
    assert_int_equal(g_b.app.state, APP_ST_CAL);
    g_b.button = 3; /* held: the debounce sees it and aborts after the long press */
    app_bench_run_ms(&g_b, 2200);
    assert_true(app_bench_wait_line(&g_b, "<fault ", g_line, sizeof g_line, 100));
    assert_non_null(strstr(g_line, "reason=aborted"));
    g_b.button = 4; /* released: the board counts that press too */
    app_bench_run_ms(&g_b, 400);
    assert_int_equal(g_b.app.state, APP_ST_FAULT);
    g_b.button = 6; /* a later press between two passes: a run again */
    assert_true(app_bench_wait_line(&g_b, "<progress state=start", g_line, sizeof g_line, 1000));
}

/* Missing devices are named before any motion and refuse the calibration. */
static void test_missing_sensor_and_servo(void **state)
{
    (void)state;
    assert_int_equal(app_bench_init(&g_b, 1), 0);
    /* sensor 1 unplugged, servo of tendon 4 (ID 5) silent: rebuild the bus */
    g_b.icm[1].present = 0;
    dxl_fakebus_init(&g_b.bus, 1000000u, 10);
    for (uint8_t i = 0; i < 6; i++) {
        if (i != 4) {
            dxl_fakebus_add(&g_b.bus, &g_b.servo[i]);
        }
    }
    assert_true(app_bench_wait_line(&g_b, "<missing dev=sensor", g_line, sizeof g_line, 4000));
    assert_int_equal(app_bench_field(g_line, "index", -1), 1);
    assert_true(app_bench_wait_line(&g_b, "<missing dev=servo", g_line, sizeof g_line, 100));
    assert_int_equal(app_bench_field(g_line, "id", -1), 5);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 100));
    assert_int_equal(app_bench_field(g_line, "sensors", -1), 2);
    assert_int_equal(app_bench_field(g_line, "servos", -1), 5);
    /* `cal` brings the devices up again once before it refuses */
    app_bench_send(&g_b, "cal");
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    reply(&g_b, "error:13 sensor missing or faulty", 4000);
    g_b.icm[1].present = 1; /* plugged in again: the sensor set re-inits it */
    app_bench_run_ms(&g_b, 1500);
    cmd(&g_b, "cal", "error:14 servo missing or faulty");
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
    for (uint8_t i = 0; i < 6; i++) {
        assert_true(app_bench_tension(&g_b, i) < 0.001);
    }
    /* the servo answers again: the next `cal` finds it in the new bring-up
     * and the calibration runs, with no `scan` or power cycle first */
    dxl_fakebus_add(&g_b.bus, &g_b.servo[4]);
    cmd(&g_b, "cal", "ok");
    assert_true(app_bench_wait_line(&g_b, "<done mode=full", g_line, sizeof g_line, 30000));
}

/* Listings go out a line a main-loop pass and are answered after the last:
 * written at once they held the loop 13-73 ms at rest. Each is complete and
 * in order. */
static void test_listings_one_line_a_pass(void **state)
{
    static const struct {
        const char *cmd, *kind;
        int lines;
    } want[] = {
        {"table", "<tendon ", 6},   {"get", "<setting ", STORE_SETTING_COUNT},
        {"sensors", "<sensor ", 3}, {"servos pos", "<servo ", 6},
        {"servos", "<servo ", 6},   {"status", "<home ", 0},
        {"history", "<hist ", 0},
    };
    (void)state;
    boot(&g_b, 1);
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        int lines = 0, passes = 0, done = 0, next = 0;
        app_bench_send(&g_b, want[k].cmd);
        while (!done && passes < 2000) {
            int in_pass = 0;
            app_bench_step(&g_b);
            passes++;
            while (con_fake_line(&g_b.con, g_line, sizeof g_line)) {
                if (strncmp(g_line, want[k].kind, strlen(want[k].kind)) == 0) {
                    /* items in order, one a pass */
                    long i = app_bench_field(
                        g_line,
                        strcmp(want[k].kind, "<setting ") == 0
                            ? "none"
                            : (strcmp(want[k].kind, "<sensor ") == 0 ? "index" : "tendon"),
                        next);
                    assert_int_equal(i, next);
                    next++;
                    lines++;
                    in_pass++;
                }
                done |= strcmp(g_line, "ok") == 0;
                assert_null(strstr(g_line, "error:"));
            }
            assert_true(in_pass <= 1);
        }
        assert_true(done);
        assert_int_equal(lines, want[k].lines);
    }
}

/* Settings: get/set/save survive a restart; bad names and values refused. */
static void test_settings(void **state)
{
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "set cal_tension 900", "ok");
    cmd(&g_b, "set nope 1", "error:17 unknown setting");
    cmd(&g_b, "set cal_tension 1", "error:16 tension outside the table grid");
    cmd(&g_b, "set filter_k 99", "error:18 setting value out of range");
    /* inside the setting's range but outside the table's grid (200..1500) */
    cmd(&g_b, "set cal_tension 100", "error:16 tension outside the table grid");
    cmd(&g_b, "set cal_tension 1600", "error:16 tension outside the table grid");
    cmd(&g_b, "save", "ok");
    app_bench_restart(&g_b, 0);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    app_bench_send(&g_b, "get cal_tension");
    assert_true(app_bench_wait_line(&g_b, "<setting ", g_line, sizeof g_line, 100));
    assert_int_equal(app_bench_field(g_line, "value", 0), 900);
    reply(&g_b, "ok", 100);
    cmd(&g_b, "get", "ok");
    cmd(&g_b, "sensors", "ok");
    cmd(&g_b, "servos pos", "ok");
    cmd(&g_b, "servos", "ok");
    /* the approach speeds and the samples per fine point reach the homing */
    cmd(&g_b, "set filter_k 4", "ok");
    cmd(&g_b, "set approach_slow 30", "ok");
    cmd(&g_b, "set approach_fast 90", "ok");
    /* above the XL430's Velocity Limit a servo would drop the goal silently */
    cmd(&g_b, "set approach_fast 266", "error:18 setting value out of range");
    cmd(&g_b, "cal 0.9 0", "ok");
    assert_int_equal(g_b.app.u.hom.cfg.avg_samples, 4);
    assert_int_equal(g_b.app.u.hom.cfg.v_fine, 30);
    assert_int_equal(g_b.app.u.hom.cfg.v_fast, 90);
    assert_int_equal(g_b.app.u.hom.tension_mN, 900);
    (void)con_rt_byte(&g_b.rt, '!');
    assert_true(app_bench_wait_line(&g_b, "<fault ", g_line, sizeof g_line, 200));
    assert_non_null(strstr(g_line, "reason=aborted"));
}

/* The rehome= of `status` (1: a press re-homes quickly). */
static int status_rehome(void)
{
    int v;
    app_bench_send(&g_b, "status");
    assert_true(app_bench_wait_line(&g_b, "<status ", g_line, sizeof g_line, 200));
    v = app_bench_field(g_line, "rehome", -1);
    reply(&g_b, "ok", 200);
    return v;
}

/* Waits for a run's start and checks its mode and tension, then its <done>. */
static void run_at(const char *mode, int tension_mN)
{
    char want[32];
    assert_true(app_bench_wait_line(&g_b, "<progress state=start", g_line, sizeof g_line, 4000));
    snprintf(want, sizeof want, "mode=%s", mode);
    assert_non_null(strstr(g_line, want));
    assert_int_equal(app_bench_field(g_line, "tension_mN", -1), tension_mN);
    assert_true(app_bench_wait_line(&g_b, "<done mode=", g_line, sizeof g_line, 30000));
    app_bench_run_ms(&g_b, 3000); /* homes and rest positions written */
}

/* The button works at cal_tension: its quick re-home is offered only while
 * the recovered homes were calibrated at that tension. A press after `set
 * cal_tension 800` once re-homed at the stored homes' 1.5 N, and the robot
 * stood at almost twice the tension asked. `rehome` still re-homes at the
 * homes' own tension. */
static void test_press_works_at_cal_tension(void **state)
{
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "cal 1.2", "ok");
    run_at("full", 1200);
    app_bench_restart(&g_b, 1);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_non_null(strstr(g_line, "homes=stored"));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 0); /* cal_tension 800 */
    cmd(&g_b, "set cal_tension 1200", "ok");
    assert_int_equal(status_rehome(), 1);
    cmd(&g_b, "set cal_tension 900", "ok");
    assert_int_equal(status_rehome(), 0);
    press(&g_b, 100);
    run_at("full", 900);
    /* a run's new homes are no recovered ones: no offer until the next boot */
    assert_int_equal(status_rehome(), 0);
    app_bench_restart(&g_b, 1); /* cal_tension was not saved: 800 again */
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 0);
    cmd(&g_b, "rehome", "ok");
    run_at("quick", 900);
    cmd(&g_b, "set cal_tension 900", "ok");
    cmd(&g_b, "save", "ok");
    app_bench_restart(&g_b, 1);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 1);
    press(&g_b, 100);
    run_at("quick", 900);
}

/* Runs `cal 0.8 0` (tendon 0 alone) to its <done>; returns tendon 0's home
 * error against the plant's truth in ticks and checks the target word of
 * <result> and <done>. */
static double cal_tendon0(const char *target)
{
    double truth, err = 1e9;
    cmd(&g_b, "cal 0.8 0", "ok");
    for (;;) {
        assert_true(app_bench_wait_line(&g_b, "<", g_line, sizeof g_line, 20000));
        assert_null(strstr(g_line, "<fault"));
        if (strncmp(g_line, "<result ", 8) == 0) {
            assert_int_equal(plant_true_home(&g_b.cfg, 0, 800, &truth), 0);
            err = (double)app_bench_field(g_line, "home", 0) - truth;
            assert_non_null(strstr(g_line, target));
        }
        if (strncmp(g_line, "<done ", 6) == 0) {
            assert_non_null(strstr(g_line, target));
            return err;
        }
    }
}

/* target_mode 1: the first absolute run captures the ambient and lands where
 * the delta mode does; after the ambient moves, the next absolute run reuses
 * the stale capture and misses (50 uT along -z: hh_closedloop measures 6.6
 * ticks too far, 88 mN too much tension); the delta mode does not; `set target_mode` makes the next
 * run capture again. */
static void test_absolute_target_mode(void **state)
{
    uint8_t k;
    double e;
    (void)state;
    boot(&g_b, 1);
    assert_true(fabs(cal_tendon0("target=delta")) <= 2.0);
    assert_int_equal(g_b.app.run.amb_ok, 0);
    cmd(&g_b, "set target_mode 1", "ok");
    assert_true(fabs(cal_tendon0("target=abs")) <= 2.0);
    assert_int_equal(g_b.app.run.amb_ok, 1);
    for (k = 0; k < g_b.cfg.n_sensors; k++) {
        g_b.plant.extra_uT[k][2] = -50.0; /* the bench moved, iron came near */
    }
    e = cal_tendon0("target=abs");
    print_message("absolute mode, ambient moved 50 uT: home error %.2f ticks\n", e);
    assert_true(e >= 4.0);
    cmd(&g_b, "set target_mode 0", "ok");
    assert_true(fabs(cal_tendon0("target=delta")) <= 2.0);
    cmd(&g_b, "set target_mode 1", "ok");
    assert_int_equal(g_b.app.run.amb_ok, 0);
    assert_true(fabs(cal_tendon0("target=abs")) <= 2.0);
}

/* Model-free learning: release (baseline), a weight pulls tendon 1 to 0.8 N,
 * learn records |dB|; the table shows it, and it overrides the compiled one. */
static void test_learn_with_weight(void **state)
{
    double ticks;
    long learned;
    tbl_tendon_t eff;
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "learn 1 0.8", "error:12 no homes: calibrate first"); /* no baseline yet */
    cmd(&g_b, "release", "ok");
    assert_true(app_bench_wait_line(&g_b, "<done mode=release", g_line, sizeof g_line, 3000));
    assert_int_equal(app_bench_field(g_line, "baseline", 0), 1);
    /* the release gave every tendon a fresh engagement window, which goes
     * to the EEPROM now (a power cycle then keeps it): meanwhile `learn`,
     * which shares the record's storage, answers busy */
    cmd(&g_b, "learn 1 0.75", "error:9 busy");
    for (int ms = 0; ms < 1000 && (store_busy(&g_b.app.rec.store) || g_b.app.rec.save_due); ms++) {
        app_bench_run_ms(&g_b, 1);
    }
    assert_false(store_busy(&g_b.app.rec.store));
    cmd(&g_b, "learn 1 0.75", "error:16 tension outside the table grid");
    /* no weight hung: the field has not changed, and the reading is refused
     * rather than stored (it would make every later calibration fault) */
    cmd(&g_b, "learn 1 0.8",
        "error:25 implausible reading: not above noise or not rising with "
        "tension");
    assert_int_equal(g_b.app.learn.mask, 0);
    assert_int_equal(plant_true_home(&g_b.cfg, 1, 800, &ticks), 0);
    g_b.weight_on = 1;
    g_b.weight_tendon = 1;
    g_b.weight_ticks = ticks;
    app_bench_run_ms(&g_b, 100);
    app_bench_send(&g_b, "learn 1 0.8");
    assert_true(app_bench_wait_line(&g_b, "<learned ", g_line, sizeof g_line, 1000));
    learned = app_bench_field(g_line, "tendon", -1);
    assert_int_equal(learned, 1);
    reply(&g_b, "ok", 100);
    g_b.weight_on = 0;
    /* learned |dB| close to the plant-made table's target at 800 mN (grid 4) */
    {
        uint32_t want = g_b.table.tendons[1].target_cuT[4];
        app_bench_run_ms(&g_b, 1000);
        assert_int_equal(tbl_tendon(&g_b.app.htab, 1, &eff), 0);
        /* learned (stored in whole LSB: it may round to the table's value) */
        assert_true((g_b.app.learn.mask & (1u << 1)) != 0u);
        assert_int_equal(eff.target_cuT[4] % TBL_CUT_PER_LSB, 0);
        assert_true(labs((long)eff.target_cuT[4] - (long)want) < (long)want / 20);
        assert_int_equal(eff.target_cuT[3], g_b.table.tendons[1].target_cuT[3]);
    }
    cmd(&g_b, "table", "ok");
    /* the same weight learned as a higher tension would not rise with it */
    g_b.weight_on = 1;
    app_bench_run_ms(&g_b, 100);
    cmd(&g_b, "learn 1 0.9",
        "error:25 implausible reading: not above noise or not rising with "
        "tension");
    g_b.weight_on = 0;
    /* forget: the compiled target applies again, and survives a restart */
    cmd(&g_b, "forget 12", "error:15 no such tendon");
    cmd(&g_b, "forget x", "error:15 no such tendon");
    cmd(&g_b, "forget 1", "ok");
    assert_int_equal(g_b.app.learn.mask, 0);
    assert_int_equal(tbl_tendon(&g_b.app.htab, 1, &eff), 0);
    assert_int_equal(eff.target_cuT[4], g_b.table.tendons[1].target_cuT[4]);
    cmd(&g_b, "forget all", "ok"); /* nothing left: at once */
    app_bench_restart(&g_b, 0);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_int_equal(g_b.app.learn.mask, 0);
}

/* `learn T N DB`: a host-computed target installed as a learned one (the record,
 * checks and table override of `learn`), answered once written, kept over a
 * restart; implausible values and off-grid tensions refused. */
static void test_learn_installs_a_given_target(void **state)
{
    char line[64];
    tbl_tendon_t eff;
    uint32_t want = g_b.table.tendons[1].target_cuT[4] * 21u / 20u; /* 5 % above the table */
    (void)state;
    boot(&g_b, 1);
    snprintf(line, sizeof line, "learn 1 0.8 %lu.%02lu", (unsigned long)(want / 100u),
             (unsigned long)(want % 100u));
    cmd(&g_b, "learn 1 0.75 100", "error:16 tension outside the table grid");
    cmd(&g_b, "learn 6 0.8 100", "error:15 no such tendon");
    cmd(&g_b, "learn 1 0.8 0.1",
        "error:25 implausible reading: not above noise or not rising with tension");
    cmd(&g_b, "learn 1 0.8 x", "error:2 bad number");
    assert_int_equal(g_b.app.learn.mask, 0);
    app_bench_send(&g_b, line);
    assert_true(app_bench_wait_line(&g_b, "<learned ", g_line, sizeof g_line, 1000));
    assert_int_equal(app_bench_field(g_line, "tendon", -1), 1);
    assert_int_equal(app_bench_field(g_line, "grid", -1), 4);
    reply(&g_b, "ok", 3000); /* once the record is written */
    assert_int_equal(g_b.app.learn.mask, 1u << 1);
    assert_int_equal(tbl_tendon(&g_b.app.htab, 1, &eff), 0);
    /* stored in the table's unit: the nearest whole LSB */
    assert_int_equal(eff.target_cuT[4], (uint32_t)tbl_lsb_of_cuT(want) * TBL_CUT_PER_LSB);
    assert_int_equal(eff.target_cuT[3], g_b.table.tendons[1].target_cuT[3]);
    /* a higher tension must get a higher target */
    snprintf(line, sizeof line, "learn 1 0.9 %lu.%02lu", (unsigned long)(want / 100u),
             (unsigned long)(want % 100u));
    cmd(&g_b, line, "error:25 implausible reading: not above noise or not rising with tension");
    app_bench_restart(&g_b, 0);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_int_equal(g_b.app.learn.mask, 1u << 1);
    assert_int_equal(tbl_tendon(&g_b.app.htab, 1, &eff), 0);
    assert_int_equal(eff.target_cuT[4], (uint32_t)tbl_lsb_of_cuT(want) * TBL_CUT_PER_LSB);
    cmd(&g_b, "forget 1", "ok");
    assert_int_equal(g_b.app.learn.mask, 0);
}

/* The pace of the AVR (about 2 ms per pass) and a start at an even
 * millisecond, which the homing's preflight clock must survive. */
static void test_slow_loop_single_tendon(void **state)
{
    double truth;
    (void)state;
    boot(&g_b, 1);
    app_bench_run_ms(&g_b, 3);
    /* align on an even millisecond with the default pass, then slow down:
     * 2 ms passes alone never change the parity */
    while (((g_b.now_us / 1000u) & 1u) != 0u) {
        app_bench_step(&g_b);
    }
    g_b.loop_us = 2000;
    app_bench_send(&g_b, "cal 0.8 2");
    assert_true(app_bench_wait_line(&g_b, "<result ", g_line, sizeof g_line, 20000));
    assert_int_equal(app_bench_field(g_line, "tendon", -1), 2);
    assert_int_equal(plant_true_home(&g_b.cfg, 2, 800, &truth), 0);
    assert_true(fabs((double)app_bench_field(g_line, "home", 0) - truth) <= 2.0);
    assert_true(app_bench_wait_line(&g_b, "<done ", g_line, sizeof g_line, 10000));
    assert_non_null(strstr(g_line, "mode=single"));
}

/* While a run pulls a tendon, the position reads ask its servo alone but
 * every APP_FOCUS_READS + 1-th asks every servo (app_bus.c, focus()): the
 * pulled servo is read most, the others often enough that no position
 * goes stale, and a read of every servo still ends each silence check. */
static void test_pulled_servo_read_alone(void **state)
{
    uint16_t n_pulled, n_other;
    uint32_t oldest = 0, t;
    uint8_t i, k;
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "cal", "ok");
    assert_true(app_bench_wait_line(&g_b, "<progress state=engaged tendon=0", g_line, sizeof g_line,
                                    20000));
    n_pulled = g_b.servo[0].replies;
    n_other = g_b.servo[3].replies;
    for (t = 0; t < 40u; t++) {
        app_bench_run_ms(&g_b, 1);
        assert_int_equal(hom_pulling(&g_b.app.u.hom, &k), 1);
        assert_int_equal(k, 0);
        for (i = 0; i < g_b.cfg.n_tendons; i++) {
            uint32_t age =
                (uint16_t)((uint16_t)g_b.app.u.hom.now_ms - g_b.app.u.hom.tendon[i].servo_ok_ms);
            oldest = age > oldest ? age : oldest;
        }
        assert_true((uint16_t)(g_b.app.u.hom.now_ms - g_b.app.bus.t_all_ok) < 10u);
    }
    n_pulled = (uint16_t)(g_b.servo[0].replies - n_pulled);
    n_other = (uint16_t)(g_b.servo[3].replies - n_other);
    print_message("40 ms of a fine approach: %u replies of the pulled servo, %u of another, "
                  "oldest position %u ms\n",
                  n_pulled, n_other, (unsigned)oldest);
    assert_true(n_other >= 5u);
    assert_true(n_pulled >= 2u * n_other);
    assert_true(oldest < 10u);
}

/* EEPROM writes only while nothing moves: a run asked for while the records
 * of the previous one are being written starts after them, and no byte is
 * written during it. After a power cycle with a spool turned by hand, the
 * homes are not trusted: `rehome` answers error:22. */
static void test_store_idle_only_and_moved_spool(void **state)
{
    uint32_t writes;
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "cal 0.8 0", "ok");
    assert_true(app_bench_wait_line(&g_b, "<done ", g_line, sizeof g_line, 20000));
    app_bench_send(&g_b, "cal 0.8 1"); /* held until the homes and history are written */
    app_bench_step(&g_b);
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
    reply(&g_b, "ok", 3000);
    assert_int_equal(g_b.app.state, APP_ST_CAL);
    writes = g_b.ee.writes;
    while (g_b.app.state == APP_ST_CAL) {
        app_bench_step(&g_b);
        assert_int_equal(g_b.ee.writes, writes);
    }
    assert_true(app_bench_wait_line(&g_b, "<done ", g_line, sizeof g_line, 100));
    app_bench_run_ms(&g_b, 2000);
    assert_true(g_b.ee.writes > writes);
    assert_int_equal(g_b.ee.violations, 0);
    /* a rest position is known for tendons 0 and 1 only: no quick re-home */
    app_bench_restart(&g_b, 1);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_non_null(strstr(g_line, "homes=stored"));
    assert_int_equal(app_bench_field(g_line, "rehome", -1), 0);
    cmd(&g_b, "rehome", "error:12 no homes: calibrate first");
    /* a spool turned by half a turn while powered off */
    g_b.shaft0[0] -= 2000.0;
    g_b.servo[0].shaft += 2000.0;
    app_bench_restart(&g_b, 1);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_non_null(strstr(g_line, "homes=moved"));
    cmd(&g_b, "home", "error:12 no homes: calibrate first");
}

/* Bounces shorter than the debounce time do nothing; the LED shows the
 * state; a worn EEPROM cell makes `save` fail with error:19. */
static void test_debounce_led_and_eeprom_failure(void **state)
{
    uint32_t changes;
    uint8_t i;
    (void)state;
    assert_int_equal(app_bench_init(&g_b, 1), 0);
    assert_int_equal(app_led_pattern(&g_b.app), APP_LED_BOOT);
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    for (i = 0; i < 10; i++) {
        g_b.button = 1;
        app_bench_run_ms(&g_b, 10);
        g_b.button = 0;
        app_bench_run_ms(&g_b, 10);
    }
    app_bench_run_ms(&g_b, 100);
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
    changes = g_b.led_changes;
    app_bench_run_ms(&g_b, 4100);
    assert_true(g_b.led_changes >= changes + 4u); /* two blips in 4 s */
    assert_true(g_b.kicks >= g_b.app.loops);
    /* a cell of both settings slots ignores writes: the save does not verify */
    g_b.ee.stuck_addr = (int32_t)STORE_ADDR_SETTINGS + 6;
    cmd(&g_b, "set cal_tension 700", "ok");
    app_bench_send(&g_b, "save");
    reply(&g_b, "error:19 EEPROM write failed", 3000);
    g_b.ee.stuck_addr = -1;
    cmd(&g_b, "save", "ok");
    /* a long press while idle releases every tendon and captures the baseline */
    g_b.button = 1;
    assert_true(app_bench_wait_line(&g_b, "<released ", g_line, sizeof g_line, 2200));
    assert_non_null(strstr(g_line, "reason=aborted"));
    g_b.button = 0;
    assert_true(app_bench_wait_line(&g_b, "<done mode=release", g_line, sizeof g_line, 3000));
    assert_int_equal(app_bench_field(g_line, "baseline", 0), 1);
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
}

/* One servo-bus byte in a thousand corrupted, in both directions, from power-up
 * on: a servo that misses a goal to a corrupted sync write is sent it again,
 * and the calibration completes with every home where it belongs. */
static void test_bus_noise_calibrates(void **state)
{
    uint8_t results = 0;
    (void)state;
    assert_int_equal(app_bench_init(&g_b, 1), 0);
    g_b.noise = 1e-3;
    assert_true(app_bench_wait_line(&g_b, "<ready ", g_line, sizeof g_line, 4000));
    assert_int_equal(app_bench_field(g_line, "servos", -1), 6);
    cmd(&g_b, "cal", "ok");
    for (;;) {
        assert_true(app_bench_wait_line(&g_b, "<", g_line, sizeof g_line, 20000));
        assert_null(strstr(g_line, "<fault"));
        if (strncmp(g_line, "<result ", 8) == 0) {
            long t = app_bench_field(g_line, "tendon", -1);
            double truth;
            assert_true(t >= 0 && t < 6);
            assert_int_equal(plant_true_home(&g_b.cfg, (uint8_t)t, 800, &truth), 0);
            assert_true(fabs((double)app_bench_field(g_line, "home", 0) - truth) <= 2.0);
            results++;
        }
        if (strncmp(g_line, "<done ", 6) == 0) {
            break;
        }
    }
    assert_int_equal(results, 6);
    /* the noise did hit the bus, goals included */
    assert_true(g_b.noise_hits > 20u);
    assert_true(g_b.app.bus.dxl.stats.retries > 0u);
}

/* The report words kept as the tail of another word or of the console's
 * texts (app_priv.h) read as themselves. */
static void test_shared_words(void **state)
{
    (void)state;
    assert_string_equal(app_w_version, "version");
    assert_string_equal(app_w_status, "status");
    assert_string_equal(app_w_sensors, "sensors");
    assert_string_equal(app_w_servos, "servos");
    assert_string_equal(app_w_rehome, "rehome");
    assert_string_equal(app_w_release, "release");
    assert_string_equal(app_w_boot, "boot");
    assert_string_equal(app_w_p, "p");
    assert_string_equal(app_w_homes, "homes");
    assert_string_equal(app_w_dB_uT, "dB_uT");
    assert_string_equal(app_w_aborted, "aborted");
    assert_string_equal(app_w_setting, "setting");
    assert_string_equal(app_w_grid, "grid");
    assert_string_equal(app_w_fault, "fault");
    assert_string_equal(app_w_error, "error");
    assert_string_equal(app_w_err, "err");
    assert_string_equal(app_w_id, "id");
    assert_string_equal(app_w_pos, "pos");
    assert_string_equal(app_w_table, "table");
    assert_string_equal(app_w_home, "home");
    assert_string_equal(app_w_released, "released");
    assert_string_equal(app_w_now, "now");
    assert_string_equal(app_w_t, "t");
    assert_string_equal(app_w_tendon, "tendon");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_shared_words),
        cmocka_unit_test(test_boot_banner_and_ready),
        cmocka_unit_test(test_no_table),
        cmocka_unit_test(test_missing_sensor_and_servo),
        cmocka_unit_test(test_listings_one_line_a_pass),
        cmocka_unit_test(test_settings),
        cmocka_unit_test(test_press_works_at_cal_tension),
        cmocka_unit_test(test_absolute_target_mode),
        cmocka_unit_test(test_learn_with_weight),
        cmocka_unit_test(test_learn_installs_a_given_target),
        cmocka_unit_test(test_board_counted_press),
        cmocka_unit_test(test_debounce_led_and_eeprom_failure),
        cmocka_unit_test(test_slow_loop_single_tendon),
        cmocka_unit_test(test_pulled_servo_read_alone),
        cmocka_unit_test(test_store_idle_only_and_moved_spool),
        cmocka_unit_test(test_button_calibrates_and_stores),
        cmocka_unit_test(test_bus_noise_calibrates),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
