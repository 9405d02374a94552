#include "icm20948/icm20948.h"

#include <stddef.h>
#include <string.h>

#include "icm20948/icm20948_reg.h"
#include "icm20948/tca9548a.h"

/* The init's register writes are a constant table, kept in program memory on
 * the AVR (a const array would be copied to RAM at start-up). */
#ifdef __AVR__
#include <avr/pgmspace.h>
#define ICM_FLASH               PROGMEM
#define ICM_FLASH_COPY(d, s, n) memcpy_P((d), (s), (n))
#else
#define ICM_FLASH
#define ICM_FLASH_COPY(d, s, n) memcpy((d), (s), (n))
#endif

enum { ICM_ST_IDLE, ICM_ST_INIT, ICM_ST_RUN, ICM_ST_FAIL };

/* A device icm_setup() has not prepared (icm20948.h, ICM_BUS_FIXED: without
 * a bus of its own, by its address, which icm_setup() always sets). */
#if ICM_BUS_FIXED
#define ICM_DEV_UNSET(dev) ((dev)->addr == 0u)
#else
#define ICM_DEV_UNSET(dev) ((dev)->bus == NULL)
#endif

/* Functions that measured smaller on the AVR as calls than inlined: icm_wait()
 * at each wait, icm_read_failed(), icm_bus_error(). */
#if defined(__GNUC__)
#define ICM_NOINLINE __attribute__((noinline))
#else
#define ICM_NOINLINE
#endif

#define ICM_BANK_UNKNOWN 0xFFu

/* Init steps, in order; a failed AK09916 attempt goes to IS_RETRY_RST, which
 * loops back to IS_AK_SRST. A wait before a step is dev->wait_us from
 * dev->wait_from_us, set by icm_wait(). */
enum {
    IS_BANK0,
    IS_WHO,
    IS_RESET,
    IS_WAKE,
    IS_WHO2,
    IS_SENSORS_OFF,
    IS_LP,
    IS_MST_CFG,
    IS_MST_EN,
    IS_MST_RST,
    IS_AK_SRST,
    IS_AK_SRST_DONE,
    IS_WIA,
    IS_WIA_DONE,
    IS_WIA_DI,
    IS_RETRY_RST,
    IS_MODE,
    IS_MODE_DONE,
    IS_SLV0,
    IS_BANK_BACK
};

/* The init steps that only write registers: up to three consecutive
 * registers of one bank, then the next step after wait_ms. */
typedef struct {
    uint8_t step;
    uint8_t bank;
    uint8_t reg;
    uint8_t n;
    uint8_t v[3];
    uint8_t next;
    uint8_t wait_ms;
} icm_init_write_t;

typedef char
    icm_waits_in_ms_t[(ICM_RESET_WAIT_US % 1000u == 0u && ICM_RESET_WAIT_US / 1000u < 256u &&
                       ICM_WAKE_WAIT_US % 1000u == 0u && ICM_WAKE_WAIT_US / 1000u < 256u)
                          ? 1
                          : -1];

