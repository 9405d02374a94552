/* Fixtures for the store tests (store_fixture.h). */
#include "store_fixture.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <string.h>

#include <cmocka.h>

store_fake_t g_ee;
store_t g_st;

void store_fix_boot(void)
{
    store_fake_power_on(&g_ee);
    assert_int_equal(store_init(&g_st, &g_ee.ee, store_fake_copy), 0);
}

void store_fix_fresh(uint8_t fill)
{
    store_fake_init(&g_ee, fill);
    store_fix_boot();
}

void store_fix_homes(store_homes_t *h, uint32_t cal, int32_t base)
{
    uint8_t t;
    memset(h, 0, sizeof(*h));
    h->table_id = STORE_FIX_TABLE_ID;
    h->cal_count = cal;
    h->tension_mN = 800;
    h->n_tendons = 6;
    h->valid_mask = 0x3F;
    for (t = 0; t < 6; t++) {
        store_home_set(&h->t[t], base + 1000 * t - 2500, base + 1000 * t - 2900);
    }
}

void store_fix_hist(store_hist_t *e, uint32_t cal)
{
    uint8_t t;
    memset(e, 0, sizeof(*e));
    e->cal_count = cal;
    e->table_id = STORE_FIX_TABLE_ID;
    e->tension_mN = (uint16_t)(500 + cal);
    e->n_tendons = 4;
    e->valid_mask = 0xF;
    for (t = 0; t < 4; t++) {
        e->home_ticks[t] = (int32_t)(cal * 10u + t);
    }
}

void store_fix_learned(store_learned_t *l, uint8_t tendon, uint32_t v)
{
    uint8_t g;
    memset(l, 0, sizeof(*l));
    l->table_id = STORE_FIX_TABLE_ID;
    l->tendon = tendon;
    l->n_grid = 5;
    l->grid_mask = 0x15;
    for (g = 0; g < TBL_MAX_GRID; g++) {
        l->target_lsb[g] = (uint16_t)(v + g);
    }
}

void store_fix_save_homes(const store_homes_t *h)
{
    assert_int_equal(store_save_homes(&g_st, h), 1);
    assert_int_equal(store_fake_run(&g_st, STORE_FIX_POLLS), 0);
}
