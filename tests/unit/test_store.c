/* Unit tests of lib/store against the RAM EEPROM fake, power cuts included. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "store/store.h"
#include "store_fake.h"

#define TABLE_ID 0xC0FFEE01UL
#define POLLS    100000u

static store_fake_t fake;
static store_t st;

static void boot(void)
{
    store_fake_power_on(&fake);
    assert_int_equal(store_init(&st, &fake.ee, store_fake_copy), 0);
}

static void fresh(uint8_t fill)
{
    store_fake_init(&fake, fill);
    boot();
}

static void make_homes(store_homes_t *h, uint32_t cal, int32_t base)
{
    uint8_t t;
    memset(h, 0, sizeof(*h));
    h->table_id = TABLE_ID;
    h->cal_count = cal;
    h->tension_mN = 800;
    h->n_tendons = 6;
    h->valid_mask = 0x3F;
    for (t = 0; t < 6; t++) {
        store_home_set(&h->t[t], base + 1000 * t - 2500, base + 1000 * t - 2900);
    }
}

static void make_hist(store_hist_t *e, uint32_t cal)
{
    uint8_t t;
    memset(e, 0, sizeof(*e));
    e->cal_count = cal;
    e->table_id = TABLE_ID;
    e->tension_mN = (uint16_t)(500 + cal);
    e->n_tendons = 4;
    e->valid_mask = 0xF;
    for (t = 0; t < 4; t++) {
        e->home_ticks[t] = (int32_t)(cal * 10u + t);
    }
}

static void make_learned(store_learned_t *l, uint8_t tendon, uint32_t v)
{
    uint8_t g;
    memset(l, 0, sizeof(*l));
    l->table_id = TABLE_ID;
    l->tendon = tendon;
    l->n_grid = 5;
    l->grid_mask = 0x15;
    for (g = 0; g < TBL_MAX_GRID; g++) {
        l->target_lsb[g] = (uint16_t)(v + g);
    }
}

static void save_homes_ok(const store_homes_t *h)
{
    assert_int_equal(store_save_homes(&st, h), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
}

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
    fresh(0xFF);
    memset(&h, 0x5A, sizeof(h));
    assert_int_equal(store_homes_load(&st, TABLE_ID, &h), STORE_E_EMPTY);
    assert_int_equal(h.table_id, 0x5A5A5A5Au); /* untouched */
    assert_int_equal(store_learned_load(&st, 0, TABLE_ID, &l), STORE_E_EMPTY);
    assert_int_equal(store_hist_count(&st), 0);
    assert_int_equal(store_hist_get(&st, 0, &e), STORE_E_EMPTY);
    assert_int_equal(store_settings_load(&st, &s), STORE_E_DEFAULTS);
    store_settings_defaults(&st, &d);
    assert_memory_equal(&s, &d, sizeof(s));
    assert_int_equal(s.v[STORE_SET_CAL_TENSION], 800);
    /* an all-zero chip is no valid record either */
    fresh(0x00);
    assert_int_equal(store_homes_load(&st, TABLE_ID, &h), STORE_E_EMPTY);
    assert_int_equal(store_hist_count(&st), 0);
}

static void test_poll_idle_busy_hold(void **state)
{
    store_homes_t h;
    store_settings_t s;
    uint32_t w;
    (void)state;
    fresh(0xFF);
    assert_int_equal(store_poll(&st, 1), STORE_E_IDLE);
    make_homes(&h, 1, 0);
    store_settings_defaults(&st, &s);
    assert_int_equal(store_save_homes(&st, &h), 1);
    assert_true(store_busy(&st));
    assert_int_equal(store_save_settings(&st, &s), STORE_E_BUSY);
    assert_int_equal(store_save_homes(&st, &h), STORE_E_BUSY);
    assert_int_equal(store_save_hist(&st, (const store_hist_t *)NULL), STORE_E_BUSY);
    /* not idle: nothing is written however often it is polled */
    w = fake.writes;
    for (int i = 0; i < 100; i++) {
        assert_int_equal(store_poll(&st, 0), 1);
    }
    assert_int_equal(fake.writes, w);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    assert_false(store_busy(&st));
    assert_int_equal(store_poll(&st, 1), STORE_E_IDLE);
}

