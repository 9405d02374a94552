#include "twi.h"

#include <stddef.h>

#include <avr/io.h>
#include <util/delay.h>
#include <util/twi.h>

#include "board.h"
#include "tick.h"

/* ATmega2560 datasheet (2549Q), section 24.5.2 "Bit Rate Generator Unit":
 * SCL = F_CPU / (16 + 2 * TWBR * prescaler). 16 MHz, 400 kHz -> TWBR 12. */
#define TWI_TWBR ((F_CPU / BOARD_TWI_HZ - 16u) / 2u)
#if TWI_TWBR < 1 || TWI_TWBR > 255
#error "BOARD_TWI_HZ out of reach with prescaler 1"
#endif

/* A second bound on every wait, in loop iterations, for when the tick does
 * not advance (interrupts off): each iteration reads tick_us(), > 1 us. */
#define TWI_SPIN_MAX 20000u

#define TWI_SDA _BV(BOARD_TWI_SDA_BIT)
#define TWI_SCL _BV(BOARD_TWI_SCL_BIT)

static uint16_t twi_recovery_count;

void twi_init(void)
{
    BOARD_TWI_DDR &= (uint8_t) ~(TWI_SDA | TWI_SCL);
    BOARD_TWI_PORT &= (uint8_t) ~(TWI_SDA | TWI_SCL); /* external pull-ups only */
    TWSR = 0;                                         /* prescaler 1 */
    TWBR = (uint8_t)TWI_TWBR;
    TWCR = _BV(TWEN);
}

/* TWINT is tested TWI_FAST_SPINS times between deadline checks: reading
 * tick_us() takes a few microseconds, which would otherwise add up to a
 * third to every 22.5 us byte. */
#define TWI_FAST_SPINS 32u

/* Waits (bounded) until the bits `mask` of the register at reg read `want`,
 * testing them `polls` times between deadline checks: 0, or
 * ICM_BUS_E_TIMEOUT. */
static int8_t twi_wait(volatile uint8_t *reg, uint8_t mask, uint8_t want, uint8_t polls)
{
    uint32_t t0 = tick_us();
    uint16_t spin = 0;
    for (;;) {
        uint8_t n;
        for (n = 0; n < polls; n++) {
            if ((*reg & mask) == want) {
                return 0;
            }
        }
        if ((uint32_t)(tick_us() - t0) > TWI_BYTE_DEADLINE_US || ++spin > TWI_SPIN_MAX) {
            return ICM_BUS_E_TIMEOUT;
        }
    }
}

static int8_t twi_wait_int(void)
{
    return twi_wait(&TWCR, _BV(TWINT), _BV(TWINT), TWI_FAST_SPINS);
}

/* Sends STOP and waits (bounded) for the hardware to put it on the wire. */
static int8_t twi_stop(void)
{
    TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWSTO);
    return twi_wait(&TWCR, _BV(TWSTO), 0, 1);
}

/* Ends a failed transfer: a NACK leaves a healthy bus (STOP is enough); a
 * timeout or bus error resets the TWI and recovers the lines. */
static int8_t twi_fail(int8_t rc)
{
    if (rc == ICM_BUS_E_ADDR_NACK || rc == ICM_BUS_E_DATA_NACK) {
        if (twi_stop() == 0) {
            return rc;
        }
        rc = ICM_BUS_E_TIMEOUT;
    }
    (void)twi_recover();
    return rc;
}

static int8_t twi_start(uint8_t sla)
{
    uint8_t st;
    TWCR = _BV(TWINT) | _BV(TWSTA) | _BV(TWEN);
    if (twi_wait_int() != 0) {
        return ICM_BUS_E_TIMEOUT;
    }
    st = TW_STATUS;
    if (st != TW_START && st != TW_REP_START) {
        return ICM_BUS_E_BUS;
    }
    TWDR = sla;
    TWCR = _BV(TWINT) | _BV(TWEN);
    if (twi_wait_int() != 0) {
        return ICM_BUS_E_TIMEOUT;
    }
    st = TW_STATUS;
    if (st == TW_MT_SLA_ACK || st == TW_MR_SLA_ACK) {
        return 0;
    }
    if (st == TW_MT_SLA_NACK || st == TW_MR_SLA_NACK) {
        return ICM_BUS_E_ADDR_NACK;
    }
    return ICM_BUS_E_BUS; /* arbitration lost or bus error */
}

static int8_t twi_send(const uint8_t *data, uint8_t len)
{
    uint8_t i;
    for (i = 0; i < len; i++) {
        uint8_t st;
        TWDR = data[i];
        TWCR = _BV(TWINT) | _BV(TWEN);
        if (twi_wait_int() != 0) {
            return ICM_BUS_E_TIMEOUT;
        }
        st = TW_STATUS;
        if (st == TW_MT_DATA_NACK) {
            return ICM_BUS_E_DATA_NACK;
        }
        if (st != TW_MT_DATA_ACK) {
            return ICM_BUS_E_BUS;
        }
    }
    return 0;
}

