/*
 * xl430_model: a byte-level model of one DYNAMIXEL XL430-W250-T on a
 * Protocol 2.0 bus, for the native tests (as the fake servo) and the simavr
 * virtual bench (which only moves bytes between the firmware's UART1 and the
 * models).
 *
 * Time is a uint32_t microsecond count supplied by the caller (wrap-safe).
 * The caller delivers every byte that appears on the bus, from the master or
 * from other servos (never the servo's own), with xl430_rx() at the time its
 * stop bit ends; the model queues its reply bytes, each with the time its
 * stop bit ends, and the caller takes them with xl430_tx_peek()/_pop() when
 * that time has come. The model keeps a control table (e-manual layout, see
 * lib/dxl/dxl_xl430_reg.h), runs the trapezoidal profile of position and
 * extended-position modes, and answers ping, read, write, reg write, action,
 * reboot, clear, factory reset, sync read/write, bulk read/write and fast sync
 * read, honouring Status Return Level and Return Delay Time.
 *
 * Device behaviour modelled on purpose (e-manual XL430-W250-T):
 *  - Present Position is reset to within one turn at power-up, at reboot and
 *    when the operating mode is set to position mode; the shaft itself keeps
 *    its angle (xl430_shaft_ticks()).
 *  - EEPROM fields refuse writes while torque is on (Access Error).
 *  - A hardware error (xl430_inject_hw_error) switches torque off, sets the
 *    alert bit in every status packet and refuses torque on (Result Fail)
 *    until a reboot.
 *  - Sync read and bulk read replies come in list order: each servo answers
 *    after the previous ID's status packet, so a silent servo silences the
 *    ones after it. Fast sync read chunks follow each other with no gap; the
 *    partial CRC of each chunk covers the packet up to that chunk and the
 *    last one is the packet CRC. The model does not stuff fast replies. A
 *    servo waiting for its turn gives up when the bus stays idle for 1 ms
 *    plus three byte times,
 *    and any new instruction packet ends a group read still waiting.
 *  - Bus Watchdog: with torque on and no instruction for the set time, the
 *    servo stops, the field reads 0xFF and goal writes get Data Range Error
 *    until 0 is written.
 *
 * No allocation, no hidden state: everything is in the xl430 struct.
 */
#ifndef HALLHOME_XL430_MODEL_H
#define HALLHOME_XL430_MODEL_H

#include <stdint.h>

#include "dxl/dxl_proto.h"
#include "dxl/dxl_xl430_reg.h"

#define XL430_RX_CAP  192u
#define XL430_TX_CAP  192u
#define XL430_REG_CAP 16u /* bytes a reg write can hold */

typedef struct {
    uint8_t id;
    uint8_t baud_index;    /* control table value, 3 = 1 Mbps */
    uint8_t return_delay;  /* control table value, 2 us units (factory 250) */
    uint8_t bits_per_byte; /* 10 on the wire, 11 in simavr */
    uint8_t firmware;      /* reported firmware version */
    uint32_t boot_us;      /* time a reboot takes before the servo answers again */
    double shaft_ticks;    /* shaft angle at power-up, ticks (4096 per turn) */
} xl430_config;

typedef struct {
    uint8_t ct[DXL_XL430_TABLE_SIZE];
    xl430_config cfg;
    dxl_parser rx;
    uint8_t rx_buf[XL430_RX_CAP];
    /* queued reply */
    uint8_t tx[XL430_TX_CAP];
    uint16_t tx_len;
    uint16_t tx_pos;
    uint32_t tx_t0;   /* start bit of the first reply byte */
    uint32_t tx_baud; /* rate the reply is sent at */
    /* reply that waits for another servo */
    uint8_t wait; /* XL430_WAIT_* in the .c file */
    uint8_t wait_id;
    uint16_t wait_addr;
    uint16_t wait_n;
    uint16_t fast_seen;
    uint16_t fast_need;
    uint16_t fast_crc;
    /* registered write */
    uint16_t reg_addr;
    uint8_t reg_n;
    uint8_t reg_data[XL430_REG_CAP];
    /* motion, in shaft ticks */
    double shaft;
    double vel;    /* ticks/s */
    double target; /* shaft ticks the profile heads for */
    double base;   /* shaft ticks where the multi-turn count is zero */
    uint32_t now;
    uint32_t last_rx;
    uint32_t last_inst;
    uint32_t boot_until;
    uint8_t booting;
    uint8_t started;
    /* counters */
    uint16_t instructions;  /* instruction packets addressed to this servo */
    uint16_t replies;       /* status packets queued */
    uint16_t reboots;       /* Reboot instructions carried out */
    uint16_t eeprom_writes; /* writes stored into the EEPROM area (addresses 0..63) */
} xl430;

/* Factory defaults for `id` at 1 Mbps, return delay 250 (500 us), 10 bits per
 * byte, firmware 46, 300 ms boot, shaft at 0. */
void xl430_config_default(xl430_config *cfg, uint8_t id);

/* Powers the servo up at time t_us with `cfg` (copied). */
void xl430_init(xl430 *m, const xl430_config *cfg, uint32_t t_us);

/* Power cycle at t_us: RAM back to defaults, multi-turn count lost, torque
 * off, hardware error cleared, pending replies dropped. */
void xl430_power_cycle(xl430 *m, uint32_t t_us);

/* Advances motion and timers to t_us (never backwards). */
void xl430_step(xl430 *m, uint32_t t_us);

/* A byte seen on the bus whose stop bit ended at t_us. */
void xl430_rx(xl430 *m, uint8_t byte, uint32_t t_us);

/* Next reply byte: stores it and the time its stop bit ends; returns 1, or 0
 * when nothing is queued (or the servo waits for another servo's turn). */
uint8_t xl430_tx_peek(const xl430 *m, uint8_t *byte, uint32_t *due_us);

/* Removes the byte xl430_tx_peek() returned. */
void xl430_tx_pop(xl430 *m);

/* Nonzero while the servo drives the bus at t_us (from the start bit of its
 * first reply byte to the stop bit of its last). */
uint8_t xl430_transmitting(const xl430 *m, uint32_t t_us);

/* Current bit rate (from the Baud Rate field). */
uint32_t xl430_baud(const xl430 *m);

/* Sets hardware error bits (DXL_XL430_HW_ERR_*): torque goes off, replies
 * carry the alert bit until a reboot. */
void xl430_inject_hw_error(xl430 *m, uint8_t bits);

/* Present Position as the servo reports it (ticks, multi-turn in mode 4). */
int32_t xl430_present_position(const xl430 *m);

/* Physical shaft angle in ticks since the model was created: never reset,
 * the quantity the robot plant turns into spool travel. */
double xl430_shaft_ticks(const xl430 *m);

/* Sets what the servo senses: Present Load (0.1 %), input voltage (0.1 V),
 * temperature (degC). */
void xl430_set_sensed(xl430 *m, int16_t load, uint16_t voltage, uint8_t temperature);

/* Reads `size` (1, 2, 4) bytes of the control table at addr, little-endian;
 * 0 outside the table. */
uint32_t xl430_get(const xl430 *m, uint16_t addr, uint8_t size);

#endif /* HALLHOME_XL430_MODEL_H */
