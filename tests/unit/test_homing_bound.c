/* The bounded pull under ambient field steps (docs/homing.md, "Bounded
 * pull"). A step of up to 30 uT per axis on one sensor, at a random moment
 * of a calibration, turns or cancels part of a tendon's own field change.
 * One magnetometer cannot tell it from the tendon: a step against the
 * tendon's field asks for more pull, and where the field flattens near the
 * target a small step asks for much more. The field's own checks end such
 * a run in field_step, but only after the pull (chaos seeds 13456, 19346,
 * 19952: 1.41-2.10 x the target). The homing now never pulls a tendon past
 * its engagement further than the table's travel at 1.25 x the tension +
 * 100 mN; a target beyond that searches for the engagement once more,
 * slowly, then ends in travel_limit. Measured by the plant: the highest
 * tension of each tendon while it was pulled and had no home yet
 * (max_pull_N). Every run here holds 1.25 x the target + 0.1 N. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "hom_fixture.h"
#include "icm20948/icm_set.h"

static plant_cfg_t g_cfg;
static tbl_wide_t g_tab;
static plant_run_result_t g_res;

/* The robots, each loaded (and its table computed) once. */
static const char *const g_names[] = {"paper_2seg.cfg", "c3s9_pass.cfg", "c3s12t3k9ccfb.cfg"};
static plant_cfg_t g_cfgs[3];
static tbl_wide_t g_tabs[3];

static int group_setup(void **state)
{
    unsigned r;
    (void)state;
    for (r = 0; r < 3u; r++) {
        if (hom_fix_load(g_names[r], &g_cfgs[r], &g_tabs[r]) != 0) {
            return -1;
        }
    }
    return 0;
}

static void use_robot(const char *cfg)
{
    unsigned r;
    for (r = 0; r < 3u; r++) {
        if (strcmp(cfg, g_names[r]) == 0) {
            g_cfg = g_cfgs[r];
            g_tab = g_tabs[r];
            return;
        }
    }
    fail_msg("robot %s not loaded", cfg);
}

/* Run `run` of the series s0 on robot `cfg` at tension_mN: bus timing from
 * the run number, and with `step`, an ambient step on a random sensor at a
 * random moment. Returns the worst pull over the bound's share (<= 1: held). */
static double run_one(const char *cfg, uint32_t s0, unsigned run, uint16_t tension_mN, int step)
{
    plant_run_cfg_t rc;
    double bound = 1.25 * tension_mN * 1e-3 + 0.1;
    double worst = 0.0;
    uint8_t i;
    use_robot(cfg);
    plant_run_defaults(&rc, &g_cfg, hom_fix_pack(&g_tab));
    plant_run_scan(&rc, s0, run, g_cfg.n_sensors, g_cfg.n_tendons, step);
    rc.cmd.tension_mN = tension_mN;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    for (i = 0; i < g_res.n_tendons; i++) {
        if (g_res.max_pull_N[i] / bound > worst) {
            worst = g_res.max_pull_N[i] / bound;
        }
    }
    if (worst > 1.0) {
        print_message("%s at %u mN, run %u: %.3f of the bound (%s)\n", cfg, tension_mN, run, worst,
                      hom_fault_name(g_res.fault));
    }
    return worst;
}

/* The runs of the scan that went past the bound before the limit: 3.76 N
 * (2.51 x) on c3s12t3k9ccfb, 2.02 N (1.34 x, bound 1.975 N) on c3s9_pass,
 * each at 1.5 N, each ending in field_step or travel_limit only after the
 * pull. */
static void test_steps_that_pulled_past_the_bound(void **state)
{
    static const struct {
        const char *cfg;
        unsigned run;
    } cases[] = {{"c3s12t3k9ccfb.cfg", 13},
                 {"c3s12t3k9ccfb.cfg", 38},
                 {"c3s12t3k9ccfb.cfg", 60},
                 {"c3s9_pass.cfg", 6},
                 {"c3s9_pass.cfg", 60}};
    unsigned k;
    (void)state;
    for (k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        double w = run_one(cases[k].cfg, 1000u, cases[k].run, 1500u, 1);
        print_message("%s run %u: worst pull %.3f of the bound, %s\n", cases[k].cfg, cases[k].run,
                      w, hom_fault_name(g_res.fault));
        assert_true(w <= 1.0);
    }
}

/* Random steps on three robots at 0.8 and 1.5 N. */
static void test_random_steps_hold_the_bound(void **state)
{
    const char *const *robots = g_names;
    static const uint16_t tensions[] = {800u, 1500u};
    unsigned r, t, run, faults = 0, n = 0;
    double worst = 0.0;
    (void)state;
    for (r = 0; r < 3u; r++) {
        for (t = 0; t < 2u; t++) {
            for (run = 0; run < 4u; run++) {
                double w = run_one(robots[r], 3000u, run, tensions[t], 1);
                worst = w > worst ? w : worst;
                faults += g_res.rc != 0;
                n++;
            }
        }
    }
    print_message("%u runs with a step: %u ended in a fault, worst pull %.3f of the bound\n", n,
                  faults, worst);
    assert_true(worst <= 1.0);
}

/* Undisturbed, the limit never stops a calibration: no travel_limit, every
 * home found, on the robots above at 0.3 and 0.8 N (the engagement found at
 * the take-up's speed may be a third of the travel early, and then the
 * search again finds it). */
