/*
 * tca9548a_model: byte-level model of a TCA9548A I2C multiplexer, and the
 * byte-level I2C slave interface every bus model in sim/devices offers
 * (declared here because the mux is the part that routes to other slaves).
 *
 * The slave interface is what a slave sees on the wire: a START (or repeated
 * START) with the 8-bit address byte, written bytes, bytes the master reads
 * (with the master's ACK/NACK after each), and STOP. The native test bus
 * adapter and the simavr bench both drive models through it.
 *
 * Models are time-driven: `advance` brings a model to the given simulated
 * time (microseconds, monotonic) before the bus touches it.
 */
#ifndef HALLHOME_SIM_TCA9548A_MODEL_H
#define HALLHOME_SIM_TCA9548A_MODEL_H

#include <stdint.h>

typedef struct {
    void *ctx;
    /* START/repeated START with address byte (7-bit address << 1 | R). Returns
     * 1 for ACK, 0 for NACK. */
    uint8_t (*start)(void *ctx, uint8_t addr_byte);
    /* One byte written by the master. Returns 1 for ACK, 0 for NACK. */
    uint8_t (*write)(void *ctx, uint8_t byte);
    /* One byte read by the master; master_ack is 1 when the master ACKs it
     * (more bytes follow), 0 for the final NACK. */
    uint8_t (*read)(void *ctx, uint8_t master_ack);
    /* STOP. */
    void (*stop)(void *ctx);
    /* Brings the model to time now_us. May be NULL. */
    void (*advance)(void *ctx, uint64_t now_us);
} simi2c_slave_t;

#define TCAM_CHANNELS    8u
#define TCAM_PER_CHANNEL 2u /* slaves per channel (0x68 and 0x69) */

typedef struct {
    uint8_t addr;    /* 7-bit, 0x70..0x77 */
    uint8_t present; /* 0: never acknowledges (a missing mux) */
    uint8_t ctrl;    /* control register: bit n enables channel n */
    simi2c_slave_t down[TCAM_CHANNELS][TCAM_PER_CHANNEL];
    uint8_t n_down[TCAM_CHANNELS];
    /* transaction */
    uint8_t target; /* 0 none, 1 the mux itself, 2 downstream */
    uint8_t reading;
    uint8_t acked[TCAM_CHANNELS]; /* per channel: bit i = down[ch][i] acked the address */
    uint32_t ctrl_writes;         /* control bytes received */
} tcam_t;

/* Power-on state: all channels off, no downstream slaves. */
void tcam_init(tcam_t *m, uint8_t addr);

/* Attaches a slave to a channel. Returns 0, or -1 when the channel is out of
 * range or already holds TCAM_PER_CHANNEL slaves. */
int tcam_attach(tcam_t *m, uint8_t channel, simi2c_slave_t slave);

/* This mux as a slave on the upstream bus. */
simi2c_slave_t tcam_slave(tcam_t *m);

#endif /* HALLHOME_SIM_TCA9548A_MODEL_H */