static void test_one_byte_per_ready(void **state)
{
    store_homes_t h, r;
    uint32_t polls = 0;
    int8_t rc;
    (void)state;
    fresh(0xFF);
    fake.busy_polls = 3;
    make_homes(&h, 1, 0);
    assert_int_equal(store_save_homes(&st, &h), 1);
    do {
        uint32_t before = fake.writes;
        rc = store_poll(&st, 1);
        assert_true(fake.writes - before <= 1u);
        polls++;
    } while (rc > 0 && polls < POLLS);
    assert_int_equal(rc, 0);
    assert_int_equal(fake.violations, 0);
    /* every byte that differs from the erased chip was written, 4 polls each */
    assert_true(fake.writes <= STORE_SLOT_LEN(sizeof(h)));
    assert_true(fake.writes > STORE_SLOT_LEN(sizeof(h)) / 2u);
    assert_true(polls >= 4u * fake.writes);
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_memory_equal(&r, &h, sizeof(h));
}

static void test_unchanged_bytes_not_rewritten(void **state)
{
    store_homes_t h;
    uint32_t w;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 1, 0);
    save_homes_ok(&h); /* slot A, seq 1 */
    save_homes_ok(&h); /* slot B, seq 2 */
    w = fake.writes;
    save_homes_ok(&h); /* slot A again: only kind (invalidate, restore), seq and CRC change */
    assert_true(fake.writes - w <= 6u);
    assert_true(fake.writes - w >= 3u);
}

static void test_roundtrip_all_records(void **state)
{
    store_settings_t s, r;
    store_homes_t h, hr;
    store_learned_t l, lr;
    store_hist_t e, er;
    (void)state;
    fresh(0xFF);
    store_settings_defaults(&st, &s);
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_CAL_TENSION, 1200), 0);
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_BUS_BAUD, 2000000), 0);
    assert_int_equal(store_save_settings(&st, &s), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    make_homes(&h, 7, -70000);
    save_homes_ok(&h);
    make_learned(&l, 11, 4000);
    assert_int_equal(store_save_learned(&st, &l), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    make_hist(&e, 7);
    assert_int_equal(store_save_hist(&st, &e), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);

    boot(); /* power cycle */
    assert_int_equal(store_settings_load(&st, &r), 0);
    assert_memory_equal(&r, &s, sizeof(s));
    assert_int_equal(store_homes_load(&st, TABLE_ID, &hr), 0);
    assert_memory_equal(&hr, &h, sizeof(h));
    assert_int_equal(store_learned_load(&st, 11, TABLE_ID, &lr), 0);
    assert_memory_equal(&lr, &l, sizeof(l));
    assert_int_equal(store_learned_load(&st, 10, TABLE_ID, &lr), STORE_E_EMPTY);
    assert_int_equal(store_hist_count(&st), 1);
    assert_int_equal(store_hist_get(&st, 0, &er), 0);
    assert_memory_equal(&er, &e, sizeof(e));
    assert_int_equal(fake.violations, 0);
}

static void test_other_table_flagged(void **state)
{
    store_homes_t h, r;
    store_learned_t l, lr;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 3, 0);
    save_homes_ok(&h);
    memset(&r, 0, sizeof(r));
    assert_int_equal(store_homes_load(&st, TABLE_ID + 1u, &r), STORE_E_OTHER_TABLE);
    assert_int_equal(r.table_id, TABLE_ID); /* filled so it can be shown */
    make_learned(&l, 2, 99);
    assert_int_equal(store_save_learned(&st, &l), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    assert_int_equal(store_learned_load(&st, 2, 0x1234, &lr), STORE_E_OTHER_TABLE);
    assert_int_equal(lr.target_lsb[0], 99);
}

static void test_argument_errors(void **state)
{
    store_homes_t h;
    store_learned_t l;
    store_hist_t e;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 1, 0);
    h.n_tendons = STORE_MAX_TENDONS + 1u;
    assert_int_equal(store_save_homes(&st, &h), STORE_E_ARG);
    make_learned(&l, STORE_MAX_TENDONS, 1);
    assert_int_equal(store_save_learned(&st, &l), STORE_E_ARG);
    make_learned(&l, 0, 1);
    l.n_grid = TBL_MAX_GRID + 1u;
    assert_int_equal(store_save_learned(&st, &l), STORE_E_ARG);
    assert_int_equal(store_learned_load(&st, STORE_MAX_TENDONS, TABLE_ID, &l), STORE_E_ARG);
    make_hist(&e, 1);
    e.n_tendons = 200;
    assert_int_equal(store_save_hist(&st, &e), STORE_E_ARG);
    assert_int_equal(store_hist_get(&st, STORE_HIST_N, &e), STORE_E_ARG);
    assert_false(store_busy(&st));
    assert_int_equal(fake.writes, 0);
}