static const icm_init_write_t icm_init_writes[] ICM_FLASH = {
    {IS_RESET,
     0,
     ICM_REG_PWR_MGMT_1,
     1,
     {ICM_REG_PWR_DEVICE_RST, 0, 0},
     IS_WAKE,
     ICM_RESET_WAIT_US / 1000u},
    {IS_WAKE,
     0,
     ICM_REG_PWR_MGMT_1,
     1,
     {ICM_REG_PWR_CLKSEL_AUTO, 0, 0},
     IS_WHO2,
     ICM_WAKE_WAIT_US / 1000u},
    /* only the magnetometer is used; with the gyro and accelerometer off the
     * master runs at its own rate (and they draw no current) */
    {IS_SENSORS_OFF, 0, ICM_REG_PWR_MGMT_2, 1, {ICM_REG_PWR2_SENSORS_OFF, 0, 0}, IS_LP, 0},
    {IS_LP, 0, ICM_REG_LP_CONFIG, 1, {ICM_REG_LP_I2C_MST_CYCLE, 0, 0}, IS_MST_CFG, 0},
    /* rate, clock and shadow delay in one burst (bank 3, 0x00..0x02), all
     * before the master is enabled */
    {IS_MST_CFG,
     3,
     ICM_REG_I2C_MST_ODR_CONFIG,
     3,
     {ICM_REG_MST_ODR_137HZ, ICM_REG_MST_P_NSR | ICM_REG_MST_CLK_345KHZ, ICM_REG_DELAY_ES_SHADOW},
     IS_MST_EN,
     0},
    {IS_MST_EN, 0, ICM_REG_USER_CTRL, 1, {ICM_REG_USER_I2C_MST_EN, 0, 0}, IS_MST_RST, 0},
    {IS_MST_RST,
     0,
     ICM_REG_USER_CTRL,
     1,
     {ICM_REG_USER_I2C_MST_EN | ICM_REG_USER_I2C_MST_RST, 0, 0},
     IS_AK_SRST,
     ICM_WAKE_WAIT_US / 1000u},
    {IS_RETRY_RST,
     0,
     ICM_REG_USER_CTRL,
     1,
     {ICM_REG_USER_I2C_MST_EN | ICM_REG_USER_I2C_MST_RST, 0, 0},
     IS_AK_SRST,
     ICM_WAKE_WAIT_US / 1000u},
    {IS_SLV0,
     3,
     ICM_REG_I2C_SLV0_ADDR,
     3,
     {AK_REG_ADDR | ICM_REG_SLV_ADDR_READ, AK_REG_ST1, ICM_REG_SLV_CTRL_EN | AK_REG_BLOCK_LEN},
     IS_BANK_BACK,
     0},
};

/* Compares rather than a switch: GCC turns that switch into a lookup table,
 * which the AVR keeps in RAM. */
ICM_NOINLINE int8_t icm_bus_error(int8_t bus_rc)
{
    if (bus_rc == ICM_BUS_OK) {
        return 0;
    }
    if (bus_rc == ICM_BUS_E_ADDR_NACK) {
        return ICM_E_ABSENT;
    }
    if (bus_rc == ICM_BUS_E_DATA_NACK) {
        return ICM_E_NACK;
    }
    return bus_rc == ICM_BUS_E_TIMEOUT ? ICM_E_TIMEOUT : ICM_E_BUS;
}

/* A failed transfer leaves the bank and mux state unknown; a stuck or timed
 * out bus gets one recovery attempt before the error is reported. */
static int8_t icm_fail_xfer(icm_dev_t *dev, int8_t bus_rc)
{
    dev->bank = ICM_BANK_UNKNOWN;
    if (dev->mux != NULL) {
        tca_invalidate(dev->mux);
    }
    if (bus_rc == ICM_BUS_E_TIMEOUT || bus_rc == ICM_BUS_E_BUS) {
        ICM_BUS_RECOVER(dev->bus);
    }
    return icm_bus_error(bus_rc);
}

static int8_t icm_write(icm_dev_t *dev, const uint8_t *data, uint8_t len)
{
    int8_t rc = ICM_BUS_WRITE(dev->bus, dev->addr, data, len);
    return rc == ICM_BUS_OK ? 0 : icm_fail_xfer(dev, rc);
}

static int8_t icm_bank(icm_dev_t *dev, uint8_t bank)
{
    uint8_t cmd[2];
    int8_t rc;
    if (dev->bank == bank) {
        return 0;
    }
    cmd[0] = ICM_REG_BANK_SEL;
    cmd[1] = (uint8_t)(bank << ICM_REG_BANK_SHIFT);
    rc = icm_write(dev, cmd, 2);
    if (rc == 0) {
        dev->bank = bank;
    }
    return rc;
}

