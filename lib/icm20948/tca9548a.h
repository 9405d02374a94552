/*
 * tca9548a: TCA9548A 1-to-8 I2C multiplexer (TI SCPS207, "Register Maps",
 * "Control Register": one byte, bit n enables channel n; 0 disables all).
 * Part of the icm20948 module directory, prefix tca_.
 *
 * The last written control byte is cached so selecting the channel already
 * selected costs no bus traffic. Exactly one channel is on at a time, so two
 * sensors with the same address on different channels never collide.
 *
 * Error convention: 0 = done, negative = TCA_E_* code.
 */
#ifndef HALLHOME_TCA9548A_H
#define HALLHOME_TCA9548A_H

#include <stdint.h>

#include "icm20948/icm20948.h"

#define TCA_ADDR_DEFAULT 0x70u
#define TCA_CHANNELS     8u

/* The bus errors are the sensor driver's (icm_bus_error() maps a bus result
 * for both), so a failed select reads the same wherever it surfaces. */
enum tca_err {
    TCA_E_ARG = ICM_E_ARG,         /* NULL pointer, address outside 0x70..0x77, channel > 7 */
    TCA_E_ABSENT = ICM_E_ABSENT,   /* the multiplexer did not acknowledge its address */
    TCA_E_NACK = ICM_E_NACK,       /* the control byte was refused */
    TCA_E_TIMEOUT = ICM_E_TIMEOUT, /* the bus timed out */
    TCA_E_BUS = ICM_E_BUS          /* bus error */
};

typedef struct tca {
#if !ICM_BUS_FIXED
    const icm_bus_t *bus;
#endif
    uint8_t addr;    /* 7-bit, 0x70..0x77 */
    uint8_t ctrl;    /* cached control register */
    uint8_t valid;   /* ctrl reflects the device */
    uint16_t writes; /* control writes made (for diagnostics and tests) */
    uint16_t errors; /* failed control writes */
} tca_t;

/* Prepares mux; the cache starts invalid so the first select always writes.
 * Returns 0 or TCA_E_ARG. */
int8_t tca_setup(tca_t *mux, const icm_bus_t *bus, uint8_t addr);

/* Enables `channel` alone (every other channel off). Writes only when the
 * cache differs. Returns 0, TCA_E_ARG, or TCA_E_ABSENT / TCA_E_NACK /
 * TCA_E_TIMEOUT / TCA_E_BUS (the cache is then invalid, so the next select
 * writes again). */
int8_t tca_select(tca_t *mux, uint8_t channel);

/* Disables every channel (always writes). Same returns as tca_select(). */
int8_t tca_disable_all(tca_t *mux);

/* Forgets the cached state, e.g. after a bus recovery or a mux reset. */
void tca_invalidate(tca_t *mux);

#endif /* HALLHOME_TCA9548A_H */
