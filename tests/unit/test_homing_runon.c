/* Fine points on the way out only, on a 12-servo bus (hom_approach.c). With
 * 12 servos positions are read every 6-18 ms and a goal reaches its servo a
 * bus cycle after it was decided, so a servo at the moderate speed (about a
 * tick per ms) runs on well past the last position read. A stop at that read
 * sent it back: the spool's backlash and the path's friction held the spool
 * where the servo had been, the fine points read the field of a place
 * further on, and their flat slope put the target beyond the travel limit
 * (chaos seed 18451: a moderate approach to 217 read at 209 and stopped at
 * 211; a clean calibration ended in HOM_F_TRAVEL_LIMIT). A stop now allows
 * for the servo's run since its read and until the goal lands a bus cycle
 * later, and a servo seen past its goal has the goal raised to the furthest
 * read. Measured by the plant:
 * where the servo stood, behind the furthest it had been since it was last
 * slack, while each fine point was averaged. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include <cmocka.h>

#include "hom_fixture.h"

#define RUNS 30u

static plant_cfg_t g_nom;
static plant_cfg_t g_cfg;
static tbl_wide_t g_tab;
static plant_run_result_t g_res;

static int group_setup(void **state)
{
    (void)state;
    return hom_fix_load("c2s12t4k77d98.cfg", &g_nom, &g_tab);
}

/* RUNS robots perturbed by 5 % from the table's, each with its own bus
 * timing; returns the deepest a fine point was taken behind the servo's
 * furthest place, in ticks, and fails any run that faults */
static double behind_over_runs(uint16_t tension_mN, uint32_t seed0)
{
    double worst = 0.0;
    unsigned run;
    uint8_t i;
    for (run = 0; run < RUNS; run++) {
        plant_run_cfg_t rc;
        g_cfg = g_nom;
        assert_int_equal(plant_cfg_perturb(&g_cfg, seed0 + run, 0.05), 0);
        plant_run_defaults(&rc, &g_cfg, hom_fix_pack(&g_tab));
        rc.cmd.tension_mN = tension_mN;
        rc.seed = seed0 + 500u + run;
        rc.pos_period_ms = (uint8_t)(6u + run % 13u);
        rc.goal_lag_ms = (uint8_t)(2u + run % 11u);
        rc.sample_lag_ms = (uint8_t)(run % 13u);
        rc.start_min_um = -3000.0;
        rc.start_max_um = 400.0;
        assert_int_equal(plant_run(&rc, &g_res), 0);
        if (g_res.rc != 0) {
            print_message("run %u: fault %u index %u\n", run, g_res.fault, g_res.fault_index);
        }
        assert_int_equal(g_res.rc, 0);
        for (i = 0; i < g_res.n_tendons; i++) {
            if (g_res.max_behind_ticks[i] > worst) {
                worst = g_res.max_behind_ticks[i];
            }
        }
    }
    return worst;
}

/* At 0.8 and 1.5 N. Over 150 runs per tension and seed set the stop before
 * these came back up to 14-15 ticks at 0.8 N (43 of 300 runs) and 17 at
 * 1.5 N (91 of 300); with the run allowed for until the goal lands, no point
 * of the 600 runs lies more than a tick behind. The sets below give 15 and
 * 9 ticks on the stop before. */
static void test_fine_points_are_taken_on_the_way_out(void **state)
{
    double w800;
    double w1500;
    (void)state;
    w800 = behind_over_runs(800u, 1000u);
    w1500 = behind_over_runs(1500u, 2000u);
    print_message("deepest behind the furthest place: %.1f ticks at 0.8 N, %.1f at 1.5 N\n", w800,
                  w1500);
    assert_true(w800 <= 2.0);
    assert_true(w1500 <= 2.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fine_points_are_taken_on_the_way_out),
    };
    return cmocka_run_group_tests(tests, group_setup, NULL);
}