/* Writes up to three consecutive registers of one bank in one transfer. */
static int8_t icm_wr(icm_dev_t *dev, uint8_t bank, uint8_t reg, const uint8_t *val, uint8_t n)
{
    uint8_t cmd[4];
    int8_t rc = icm_bank(dev, bank);
    if (rc != 0) {
        return rc;
    }
    cmd[0] = reg;
    memcpy(&cmd[1], val, n);
    return icm_write(dev, cmd, (uint8_t)(n + 1u));
}

static int8_t icm_wr1(icm_dev_t *dev, uint8_t bank, uint8_t reg, uint8_t val)
{
    return icm_wr(dev, bank, reg, &val, 1);
}

static int8_t icm_rd(icm_dev_t *dev, uint8_t bank, uint8_t reg, uint8_t *buf, uint8_t n)
{
    int8_t rc = icm_bank(dev, bank);
    if (rc != 0) {
        return rc;
    }
    rc = ICM_BUS_WRITE_READ(dev->bus, dev->addr, &reg, 1, buf, n);
    return rc == ICM_BUS_OK ? 0 : icm_fail_xfer(dev, rc);
}

static int8_t icm_select(icm_dev_t *dev)
{
    int8_t rc;
    if (dev->mux == NULL) {
        return 0;
    }
    rc = tca_select(dev->mux, dev->channel);
    if (rc != 0) {
        dev->bank = ICM_BANK_UNKNOWN;
        if (rc == TCA_E_BUS || rc == TCA_E_TIMEOUT) {
            ICM_BUS_RECOVER(dev->bus);
        }
        return ICM_E_MUX;
    }
    return 0;
}

int8_t icm_setup(icm_dev_t *dev, const icm_bus_t *bus, struct tca *mux, uint8_t channel,
                 uint8_t addr)
{
    if (dev == NULL || ICM_BUS_BAD(bus, 1)) {
        return ICM_E_ARG;
    }
    if (addr != ICM_REG_ADDR_AD0_LOW && addr != ICM_REG_ADDR_AD0_HIGH) {
        return ICM_E_ARG;
    }
    if ((mux != NULL && channel >= TCA_CHANNELS) || (mux == NULL && channel != ICM_NO_MUX)) {
        return ICM_E_ARG;
    }
    memset(dev, 0, sizeof(*dev));
#if !ICM_BUS_FIXED
    dev->bus = bus;
#endif
    dev->mux = mux;
    dev->channel = channel;
    dev->addr = addr;
    dev->bank = ICM_BANK_UNKNOWN;
    dev->state = ICM_ST_IDLE;
    dev->stale_us = ICM_STALE_US_DEFAULT;
    return 0;
}

int8_t icm_set_stale_us(icm_dev_t *dev, uint32_t stale_us)
{
    if (dev == NULL || stale_us == 0u) {
        return ICM_E_ARG;
    }
    dev->stale_us = stale_us;
    return 0;
}

int8_t icm_init_start(icm_dev_t *dev, uint32_t now_us)
{
    if (dev == NULL || ICM_DEV_UNSET(dev)) {
        return ICM_E_ARG;
    }
    dev->state = ICM_ST_INIT;
    dev->step = IS_BANK0;
    dev->bank = ICM_BANK_UNKNOWN;
    dev->tries = 0;
    dev->mag_fail = 0;
    dev->who_am_i = 0;
    dev->mag_id = 0;
    dev->mag_company = 0;
    dev->have = 0;
    dev->err = 0;
    dev->wait_from_us = now_us;
    dev->wait_us = 0;
    return 0;
}

uint8_t icm_ready(const icm_dev_t *dev)
{
    return (uint8_t)(dev != NULL && dev->state == ICM_ST_RUN);
}

ICM_NOINLINE static void icm_wait(icm_dev_t *dev, uint32_t now_us, uint32_t us, uint8_t next)
{
    dev->wait_from_us = now_us;
    dev->wait_us = us;
    dev->step = next;
}

static uint8_t icm_waited(const icm_dev_t *dev, uint32_t now_us)
{
    return (uint8_t)((uint32_t)(now_us - dev->wait_from_us) >= dev->wait_us);
}

