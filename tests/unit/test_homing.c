/* Closed-loop tests of the homing state machine against the plant model:
 * accuracy and repeatability at nominal parameters, the modes, and every
 * abort and fault path (all tendons released, a clear event, the travel limit
 * never exceeded). The state machine at its limits (the field while a tendon
 * pulls, targets out of reach, travel limits): test_homing_limits.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "hom_fixture.h"

static plant_run_result_t g_res;
static plant_run_result_t g_res2;

/* Runs with the given fault and checks the common abort contract: the named
 * fault, a fault event, release sent and every tendon slack within 100 ms,
 * and no pull past the travel limit. */
static void expect_fault(plant_fault_t fi, uint8_t index, uint32_t at_ms, hom_fault_t want,
                         int moved)
{
    plant_run_cfg_t rc;
    const hom_event_t *ev;
    uint8_t i;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.seed = 11;
    rc.fault = fi;
    rc.fault_index = index;
    rc.fault_ms = at_ms;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, -(int)want);
    assert_int_equal(g_res.fault, want);
    ev = hom_fix_find_event(&g_res, HOM_EV_FAULT);
    assert_non_null(ev);
    assert_int_equal(ev->code, want);
    if (moved) {
        assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_RELEASED), 1);
        assert_true(g_res.released);
        assert_true(g_res.release_ms <= 100u);
    } else {
        assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_RELEASED), 0);
    }
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_true(g_res.max_past_engage_ticks[i] <= (double)g_res.limit_ticks[i]);
    }
}

static void test_nominal_lands_within_one_tick(void **state)
{
    plant_run_cfg_t rc;
    uint8_t i;
    (void)state;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.seed = 3;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    assert_non_null(hom_fix_find_event(&g_res, HOM_EV_DONE));
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_HOME), g_res.n_tendons);
    assert_true(g_res.end_ms <= 12000u);
    {
        /* each home's residue is signed, within half a tick; some below 0 */
        uint16_t e;
        int below = 0;
        for (e = 0; e < g_res.n_events; e++) {
            if (g_res.events[e].type == HOM_EV_HOME) {
                assert_in_range(g_res.events[e].b + 128, 0, 255);
                below += g_res.events[e].b < 0;
            }
        }
        assert_true(below > 0);
    }
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_true(g_res.have_home[i]);
        assert_true(fabs(g_res.err_ticks[i]) <= 1.0);
        assert_true(fabs(g_res.tension_at_home_N[i] - hom_fix_tab.default_mN * 1e-3) <= 0.02);
        /* the final move left every tendon taut */
        assert_true(g_res.final_tension_N[i] > 0.0);
    }
}

static void test_other_tensions(void **state)
{
    static const uint16_t tensions[] = {400, 1200};
    plant_run_cfg_t rc;
    unsigned k;
    uint8_t i;
    (void)state;
    for (k = 0; k < sizeof tensions / sizeof tensions[0]; k++) {
        unsigned beyond = 0;
        plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
        rc.seed = 5 + k;
        rc.cmd.tension_mN = tensions[k];
        assert_int_equal(plant_run(&rc, &g_res), 0);
        assert_int_equal(g_res.rc, 0);
        /* within a tick; where the field flattens (1100 mN and up) sensor
         * noise rounds a true home that sits near a half tick the other way
         * now and then (docs/homing.md, "Measured"): never by a tick and a
         * half, and not for more than one tendon of a run */
        for (i = 0; i < g_res.n_tendons; i++) {
            assert_true(fabs(g_res.err_ticks[i]) <= 1.5);
            beyond += fabs(g_res.err_ticks[i]) > 1.0 ? 1u : 0u;
        }
        assert_true(beyond <= 1u);
    }
}

static void test_repeatable_from_random_slack(void **state)
{
    plant_run_cfg_t rc;
    int32_t first[TBL_MAX_TENDONS];
    unsigned run;
    uint8_t i;
    (void)state;
    for (run = 0; run < 6; run++) {
        plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
        rc.seed = 100 + run;
        rc.start_min_um = -3000.0; /* 3 mm slack ... */
        rc.start_max_um = 400.0;   /* ... to 0.4 mm past engagement */
        assert_int_equal(plant_run(&rc, &g_res), 0);
        assert_int_equal(g_res.rc, 0);
        for (i = 0; i < g_res.n_tendons; i++) {
            if (run == 0) {
                first[i] = g_res.home[i];
            }
            assert_true(abs(g_res.home[i] - first[i]) <= 1);
            assert_true(fabs(g_res.err_ticks[i]) <= 1.0);
        }
    }
}

