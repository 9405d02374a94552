/* Unit tests of lib/store's records against the RAM EEPROM fake: CRC, layout,
 * the empty chip, write pacing, round trips, argument errors, the history ring
 * and the settings. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "store/store.h"
#include "store_fake.h"
#include "store_fixture.h"

/* ---- basics ------------------------------------------------------ */

static void test_crc_vector(void **state)
{
    (void)state;
    assert_int_equal(store_crc16(0xFFFFu, "123456789", 9), 0x29B1);
    assert_int_equal(store_crc16(0xFFFFu, "", 0), 0xFFFF);
    /* continuing a CRC over a split buffer gives the same value */
    assert_int_equal(store_crc16(store_crc16(0xFFFFu, "1234", 4), "56789", 5), 0x29B1);
}

static void test_layout(void **state)
{
    (void)state;
    assert_true(STORE_HIST_N >= 16u);
    assert_true(STORE_ADDR_END <= STORE_EEPROM_SIZE);
    assert_int_equal(STORE_ADDR_WIN, 0xF40);
    assert_int_equal(STORE_ADDR_END, 0x1000);
    assert_true(STORE_SLOT_LEN(sizeof(store_homes_t)) <= STORE_HOMES_STRIDE);
    assert_true(sizeof(store_t) <= 64u); /* host pointers are wider than the AVR's */
}

static void test_empty_eeprom(void **state)
{
    store_settings_t s, d;
    store_homes_t h;
    store_learned_t l;
    store_hist_t e;
    (void)state;
    store_fix_fresh(0xFF);
    memset(&h, 0x5A, sizeof(h));
    assert_int_equal(store_homes_load(&g_st, STORE_FIX_TABLE_ID, &h), STORE_E_EMPTY);
    assert_int_equal(h.table_id, 0x5A5A5A5Au); /* untouched */
    assert_int_equal(store_learned_load(&g_st, 0, STORE_FIX_TABLE_ID, &l), STORE_E_EMPTY);
    assert_int_equal(store_hist_count(&g_st), 0);
    assert_int_equal(store_hist_get(&g_st, 0, &e), STORE_E_EMPTY);
    assert_int_equal(store_settings_load(&g_st, &s), STORE_E_DEFAULTS);
    store_settings_defaults(&g_st, &d);
    assert_memory_equal(&s, &d, sizeof(s));
    assert_int_equal(s.v[STORE_SET_CAL_TENSION], 800);
    /* an all-zero chip is no valid record either */
    store_fix_fresh(0x00);
    assert_int_equal(store_homes_load(&g_st, STORE_FIX_TABLE_ID, &h), STORE_E_EMPTY);
    assert_int_equal(store_hist_count(&g_st), 0);
}

static void test_poll_idle_busy_hold(void **state)
{
    store_homes_t h;
    store_settings_t s;
    uint32_t w;
    (void)state;
    store_fix_fresh(0xFF);
    assert_int_equal(store_poll(&g_st, 1), STORE_E_IDLE);
    store_fix_homes(&h, 1, 0);
    store_settings_defaults(&g_st, &s);
    assert_int_equal(store_save_homes(&g_st, &h), 1);
    assert_true(store_busy(&g_st));
    assert_int_equal(store_save_settings(&g_st, &s), STORE_E_BUSY);
    assert_int_equal(store_save_homes(&g_st, &h), STORE_E_BUSY);
    assert_int_equal(store_save_hist(&g_st, (const store_hist_t *)NULL), STORE_E_BUSY);
    /* not idle: nothing is written however often it is polled */
    w = g_ee.writes;
    for (int i = 0; i < 100; i++) {
        assert_int_equal(store_poll(&g_st, 0), 1);
    }
    assert_int_equal(g_ee.writes, w);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    assert_false(store_busy(&g_st));
    assert_int_equal(store_poll(&g_st, 1), STORE_E_IDLE);
}

static void test_one_byte_per_ready(void **state)
{
    store_homes_t h, r;
    uint32_t polls = 0;
    int8_t rc;
    (void)state;
    store_fix_fresh(0xFF);
    g_ee.busy_polls = 3;
    store_fix_homes(&h, 1, 0);
    assert_int_equal(store_save_homes(&g_st, &h), 1);
    do {
        uint32_t before = g_ee.writes;
        rc = store_poll(&g_st, 1);
        assert_true(g_ee.writes - before <= 1u);
        polls++;
    } while (rc > 0 && polls < STORE_FIX_POLLS);
    assert_int_equal(rc, 0);
    assert_int_equal(g_ee.violations, 0);
    /* every byte that differs from the erased chip was written, 4 polls each */
    assert_true(g_ee.writes <= STORE_SLOT_LEN(sizeof(h)));
    assert_true(g_ee.writes > STORE_SLOT_LEN(sizeof(h)) / 2u);
    assert_true(polls >= 4u * g_ee.writes);
    assert_int_equal(store_homes_load(&g_st, STORE_FIX_TABLE_ID, &r), 0);
    assert_memory_equal(&r, &h, sizeof(h));
}

