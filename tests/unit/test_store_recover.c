/* Unit tests of lib/store's recovery on the circle: a home or a window saved
 * before a power-up, found again from the turn the servo restarts in. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "store/store.h"

/* ---- multi-turn recovery ----------------------------------------- */

static void test_home_set_turns(void **state)
{
    store_home_t e;
    (void)state;
    store_home_set(&e, 4096 * 3 + 17, -1);
    assert_int_equal(e.home_turn, 17);
    assert_int_equal(e.rest_turn, 4095);
    store_home_set(&e, -4096 * 2 - 100, 0);
    assert_int_equal(e.home_turn, 4096 - 100);
    assert_int_equal(e.rest_turn, 0);
}

static void test_recover_position(void **state)
{
    store_home_t e;
    int32_t pos = 0;
    (void)state;
    /* rested at 3 turns + 1000 in the calibration's frame */
    store_home_set(&e, 4096 * 3 + 2200, 4096 * 3 + 1000);
    assert_int_equal(store_recover_position(&e, 1000, 512, &pos), 0);
    assert_int_equal(pos, 4096 * 3 + 1000);
    assert_int_equal(store_recover_position(&e, 1300, 512, &pos), 0);
    assert_int_equal(pos, 4096 * 3 + 1300);
    assert_int_equal(store_recover_position(&e, 1000 - 512, 512, &pos), 0);
    assert_int_equal(pos, 4096 * 3 + 488);
    /* present given in another turn (e.g. a homing offset): reduced modulo 4096 */
    assert_int_equal(store_recover_position(&e, 1000 + 4096 * 5, 512, &pos), 0);
    assert_int_equal(pos, 4096 * 3 + 1000);
    assert_int_equal(store_recover_position(&e, 1000 - 4096, 512, &pos), 0);
    assert_int_equal(pos, 4096 * 3 + 1000);
    /* spool turned by more than tol: moved */
    pos = 42;
    assert_int_equal(store_recover_position(&e, 1000 + 513, 512, &pos), STORE_E_MOVED);
    assert_int_equal(store_recover_position(&e, 1000 - 513, 512, &pos), STORE_E_MOVED);
    assert_int_equal(store_recover_position(&e, 1000 + 2048, 2047, &pos), STORE_E_MOVED);
    assert_int_equal(pos, 42);
    /* across the 4095/0 seam, both ways, negative frames too */
    store_home_set(&e, -10, -4096 * 2 + 4090);
    assert_int_equal(store_recover_position(&e, 5, 100, &pos), 0);
    assert_int_equal(pos, -4096 * 2 + 4096 + 5);
    store_home_set(&e, 0, 4096 * 7 + 3);
    assert_int_equal(store_recover_position(&e, 4090, 100, &pos), 0);
    assert_int_equal(pos, 4096 * 7 - 6);
    /* bad tolerance, inconsistent entries */
    assert_int_equal(store_recover_position(&e, 3, 2048, &pos), STORE_E_ARG);
    e.rest_turn++;
    assert_int_equal(store_recover_position(&e, 3, 100, &pos), STORE_E_ARG);
    store_home_set(&e, 0, 0);
    e.home_turn = 1;
    assert_int_equal(store_recover_position(&e, 0, 100, &pos), STORE_E_ARG);
}

/* A window kept over a power-up: the servo restarts in the turn its shaft
 * stands in; the window follows the spool, whatever turn the frame says. */
static void test_win_recover(void **state)
{
    store_win_tendon_t e;
    int32_t lo = 0, hi = 0;
    (void)state;
    /* saved standing at 3 turns + 1000, window 1000-600 .. 1000+700 */
    e.at_turn = 1000;
    e.lo = -600;
    e.hi = 700;
    /* power-up where it was saved: the window in the new frame (0..4095) */
    assert_int_equal(store_win_recover(&e, 1000, 200, 900, &lo, &hi), 0);
    assert_int_equal(lo, 400);
    assert_int_equal(hi, 1700);
    /* released below the window before the cut (power-up at 1000-800) */
    assert_int_equal(store_win_recover(&e, 200, 200, 900, &lo, &hi), 0);
    assert_int_equal(lo, 400);
    assert_int_equal(hi, 1700);
    /* pulled above it, across the 4095/0 seam of the new frame */
    e.at_turn = 3900;
    assert_int_equal(store_win_recover(&e, 3900 + 1500 - 4096, 200, 900, &lo, &hi), 0);
    assert_int_equal(lo, 3300 - 4096);
    assert_int_equal(hi, 4600 - 4096);
    /* a present given in another turn is reduced modulo 4096 */
    assert_int_equal(store_win_recover(&e, 3900 + 4096 * 2, 200, 900, &lo, &hi), 0);
    assert_int_equal(lo, 3300 + 4096 * 2);
    /* outside the span the spool can have reached: turned by hand */
    lo = 42;
    assert_int_equal(store_win_recover(&e, 3900 - 801, 200, 900, &lo, &hi), STORE_E_MOVED);
    assert_int_equal(store_win_recover(&e, 3900 + 1601, 200, 900, &lo, &hi), STORE_E_MOVED);
    assert_int_equal(lo, 42);
    /* a span of a turn or more is ambiguous */
    assert_int_equal(store_win_recover(&e, 3900, 2000, 1500, &lo, &hi), STORE_E_ARG);
    /* a tendon pulled towards lower ticks: slack side above, order kept */
    e.at_turn = 100;
    e.lo = 600;
    e.hi = -700;
    assert_int_equal(store_win_recover(&e, 100 + 800, 900, 200, &lo, &hi), 0);
    assert_int_equal(lo, 700);
    assert_int_equal(hi, -600);
    assert_int_equal(store_win_recover(&e, 100 + 801, 900, 200, &lo, &hi), STORE_E_MOVED);
    assert_int_equal(store_win_recover(&e, 100 - 1600, 900, 200, &lo, &hi), 0);
    assert_int_equal(store_win_recover(&e, 100 - 1601, 900, 200, &lo, &hi), STORE_E_MOVED);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_win_recover),
        cmocka_unit_test(test_home_set_turns),
        cmocka_unit_test(test_recover_position),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
