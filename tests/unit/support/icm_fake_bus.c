#include "icm_fake_bus.h"

#include <stddef.h>
#include <string.h>

static void fb_bits(icm_fake_bus_t *fb, uint32_t bits)
{
    uint64_t ns = (uint64_t)bits * 1000000000u / fb->hz;
    fb->now_ns += ns;
    fb->last_transfer_ns += (uint32_t)ns;
}

static void fb_tick(icm_fake_bus_t *fb)
{
    if (fb->root.advance != NULL) {
        fb->root.advance(fb->root.ctx, fb->now_ns / 1000u);
    }
}

/* Common prologue: stuck bus and timeouts fail before any slave sees a byte. */
static int8_t fb_begin(icm_fake_bus_t *fb)
{
    fb->transfers++;
    fb->last_transfer_ns = 0;
    fb_tick(fb);
    if (fb->stuck_sda) {
        fb_bits(fb, 1);
        return ICM_BUS_E_BUS;
    }
    if (fb->timeouts > 0u) {
        fb->timeouts--;
        fb->now_ns += (uint64_t)ICM_FAKE_TIMEOUT_US * 1000u;
        return ICM_BUS_E_TIMEOUT;
    }
    return ICM_BUS_OK;
}

static uint8_t fb_injected_nack(icm_fake_bus_t *fb, int16_t index)
{
    if (fb->nack_at_byte >= 0 && fb->nack_at_byte == index) {
        fb->nack_at_byte = -1;
        return 1;
    }
    return 0;
}

static uint8_t fb_start(icm_fake_bus_t *fb, uint8_t addr_byte, int16_t index)
{
    uint8_t ack;
    fb_bits(fb, 10); /* START + 9 bits */
    fb_tick(fb);
    fb->bytes++;
    ack = fb->root.start(fb->root.ctx, addr_byte);
    if (fb_injected_nack(fb, index)) {
        ack = 0;
    }
    return ack;
}

static uint8_t fb_write_byte(icm_fake_bus_t *fb, uint8_t b, int16_t index)
{
    uint8_t ack;
    fb_bits(fb, 9);
    fb_tick(fb);
    fb->bytes++;
    if (fb_injected_nack(fb, index)) {
        return 0;
    }
    ack = fb->root.write(fb->root.ctx, b);
    return ack;
}

static void fb_stop(icm_fake_bus_t *fb)
{
    fb_bits(fb, 1);
    fb->root.stop(fb->root.ctx);
    fb_tick(fb);
}

static int8_t fb_write_phase(icm_fake_bus_t *fb, uint8_t addr, const uint8_t *data, uint8_t len,
                             int16_t *index)
{
    uint8_t i;
    if (!fb_start(fb, (uint8_t)(addr << 1), (*index)++)) {
        fb_stop(fb);
        return ICM_BUS_E_ADDR_NACK;
    }
    for (i = 0; i < len; i++) {
        if (!fb_write_byte(fb, data[i], (*index)++)) {
            fb_stop(fb);
            return ICM_BUS_E_DATA_NACK;
        }
    }
    return ICM_BUS_OK;
}

static int8_t fb_write(void *ctx, uint8_t addr, const uint8_t *data, uint8_t len)
{
    icm_fake_bus_t *fb = ctx;
    int16_t index = 0;
    int8_t rc = fb_begin(fb);
    if (rc != ICM_BUS_OK) {
        return rc;
    }
    rc = fb_write_phase(fb, addr, data, len, &index);
    if (rc == ICM_BUS_OK) {
        fb_stop(fb);
    }
    fb->nack_at_byte = -1;
    return rc;
}

static int8_t fb_write_read(void *ctx, uint8_t addr, const uint8_t *wdata, uint8_t wlen,
                            uint8_t *rdata, uint8_t rlen)
{
    icm_fake_bus_t *fb = ctx;
    int16_t index = 0;
    uint8_t i;
    int8_t rc = fb_begin(fb);
    if (rc != ICM_BUS_OK) {
        return rc;
    }
    rc = fb_write_phase(fb, addr, wdata, wlen, &index);
    if (rc == ICM_BUS_OK && fb_injected_nack(fb, index)) {
        fb_stop(fb); /* the repeated START's address byte */
        rc = ICM_BUS_E_ADDR_NACK;
    }
    fb->nack_at_byte = -1;
    if (rc != ICM_BUS_OK) {
        return rc;
    }
    if (!fb_start(fb, (uint8_t)((addr << 1) | 1u), index++)) {
        fb_stop(fb);
        return ICM_BUS_E_ADDR_NACK;
    }
    for (i = 0; i < rlen; i++) {
        fb_bits(fb, 9);
        fb_tick(fb);
        fb->bytes++;
        rdata[i] = fb->root.read(fb->root.ctx, (uint8_t)(i + 1u < rlen));
    }
    fb_stop(fb);
    return ICM_BUS_OK;
}

/* Nine SCL pulses then STOP, as the firmware's recovery does. */
static int8_t fb_recover(void *ctx)
{
    icm_fake_bus_t *fb = ctx;
    fb->recoveries++;
    fb_bits(fb, 10);
    if (fb->stuck_sda && fb->stuck_recoverable) {
        fb->stuck_sda = 0;
    }
    fb->root.stop(fb->root.ctx);
    return fb->stuck_sda ? ICM_BUS_E_BUS : ICM_BUS_OK;
}

void icm_fake_bus_setup(icm_fake_bus_t *fb, simi2c_slave_t root)
{
    memset(fb, 0, sizeof(*fb));
    fb->root = root;
    fb->hz = 400000u;
    fb->nack_at_byte = -1;
    fb->bus.ctx = fb;
    fb->bus.write = fb_write;
    fb->bus.write_read = fb_write_read;
    fb->bus.recover = fb_recover;
}

void icm_fake_bus_sleep_us(icm_fake_bus_t *fb, uint32_t us)
{
    fb->now_ns += (uint64_t)us * 1000u;
    fb_tick(fb);
}

uint32_t icm_fake_bus_now_us(const icm_fake_bus_t *fb)
{
    return (uint32_t)(fb->now_ns / 1000u);
}