/* ---- two copies -------------------------------------------------- */

static void test_newest_copy_wins_and_alternates(void **state)
{
    store_homes_t h, r;
    uint32_t i;
    (void)state;
    fresh(0xFF);
    for (i = 1; i <= 5; i++) {
        make_homes(&h, i, (int32_t)i * 100);
        save_homes_ok(&h);
        assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
        assert_int_equal(r.cal_count, i);
        /* save i went to slot A for odd i, B for even i */
        assert_int_equal(fake.mem[STORE_ADDR_HOMES + ((i & 1u) ? 0u : STORE_HOMES_STRIDE) + 2u], i);
    }
}

static void test_corrupt_newest_falls_back(void **state)
{
    store_homes_t h, r;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 1, 0);
    save_homes_ok(&h); /* A */
    make_homes(&h, 2, 0);
    save_homes_ok(&h); /* B, newest */
    fake.mem[STORE_ADDR_HOMES + STORE_HOMES_STRIDE + 20u] ^= 0x01u;
    boot();
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_int_equal(r.cal_count, 1);
    /* the next save overwrites the bad slot, not the good one */
    make_homes(&h, 3, 0);
    save_homes_ok(&h);
    assert_int_equal(fake.mem[STORE_ADDR_HOMES + STORE_HOMES_STRIDE + 2u], 2); /* seq 1 + 1 */
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_int_equal(r.cal_count, 3);
    /* both copies bad: empty */
    fake.mem[STORE_ADDR_HOMES + 10u] ^= 0x80u;
    fake.mem[STORE_ADDR_HOMES + STORE_HOMES_STRIDE + 10u] ^= 0x80u;
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), STORE_E_EMPTY);
}

/* Writes a valid homes slot by hand with the given sequence number. */
static void put_homes_slot(uint16_t addr, uint16_t seq, const store_homes_t *h)
{
    uint8_t *p = &fake.mem[addr];
    uint16_t crc;
    p[0] = STORE_KIND_HOMES;
    p[1] = STORE_HOMES_VERSION;
    p[2] = (uint8_t)seq;
    p[3] = (uint8_t)(seq >> 8);
    memcpy(p + 4, h, sizeof(*h));
    crc = store_crc16(0xFFFFu, p, 4u + sizeof(*h));
    p[4 + sizeof(*h)] = (uint8_t)crc;
    p[5 + sizeof(*h)] = (uint8_t)(crc >> 8);
}

static void test_sequence_wraps(void **state)
{
    store_homes_t a, b, r;
    (void)state;
    fresh(0xFF);
    make_homes(&a, 100, 0);
    make_homes(&b, 101, 0);
    put_homes_slot(STORE_ADDR_HOMES, 0xFFFFu, &a);
    put_homes_slot(STORE_ADDR_HOMES + STORE_HOMES_STRIDE, 0x0000u, &b);
    boot();
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_int_equal(r.cal_count, 101); /* 0x0000 follows 0xFFFF */
    /* and the next save goes to A with seq 1 */
    make_homes(&a, 102, 0);
    save_homes_ok(&a);
    assert_int_equal(fake.mem[STORE_ADDR_HOMES + 2u], 1);
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_int_equal(r.cal_count, 102);
}

static void test_wrong_version_or_kind_ignored(void **state)
{
    store_homes_t a, r;
    (void)state;
    fresh(0xFF);
    make_homes(&a, 5, 0);
    put_homes_slot(STORE_ADDR_HOMES, 1, &a);
    boot();
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    fake.mem[STORE_ADDR_HOMES + 1u] = STORE_HOMES_VERSION + 1u;
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), STORE_E_EMPTY);
    fake.mem[STORE_ADDR_HOMES + 1u] = STORE_HOMES_VERSION;
    fake.mem[STORE_ADDR_HOMES] = STORE_KIND_HIST;
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), STORE_E_EMPTY);
}