int8_t twi_write(uint8_t addr, const uint8_t *data, uint8_t len)
{
    int8_t rc = twi_start((uint8_t)(addr << 1));
    if (rc == 0) {
        rc = twi_send(data, len);
    }
    if (rc != 0) {
        return twi_fail(rc);
    }
    return twi_stop() == 0 ? 0 : twi_fail(ICM_BUS_E_TIMEOUT);
}

int8_t twi_write_read(uint8_t addr, const uint8_t *wdata, uint8_t wlen, uint8_t *rdata,
                      uint8_t rlen)
{
    uint8_t i;
    int8_t rc = twi_start((uint8_t)(addr << 1));
    if (rc == 0) {
        rc = twi_send(wdata, wlen);
    }
    if (rc == 0) {
        rc = twi_start((uint8_t)((addr << 1) | 1u));
    }
    for (i = 0; rc == 0 && i < rlen; i++) {
        uint8_t more = (uint8_t)(i + 1u < rlen);
        TWCR = (uint8_t)(_BV(TWINT) | _BV(TWEN) | (more ? _BV(TWEA) : 0u));
        if (twi_wait_int() != 0) {
            rc = ICM_BUS_E_TIMEOUT;
        } else if (TW_STATUS != (more ? TW_MR_DATA_ACK : TW_MR_DATA_NACK)) {
            rc = ICM_BUS_E_BUS;
        } else {
            rdata[i] = TWDR;
        }
    }
    if (rc != 0) {
        return twi_fail(rc);
    }
    return twi_stop() == 0 ? 0 : twi_fail(ICM_BUS_E_TIMEOUT);
}

/* Open-drain line control: low = output driving 0, high = input (released). */
static void twi_line(uint8_t mask, uint8_t high)
{
    if (high) {
        BOARD_TWI_DDR &= (uint8_t)~mask;
    } else {
        BOARD_TWI_PORT &= (uint8_t)~mask;
        BOARD_TWI_DDR |= mask;
    }
    _delay_us(5);
}

/* Waits (bounded) for a slave to stop stretching SCL: 1 done, 0 timed out. */
static uint8_t twi_scl_high(void)
{
    return twi_wait(&BOARD_TWI_PIN, TWI_SCL, TWI_SCL, 1) == 0;
}

/* NXP UM10204 section 3.1.16 "Bus clear": a slave stuck mid-byte holds SDA
 * low until it has clocked out its remaining bits; nine clocks are enough
 * for any byte plus its acknowledge. */
int8_t twi_recover(void)
{
    uint8_t i;
    uint8_t ok;
    twi_recovery_count++;
    TWCR = 0;
    twi_line(TWI_SDA, 1);
    twi_line(TWI_SCL, 1);
    for (i = 0; i < 9u && !(BOARD_TWI_PIN & TWI_SDA); i++) {
        twi_line(TWI_SCL, 0);
        twi_line(TWI_SCL, 1);
        if (!twi_scl_high()) {
            break;
        }
    }
    twi_line(TWI_SCL, 0);
    twi_line(TWI_SDA, 0);
    twi_line(TWI_SCL, 1);
    (void)twi_scl_high();
    twi_line(TWI_SDA, 1);
    ok = (uint8_t)((BOARD_TWI_PIN & (TWI_SDA | TWI_SCL)) == (TWI_SDA | TWI_SCL));
    twi_init();
    return ok ? 0 : ICM_BUS_E_BUS;
}

uint16_t twi_recoveries(void)
{
    return twi_recovery_count;
}

#if ICM_BUS_FIXED
/* The sensors' bus (lib/icm20948/icm20948.h, ICM_BUS_FIXED). */
int8_t icm_bus_write(uint8_t addr, const uint8_t *data, uint8_t len)
{
    return twi_write(addr, data, len);
}

int8_t icm_bus_write_read(uint8_t addr, const uint8_t *wdata, uint8_t wlen, uint8_t *rdata,
                          uint8_t rlen)
{
    return twi_write_read(addr, wdata, wlen, rdata, rlen);
}

int8_t icm_bus_recover(void)
{
    return twi_recover();
}
#else
static int8_t twi_bus_write(void *ctx, uint8_t addr, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    return twi_write(addr, data, len);
}

static int8_t twi_bus_write_read(void *ctx, uint8_t addr, const uint8_t *wdata, uint8_t wlen,
                                 uint8_t *rdata, uint8_t rlen)
{
    (void)ctx;
    return twi_write_read(addr, wdata, wlen, rdata, rlen);
}

static int8_t twi_bus_recover(void *ctx)
{
    (void)ctx;
    return twi_recover();
}

static const icm_bus_t twi_bus_if = {NULL, twi_bus_write, twi_bus_write_read, twi_bus_recover};

const icm_bus_t *twi_bus(void)
{
    return &twi_bus_if;
}
#endif