static void test_unchanged_bytes_not_rewritten(void **state)
{
    store_homes_t h;
    uint32_t w;
    (void)state;
    store_fix_fresh(0xFF);
    store_fix_homes(&h, 1, 0);
    store_fix_save_homes(&h); /* slot A, seq 1 */
    store_fix_save_homes(&h); /* slot B, seq 2 */
    w = g_ee.writes;
    store_fix_save_homes(
        &h); /* slot A again: only kind (invalidate, restore), seq and CRC change */
    assert_true(g_ee.writes - w <= 6u);
    assert_true(g_ee.writes - w >= 3u);
}

static void test_roundtrip_all_records(void **state)
{
    store_settings_t s, r;
    store_homes_t h, hr;
    store_learned_t l, lr;
    store_hist_t e, er;
    (void)state;
    store_fix_fresh(0xFF);
    store_settings_defaults(&g_st, &s);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_CAL_TENSION, 1200), 0);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_BUS_BAUD, 2000000), 0);
    assert_int_equal(store_save_settings(&g_st, &s), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    store_fix_homes(&h, 7, -70000);
    store_fix_save_homes(&h);
    store_fix_learned(&l, 11, 4000);
    assert_int_equal(store_save_learned(&g_st, &l), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    store_fix_hist(&e, 7);
    assert_int_equal(store_save_hist(&g_st, &e), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);

    store_fix_boot(); /* power cycle */
    assert_int_equal(store_settings_load(&g_st, &r), 0);
    assert_memory_equal(&r, &s, sizeof(s));
    assert_int_equal(store_homes_load(&g_st, STORE_FIX_TABLE_ID, &hr), 0);
    assert_memory_equal(&hr, &h, sizeof(h));
    assert_int_equal(store_learned_load(&g_st, 11, STORE_FIX_TABLE_ID, &lr), 0);
    assert_memory_equal(&lr, &l, sizeof(l));
    assert_int_equal(store_learned_load(&g_st, 10, STORE_FIX_TABLE_ID, &lr), STORE_E_EMPTY);
    assert_int_equal(store_hist_count(&g_st), 1);
    assert_int_equal(store_hist_get(&g_st, 0, &er), 0);
    assert_memory_equal(&er, &e, sizeof(e));
    assert_int_equal(g_ee.violations, 0);
}

static void test_other_table_flagged(void **state)
{
    store_homes_t h, r;
    store_learned_t l, lr;
    (void)state;
    store_fix_fresh(0xFF);
    store_fix_homes(&h, 3, 0);
    store_fix_save_homes(&h);
    memset(&r, 0, sizeof(r));
    assert_int_equal(store_homes_load(&g_st, STORE_FIX_TABLE_ID + 1u, &r), STORE_E_OTHER_TABLE);
    assert_int_equal(r.table_id, STORE_FIX_TABLE_ID); /* filled so it can be shown */
    store_fix_learned(&l, 2, 99);
    assert_int_equal(store_save_learned(&g_st, &l), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    assert_int_equal(store_learned_load(&g_st, 2, 0x1234, &lr), STORE_E_OTHER_TABLE);
    assert_int_equal(lr.target_lsb[0], 99);
}

static void test_argument_errors(void **state)
{
    store_homes_t h;
    store_learned_t l;
    store_hist_t e;
    (void)state;
    store_fix_fresh(0xFF);
    store_fix_homes(&h, 1, 0);
    h.n_tendons = STORE_MAX_TENDONS + 1u;
    assert_int_equal(store_save_homes(&g_st, &h), STORE_E_ARG);
    store_fix_learned(&l, STORE_MAX_TENDONS, 1);
    assert_int_equal(store_save_learned(&g_st, &l), STORE_E_ARG);
    store_fix_learned(&l, 0, 1);
    l.n_grid = TBL_MAX_GRID + 1u;
    assert_int_equal(store_save_learned(&g_st, &l), STORE_E_ARG);
    assert_int_equal(store_learned_load(&g_st, STORE_MAX_TENDONS, STORE_FIX_TABLE_ID, &l),
                     STORE_E_ARG);
    store_fix_hist(&e, 1);
    e.n_tendons = 200;
    assert_int_equal(store_save_hist(&g_st, &e), STORE_E_ARG);
    assert_int_equal(store_hist_get(&g_st, STORE_HIST_N, &e), STORE_E_ARG);
    assert_false(store_busy(&g_st));
    assert_int_equal(g_ee.writes, 0);
}

/* ---- history ring ------------------------------------------------ */

static void test_history_ring(void **state)
{
    store_hist_t e;
    uint32_t i;
    (void)state;
    store_fix_fresh(0xFF);
    for (i = 1; i <= 30; i++) {
        store_fix_hist(&e, i);
        assert_int_equal(store_save_hist(&g_st, &e), 1);
        assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
        assert_int_equal(store_hist_count(&g_st), i < STORE_HIST_N ? i : STORE_HIST_N);
    }
    store_fix_boot();
    assert_int_equal(store_hist_count(&g_st), STORE_HIST_N);
    for (i = 0; i < STORE_HIST_N; i++) {
        assert_int_equal(store_hist_get(&g_st, (uint8_t)i, &e), 0);
        assert_int_equal(e.cal_count, 30u - i);
        assert_int_equal(e.home_ticks[3], (int32_t)((30u - i) * 10u + 3u));
    }
    /* a cut in the next save loses the oldest entry only */
    g_ee.cut_at = (int32_t)(g_ee.writes + 10u);
    store_fix_hist(&e, 31);
    assert_int_equal(store_save_hist(&g_st, &e), 1);
    (void)store_fake_run(&g_st, STORE_FIX_POLLS);
    store_fix_boot();
    assert_int_equal(store_hist_get(&g_st, 0, &e), 0);
    assert_int_equal(e.cal_count, 30);
    assert_int_equal(store_hist_count(&g_st), STORE_HIST_N - 1u);
    /* the next save reuses the torn slot */
    store_fix_hist(&e, 31);
    assert_int_equal(store_save_hist(&g_st, &e), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    assert_int_equal(store_hist_count(&g_st), STORE_HIST_N);
    assert_int_equal(store_hist_get(&g_st, 0, &e), 0);
    assert_int_equal(e.cal_count, 31);
    assert_int_equal(store_hist_get(&g_st, STORE_HIST_N - 1u, &e), 0);
    assert_int_equal(e.cal_count, 8);
}

static void test_history_gap_stops_count(void **state)
{
    store_hist_t e;
    uint32_t i;
    (void)state;
    store_fix_fresh(0xFF);
    for (i = 1; i <= 5; i++) {
        store_fix_hist(&e, i);
        assert_int_equal(store_save_hist(&g_st, &e), 1);
        assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    }
    /* damage entry 3 (ring index 2): ages 0,1 readable, age 2 lost, age 3 still there */
    g_ee.mem[STORE_ADDR_HIST + 2u * STORE_HIST_STRIDE + 9u] ^= 0xFFu;
    store_fix_boot();
    assert_int_equal(store_hist_count(&g_st), 2);
    assert_int_equal(store_hist_get(&g_st, 2, &e), STORE_E_EMPTY);
    assert_int_equal(store_hist_get(&g_st, 3, &e), 0);
    assert_int_equal(e.cal_count, 2);
    assert_int_equal(store_hist_get(&g_st, 5, &e), STORE_E_EMPTY);
}

/* ---- settings ---------------------------------------------------- */

static void test_settings_declaration(void **state)
{
    store_setting_info_t info;
    char buf[64];
    (void)state;
    store_fix_fresh(0xFF);
    assert_true(STORE_SETTING_COUNT >= 6);
    assert_int_equal(store_setting_info(&g_st, STORE_SET_CAL_TENSION, &info), 0);
    assert_int_equal(info.min, 50);
    assert_int_equal(info.max, 5000);
    assert_int_equal(info.def, 800);
    assert_int_equal(info.type, STORE_T_U16);
    assert_int_equal(store_setting_info(&g_st, STORE_SETTING_COUNT, &info), STORE_E_ARG);
    assert_int_equal(store_setting_text(&g_st, STORE_SET_CAL_TENSION, 0, buf, sizeof(buf)), 11);
    assert_string_equal(buf, "cal_tension");
    assert_true(store_setting_text(&g_st, STORE_SET_CAL_TENSION, 1, buf, sizeof(buf)) == 2);
    assert_string_equal(buf, "mN");
    assert_true(store_setting_text(&g_st, STORE_SET_BUS_BAUD, 0, buf, sizeof(buf)) > 0);
    assert_string_equal(buf, "bus_baud");
    assert_true(store_setting_text(&g_st, STORE_SET_BUS_BAUD, 2, buf, sizeof(buf)) > 10);
    /* truncation keeps the full length as the answer */
    assert_int_equal(store_setting_text(&g_st, STORE_SET_CAL_TENSION, 0, buf, 4), 11);
    assert_string_equal(buf, "cal");
    assert_int_equal(store_setting_text(&g_st, STORE_SET_CAL_TENSION, 0, buf, 1), 11);
    assert_string_equal(buf, "");
    assert_int_equal(store_setting_text(&g_st, STORE_SET_CAL_TENSION, 0, buf, 0), STORE_E_ARG);
    assert_int_equal(store_setting_text(&g_st, STORE_SET_CAL_TENSION, 3, buf, 8), STORE_E_ARG);
    assert_int_equal(store_setting_text(&g_st, STORE_SETTING_COUNT, 0, buf, 8), STORE_E_ARG);
    assert_int_equal(store_setting_find(&g_st, "filter_k", 8), STORE_SET_FILTER_K);
    assert_int_equal(store_setting_find(&g_st, "filter_kx", 8), STORE_SET_FILTER_K);
    assert_int_equal(store_setting_find(&g_st, "filter", 6), STORE_E_NAME);
    assert_int_equal(store_setting_find(&g_st, "filter_k2", 9), STORE_E_NAME);
    assert_int_equal(store_setting_find(&g_st, "", 0), STORE_E_NAME);
}

static void test_settings_set_range(void **state)
{
    store_settings_t s, before;
    (void)state;
    store_fix_fresh(0xFF);
    store_settings_defaults(&g_st, &s);
    before = s;
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_CAL_TENSION, 49), STORE_E_RANGE);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_CAL_TENSION, 5001), STORE_E_RANGE);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_TARGET_MODE, -1), STORE_E_RANGE);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SETTING_COUNT, 1), STORE_E_ARG);
    assert_memory_equal(&s, &before, sizeof(s));
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_CAL_TENSION, 50), 0);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_TARGET_MODE, 1), 0);
    assert_int_equal(s.v[STORE_SET_CAL_TENSION], 50);
    assert_int_equal(s.v[STORE_SET_TARGET_MODE], 1);
}