/* A learned record of format 1 (uint32 cuT targets, 56-byte body) left by
 * an older firmware has a valid CRC but another version: it reads as
 * missing, never as uint16 targets. */
static void test_learned_v1_refused(void **state)
{
    store_learned_t l;
    uint8_t body[56];
    uint8_t *p;
    uint16_t crc, addr = (uint16_t)(STORE_ADDR_LEARNED + 2u * 1u * STORE_LEARNED_STRIDE);
    uint32_t tid = TABLE_ID, t = 12345u;
    (void)state;
    fresh(0xFF);
    memset(body, 0, sizeof body);
    memcpy(body, &tid, 4);
    body[4] = 1;    /* tendon */
    body[5] = 5;    /* n_grid */
    body[6] = 0x1F; /* grid_mask */
    memcpy(body + 8, &t, 4);
    p = &fake.mem[addr];
    p[0] = STORE_KIND_LEARNED;
    p[1] = 1u; /* STORE_LEARNED_VERSION of the uint32 layout */
    p[2] = 1;
    p[3] = 0;
    memcpy(p + 4, body, sizeof body);
    crc = store_crc16(0xFFFFu, p, 4u + sizeof body);
    p[4 + sizeof body] = (uint8_t)crc;
    p[5 + sizeof body] = (uint8_t)(crc >> 8);
    boot();
    assert_int_equal(STORE_LEARNED_VERSION, 2);
    assert_int_equal(store_learned_load(&st, 1, TABLE_ID, &l), STORE_E_EMPTY);
    /* a save of the new layout then reads back */
    make_learned(&l, 1, 700);
    assert_int_equal(store_save_learned(&st, &l), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    memset(&l, 0, sizeof l);
    assert_int_equal(store_learned_load(&st, 1, TABLE_ID, &l), 0);
    assert_int_equal(l.target_lsb[2], 702);
}

/* Until its last write the slot being saved carries no valid kind, so a
 * torn slot cannot pass for a record even if its CRC happened to match. */
static void test_torn_slot_marked_invalid(void **state)
{
    store_homes_t h;
    uint32_t k, needed, base;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 1, 0);
    save_homes_ok(&h); /* A */
    make_homes(&h, 2, 0);
    save_homes_ok(&h); /* B */
    base = fake.writes;
    make_homes(&h, 3, 5000);
    save_homes_ok(&h); /* A again */
    needed = fake.writes - base;
    assert_int_equal(fake.mem[STORE_ADDR_HOMES], STORE_KIND_HOMES);
    for (k = 1; k + 1u < needed; k++) {
        fresh(0xFF);
        make_homes(&h, 1, 0);
        save_homes_ok(&h);
        make_homes(&h, 2, 0);
        save_homes_ok(&h);
        fake.cut_at = (int32_t)(fake.writes + k);
        fake.torn = STORE_FAKE_TORN_GARBAGE;
        make_homes(&h, 3, 5000);
        assert_int_equal(store_save_homes(&st, &h), 1);
        (void)store_fake_run(&st, POLLS);
        assert_int_equal(fake.mem[STORE_ADDR_HOMES], STORE_KIND_NONE);
    }
}

static void test_verify_failure_keeps_old(void **state)
{
    store_homes_t h, r;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 1, 0);
    save_homes_ok(&h);                                            /* A */
    fake.stuck_addr = STORE_ADDR_HOMES + STORE_HOMES_STRIDE + 30; /* worn cell in B */
    make_homes(&h, 2, 12345);
    assert_int_equal(store_save_homes(&st, &h), 1);
    assert_int_equal(store_fake_run(&st, POLLS), STORE_E_VERIFY);
    assert_false(store_busy(&st));
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_int_equal(r.cal_count, 1);
}

/* ---- power cut at every byte ------------------------------------- */

typedef int8_t (*start_fn)(uint32_t version);
typedef uint32_t (*probe_fn)(void); /* version found after the cut, 0 = none */

