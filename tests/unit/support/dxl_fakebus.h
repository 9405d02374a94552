/*
 * dxl_fakebus: a simulated half-duplex DYNAMIXEL bus for native tests and
 * tools. It implements the dxl_port of lib/dxl on a microsecond clock of its
 * own, carries the master's bytes to xl430 models and their replies back,
 * byte by byte at the configured rate, and can corrupt, inject and count.
 *
 * Like the firmware's UART1 driver, it turns the bus back to receive by
 * itself once the master's last byte has left.
 */
#ifndef HALLHOME_DXL_FAKEBUS_H
#define HALLHOME_DXL_FAKEBUS_H

#include <stdint.h>

#include "devices/xl430_model.h"
#include "dxl/dxl.h"

#define DXL_FAKEBUS_SERVOS 12u
#define DXL_FAKEBUS_QUEUE  512u

typedef struct {
    xl430 *servo[DXL_FAKEBUS_SERVOS];
    uint8_t n;
    uint32_t now; /* us */
    uint64_t now_ns;
    uint32_t baud;
    uint8_t bits;
    /* master to bus */
    uint8_t out[DXL_FAKEBUS_QUEUE];
    uint64_t out_due_ns[DXL_FAKEBUS_QUEUE];
    uint16_t out_head, out_tail;
    uint64_t line_free_ns;
    uint8_t dir;
    /* bus to master */
    uint8_t in[DXL_FAKEBUS_QUEUE];
    uint16_t in_head, in_tail;
    /* faults and counters */
    int32_t corrupt_at;     /* servo byte index (from now) to flip, -1 for none */
    uint32_t servo_bytes;   /* servo bytes put on the bus */
    uint32_t master_bytes;  /* master bytes put on the bus */
    uint32_t collisions;    /* bytes sent while another device was sending */
    uint32_t lost_while_tx; /* servo bytes that arrived while the master drove the bus */
    uint32_t write_no_dir;  /* master writes while the direction was receive */
    uint16_t write_limit;   /* most bytes one write call takes (0: no limit) */
    uint32_t last_rx_us;    /* time the last byte reached the master */
} dxl_fakebus;

/* An empty bus at `baud`, `bits` per byte (10 real, 11 simavr), time 0. */
void dxl_fakebus_init(dxl_fakebus *bus, uint32_t baud, uint8_t bits);

/* Connects a servo model (at most DXL_FAKEBUS_SERVOS). */
void dxl_fakebus_add(dxl_fakebus *bus, xl430 *servo);

/* The port functions bound to this bus. */
void dxl_fakebus_port(dxl_fakebus *bus, dxl_port *port);

/* Moves time forward by `us`, one microsecond at a time. */
void dxl_fakebus_advance(dxl_fakebus *bus, uint32_t us);

/* Puts bytes straight into the master's receive queue, as if just received. */
void dxl_fakebus_inject(dxl_fakebus *bus, const uint8_t *bytes, uint16_t n);

/* Polls the master, one microsecond per poll, until its transaction is over
 * or `max_us` passed. Returns dxl_poll()'s last value. */
int8_t dxl_fakebus_run(dxl_fakebus *bus, dxl_master *m, uint32_t max_us);

/* Same for a bring-up. */
int8_t dxl_fakebus_run_bringup(dxl_fakebus *bus, dxl_bringup *b, uint32_t max_us);

#endif /* HALLHOME_DXL_FAKEBUS_H */