static void test_settings_invalid_restored(void **state)
{
    store_settings_t s, r, d;
    uint16_t crc;
    uint8_t *p;
    (void)state;
    store_fix_fresh(0xFF);
    store_settings_defaults(&g_st, &d);
    s = d;
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_FILTER_K, 3), 0);
    assert_int_equal(store_setting_set(&g_st, &s, STORE_SET_CAL_TENSION, 1500), 0);
    assert_int_equal(store_save_settings(&g_st, &s), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
    /* one value out of range, CRC recomputed so the record is "valid" */
    p = &g_ee.mem[STORE_ADDR_SETTINGS];
    s.v[STORE_SET_FILTER_K] = 1000;
    memcpy(p + 4, &s, sizeof(s));
    crc = store_crc16(0xFFFFu, p, 4u + sizeof(s));
    p[4 + sizeof(s)] = (uint8_t)crc;
    p[5 + sizeof(s)] = (uint8_t)(crc >> 8);
    store_fix_boot();
    assert_int_equal(store_settings_load(&g_st, &r), STORE_E_DEFAULTS);
    assert_int_equal(r.v[STORE_SET_FILTER_K], d.v[STORE_SET_FILTER_K]); /* restored */
    assert_int_equal(r.v[STORE_SET_CAL_TENSION], 1500);                 /* kept */
    /* another settings version: everything back to defaults */
    p[1] = STORE_SETTINGS_VERSION + 1u;
    assert_int_equal(store_settings_load(&g_st, &r), STORE_E_DEFAULTS);
    assert_memory_equal(&r, &d, sizeof(r));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_vector),
        cmocka_unit_test(test_layout),
        cmocka_unit_test(test_empty_eeprom),
        cmocka_unit_test(test_poll_idle_busy_hold),
        cmocka_unit_test(test_one_byte_per_ready),
        cmocka_unit_test(test_unchanged_bytes_not_rewritten),
        cmocka_unit_test(test_roundtrip_all_records),
        cmocka_unit_test(test_other_table_flagged),
        cmocka_unit_test(test_argument_errors),
        cmocka_unit_test(test_history_ring),
        cmocka_unit_test(test_history_gap_stops_count),
        cmocka_unit_test(test_settings_declaration),
        cmocka_unit_test(test_settings_set_range),
        cmocka_unit_test(test_settings_invalid_restored),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