static int8_t start_homes(uint32_t v)
{
    static store_homes_t h;
    make_homes(&h, v, (int32_t)v * 7919);
    return store_save_homes(&st, &h);
}

static uint32_t probe_homes(void)
{
    store_homes_t r, want;
    if (store_homes_load(&st, TABLE_ID, &r) != 0) {
        return 0;
    }
    make_homes(&want, r.cal_count, (int32_t)r.cal_count * 7919);
    assert_memory_equal(&r, &want, sizeof(r)); /* never a mix of two versions */
    return r.cal_count;
}

static int8_t start_settings(uint32_t v)
{
    static store_settings_t s;
    store_settings_defaults(&st, &s);
    s.v[STORE_SET_CAL_TENSION] = (int32_t)(100 + v);
    s.v[STORE_SET_APPROACH_FAST] = (int32_t)(v % 1000u + 1u);
    return store_save_settings(&st, &s);
}

static uint32_t probe_settings(void)
{
    store_settings_t s;
    uint32_t v;
    if (store_settings_load(&st, &s) != 0) {
        return 0;
    }
    v = (uint32_t)s.v[STORE_SET_CAL_TENSION] - 100u;
    assert_int_equal(s.v[STORE_SET_APPROACH_FAST], (int32_t)(v % 1000u + 1u));
    return v;
}

static int8_t start_learned(uint32_t v)
{
    static store_learned_t l;
    make_learned(&l, 3, v * 1000u);
    l.n_grid = (uint8_t)(v % 12u);
    return store_save_learned(&st, &l);
}

static uint32_t probe_learned(void)
{
    store_learned_t l, want;
    if (store_learned_load(&st, 3, TABLE_ID, &l) != 0) {
        return 0;
    }
    make_learned(&want, 3, l.target_lsb[0]);
    want.n_grid = (uint8_t)((l.target_lsb[0] / 1000u) % 12u);
    assert_memory_equal(&l, &want, sizeof(l));
    return l.target_lsb[0] / 1000u;
}

static int8_t start_hist(uint32_t v)
{
    static store_hist_t e;
    make_hist(&e, v);
    return store_save_hist(&st, &e);
}

static uint32_t probe_hist(void)
{
    store_hist_t e, want;
    if (store_hist_get(&st, 0, &e) != 0) {
        return 0;
    }
    make_hist(&want, e.cal_count);
    assert_memory_equal(&e, &want, sizeof(e));
    return e.cal_count;
}

/* Saves versions 1..3 completely, then for every write k of version 4
 * (and again of version 5, which goes to the other slot) cuts the power
 * in write k with each kind of torn byte, powers on and checks that the
 * newest complete version is intact (or the new one, if it was complete). */
static void cut_everywhere(start_fn start, probe_fn probe)
{
    uint32_t target, k, writes_needed, v;
    uint8_t torn;
    for (target = 4; target <= 5; target++) {
        /* how many writes does a clean save of `target` take? */
        fresh(0xFF);
        for (v = 1; v < target; v++) {
            assert_int_equal(start(v), 1);
            assert_int_equal(store_fake_run(&st, POLLS), 0);
        }
        k = fake.writes;
        assert_int_equal(start(target), 1);
        assert_int_equal(store_fake_run(&st, POLLS), 0);
        writes_needed = fake.writes - k;
        assert_true(writes_needed > 0u);
        assert_int_equal(probe(), target);

        for (torn = 0; torn <= STORE_FAKE_TORN_GARBAGE; torn++) {
            for (k = 0; k < writes_needed; k++) {
                fresh(0xFF);
                for (v = 1; v < target; v++) {
                    assert_int_equal(start(v), 1);
                    assert_int_equal(store_fake_run(&st, POLLS), 0);
                }
                fake.cut_at = (int32_t)(fake.writes + k);
                fake.torn = torn;
                assert_int_equal(start(target), 1);
                (void)store_fake_run(&st, POLLS); /* runs into the cut; result meaningless */
                boot();
                v = probe();
                if (k + 1u == writes_needed && torn == STORE_FAKE_TORN_NEW) {
                    assert_true(v == target || v == target - 1u);
                } else {
                    assert_int_equal(v, target - 1u);
                }
                /* and the store works again after the cut */
                assert_int_equal(start(target + 10u), 1);
                assert_int_equal(store_fake_run(&st, POLLS), 0);
                assert_int_equal(probe(), target + 10u);
            }
        }
    }
}