/* Positions read only every few ms (a 12-servo bus reads them every 5-7
 * ms), so a field sample often comes before the next read shows where the
 * servo is. A take-up that ran past the moderate goal and is sent back
 * lowers the field with it: no false HOM_F_FIELD_STEP, the homes within
 * 6 ticks (chaos seeds 2010, 12091: the fall read against a stale
 * position; the check before this one fails seed 312 here). Samples reach
 * the homing up to 12 ms after they were taken (the AK09916's period and the
 * ICM-20948 master's poll). */
static void test_slow_position_reads(void **state)
{
    plant_run_cfg_t rc;
    hom_config_t hc;
    unsigned run;
    uint8_t i;
    (void)state;
    hom_config_default(&hc);
    hc.v_fast = 265;
    hc.takeup_per_tick = 255;
    for (run = 0; run < 24; run++) {
        plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
        rc.seed = 300 + run;
        rc.pos_period_ms = (uint8_t)(6u + run % 13u);
        rc.goal_lag_ms = (uint8_t)(4u + run % 17u);
        rc.sample_lag_ms = (uint8_t)(run % 13u);
        rc.hom = &hc;
        rc.start_min_um = -3000.0;
        rc.start_max_um = 400.0;
        assert_int_equal(plant_run(&rc, &g_res), 0);
        if (g_res.rc != 0) {
            print_message("seed %u period %u: fault %u index %u\n", rc.seed, rc.pos_period_ms,
                          g_res.fault, g_res.fault_index);
        }
        assert_int_equal(g_res.rc, 0);
        for (i = 0; i < g_res.n_tendons; i++) {
            /* a goal 15 ms late and samples 8 ms late cost accuracy (seed
             * 328: 4.9 ticks); the bus of 12 servos is faster than that */
            assert_true(fabs(g_res.err_ticks[i]) <= 6.0);
        }
    }
}

/* A quick re-home finds the full run's homes again (within a tick: its near
 * points average fewer samples, HOM_NEAR_DIV_QUICK), on several seeds. */
static void test_quick_rehome_same_homes(void **state)
{
    plant_run_cfg_t rc;
    double start[TBL_MAX_TENDONS];
    uint8_t i;
    unsigned seed;
    (void)state;
    for (seed = 21; seed < 27; seed += 2) {
        plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
        rc.seed = seed;
        assert_int_equal(plant_run(&rc, &g_res), 0);
        assert_int_equal(g_res.rc, 0);
        /* power cycle: the robot stays at its homes, the encoders lose two turns */
        rc.cmd.mode = HOM_MODE_QUICK;
        for (i = 0; i < g_res.n_tendons; i++) {
            rc.cmd.stored_home[i] = g_res.home[i];
            rc.cmd.stored_mask |= (uint16_t)(1u << i);
            start[i] = g_res.home_plant[i];
        }
        rc.start_ticks = start;
        rc.frame_offset = 2 * 4096;
        rc.seed = seed + 1u;
        assert_int_equal(plant_run(&rc, &g_res2), 0);
        assert_int_equal(g_res2.rc, 0);
        for (i = 0; i < g_res.n_tendons; i++) {
            assert_true(g_res2.have_home[i]);
            assert_true(fabs(g_res2.home_plant[i] - g_res.home_plant[i]) <= 1.0);
            assert_true(fabs(g_res2.err_ticks[i]) <= 1.0);
            /* homes are reported in the new encoder frame */
            assert_int_equal(g_res2.home[i], (int32_t)g_res2.home_plant[i] - 2 * 4096);
        }
        /* well under 3/4 of a full run (2/3 before issue 14's last round: the
         * full run's back-offs and far fine points got shorter, the quick run's
         * release and slack check, half a second, did not; 2523 / 4003 ms near,
         * 2980 / 4310 ms with the described geometry) */
        assert_true(g_res2.end_ms * 4u < g_res.end_ms * 3u);
        print_message("quick re-home, seeds %u/%u: %u ms, full %u ms\n", seed, seed + 1u,
                      (unsigned)g_res2.end_ms, (unsigned)g_res.end_ms);
    }
}

