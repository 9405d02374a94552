/*
 * icm_fake_bus: an icm_bus_t for native tests that drives the byte-level
 * device models of sim/devices (a mux, ICMs) like a 400 kHz I2C master.
 *
 * It keeps a simulated clock: each transfer advances it by the wire time of
 * its bits (9 per byte, one each for START, repeated START and STOP at
 * `hz`), and the models are advanced before every byte. Faults can be
 * injected: a NACK at a given byte of the next transfer, SDA stuck low
 * (recoverable by the bus recovery or not), and transfers that time out.
 */
#ifndef HALLHOME_ICM_FAKE_BUS_H
#define HALLHOME_ICM_FAKE_BUS_H

#include <stdint.h>

#include "devices/tca9548a_model.h"
#include "icm20948/icm20948.h"

#define ICM_FAKE_TIMEOUT_US 1000u /* wire time charged for a timed-out transfer */

typedef struct {
    simi2c_slave_t root; /* what is wired to the master: the mux or one ICM */
    icm_bus_t bus;       /* the interface handed to the driver */
    uint64_t now_ns;     /* simulated clock */
    uint32_t hz;         /* SCL frequency, 400000 by default */
    /* fault injection */
    int16_t nack_at_byte;      /* >= 0: NACK byte n (0 = address) of the next transfer, once */
    uint8_t stuck_sda;         /* SDA held low: every transfer fails with ICM_BUS_E_BUS */
    uint8_t stuck_recoverable; /* recover() releases a stuck SDA */
    uint8_t timeouts;          /* this many next transfers time out */
    /* statistics */
    uint32_t transfers;
    uint32_t bytes;
    uint32_t recoveries;
    uint32_t last_transfer_ns;
} icm_fake_bus_t;

/* Wires `root` to a fresh master at time 0 and fills fb->bus. */
void icm_fake_bus_setup(icm_fake_bus_t *fb, simi2c_slave_t root);

/* Lets simulated time pass with the bus idle. */
void icm_fake_bus_sleep_us(icm_fake_bus_t *fb, uint32_t us);

/* Simulated time in microseconds (the driver's now_us). */
uint32_t icm_fake_bus_now_us(const icm_fake_bus_t *fb);

#endif /* HALLHOME_ICM_FAKE_BUS_H */