/* Queues one SLV4 transaction with the AK09916: I2C_MST_STATUS is read
 * first (clear on read) so a late SLV4_DONE from an abandoned transfer is not
 * taken for this one; then DO, address and register, and the enable bit last
 * so the master never starts on a half-written setup. */
static int8_t icm_slv4_begin(icm_dev_t *dev, uint8_t read, uint8_t reg, uint8_t value)
{
    uint8_t ar[2];
    uint8_t st;
    int8_t rc = icm_rd(dev, 0, ICM_REG_I2C_MST_STATUS, &st, 1);
    if (rc == 0 && !read) {
        rc = icm_wr1(dev, 3, ICM_REG_I2C_SLV4_DO, value);
    }
    if (rc == 0) {
        ar[0] = (uint8_t)(AK_REG_ADDR | (read ? ICM_REG_SLV_ADDR_READ : 0u));
        ar[1] = reg;
        rc = icm_wr(dev, 3, ICM_REG_I2C_SLV4_ADDR, ar, 2);
    }
    if (rc == 0) {
        rc = icm_wr1(dev, 3, ICM_REG_I2C_SLV4_CTRL, ICM_REG_SLV_CTRL_EN);
    }
    return rc;
}

/* Polls I2C_MST_STATUS: ICM_BUSY until SLV4_DONE, 0 when the AK09916 acked,
 * ICM_E_MAG_ABSENT on SLV4_NACK or when the master never finishes. */
static int8_t icm_slv4_poll(icm_dev_t *dev, uint32_t now_us)
{
    uint8_t st = 0;
    int8_t rc = icm_rd(dev, 0, ICM_REG_I2C_MST_STATUS, &st, 1);
    if (rc != 0) {
        return rc;
    }
    if (st & ICM_REG_MST_SLV4_DONE) {
        return (st & ICM_REG_MST_SLV4_NACK) ? ICM_E_MAG_ABSENT : 0;
    }
    if (icm_waited(dev, now_us)) {
        return ICM_E_MAG_ABSENT;
    }
    return ICM_BUSY;
}

/* One failed AK09916 attempt: reset the I2C master and retry, or give up. */
static int8_t icm_mag_failed(icm_dev_t *dev, int8_t why)
{
    dev->mag_fail = why;
    dev->tries++;
    if (dev->tries >= ICM_MAG_TRIES) {
        return why;
    }
    dev->step = IS_RETRY_RST;
    return ICM_BUSY;
}

/* A step of icm_init_writes: its registers written, then the wait. */
static int8_t icm_init_write(icm_dev_t *dev, uint32_t now_us)
{
    icm_init_write_t w;
    uint8_t i;
    int8_t rc;
    for (i = 0; i < sizeof icm_init_writes / sizeof icm_init_writes[0]; i++) {
        ICM_FLASH_COPY(&w, &icm_init_writes[i], sizeof w);
        if (w.step == dev->step) {
            rc = icm_wr(dev, w.bank, w.reg, w.v, w.n);
            if (rc == 0) {
                if (w.step == IS_RESET) {
                    dev->bank = ICM_BANK_UNKNOWN; /* the reset selects bank 0 */
                }
                icm_wait(dev, now_us, (uint32_t)w.wait_ms * 1000u, w.next);
            }
            return rc;
        }
    }
    return ICM_E_STATE;
}

