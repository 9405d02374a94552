/* Unit tests of the plant's straight-pose truth (sim/plant/pose.h) and the
 * backbone compression: the compression against L * T / EA, the ramp of
 * every tendon together (today's final pose is far above the target, the
 * single homes minus each tendon's own bending shortening are straight at the
 * target without friction), the true straight homes with friction, the field
 * home, and the refusals. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <string.h>

#include <cmocka.h>

#include "plant/pose.h"

/* Three tendons 120 deg apart per segment, like paper_2seg. */
static const char k_cfg[] = "name = pose\n"
                            "segment_len_mm = 53 53\n"
                            "backbone_ei_Nm2 = 2.945e-3\n"
                            "segment_ea_N = 47000 47000\n"
                            "grid_mN = 300 800 1500\n"
                            "default_mN = 800\n"
                            "tendon.*.ea_N = 2000\n"
                            "tendon.*.free_len_mm = 203\n"
                            "tendon.*.friction_mN = 0\n"
                            "tendon.*.friction_mu = 0\n"
                            "tendon.*.backlash_um = 0\n"
                            "tendon.0.angle_deg = 60\n"
                            "tendon.1.angle_deg = 180\n"
                            "tendon.2.angle_deg = 300\n"
                            "tendon.3.angle_deg = 0\n"
                            "tendon.3.segment = 2\n"
                            "tendon.4.angle_deg = 120\n"
                            "tendon.4.segment = 2\n"
                            "tendon.5.angle_deg = 240\n"
                            "tendon.5.segment = 2\n"
                            "sensor.0.pos_mm = 0 22 120\n";

static void load(plant_cfg_t *c, const char *extra)
{
    int line = -1;
    assert_int_equal(plant_cfg_defaults(c), 0);
    assert_int_equal(plant_cfg_parse(c, k_cfg, &line), 0);
    if (extra != NULL) {
        assert_int_equal(plant_cfg_parse(c, extra, &line), 0);
    }
    assert_int_equal(plant_cfg_check(c), 0);
}

static double um_per_tick(const plant_cfg_t *c, uint8_t i)
{
    return plant_nm_per_tick(c, i) * 1e-3;
}

static void test_compression(void **state)
{
    plant_cfg_t c;
    plant_cfg_t rigid;
    double h;
    double hr;
    (void)state;
    load(&c, NULL);
    load(&rigid, "segment_ea_N = 0 0\n");
    /* the off-diagonal compliance of two tendons 120 deg apart in segment 1:
     * bending r^2 L cos(120) / EI plus compression L / EA */
    assert_true(fabs(plant_path_compliance(&c, 0, 1) - plant_path_compliance(&rigid, 0, 1) -
                     0.053 / 47000.0) < 1e-12);
    assert_true(fabs(plant_path_compliance(&c, 3, 4) - plant_path_compliance(&rigid, 3, 4) -
                     0.106 / 47000.0) < 1e-12);
    /* a single tendon's home moves by its own compression L T / EA */
    assert_int_equal(plant_true_home(&c, 3, 800, &h), 0);
    assert_int_equal(plant_true_home(&rigid, 3, 800, &hr), 0);
    assert_true(fabs((h - hr) * um_per_tick(&c, 3) - 0.106 * 0.8 / 47000.0 * 1e6) < 0.01);
    assert_true(plant_path_compliance(&c, 0, 6) == 0.0); /* out of range */
}