/* The homing keeps some times in 16 bits (a servo's last answer and last
 * motion, a sensor's last sample): a run whose clock passes 2^16 and 2^32 ms
 * finds the same homes as one that starts at 0, and a servo that falls
 * silent across the wrap still times out. */
static void test_clock_wrap_same_homes(void **state)
{
    static const uint32_t clock0[3] = {0xFFFFu - 1500u, 0xFFFFFFFFu - 2500u, 0x7FFFu};
    plant_run_cfg_t rc;
    uint8_t i, k;
    (void)state;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.seed = 41;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    for (k = 0; k < 3u; k++) {
        rc.clock0_ms = clock0[k];
        assert_int_equal(plant_run(&rc, &g_res2), 0);
        assert_int_equal(g_res2.rc, 0);
        assert_int_equal(g_res2.end_ms, g_res.end_ms);
        for (i = 0; i < g_res.n_tendons; i++) {
            assert_int_equal(g_res2.home[i], g_res.home[i]);
        }
    }
    /* a servo silent from 1.5 s on, with the clock's low 16 bits wrapping then */
    rc.clock0_ms = 0xFFFFu - 1600u;
    rc.fault = PLANT_FI_SERVO_SILENT;
    rc.fault_index = 2;
    rc.fault_ms = 1500;
    assert_int_equal(plant_run(&rc, &g_res2), 0);
    assert_int_equal(g_res2.fault, HOM_F_SERVO_TIMEOUT);
    assert_int_equal(g_res2.fault_index, 2);
}

static void test_overshoot_recovers(void **state)
{
    /* at the servo's top speed the take-up crosses a low target within one
     * sensor sample: the machine backs off and comes again, from slack
     * (takeup_per_tick lifted: the default ties the take-up speed to the
     * short travel of the lowest grid tension, which keeps it from this) */
    plant_run_cfg_t rc;
    hom_config_t hc;
    uint8_t i;
    uint16_t e;
    int backoffs = 0;
    (void)state;
    hom_config_default(&hc);
    hc.v_fast = 265;
    hc.v_moderate = 265;
    hc.takeup_per_tick = 255;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.hom = &hc;
    rc.cmd.tension_mN = hom_fix_tab.grid_mN[0];
    rc.seed = 51;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_true(fabs(g_res.err_ticks[i]) <= 1.0);
    }
    /* engaged once per tendon, yet some tendon went past its target first */
    for (e = 0; e < g_res.n_events; e++) {
        if (g_res.events[e].type == HOM_EV_ENGAGED &&
            (uint32_t)g_res.events[e].b >
                hom_fix_tab.tendons[g_res.events[e].index].target_cuT[0]) {
            backoffs++;
        }
    }
    assert_true(backoffs > 0);
}

static void test_quick_needs_homes(void **state)
{
    plant_run_cfg_t rc;
    (void)state;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.cmd.mode = HOM_MODE_QUICK;
    rc.cmd.stored_mask = 0x1F; /* one missing */
    assert_int_equal(plant_run(&rc, &g_res), PLANT_E_RANGE);
    assert_int_equal(g_res.rc, HOM_E_HOMES);
}

static void test_single_tendon(void **state)
{
    plant_run_cfg_t rc;
    uint8_t i;
    (void)state;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.cmd.mode = HOM_MODE_SINGLE;
    rc.cmd.tendon = 4;
    rc.seed = 31;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_HOME), 1);
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_int_equal(g_res.have_home[i], i == 4);
        if (i != 4) {
            assert_true(g_res.final_tension_N[i] < 1e-6); /* released */
        }
    }
    assert_true(fabs(g_res.err_ticks[4]) <= 1.0);
    assert_true(fabs(g_res.final_tension_N[4] - hom_fix_tab.default_mN * 1e-3) <= 0.03);
    assert_true(g_res.end_ms < 2500u);
}