static int8_t icm_init_step(icm_dev_t *dev, uint32_t now_us)
{
    uint8_t v = 0;
    int8_t rc;

    switch (dev->step) {
    case IS_BANK0:
        rc = icm_bank(dev, 0);
        if (rc == 0) {
            dev->step = IS_WHO;
        }
        return rc;
    case IS_WHO:
    case IS_WHO2:
        rc = icm_rd(dev, 0, ICM_REG_WHO_AM_I, &v, 1);
        if (rc != 0) {
            return rc;
        }
        dev->who_am_i = v;
        if (v != ICM_REG_WHO_AM_I_V) {
            return ICM_E_WHOAMI;
        }
        dev->step = (dev->step == IS_WHO) ? IS_RESET : IS_SENSORS_OFF;
        return 0;
    case IS_AK_SRST:
        rc = icm_slv4_begin(dev, 0, AK_REG_CNTL3, AK_REG_CNTL3_SRST);
        if (rc == 0) {
            icm_wait(dev, now_us, ICM_SLV4_TIMEOUT_US, IS_AK_SRST_DONE);
        }
        return rc;
    case IS_AK_SRST_DONE:
        rc = icm_slv4_poll(dev, now_us);
        if (rc == ICM_E_MAG_ABSENT) {
            return icm_mag_failed(dev, rc);
        }
        if (rc == 0) {
            icm_wait(dev, now_us, ICM_AK_RESET_WAIT_US, IS_WIA);
        }
        return rc;
    case IS_WIA:
        /* WIA1 (company) first, then WIA2 (device): mag_company tells which */
        rc = icm_slv4_begin(dev, 1, dev->mag_company == AK_REG_WIA1_V ? AK_REG_WIA2 : AK_REG_WIA1,
                            0);
        if (rc == 0) {
            icm_wait(dev, now_us, ICM_SLV4_TIMEOUT_US, IS_WIA_DONE);
        }
        return rc;
    case IS_WIA_DONE:
        rc = icm_slv4_poll(dev, now_us);
        if (rc == ICM_E_MAG_ABSENT) {
            return icm_mag_failed(dev, rc);
        }
        if (rc == 0) {
            dev->step = IS_WIA_DI;
        }
        return rc;
    case IS_WIA_DI:
        rc = icm_rd(dev, 3, ICM_REG_I2C_SLV4_DI, &v, 1);
        if (rc != 0) {
            return rc;
        }
        if (dev->mag_company != AK_REG_WIA1_V) {
            dev->mag_company = v;
            if (v != AK_REG_WIA1_V) {
                return icm_mag_failed(dev, ICM_E_MAG_ID);
            }
            dev->step = IS_WIA; /* now WIA2 */
            return 0;
        }
        dev->mag_id = v;
        if (v != AK_REG_WIA2_V) {
            dev->mag_company = 0; /* a retry checks both again */
            return icm_mag_failed(dev, ICM_E_MAG_ID);
        }
        dev->mag_fail = 0;
        dev->step = IS_MODE;
        return 0;
    case IS_MODE:
        rc = icm_slv4_begin(dev, 0, AK_REG_CNTL2, AK_REG_MODE_CONT_100HZ);
        if (rc == 0) {
            icm_wait(dev, now_us, ICM_SLV4_TIMEOUT_US, IS_MODE_DONE);
        }
        return rc;
    case IS_MODE_DONE:
        rc = icm_slv4_poll(dev, now_us);
        if (rc == 0) {
            dev->step = IS_SLV0;
        }
        return rc;
    case IS_BANK_BACK:
        rc = icm_bank(dev, 0);
        if (rc == 0) {
            dev->state = ICM_ST_RUN;
            dev->last_new_us = now_us;
            dev->prev_st1 = 0;
            memset(dev->last, 0, sizeof(dev->last));
        }
        return rc;
    default:
        return icm_init_write(dev, now_us);
    }
}

int8_t icm_init_poll(icm_dev_t *dev, uint32_t now_us)
{
    int8_t rc;
    if (dev == NULL) {
        return ICM_E_ARG;
    }
    if (dev->state == ICM_ST_RUN) {
        return 0;
    }
    if (dev->state != ICM_ST_INIT) {
        return ICM_E_STATE;
    }
    if (!icm_waited(dev, now_us)) {
        switch (dev->step) {
        case IS_AK_SRST_DONE:
        case IS_WIA_DONE:
        case IS_MODE_DONE:
            break; /* these poll the status until their deadline */
        default:
            return ICM_BUSY;
        }
    }
    rc = icm_select(dev);
    if (rc == 0) {
        rc = icm_init_step(dev, now_us);
    }
    if (rc < 0) {
        dev->state = ICM_ST_FAIL;
        dev->err = rc;
        dev->error_count++;
        return rc;
    }
    return dev->state == ICM_ST_RUN ? 0 : ICM_BUSY;
}

