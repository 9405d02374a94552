/*
 * dxl_bench: the servo bus cycle "sync write 6 goal positions + sync read 6
 * present positions" at 1 Mbps, return delay 0. Reports, does not judge:
 * the figure from byte counts (10 bit times per byte on the wire, 11 in
 * simavr), and the same cycle run by the master against six servo models on
 * the simulated bus, plus the fast sync read variant and the factory return
 * delay for comparison.
 */
#include <stdio.h>

#include "dxl/dxl.h"
#include "dxl/dxl_xl430_reg.h"
#include "dxl_fakebus.h"

#define SERVOS 6u
#define BAUD   1000000UL

static uint16_t request_bytes(uint8_t fast, uint16_t *write_len)
{
    uint8_t buf[128];
    uint8_t ids[SERVOS];
    uint8_t data[SERVOS * 4u] = {0};
    uint16_t len = 0;
    for (uint8_t i = 0; i < SERVOS; i++) {
        ids[i] = (uint8_t)(i + 1u);
    }
    (void)dxl_build_sync_write(buf, sizeof buf, DXL_XL430_GOAL_POSITION_ADDR, 4, ids, data, SERVOS,
                               write_len);
    if (fast) {
        (void)dxl_build_fast_sync_read(buf, sizeof buf, DXL_XL430_PRESENT_POSITION_ADDR, 4, ids,
                                       SERVOS, &len);
    } else {
        (void)dxl_build_sync_read(buf, sizeof buf, DXL_XL430_PRESENT_POSITION_ADDR, 4, ids, SERVOS,
                                  &len);
    }
    return len;
}

/* One cycle on the simulated bus; returns microseconds from the first byte of
 * the sync write to the last byte of the read reply, or 0 on failure. */
static uint32_t simulated_cycle(uint8_t bits, uint8_t fast, uint8_t return_delay)
{
    static dxl_fakebus bus;
    static xl430 servo[SERVOS];
    static dxl_master m;
    dxl_port port;
    dxl_config cfg;
    uint8_t ids[SERVOS];
    uint8_t data[SERVOS * 4u];
    dxl_fakebus_init(&bus, BAUD, bits);
    for (uint8_t i = 0; i < SERVOS; i++) {
        xl430_config c;
        xl430_config_default(&c, (uint8_t)(i + 1u));
        c.bits_per_byte = bits;
        c.return_delay = return_delay;
        xl430_init(&servo[i], &c, 0);
        dxl_fakebus_add(&bus, &servo[i]);
        ids[i] = (uint8_t)(i + 1u);
        dxl_put_le(&data[i * 4u], 1000u + i, 4);
    }
    dxl_fakebus_port(&bus, &port);
    dxl_config_default(&cfg, BAUD, bits);
    dxl_master_init(&m, &port, &cfg);
    uint32_t t0 = bus.now;
    if (dxl_sync_write(&m, DXL_XL430_GOAL_POSITION_ADDR, 4, ids, data, SERVOS) != 1 ||
        dxl_fakebus_run(&bus, &m, 100000) != 0) {
        return 0;
    }
    int8_t rc = fast ? dxl_fast_sync_read(&m, DXL_XL430_PRESENT_POSITION_ADDR, 4, ids, SERVOS)
                     : dxl_sync_read(&m, DXL_XL430_PRESENT_POSITION_ADDR, 4, ids, SERVOS);
    if (rc != 1 || dxl_fakebus_run(&bus, &m, 100000) != 0 || bus.collisions != 0) {
        return 0;
    }
    return bus.last_rx_us - t0;
}

int main(void)
{
    uint16_t sw_len = 0;
    uint16_t sr_len = request_bytes(0, &sw_len);
    uint16_t fr_len = request_bytes(1, &sw_len);
    uint16_t status_len = 11u + 4u;
    uint16_t sync_total = (uint16_t)(sw_len + sr_len + SERVOS * status_len);
    uint16_t fast_reply = (uint16_t)(8u + SERVOS * (4u + 4u));
    uint16_t fast_total = (uint16_t)(sw_len + fr_len + fast_reply);
    printf("bus cycle: sync write %u goal positions + read %u present positions, %lu bit/s, "
           "return delay 0\n",
           SERVOS, SERVOS, BAUD);
    printf("bytes: sync write %u, sync read %u + %u x %u status = %u total; "
           "fast sync read %u + %u reply = %u total\n",
           sw_len, sr_len, SERVOS, status_len, sync_total, fr_len, fast_reply, fast_total);
    printf("%-34s %10s %10s\n", "", "10 bit/B", "11 bit/B");
    printf("%-34s %7.3f ms %7.3f ms\n", "sync read, from byte counts", sync_total * 10 / 1000.0,
           sync_total * 11 / 1000.0);
    printf("%-34s %7.3f ms %7.3f ms\n", "sync read, simulated bus",
           simulated_cycle(10, 0, 0) / 1000.0, simulated_cycle(11, 0, 0) / 1000.0);
    printf("%-34s %7.3f ms %7.3f ms\n", "fast sync read, from byte counts",
           fast_total * 10 / 1000.0, fast_total * 11 / 1000.0);
    printf("%-34s %7.3f ms %7.3f ms\n", "fast sync read, simulated bus",
           simulated_cycle(10, 1, 0) / 1000.0, simulated_cycle(11, 1, 0) / 1000.0);
    printf("%-34s %7.3f ms %7.3f ms\n", "sync read, return delay 500 us",
           simulated_cycle(10, 0, 250) / 1000.0, simulated_cycle(11, 0, 250) / 1000.0);
    printf("target: at most 1.5 ms per cycle\n");
    return 0;
}