static void test_dry_run_no_motion(void **state)
{
    plant_run_cfg_t rc;
    double start[TBL_MAX_TENDONS];
    uint8_t i;
    (void)state;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.cmd.mode = HOM_MODE_DRY;
    for (i = 0; i < hom_fix_cfg.n_tendons; i++) {
        start[i] = 0.0; /* slack everywhere */
    }
    rc.start_ticks = start;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_TARGET), g_res.n_tendons);
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_HOME), 0);
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_true(g_res.max_tension_N[i] == 0.0);
    }
    {
        tbl_src_t src;
        tbl_point_t pt;
        src.table = hom_fix_pack(&hom_fix_tab);
        src.copy = tbl_copy_ram;
        assert_int_equal(tbl_target(&src, 0, hom_fix_tab.default_mN, &pt), 0);
        assert_int_equal(hom_fix_find_event(&g_res, HOM_EV_TARGET)->a, (int32_t)pt.target_cuT);
    }
}

static void test_sensor_stops_answering(void **state)
{
    (void)state;
    expect_fault(PLANT_FI_SENSOR_SILENT, 2, 1500, HOM_F_SENSOR_TIMEOUT, 1);
    assert_int_equal(g_res.fault_index, 2);
    assert_int_equal(g_res.fault_dev, HOM_DEV_SENSOR);
    expect_fault(PLANT_FI_SENSOR_ERROR, 0, 900, HOM_F_SENSOR_ERROR, 1);
    assert_int_equal(g_res.fault_index, 0);
}

static void test_servo_times_out(void **state)
{
    (void)state;
    expect_fault(PLANT_FI_SERVO_SILENT, 3, 2000, HOM_F_SERVO_TIMEOUT, 1);
    assert_int_equal(g_res.fault_index, 3);
    assert_int_equal(g_res.fault_dev, HOM_DEV_SERVO);
    expect_fault(PLANT_FI_SERVO_HWERR, 1, 1200, HOM_F_SERVO_ERROR, 1);
    assert_int_equal(g_res.fault_index, 1);
}

/* A servo cut off the bus runs on to the last goal it took. The take-up's
 * goal is a lease of about 30 ms of motion ahead, so one cut off just before
 * its tendon engages stops within the bounded pull (1.25 x the target +
 * 0.1 N), not at the search's end 4 mm on (chaos seed 3008: 3.7 x). */
static void test_servo_cut_off_in_take_up_stops_within_its_lease(void **state)
{
    plant_run_cfg_t rc;
    const hom_event_t *ev = NULL;
    uint16_t k;
    uint8_t i;
    double bound = 1.25 * hom_fix_tab.default_mN * 1e-3 + 0.1;
    (void)state;
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&hom_fix_tab));
    rc.seed = 11;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    for (i = 0; i < g_res.n_tendons; i++) {
        for (k = 0; k < g_res.n_events; k++) {
            if (g_res.events[k].type == HOM_EV_ENGAGED && g_res.events[k].index == i) {
                ev = &g_res.events[k];
            }
        }
        assert_non_null(ev);
        rc.fault = PLANT_FI_SERVO_SILENT;
        rc.fault_index = i;
        rc.fault_ms = ev->t_ms - 15u; /* the take-up, shortly before the engagement */
        assert_int_equal(plant_run(&rc, &g_res2), 0);
        assert_int_equal(g_res2.fault, HOM_F_SERVO_TIMEOUT);
        assert_true(g_res2.max_tension_N[i] <= bound);
        rc.fault = PLANT_FI_NONE;
    }
}

static void test_sensor_saturates(void **state)
{
    (void)state;
    expect_fault(PLANT_FI_SATURATE, 1, 1700, HOM_F_SATURATED, 1);
    assert_int_equal(g_res.fault_index, 1);
}

static void test_field_rate(void **state)
{
    (void)state;
    expect_fault(PLANT_FI_FIELD_JUMP, 0, 1100, HOM_F_FIELD_RATE, 1);
    assert_int_equal(g_res.fault_index, 0);
}

static void test_magnet_missing(void **state)
{
    (void)state;
    /* caught at the baseline, after the release and before any pull */
    expect_fault(PLANT_FI_MAGNET_MISSING, 0, 0, HOM_F_MAGNET_MISSING, 1);
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_ENGAGED), 0);
}

