/*
 * lib/app: the held pull from the console (`survey T H`; docs/identify.md)
 * on a native board against the plant: the refusals, the run's reports,
 * nothing stored, and a stop in it followed by a calibration.
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

static uint8_t all_slack(void)
{
    uint8_t i;
    for (i = 0; i < 6u; i++) {
        if (app_bench_tension(&g_b, i) > 0.001) {
            return 0;
        }
    }
    return 1;
}

/* A hold that is the pulled tendon or beyond the table, or a pulled
 * tendon beyond the table, is refused before anything moves; `survey 1 0` runs at five eighths
 * of the top grid tension: tendon 1's engagement scanned alone, tendon 0
 * pulled alone and held (<progress state=hold tendon=0 pos=...>), tendon
 * 1's engagement scanned again; only the scans' points are streamed (tendon
 * 1, several lines at each position); everything released, nothing
 * stored. */
static void test_held_survey_from_the_console(void **state)
{
    long hold_pos = 0, p, last_p = 0;
    unsigned sv = 0, sv_alone = 0, same = 0;
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "survey 1 1", "error:26 the hold must be another tendon");
    cmd(&g_b, "survey 1 7", "error:26 the hold must be another tendon");
    cmd(&g_b, "survey 7 1", "error:15 no such tendon");
    assert_int_equal(g_b.app.state, APP_ST_IDLE);
    cmd(&g_b, "survey 1 0", "ok");
    for (;;) {
        assert_true(app_bench_wait_line(&g_b, "<", g_line, sizeof g_line, 15000));
        assert_null(strstr(g_line, "<fault"));
        assert_null(strstr(g_line, "<result"));
        if (strncmp(g_line, "<progress state=hold", 20) == 0) {
            assert_int_equal(app_bench_field(g_line, "tendon", -1), 0);
            hold_pos = app_bench_field(g_line, "pos", 0);
            assert_true(hold_pos != 0);
            assert_true(app_bench_tension(&g_b, 0) > 0.5);
        }
        if (strncmp(g_line, "<sv ", 4) == 0) {
            assert_int_equal(app_bench_field(g_line, "t", -1), 1);
            p = app_bench_field(g_line, "p", 0);
            same += p == last_p;
            last_p = p;
            if (hold_pos != 0) {
                sv++;
            } else {
                sv_alone++;
            }
        }
        if (strncmp(g_line, "<done ", 6) == 0) {
            break;
        }
    }
    assert_non_null(strstr(g_line, "mode=survey"));
    assert_int_equal(app_bench_field(g_line, "count", -1), 0);
    assert_int_equal(app_bench_field(g_line, "tension_mN", -1), 1500 * APP_HOLD_EIGHTHS / 8);
    assert_true(hold_pos != 0 && sv >= 20u && sv_alone >= 20u);
    assert_true(same * 2u >= sv + sv_alone); /* standing points, not a moving pull */
    assert_true(all_slack());
    assert_int_equal(g_b.app.rec.home_now, 0u);
    assert_int_equal(g_b.app.rec.homes.cal_count, 0u);
}

/* A stop while tendon 1 is pulled with tendon 0 held releases every tendon
 * within 100 ms; the next `cal` homes every tendon. */
static void test_stop_in_a_held_pull_then_cal(void **state)
{
    uint64_t t0;
    unsigned results = 0;
    (void)state;
    boot(&g_b, 1);
    cmd(&g_b, "survey 1 0", "ok");
    assert_true(app_bench_wait_line(&g_b, "<progress state=hold", g_line, sizeof g_line, 15000));
    app_bench_run_ms(&g_b, 400);
    assert_true(app_bench_tension(&g_b, 0) > 0.5);
    (void)con_rt_byte(&g_b.rt, '!');
    t0 = g_b.now_us;
    while (g_b.now_us - t0 < 100000u && !all_slack()) {
        app_bench_step(&g_b);
    }
    assert_true(all_slack());
    assert_true(app_bench_wait_line(&g_b, "<released ", g_line, sizeof g_line, 200));
    app_bench_run_ms(&g_b, 1500);
    cmd(&g_b, "cal", "ok");
    for (;;) {
        assert_true(app_bench_wait_line(&g_b, "<", g_line, sizeof g_line, 15000));
        assert_null(strstr(g_line, "<fault"));
        results += strncmp(g_line, "<result ", 8) == 0;
        if (strncmp(g_line, "<done ", 6) == 0) {
            break;
        }
    }
    assert_int_equal(results, 6);
    assert_non_null(strstr(g_line, "mode=full"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_held_survey_from_the_console),
        cmocka_unit_test(test_stop_in_a_held_pull_then_cal),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