/* Only a missing sensor ends the run: a NACK, timeout or bus error may be a
 * glitch, and the caller decides after how many to re-initialise. */
ICM_NOINLINE static int8_t icm_read_failed(icm_dev_t *dev, int8_t rc)
{
    dev->err = rc;
    dev->error_count++;
    if (rc == ICM_E_ABSENT) {
        dev->state = ICM_ST_FAIL;
    }
    return rc;
}

int8_t icm_read_start(icm_dev_t *dev, uint32_t now_us)
{
    int8_t rc;
    (void)now_us;
    if (dev == NULL) {
        return ICM_E_ARG;
    }
    if (dev->state != ICM_ST_RUN) {
        return ICM_E_STATE;
    }
    rc = icm_select(dev);
    if (rc == 0) {
        rc = icm_bank(dev, 0);
    }
    return rc == 0 ? 0 : icm_read_failed(dev, rc);
}

static int16_t icm_le16(const uint8_t *p)
{
    return (int16_t)(uint16_t)((uint16_t)p[0] | ((uint16_t)p[1] << 8));
}

int8_t icm_read_fetch(icm_dev_t *dev, uint32_t now_us, icm_sample_t *out)
{
    uint8_t blk[AK_REG_BLOCK_LEN];
    uint8_t fresh;
    uint8_t i;
    int8_t rc;
    if (dev == NULL || out == NULL) {
        return ICM_E_ARG;
    }
    if (dev->state != ICM_ST_RUN) {
        return ICM_E_STATE;
    }
    rc = icm_rd(dev, 0, ICM_REG_EXT_SLV_SENS_DATA_00, blk, AK_REG_BLOCK_LEN);
    if (rc != 0) {
        return icm_read_failed(dev, rc);
    }
    fresh = (uint8_t)(memcmp(&blk[1], &dev->last[1], AK_REG_BLOCK_LEN - 1u) != 0);
    /* Unchanged data are a new sample only when DRDY has just appeared: the
     * master reads faster than the AK09916 samples, so the host sees each
     * master read, and a read without a new sample carries DRDY clear. A
     * frozen copy (master stopped, AK09916 gone) never counts again. */
    if (!fresh && (blk[0] & AK_REG_ST1_DRDY) && !(dev->prev_st1 & AK_REG_ST1_DRDY)) {
        fresh = 1;
    }
    dev->prev_st1 = blk[0];
    for (i = 0; i < 3u; i++) {
        out->raw[i] = icm_le16(&blk[1u + 2u * i]);
    }
    out->st1 = blk[0];
    out->st2 = blk[8];
    out->t_us = now_us;
    out->flags = 0;
    if (blk[8] & AK_REG_ST2_HOFL) {
        out->flags |= ICM_SAMPLE_OVERFLOW;
    }
    if (fresh) {
        out->flags |= ICM_SAMPLE_NEW;
        if (blk[0] & AK_REG_ST1_DOR) {
            out->flags |= ICM_SAMPLE_OVERRUN;
#if ICM_STATS
            dev->overrun_count++;
#endif
        }
        if (blk[8] & AK_REG_ST2_HOFL) {
            dev->overflow_count++;
        }
#if ICM_STATS
        dev->new_count++;
#endif
        dev->last_new_us = now_us;
        dev->have = 1;
        memcpy(dev->last, blk, sizeof(blk));
        dev->err = 0;
        return 0;
    }
    if ((uint32_t)(now_us - dev->last_new_us) > dev->stale_us) {
        return icm_read_failed(dev, ICM_E_STALE);
    }
    return 0;
}
