#include "dxl_fakebus.h"

#include <string.h>

void dxl_fakebus_init(dxl_fakebus *bus, uint32_t baud, uint8_t bits)
{
    memset(bus, 0, sizeof(*bus));
    bus->baud = baud;
    bus->bits = bits;
    bus->corrupt_at = -1;
}

void dxl_fakebus_add(dxl_fakebus *bus, xl430 *servo)
{
    if (bus->n < DXL_FAKEBUS_SERVOS) {
        bus->servo[bus->n++] = servo;
    }
}

static uint16_t dxl_fakebus_write(void *ctx, const uint8_t *data, uint16_t n)
{
    dxl_fakebus *bus = ctx;
    uint64_t byte_ns = (uint64_t)bus->bits * 1000000000ULL / bus->baud;
    if (bus->dir != DXL_DIR_TX) {
        bus->write_no_dir++;
    }
    if (bus->write_limit != 0 && n > bus->write_limit) {
        n = bus->write_limit;
    }
    uint16_t taken = 0;
    while (taken < n) {
        uint16_t next = (uint16_t)((bus->out_head + 1u) % DXL_FAKEBUS_QUEUE);
        if (next == bus->out_tail) {
            break;
        }
        uint64_t start = bus->line_free_ns > bus->now_ns ? bus->line_free_ns : bus->now_ns;
        bus->line_free_ns = start + byte_ns;
        bus->out[bus->out_head] = data[taken++];
        bus->out_due_ns[bus->out_head] = bus->line_free_ns;
        bus->out_head = next;
    }
    return taken;
}

static uint16_t dxl_fakebus_read(void *ctx, uint8_t *out, uint16_t cap)
{
    dxl_fakebus *bus = ctx;
    uint16_t n = 0;
    while (n < cap && bus->in_tail != bus->in_head) {
        out[n++] = bus->in[bus->in_tail];
        bus->in_tail = (uint16_t)((bus->in_tail + 1u) % DXL_FAKEBUS_QUEUE);
    }
    return n;
}

static void dxl_fakebus_set_dir(void *ctx, uint8_t dir)
{
    dxl_fakebus *bus = ctx;
    bus->dir = dir;
}

static uint8_t dxl_fakebus_tx_done(void *ctx)
{
    const dxl_fakebus *bus = ctx;
    return bus->out_head == bus->out_tail && bus->dir == DXL_DIR_RX;
}

static uint32_t dxl_fakebus_now(void *ctx)
{
    const dxl_fakebus *bus = ctx;
    return bus->now;
}

void dxl_fakebus_port(dxl_fakebus *bus, dxl_port *port)
{
    port->ctx = bus;
    port->write = dxl_fakebus_write;
    port->read = dxl_fakebus_read;
    port->set_dir = dxl_fakebus_set_dir;
    port->tx_done = dxl_fakebus_tx_done;
    port->now_us = dxl_fakebus_now;
}

static void dxl_fakebus_to_master(dxl_fakebus *bus, uint8_t byte)
{
    uint16_t next = (uint16_t)((bus->in_head + 1u) % DXL_FAKEBUS_QUEUE);
    if (next != bus->in_tail) {
        bus->in[bus->in_head] = byte;
        bus->in_head = next;
        bus->last_rx_us = bus->now;
    }
}

void dxl_fakebus_inject(dxl_fakebus *bus, const uint8_t *bytes, uint16_t n)
{
    for (uint16_t i = 0; i < n; i++) {
        dxl_fakebus_to_master(bus, bytes[i]);
    }
}

static void dxl_fakebus_tick(dxl_fakebus *bus)
{
    bus->now++;
    bus->now_ns = (uint64_t)bus->now * 1000u;
    while (bus->out_tail != bus->out_head && bus->out_due_ns[bus->out_tail] <= bus->now_ns) {
        uint8_t byte = bus->out[bus->out_tail];
        bus->out_tail = (uint16_t)((bus->out_tail + 1u) % DXL_FAKEBUS_QUEUE);
        bus->master_bytes++;
        for (uint8_t i = 0; i < bus->n; i++) {
            if (xl430_transmitting(bus->servo[i], bus->now)) {
                bus->collisions++;
            }
            xl430_rx(bus->servo[i], byte, bus->now);
        }
    }
    if (bus->out_tail == bus->out_head && bus->line_free_ns <= bus->now_ns &&
        bus->dir == DXL_DIR_TX) {
        bus->dir = DXL_DIR_RX; /* the driver's end-of-frame turnaround */
    }
    for (uint8_t i = 0; i < bus->n; i++) {
        xl430 *s = bus->servo[i];
        uint8_t byte;
        uint32_t due;
        if (bus->now % 250u == 0) {
            xl430_step(s, bus->now); /* receiving a byte steps the model too */
        }
        while (xl430_tx_peek(s, &byte, &due) && (int32_t)(bus->now - due) >= 0) {
            xl430_tx_pop(s);
            uint8_t heard = byte;
            if (bus->corrupt_at >= 0 && (uint32_t)bus->corrupt_at == bus->servo_bytes) {
                heard ^= 0x10;
            }
            bus->servo_bytes++;
            for (uint8_t k = 0; k < bus->n; k++) {
                if (k == i) {
                    continue;
                }
                if (xl430_transmitting(bus->servo[k], due)) {
                    bus->collisions++;
                }
                xl430_rx(bus->servo[k], byte, due);
            }
            if (bus->dir == DXL_DIR_RX) {
                dxl_fakebus_to_master(bus, heard);
            } else {
                bus->lost_while_tx++;
            }
        }
    }
}

void dxl_fakebus_advance(dxl_fakebus *bus, uint32_t us)
{
    for (uint32_t i = 0; i < us; i++) {
        dxl_fakebus_tick(bus);
    }
}

int8_t dxl_fakebus_run(dxl_fakebus *bus, dxl_master *m, uint32_t max_us)
{
    int8_t rc = dxl_poll(m);
    for (uint32_t t = 0; rc > 0 && t < max_us; t++) {
        dxl_fakebus_tick(bus);
        rc = dxl_poll(m);
    }
    return rc;
}

int8_t dxl_fakebus_run_bringup(dxl_fakebus *bus, dxl_bringup *b, uint32_t max_us)
{
    int8_t rc = dxl_bringup_poll(b);
    for (uint32_t t = 0; rc > 0 && t < max_us; t++) {
        dxl_fakebus_tick(bus);
        rc = dxl_bringup_poll(b);
    }
    return rc;
}