static void test_cut_homes(void **state)
{
    (void)state;
    cut_everywhere(start_homes, probe_homes);
}

static void test_cut_settings(void **state)
{
    (void)state;
    cut_everywhere(start_settings, probe_settings);
}

static void test_cut_learned(void **state)
{
    (void)state;
    cut_everywhere(start_learned, probe_learned);
}

static void test_cut_history(void **state)
{
    (void)state;
    cut_everywhere(start_hist, probe_hist);
}

static void make_win(store_win_t *w, uint32_t v)
{
    uint8_t i;
    memset(w, 0, sizeof *w);
    w->table_id = TABLE_ID;
    w->n_tendons = 12;
    w->mask = (uint16_t)(v & 0x0FFFu);
    for (i = 0; i < 12u; i++) {
        w->t[i].at_turn = (uint16_t)((v * 7u + i) & 4095u);
        w->t[i].lo = (int16_t)(-(int16_t)(v % 1000u) - (int16_t)i);
        w->t[i].hi = (int16_t)(v % 1000u + i);
    }
}

static int8_t start_win(uint32_t v)
{
    static store_win_t w;
    make_win(&w, v);
    return store_save_win(&st, &w);
}

static uint32_t probe_win(void)
{
    store_win_t w, want;
    if (store_win_load(&st, TABLE_ID, &w) != 0) {
        return 0;
    }
    make_win(&want, w.mask);
    assert_memory_equal(&w, &want, sizeof(w));
    return w.mask;
}

static void test_cut_windows(void **state)
{
    (void)state;
    cut_everywhere(start_win, probe_win);
}

/* ---- history ring ------------------------------------------------ */