static void test_undisturbed_runs_are_not_limited(void **state)
{
    const char *const *robots = g_names;
    static const uint16_t tensions[] = {300u, 800u};
    unsigned r, t, run;
    (void)state;
    for (r = 0; r < 3u; r++) {
        for (t = 0; t < 2u; t++) {
            for (run = 0; run < 4u; run++) {
                double w = run_one(robots[r], 4000u, run, tensions[t], 0);
                if (g_res.rc != 0) {
                    print_message("%s at %u mN run %u: %s\n", robots[r], tensions[t], run,
                                  hom_fault_name(g_res.fault));
                }
                assert_int_equal(g_res.rc, 0);
                assert_true(w <= 1.0);
            }
        }
    }
}

/* An engagement found at the take-up's top speed (265 units, about 40
 * ticks a sample) is the last position seen slack, up to a sample's run
 * short of the real one: the home then lies past the bounded pull's limit
 * measured from it. The tendon goes back to slack and searches for its
 * engagement again, slowly (a second phase event for the tendon), and the
 * run completes with every home where it belongs. (A take-up this fast
 * runs on past the engagement before the moderate speed takes over and
 * breaks the bounded pull by itself: the default ties its speed to the
 * travel, 2 units a tick, for that.) */
static void test_an_early_engagement_is_searched_again(void **state)
{
    plant_run_cfg_t rc;
    hom_config_t hc;
    unsigned run, retakes = 0;
    uint16_t e;
    uint8_t i;
    (void)state;
    use_robot("paper_2seg.cfg");
    for (run = 0; run < 6u; run++) {
        unsigned phases = 0;
        hom_config_default(&hc);
        hc.v_fast = 265;
        hc.takeup_per_tick = 255;
        plant_run_defaults(&rc, &g_cfg, hom_fix_pack(&g_tab));
        rc.hom = &hc;
        rc.cmd.tension_mN = 800;
        rc.seed = 60u + run;
        rc.sample_lag_ms = (uint8_t)(2u * run);
        assert_int_equal(plant_run(&rc, &g_res), 0);
        assert_int_equal(g_res.rc, 0);
        for (e = 0; e < g_res.n_events; e++) {
            phases += g_res.events[e].type == HOM_EV_PHASE && g_res.events[e].code == HOM_PH_TENDON;
        }
        retakes += phases - g_res.n_tendons;
        for (i = 0; i < g_res.n_tendons; i++) {
            assert_true(fabs(g_res.err_ticks[i]) <= 1.0);
        }
    }
    print_message("6 runs at the top take-up speed: %u tendons searched again\n", retakes);
    assert_true(retakes > 0u);
}

/* Worst engagement (ticks late) of `runs` undisturbed runs per robot at
 * 0.8 N, the samples through the firmware's sensor path: the ICM-20948
 * master copies them every 7.3 ms, the host reads every 4.7 ms up to 2 ms
 * late, and each sample's age is the sensor clock's estimate (age_mode 0)
 * or none (2: every sample taken as measured when judged). */
static double worst_late_engagement(uint8_t age_mode, unsigned runs)
{
    plant_run_cfg_t rc;
    double worst = -1e9;
    unsigned r, run;
    uint8_t i;
    for (r = 0; r < 3u; r++) {
        use_robot(g_names[r]);
        for (run = 0; run < runs; run++) {
            plant_run_defaults(&rc, &g_cfg, hom_fix_pack(&g_tab));
            rc.cmd.tension_mN = 800;
            rc.seed = 700u + run;
            rc.pos_period_ms = (uint8_t)(1u + run % 7u);
            rc.mst_us = 7300u;
            rc.read_us = ICM_SET_PERIOD_US_DEFAULT;
            rc.read_jitter_us = 2000u;
            rc.age_mode = age_mode;
            assert_int_equal(plant_run(&rc, &g_res), 0);
            assert_int_equal(g_res.rc, 0);
            for (i = 0; i < g_res.n_tendons; i++) {
                if (!isnan(g_res.engage_err_ticks[i]) && g_res.engage_err_ticks[i] > worst) {
                    worst = g_res.engage_err_ticks[i];
                }
            }
        }
    }
    return worst;
}

/* A sample reaches the homing up to 16 ms after it was measured, while a
 * take-up runs 2 ticks a millisecond: taken as where the servo was when it
 * was measured (its age from the sensor clock), and the threshold's
 * crossing by the table's curve, the engagement is at most 12 ticks late
 * on three robots (native scan: 8-9 ticks); taken where the servo is when
 * it is judged, it was 21-27 ticks late (chaos seed 19346: 20 ticks, 1.45 x
 * the target with the bounded pull's limit measured from it). */
static void test_engagement_from_the_sample_time(void **state)
{
    double with_age, without;
    (void)state;
    with_age = worst_late_engagement(0u, 4u);
    without = worst_late_engagement(2u, 4u);
    print_message("engagement at most %.1f ticks late with the samples' ages, %.1f without\n",
                  with_age, without);
    assert_true(with_age <= 12.0);
    assert_true(without > 12.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_steps_that_pulled_past_the_bound),
        cmocka_unit_test(test_random_steps_hold_the_bound),
        cmocka_unit_test(test_undisturbed_runs_are_not_limited),
        cmocka_unit_test(test_an_early_engagement_is_searched_again),
        cmocka_unit_test(test_engagement_from_the_sample_time),
    };
    return cmocka_run_group_tests(tests, group_setup, NULL);
}