static void test_single_homes_together_and_shifted(void **state)
{
    plant_cfg_t c;
    plant_pose_result_t r;
    double ticks[PLANT_MAX_TENDONS];
    uint8_t i;
    (void)state;
    load(&c, NULL);
    for (i = 0; i < c.n_tendons; i++) {
        assert_int_equal(plant_true_home(&c, i, 800, &ticks[i]), 0);
    }
    assert_int_equal(plant_pose_ramp(&c, ticks, &r), 0);
    for (i = 0; i < c.n_tendons; i++) {
        assert_true(r.tension_N[i] > 3.0); /* the 3.5-5.9 N */
    }
    assert_true(r.tip_dev_mm < 0.01); /* balanced: straight, but far too tight */
    /* pay out each tendon's own shortening minus the compression under all
     * six: without friction the pose is straight at the target */
    for (i = 0; i < c.n_tendons; i++) {
        double all = 0.0;
        for (uint8_t m = 0; m < c.n_tendons; m++) {
            all += plant_path_compliance(&c, i, m);
        }
        ticks[i] -= (plant_path_compliance(&c, i, i) - all) * 0.8 * 1e6 / um_per_tick(&c, i);
    }
    assert_int_equal(plant_pose_ramp(&c, ticks, &r), 0);
    for (i = 0; i < c.n_tendons; i++) {
        assert_true(fabs(r.tension_N[i] - 0.8) < 1e-3);
    }
    assert_true(r.tip_dev_mm < 0.01);
}

static void test_true_straight_homes_with_friction(void **state)
{
    plant_cfg_t c;
    plant_pose_result_t r;
    double ticks[PLANT_MAX_TENDONS];
    uint8_t i;
    (void)state;
    load(&c, "tendon.*.friction_mN = 10\ntendon.*.friction_mu = 0.02\n"
             "tendon.*.backlash_um = 30\n");
    assert_int_equal(plant_straight_homes(&c, 1500, ticks), 0);
    assert_int_equal(plant_pose_ramp(&c, ticks, &r), 0);
    for (i = 0; i < c.n_tendons; i++) {
        assert_true(fabs(r.tension_N[i] - 1.5) < 1e-3);
        assert_true(r.tip_tension_N[i] < r.tension_N[i]); /* pulled: the tip lags */
    }
    assert_true(r.tip_dev_mm < 0.05);
}

static void test_field_home_and_refusals(void **state)
{
    plant_cfg_t c;
    plant_pose_result_t r;
    double ticks[PLANT_MAX_TENDONS] = {0};
    double h;
    double f;
    (void)state;
    load(&c, NULL);
    /* the field home of a small target lies before the true 800 mN home, of
     * a larger one after it */
    assert_int_equal(plant_true_home(&c, 0, 800, &h), 0);
    assert_int_equal(plant_field_home(&c, 0, 0, 100.0, &f), 0);
    assert_true(f < h);
    assert_int_equal(plant_field_home(&c, 0, 0, 1e9, &f), PLANT_E_SOLVE);
    assert_int_equal(plant_field_home(&c, 0, 1, 100.0, &f), PLANT_E_ARG);
    assert_int_equal(plant_field_home(&c, 0, 0, 0.0, &f), PLANT_E_ARG);
    assert_int_equal(plant_pose_ramp(NULL, ticks, &r), PLANT_E_ARG);
    assert_int_equal(plant_pose_ramp(&c, NULL, &r), PLANT_E_ARG);
    assert_int_equal(plant_straight_homes(&c, 0, ticks), PLANT_E_ARG);
    assert_int_equal(plant_straight_tip(NULL, ticks), PLANT_E_ARG);
    /* all slack: no tension, the straight tip */
    for (uint8_t i = 0; i < c.n_tendons; i++) {
        ticks[i] = (c.tendon[i].slack_um - 2000.0) / um_per_tick(&c, i);
    }
    assert_int_equal(plant_pose_ramp(&c, ticks, &r), 0);
    assert_true(r.tension_N[0] == 0.0 && r.tip_dev_mm < 1e-9);
    /* a negative axial stiffness is refused */
    {
        int line = -1;
        assert_int_equal(plant_cfg_parse(&c, "segment_ea_N = -1\n", &line), PLANT_E_RANGE);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_compression),
        cmocka_unit_test(test_single_homes_together_and_shifted),
        cmocka_unit_test(test_true_straight_homes_with_friction),
        cmocka_unit_test(test_field_home_and_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