static void test_history_ring(void **state)
{
    store_hist_t e;
    uint32_t i;
    (void)state;
    fresh(0xFF);
    for (i = 1; i <= 30; i++) {
        make_hist(&e, i);
        assert_int_equal(store_save_hist(&st, &e), 1);
        assert_int_equal(store_fake_run(&st, POLLS), 0);
        assert_int_equal(store_hist_count(&st), i < STORE_HIST_N ? i : STORE_HIST_N);
    }
    boot();
    assert_int_equal(store_hist_count(&st), STORE_HIST_N);
    for (i = 0; i < STORE_HIST_N; i++) {
        assert_int_equal(store_hist_get(&st, (uint8_t)i, &e), 0);
        assert_int_equal(e.cal_count, 30u - i);
        assert_int_equal(e.home_ticks[3], (int32_t)((30u - i) * 10u + 3u));
    }
    /* a cut in the next save loses the oldest entry only */
    fake.cut_at = (int32_t)(fake.writes + 10u);
    make_hist(&e, 31);
    assert_int_equal(store_save_hist(&st, &e), 1);
    (void)store_fake_run(&st, POLLS);
    boot();
    assert_int_equal(store_hist_get(&st, 0, &e), 0);
    assert_int_equal(e.cal_count, 30);
    assert_int_equal(store_hist_count(&st), STORE_HIST_N - 1u);
    /* the next save reuses the torn slot */
    make_hist(&e, 31);
    assert_int_equal(store_save_hist(&st, &e), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    assert_int_equal(store_hist_count(&st), STORE_HIST_N);
    assert_int_equal(store_hist_get(&st, 0, &e), 0);
    assert_int_equal(e.cal_count, 31);
    assert_int_equal(store_hist_get(&st, STORE_HIST_N - 1u, &e), 0);
    assert_int_equal(e.cal_count, 8);
}

static void test_history_gap_stops_count(void **state)
{
    store_hist_t e;
    uint32_t i;
    (void)state;
    fresh(0xFF);
    for (i = 1; i <= 5; i++) {
        make_hist(&e, i);
        assert_int_equal(store_save_hist(&st, &e), 1);
        assert_int_equal(store_fake_run(&st, POLLS), 0);
    }
    /* damage entry 3 (ring index 2): ages 0,1 readable, age 2 lost, age 3 still there */
    fake.mem[STORE_ADDR_HIST + 2u * STORE_HIST_STRIDE + 9u] ^= 0xFFu;
    boot();
    assert_int_equal(store_hist_count(&st), 2);
    assert_int_equal(store_hist_get(&st, 2, &e), STORE_E_EMPTY);
    assert_int_equal(store_hist_get(&st, 3, &e), 0);
    assert_int_equal(e.cal_count, 2);
    assert_int_equal(store_hist_get(&st, 5, &e), STORE_E_EMPTY);
}

/* ---- settings ---------------------------------------------------- */

static void test_settings_declaration(void **state)
{
    store_setting_info_t info;
    char buf[64];
    (void)state;
    fresh(0xFF);
    assert_true(STORE_SETTING_COUNT >= 6);
    assert_int_equal(store_setting_info(&st, STORE_SET_CAL_TENSION, &info), 0);
    assert_int_equal(info.min, 50);
    assert_int_equal(info.max, 5000);
    assert_int_equal(info.def, 800);
    assert_int_equal(info.type, STORE_T_U16);
    assert_int_equal(store_setting_info(&st, STORE_SETTING_COUNT, &info), STORE_E_ARG);
    assert_int_equal(store_setting_text(&st, STORE_SET_CAL_TENSION, 0, buf, sizeof(buf)), 11);
    assert_string_equal(buf, "cal_tension");
    assert_true(store_setting_text(&st, STORE_SET_CAL_TENSION, 1, buf, sizeof(buf)) == 2);
    assert_string_equal(buf, "mN");
    assert_true(store_setting_text(&st, STORE_SET_BUS_BAUD, 0, buf, sizeof(buf)) > 0);
    assert_string_equal(buf, "bus_baud");
    assert_true(store_setting_text(&st, STORE_SET_BUS_BAUD, 2, buf, sizeof(buf)) > 10);
    /* truncation keeps the full length as the answer */
    assert_int_equal(store_setting_text(&st, STORE_SET_CAL_TENSION, 0, buf, 4), 11);
    assert_string_equal(buf, "cal");
    assert_int_equal(store_setting_text(&st, STORE_SET_CAL_TENSION, 0, buf, 1), 11);
    assert_string_equal(buf, "");
    assert_int_equal(store_setting_text(&st, STORE_SET_CAL_TENSION, 0, buf, 0), STORE_E_ARG);
    assert_int_equal(store_setting_text(&st, STORE_SET_CAL_TENSION, 3, buf, 8), STORE_E_ARG);
    assert_int_equal(store_setting_text(&st, STORE_SETTING_COUNT, 0, buf, 8), STORE_E_ARG);
    assert_int_equal(store_setting_find(&st, "filter_k", 8), STORE_SET_FILTER_K);
    assert_int_equal(store_setting_find(&st, "filter_kx", 8), STORE_SET_FILTER_K);
    assert_int_equal(store_setting_find(&st, "filter", 6), STORE_E_NAME);
    assert_int_equal(store_setting_find(&st, "filter_k2", 9), STORE_E_NAME);
    assert_int_equal(store_setting_find(&st, "", 0), STORE_E_NAME);
}

static void test_settings_set_range(void **state)
{
    store_settings_t s, before;
    (void)state;
    fresh(0xFF);
    store_settings_defaults(&st, &s);
    before = s;
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_CAL_TENSION, 49), STORE_E_RANGE);
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_CAL_TENSION, 5001), STORE_E_RANGE);
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_TARGET_MODE, -1), STORE_E_RANGE);
    assert_int_equal(store_setting_set(&st, &s, STORE_SETTING_COUNT, 1), STORE_E_ARG);
    assert_memory_equal(&s, &before, sizeof(s));
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_CAL_TENSION, 50), 0);
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_TARGET_MODE, 1), 0);
    assert_int_equal(s.v[STORE_SET_CAL_TENSION], 50);
    assert_int_equal(s.v[STORE_SET_TARGET_MODE], 1);
}

