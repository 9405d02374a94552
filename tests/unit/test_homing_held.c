/* Held pulls (hom_cmd_t.hold; docs/identify.md, "Held pulls on the board")
 * in closed loop against the plant: the pulled tendon's engagement scanned
 * alone, the hold pulled alone and held, the engagement scanned again and
 * found short of the first and of the tendon's window without a fault and
 * without the window learning it, its pull and the held tendon's tension
 * bounded, nothing recorded, every tendon slack at the end; the refusals;
 * an abort in the held pull. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "hom_fixture.h"

static plant_cfg_t g_cfg;
static tbl_wide_t g_tab;
static plant_run_result_t g_res;

/* tendon 1 pulled, tendon 0 of its segment holding (120 degrees apart) */
#define PULLED 1u
#define HELD   0u

static int group_setup(void **state)
{
    (void)state;
    return hom_fix_paper(&g_cfg, &g_tab);
}

static const hom_event_t *find_event(uint8_t type, uint8_t code)
{
    uint16_t i;
    for (i = 0; i < g_res.n_events; i++) {
        const hom_event_t *e = &g_res.events[i];
        if (e->type == type && (type != HOM_EV_PHASE || e->code == code)) {
            return e;
        }
    }
    return NULL;
}

/* A survey of tendon i alone at the top of the grid (the pull a held pull
 * is compared with): where it engaged. */
static int32_t engagement_alone(uint8_t i)
{
    plant_run_cfg_t rc;
    const hom_event_t *e;
    plant_run_defaults(&rc, &g_cfg, hom_fix_pack(&g_tab));
    rc.seed = 21;
    rc.cmd.mode = HOM_MODE_SINGLE;
    rc.cmd.tendon = i;
    rc.cmd.survey = 1;
    rc.cmd.tension_mN = g_tab.grid_mN[g_tab.n_grid - 1u];
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    e = find_event(HOM_EV_ENGAGED, 0);
    assert_non_null(e);
    return e->a;
}

/* The run's tension, as the app sets it: five eighths of the top of the
 * grid (APP_HOLD_EIGHTHS) */
static uint16_t hold_mN(void)
{
    return (uint16_t)(g_tab.grid_mN[g_tab.n_grid - 1u] * 5u / 8u);
}

/* The bounded pull of a survey: 1.25 x the top of the grid + 0.1 N */
static double survey_bound_N(void)
{
    return 1.25 * g_tab.grid_mN[g_tab.n_grid - 1u] * 1e-3 + 0.1;
}

static void held_cfg(plant_run_cfg_t *rc)
{
    plant_run_defaults(rc, &g_cfg, hom_fix_pack(&g_tab));
    rc->seed = 23;
    rc->cmd.mode = HOM_MODE_SINGLE;
    rc->cmd.tendon = PULLED;
    rc->cmd.survey = 1;
    rc->cmd.hold = HELD + 1u;
    rc->cmd.tension_mN = hold_mN();
}

/* The pulled tendon's window is its pull alone's engagement (as a survey
 * leaves it): scanned alone, its engagement is there; held, the bend moves
 * it short of it, and that is no fault; the window does not learn it. Each
 * scan goes at most HOM_SCAN_AHEAD past the engagement (the take-up's run
 * before it a little further); the held tendon's tension stays within the
 * survey's bounded pull, 1.25 x the top of the grid + 0.1 N; no home, no
 * window kept; every tendon slack at the end. */
static void test_held_pull_end_to_end(void **state)
{
    plant_run_cfg_t rc;
    const hom_event_t *hold, *eng[2] = {NULL, NULL};
    int32_t alone = engagement_alone(PULLED);
    double bound = survey_bound_N();
    uint8_t i, n = 0;
    (void)state;
    held_cfg(&rc);
    rc.cmd.win_mask = 1u << PULLED;
    rc.cmd.win_lo[PULLED] = alone;
    rc.cmd.win_hi[PULLED] = alone;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.fault, HOM_F_NONE);
    assert_int_equal(g_res.rc, 0);
    hold = find_event(HOM_EV_PHASE, HOM_PH_HOLD);
    assert_non_null(hold);
    assert_int_equal(hold->index, HELD);
    /* the pulled tendon engaged twice: alone, then held */
    for (i = 0; i < g_res.n_events; i++) {
        if (g_res.events[i].type == HOM_EV_ENGAGED && g_res.events[i].index == PULLED) {
            assert_true(n < 2u);
            eng[n++] = &g_res.events[i];
        }
    }
    assert_int_equal(n, 2);
    assert_true(eng[0]->t_ms < hold->t_ms && eng[1]->t_ms > hold->t_ms);
    print_message("engagement alone %d (survey %d), held %d; held tendon at %d, %.0f mN at most, "
                  "pulled %.0f mN, %.1f ticks past\n",
                  (int)eng[0]->a, (int)alone, (int)eng[1]->a, (int)hold->a,
                  g_res.max_tension_N[HELD] * 1e3, g_res.max_pull_N[PULLED] * 1e3,
                  g_res.max_past_engage_ticks[PULLED]);
    assert_true(labs((long)(eng[0]->a - alone)) <= 6);
    /* short of the window (paper robot: pull_dir +1 for both) */
    assert_true(g_cfg.tendon[PULLED].pull_dir * (eng[1]->a - alone) < -5);
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_HOME), 0);
    assert_int_equal(hom_fix_count_events(&g_res, HOM_EV_FAULT), 0);
    assert_int_equal(g_res.win_kept & ((1u << PULLED) | (1u << HELD)), 0u);
    assert_true(g_res.max_past_engage_ticks[PULLED] <= HOM_SCAN_AHEAD + 16.0);
    assert_true(g_res.max_tension_N[HELD] > 0.5 * hold_mN() * 1e-3);
    assert_true(g_res.max_tension_N[HELD] <= bound);
    assert_true(g_res.max_pull_N[PULLED] <= bound);
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_int_equal(g_res.have_home[i], 0);
        assert_true(g_res.final_tension_N[i] < 0.001);
    }
}