static void test_magnet_missing_no_prediction(void **state)
{
    /* a table without straight-pose predictions: the take-up finds no
     * engagement within its search distance */
    static tbl_wide_t tab;
    plant_run_cfg_t rc;
    uint8_t k;
    (void)state;
    tab = hom_fix_tab;
    for (k = 0; k < tab.n_sensors; k++) {
        memset(tab.sensors[k].b_straight_cuT, 0, sizeof tab.sensors[k].b_straight_cuT);
    }
    plant_run_defaults(&rc, &hom_fix_cfg, hom_fix_pack(&tab));
    rc.fault = PLANT_FI_MAGNET_MISSING;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.fault, HOM_F_NO_ENGAGEMENT);
    assert_int_equal(g_res.fault_index, 0);
    /* release goals go out in the step that gives up; with no field the pull
     * went the whole search distance into tension, so getting back to slack
     * takes that distance at the release speed (docs/homing.md) */
    assert_int_equal(hom_fix_find_event(&g_res, HOM_EV_RELEASED)->t_ms,
                     hom_fix_find_event(&g_res, HOM_EV_FAULT)->t_ms);
    print_message("no-magnet release to slack: %u ms\n", (unsigned)g_res.release_ms);
    assert_true(g_res.released && g_res.release_ms <= 400u);
}

static void test_abort_releases(void **state)
{
    unsigned k;
    static const uint32_t when[] = {200, 800, 1900, 3700};
    (void)state;
    for (k = 0; k < sizeof when / sizeof when[0]; k++) {
        expect_fault(PLANT_FI_ABORT, 0, when[k], HOM_F_ABORTED, 1);
        assert_int_equal(hom_fix_find_event(&g_res, HOM_EV_FAULT)->t_ms, when[k]);
    }
}

static void test_preflight_names_missing(void **state)
{
    const hom_event_t *ev;
    (void)state;
    expect_fault(PLANT_FI_SENSOR_ABSENT, 1, 0, HOM_F_PREFLIGHT, 0);
    ev = hom_fix_find_event(&g_res, HOM_EV_MISSING);
    assert_non_null(ev);
    assert_int_equal(ev->code, HOM_DEV_SENSOR);
    assert_int_equal(ev->index, 1);
    assert_int_equal(ev->a, 1); /* absent */
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_MISSING), 1);
    expect_fault(PLANT_FI_SERVO_ABSENT, 5, 0, HOM_F_PREFLIGHT, 0);
    ev = hom_fix_find_event(&g_res, HOM_EV_MISSING);
    assert_non_null(ev);
    assert_int_equal(ev->code, HOM_DEV_SERVO);
    assert_int_equal(ev->index, 5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nominal_lands_within_one_tick),
        cmocka_unit_test(test_other_tensions),
        cmocka_unit_test(test_repeatable_from_random_slack),
        cmocka_unit_test(test_quick_rehome_same_homes),
        cmocka_unit_test(test_clock_wrap_same_homes),
        cmocka_unit_test(test_overshoot_recovers),
        cmocka_unit_test(test_quick_needs_homes),
        cmocka_unit_test(test_single_tendon),
        cmocka_unit_test(test_dry_run_no_motion),
        cmocka_unit_test(test_sensor_stops_answering),
        cmocka_unit_test(test_servo_times_out),
        cmocka_unit_test(test_servo_cut_off_in_take_up_stops_within_its_lease),
        cmocka_unit_test(test_sensor_saturates),
        cmocka_unit_test(test_field_rate),
        cmocka_unit_test(test_magnet_missing),
        cmocka_unit_test(test_magnet_missing_no_prediction),
        cmocka_unit_test(test_slow_position_reads),
        cmocka_unit_test(test_abort_releases),
        cmocka_unit_test(test_preflight_names_missing),
    };
    const struct CMUnitTest desc_tests[] = {
        cmocka_unit_test(test_nominal_lands_within_one_tick),
        cmocka_unit_test(test_repeatable_from_random_slack),
        cmocka_unit_test(test_quick_rehome_same_homes),
        cmocka_unit_test(test_single_tendon),
        cmocka_unit_test(test_magnet_missing),
        cmocka_unit_test(test_abort_releases),
    };
    int failed = cmocka_run_group_tests_name("near sensors", tests, hom_fix_setup_paper, NULL);
    return failed + cmocka_run_group_tests_name("described geometry", desc_tests,
                                                hom_fix_setup_paper_desc, NULL);
}
