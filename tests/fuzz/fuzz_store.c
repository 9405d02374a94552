/*
 * libFuzzer target for the store: the input is an arbitrary EEPROM image
 * (plus a cut position). Whatever the chip holds, loads never crash, settings
 * always come out inside their declared ranges, a completed save always reads
 * back as saved, and a save cut at any byte leaves either the old record or
 * the new one, never anything else.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "store/store.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

typedef struct {
    uint8_t mem[STORE_EEPROM_SIZE];
    uint32_t writes;
    int32_t cut_at;
} fz_ee_t;

static fz_ee_t ee;

static uint8_t ee_read(void *ctx, uint16_t addr)
{
    (void)ctx;
    if (addr >= STORE_EEPROM_SIZE) {
        abort();
    }
    return ee.mem[addr];
}

static void ee_block(void *ctx, void *dst, uint16_t addr, uint16_t n)
{
    (void)ctx;
    if ((uint32_t)addr + n > STORE_EEPROM_SIZE) {
        abort();
    }
    memcpy(dst, &ee.mem[addr], n);
}

static uint8_t ee_ready(void *ctx)
{
    (void)ctx;
    return 1;
}

static void ee_write(void *ctx, uint16_t addr, uint8_t v)
{
    (void)ctx;
    if (addr >= STORE_EEPROM_SIZE) {
        abort();
    }
    if (ee.cut_at >= 0 && ee.writes >= (uint32_t)ee.cut_at) {
        ee.writes++;
        return; /* power is gone */
    }
    ee.writes++;
    ee.mem[addr] = v;
}

static void copy(void *dst, const void *src, size_t n)
{
    memcpy(dst, src, n);
}

static const store_eeprom_t iface = {NULL, ee_read, ee_block, ee_ready, ee_write};

static void run(store_t *st)
{
    int n = 0;
    while (store_poll(st, 1) > 0) {
        if (++n > 100000) {
            abort(); /* a save always ends */
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    store_t st;
    store_settings_t s;
    store_homes_t old_h, new_h, h;
    store_hist_t e;
    store_learned_t l;
    store_setting_info_t info;
    int8_t old_rc, rc;
    uint8_t i, n;
    uint16_t cut = 0;
    if (size >= 2u) {
        cut = (uint16_t)(data[0] | (data[1] << 8));
        data += 2;
        size -= 2u;
    }
    memset(ee.mem, 0xFF, sizeof(ee.mem));
    memcpy(ee.mem, data, size < sizeof(ee.mem) ? size : sizeof(ee.mem));
    ee.writes = 0;
    ee.cut_at = -1;
    store_init(&st, &iface, copy);

    (void)store_settings_load(&st, &s);
    for (i = 0; i < STORE_SETTING_COUNT; i++) {
        store_setting_info(&st, i, &info);
        if (s.v[i] < info.min || s.v[i] > info.max) {
            abort();
        }
    }
    n = store_hist_count(&st);
    if (n > STORE_HIST_N) {
        abort();
    }
    for (i = 0; i < n; i++) {
        if (store_hist_get(&st, i, &e) != 0) {
            abort();
        }
    }
    for (i = 0; i < STORE_MAX_TENDONS; i++) {
        rc = store_learned_load(&st, i, 0, &l);
        if (rc == 0 && l.tendon != i) {
            abort();
        }
    }

    /* a complete save reads back as saved, whatever was there before */
    memset(&new_h, 0, sizeof(new_h));
    new_h.table_id = 7;
    new_h.cal_count = (uint32_t)size;
    new_h.n_tendons = 2;
    store_home_set(&new_h.t[0], (int32_t)cut * 3, -(int32_t)cut);
    if (store_save_homes(&st, &new_h) != 1) {
        abort();
    }
    run(&st);
    if (store_homes_load(&st, 7, &h) != 0 || memcmp(&h, &new_h, sizeof(h)) != 0) {
        abort();
    }

    /* a cut save leaves the old record or the new one */
    old_rc = store_homes_load(&st, 7, &old_h);
    new_h.cal_count++;
    new_h.t[1].home_ticks = 12345;
    ee.writes = 0;
    ee.cut_at = cut % 200u;
    if (store_save_homes(&st, &new_h) != 1) {
        abort();
    }
    run(&st);
    store_init(&st, &iface, copy);
    rc = store_homes_load(&st, 7, &h);
    if (rc != 0 || old_rc != 0) {
        abort();
    }
    if (memcmp(&h, &old_h, sizeof(h)) != 0 && memcmp(&h, &new_h, sizeof(h)) != 0) {
        abort();
    }
    return 0;
}