/* A hold whose own pull ends at its bound (targets three times what the
 * robot gives: the bounded pull's retake, then the table's limit) is held
 * there; the pulled tendon's pull after it is bounded as always. */
static void test_hold_ended_at_its_bound(void **state)
{
    static tbl_wide_t tab;
    plant_run_cfg_t rc;
    uint8_t g, i;
    (void)state;
    tab = g_tab;
    for (g = 0; g < tab.n_grid; g++) {
        tab.tendons[HELD].target_cuT[g] *= 3u;
    }
    held_cfg(&rc);
    rc.table = hom_fix_pack(&tab);
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.fault, HOM_F_NONE);
    assert_non_null(find_event(HOM_EV_PHASE, HOM_PH_HOLD));
    assert_true(g_res.max_past_engage_ticks[HELD] <= (double)g_res.limit_ticks[HELD]);
    assert_true(g_res.max_past_engage_ticks[PULLED] <= HOM_SCAN_AHEAD + 16.0);
    assert_true(g_res.max_tension_N[HELD] <= survey_bound_N());
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_true(g_res.final_tension_N[i] < 0.001);
    }
}

/* hom_start() refuses a hold that is the pulled tendon, beyond the table,
 * outside a survey or a single tendon's run: nothing moves. */
static void test_held_refusals(void **state)
{
    plant_run_cfg_t rc;
    unsigned k;
    (void)state;
    for (k = 0; k < 4u; k++) {
        held_cfg(&rc);
        if (k == 0u) {
            rc.cmd.hold = PULLED + 1u;
        } else if (k == 1u) {
            rc.cmd.hold = (uint8_t)(g_tab.n_tendons + 1u);
        } else if (k == 2u) {
            rc.cmd.survey = 0;
        } else {
            rc.cmd.mode = HOM_MODE_FULL;
        }
        assert_int_equal(plant_run(&rc, &g_res), PLANT_E_RANGE);
        assert_int_equal(g_res.rc, HOM_E_ARG);
    }
}

/* An abort while the held tendon is held and the other pulled releases
 * every tendon within 100 ms, with nothing recorded; a calibration after it
 * on the same robot homes every tendon. */
static void test_abort_during_held_pull(void **state)
{
    plant_run_cfg_t rc;
    const hom_event_t *hold;
    uint8_t i;
    (void)state;
    held_cfg(&rc);
    assert_int_equal(plant_run(&rc, &g_res), 0);
    hold = find_event(HOM_EV_PHASE, HOM_PH_HOLD);
    assert_non_null(hold);
    held_cfg(&rc);
    rc.fault = PLANT_FI_ABORT;
    rc.fault_ms = hold->t_ms + 300u;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.fault, HOM_F_ABORTED);
    assert_true(g_res.released && g_res.release_ms <= 100u);
    assert_int_equal(g_res.win_kept & ((1u << PULLED) | (1u << HELD)), 0u);
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_int_equal(g_res.have_home[i], 0);
        assert_true(g_res.final_tension_N[i] < 0.001);
    }
    plant_run_defaults(&rc, &g_cfg, hom_fix_pack(&g_tab));
    rc.seed = 23;
    assert_int_equal(plant_run(&rc, &g_res), 0);
    assert_int_equal(g_res.rc, 0);
    for (i = 0; i < g_res.n_tendons; i++) {
        assert_true(g_res.have_home[i]);
        assert_true(fabs(g_res.err_ticks[i]) <= 1.5);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_held_pull_end_to_end),
        cmocka_unit_test(test_hold_ended_at_its_bound),
        cmocka_unit_test(test_held_refusals),
        cmocka_unit_test(test_abort_during_held_pull),
    };
    return cmocka_run_group_tests(tests, group_setup, NULL);
}
