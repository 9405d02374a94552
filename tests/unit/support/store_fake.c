#include "store_fake.h"

#include <string.h>

static uint8_t fake_busy(store_fake_t *f)
{
    return f->busy_left != 0u;
}

static uint8_t fake_read_byte(void *ctx, uint16_t addr)
{
    store_fake_t *f = (store_fake_t *)ctx;
    if (fake_busy(f)) {
        f->violations++;
    }
    return f->mem[addr % STORE_EEPROM_SIZE];
}

static void fake_read_block(void *ctx, void *dst, uint16_t addr, uint16_t n)
{
    store_fake_t *f = (store_fake_t *)ctx;
    if (fake_busy(f)) {
        f->violations++;
    }
    if ((uint32_t)addr + n > STORE_EEPROM_SIZE) {
        f->violations++;
        return;
    }
    memcpy(dst, &f->mem[addr], n);
}

static uint8_t fake_ready(void *ctx)
{
    store_fake_t *f = (store_fake_t *)ctx;
    if (f->busy_left != 0u) {
        f->busy_left--;
        return 0;
    }
    return 1;
}

static void fake_write_byte(void *ctx, uint16_t addr, uint8_t value)
{
    store_fake_t *f = (store_fake_t *)ctx;
    uint32_t n = f->writes++;
    if (fake_busy(f) || addr >= STORE_EEPROM_SIZE) {
        f->violations++;
    }
    f->busy_left = f->busy_polls;
    if (f->dead || (int32_t)addr == f->stuck_addr) {
        return;
    }
    if (f->cut_at >= 0 && n == (uint32_t)f->cut_at) {
        f->dead = 1;
        if (f->torn == STORE_FAKE_TORN_NEW) {
            f->mem[addr] = value;
        } else if (f->torn == STORE_FAKE_TORN_GARBAGE) {
            /* erase done, program half done: some bits of the new value */
            f->mem[addr] = (uint8_t)(value | 0xF0u);
            if (f->mem[addr] == value) {
                f->mem[addr] = 0xFFu;
            }
        }
        return;
    }
    f->mem[addr] = value;
}

void store_fake_init(store_fake_t *f, uint8_t fill)
{
    memset(f, 0, sizeof(*f));
    memset(f->mem, fill, sizeof(f->mem));
    f->ee.ctx = f;
    f->ee.read_byte = fake_read_byte;
    f->ee.read_block = fake_read_block;
    f->ee.ready = fake_ready;
    f->ee.write_byte = fake_write_byte;
    f->cut_at = -1;
    f->stuck_addr = -1;
}

void store_fake_power_on(store_fake_t *f)
{
    f->dead = 0;
    f->cut_at = -1;
    f->busy_left = 0;
}

void store_fake_copy(void *dst, const void *src, size_t n)
{
    memcpy(dst, src, n);
}

int8_t store_fake_run(store_t *st, uint32_t limit)
{
    int8_t rc = 1;
    while (limit-- > 0u && rc > 0) {
        rc = store_poll(st, 1);
    }
    return rc;
}