static void test_settings_invalid_restored(void **state)
{
    store_settings_t s, r, d;
    uint16_t crc;
    uint8_t *p;
    (void)state;
    fresh(0xFF);
    store_settings_defaults(&st, &d);
    s = d;
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_FILTER_K, 3), 0);
    assert_int_equal(store_setting_set(&st, &s, STORE_SET_CAL_TENSION, 1500), 0);
    assert_int_equal(store_save_settings(&st, &s), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    /* one value out of range, CRC recomputed so the record is "valid" */
    p = &fake.mem[STORE_ADDR_SETTINGS];
    s.v[STORE_SET_FILTER_K] = 1000;
    memcpy(p + 4, &s, sizeof(s));
    crc = store_crc16(0xFFFFu, p, 4u + sizeof(s));
    p[4 + sizeof(s)] = (uint8_t)crc;
    p[5 + sizeof(s)] = (uint8_t)(crc >> 8);
    boot();
    assert_int_equal(store_settings_load(&st, &r), STORE_E_DEFAULTS);
    assert_int_equal(r.v[STORE_SET_FILTER_K], d.v[STORE_SET_FILTER_K]); /* restored */
    assert_int_equal(r.v[STORE_SET_CAL_TENSION], 1500);                 /* kept */
    /* another settings version: everything back to defaults */
    p[1] = STORE_SETTINGS_VERSION + 1u;
    assert_int_equal(store_settings_load(&st, &r), STORE_E_DEFAULTS);
    assert_memory_equal(&r, &d, sizeof(r));
}

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

static void test_load_during_save_sees_old_copy(void **state)
{
    store_homes_t h, r;
    store_hist_t e;
    int i;
    (void)state;
    fresh(0xFF);
    make_homes(&h, 1, 0);
    save_homes_ok(&h);
    make_hist(&e, 1);
    assert_int_equal(store_save_hist(&st, &e), 1);
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    make_homes(&h, 2, 999);
    assert_int_equal(store_save_homes(&st, &h), 1);
    for (i = 0; i < 60; i++) {
        assert_int_equal(store_poll(&st, 1), 1);
        assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
        assert_int_equal(r.cal_count, 1);
    }
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    assert_int_equal(store_homes_load(&st, TABLE_ID, &r), 0);
    assert_int_equal(r.cal_count, 2);
    make_hist(&e, 2);
    assert_int_equal(store_save_hist(&st, &e), 1);
    for (i = 0; i < 30; i++) {
        assert_int_equal(store_poll(&st, 1), 1);
        assert_int_equal(store_hist_count(&st), 1);
        assert_int_equal(store_hist_get(&st, 0, &e), 0);
        assert_int_equal(e.cal_count, 1);
    }
    assert_int_equal(store_fake_run(&st, POLLS), 0);
    assert_int_equal(store_hist_count(&st), 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_vector),
        cmocka_unit_test(test_layout),
        cmocka_unit_test(test_learned_v1_refused),
        cmocka_unit_test(test_empty_eeprom),
        cmocka_unit_test(test_poll_idle_busy_hold),
        cmocka_unit_test(test_one_byte_per_ready),
        cmocka_unit_test(test_unchanged_bytes_not_rewritten),
        cmocka_unit_test(test_roundtrip_all_records),
        cmocka_unit_test(test_other_table_flagged),
        cmocka_unit_test(test_argument_errors),
        cmocka_unit_test(test_newest_copy_wins_and_alternates),
        cmocka_unit_test(test_corrupt_newest_falls_back),
        cmocka_unit_test(test_sequence_wraps),
        cmocka_unit_test(test_wrong_version_or_kind_ignored),
        cmocka_unit_test(test_verify_failure_keeps_old),
        cmocka_unit_test(test_torn_slot_marked_invalid),
        cmocka_unit_test(test_load_during_save_sees_old_copy),
        cmocka_unit_test(test_cut_homes),
        cmocka_unit_test(test_cut_settings),
        cmocka_unit_test(test_cut_learned),
        cmocka_unit_test(test_cut_history),
        cmocka_unit_test(test_cut_windows),
        cmocka_unit_test(test_win_recover),
        cmocka_unit_test(test_history_ring),
        cmocka_unit_test(test_history_gap_stops_count),
        cmocka_unit_test(test_settings_declaration),
        cmocka_unit_test(test_settings_set_range),
        cmocka_unit_test(test_settings_invalid_restored),
        cmocka_unit_test(test_home_set_turns),
        cmocka_unit_test(test_recover_position),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
