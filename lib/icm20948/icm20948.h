/*
 * icm20948: ICM-20948 driver for its AK09916 magnetometer, over an abstract
 * I2C bus, optionally behind a TCA9548A multiplexer (tca9548a.h).
 *
 * The ICM-20948's own I2C master reads the AK09916 (continuous mode, 100 Hz)
 * through SLV0 into EXT_SLV_SENS_DATA; this driver only talks to the ICM.
 * Initialisation and sample reads are non-blocking state machines: each call
 * makes at most a few short bus transfers and returns; waits are deadlines
 * against the caller's microsecond clock (`now_us`, wrapping arithmetic).
 *
 * Error convention: 0 = done, negative = ICM_E_* code, positive = ICM_BUSY
 * (still in progress, call again).
 */
#ifndef HALLHOME_ICM20948_H
#define HALLHOME_ICM20948_H

#include <stdint.h>

/* --- abstract I2C bus ----------------------------------------------------- */

/* The sample counters no console report prints (icm_dev_t.new_count and
 * overrun_count, icm_set_slot_t.missed; icm_diag_t.samples and
 * overrun_count read 0 without them) are kept unless this is 0: the firmware
 * builds with -DICM_STATS=0 (8 bytes of RAM per sensor). */
#ifndef ICM_STATS
#define ICM_STATS 1
#endif

/* Bus results: 0 = transfer done, negative = one of these. */
enum icm_bus_err {
    ICM_BUS_OK = 0,
    ICM_BUS_E_ADDR_NACK = -1, /* nobody acknowledged the address byte */
    ICM_BUS_E_DATA_NACK = -2, /* the slave refused a data byte */
    ICM_BUS_E_TIMEOUT = -3,   /* a bus phase missed its deadline */
    ICM_BUS_E_BUS = -4        /* bus error, lost arbitration or SDA held low */
};

/* An I2C master. Addresses are 7-bit. Every function returns within a bounded
 * time and ends the transfer with STOP (also on error). */
typedef struct {
    void *ctx;
    /* START, address+W, len bytes, STOP. */
    int8_t (*write)(void *ctx, uint8_t addr, const uint8_t *data, uint8_t len);
    /* START, address+W, wlen bytes, repeated START, address+R, rlen bytes
     * (NACK on the last), STOP. */
    int8_t (*write_read)(void *ctx, uint8_t addr, const uint8_t *wdata, uint8_t wlen,
                         uint8_t *rdata, uint8_t rlen);
    /* Frees a stuck bus (clocks SCL until SDA is released, then STOP).
     * Returns 0 when the bus is idle, ICM_BUS_E_BUS when SDA stays low.
     * May be NULL when the bus has no recovery. */
    int8_t (*recover)(void *ctx);
} icm_bus_t;

/* A firmware with one I2C bus builds with -DICM_BUS_FIXED=1: the driver and
 * the multiplexer then call the board's functions below (the icm_bus_t
 * contracts without ctx; recover() is not optional; defined by the board
 * only when it builds so) directly, and the bus given to icm_set_setup(),
 * icm_setup() and tca_setup() is neither checked, kept nor read (measured: 266 bytes less AVR code,
 * 20 bytes less RAM). The default, 0, takes an icm_bus_t per device, which the native tests fill
 * with their fakes. */
#ifndef ICM_BUS_FIXED
#define ICM_BUS_FIXED 0
#endif
int8_t icm_bus_write(uint8_t addr, const uint8_t *data, uint8_t len);
int8_t icm_bus_write_read(uint8_t addr, const uint8_t *wdata, uint8_t wlen, uint8_t *rdata,
                          uint8_t rlen);
int8_t icm_bus_recover(void);

/* The bus functions on `bus` (a const icm_bus_t *), and whether it is not
 * usable: ICM_BUS_BAD(bus, need_wr) is 1 for NULL or a missing write (or a
 * missing write_read when need_wr); always 0 with ICM_BUS_FIXED. */
#if ICM_BUS_FIXED
#define ICM_BUS_WRITE(bus, addr, data, len)           icm_bus_write(addr, data, len)
#define ICM_BUS_WRITE_READ(bus, addr, wd, wl, rd, rl) icm_bus_write_read(addr, wd, wl, rd, rl)
#define ICM_BUS_RECOVER(bus)                          ((void)icm_bus_recover())
#define ICM_BUS_BAD(bus, need_wr)                     ((void)(bus), 0)
#else
#define ICM_BUS_WRITE(bus, addr, data, len) (bus)->write((bus)->ctx, addr, data, len)
#define ICM_BUS_WRITE_READ(bus, addr, wd, wl, rd, rl)                                              \
    (bus)->write_read((bus)->ctx, addr, wd, wl, rd, rl)
#define ICM_BUS_RECOVER(bus)                                                                       \
    do {                                                                                           \
        if ((bus)->recover != NULL) {                                                              \
            (void)(bus)->recover((bus)->ctx);                                                      \
        }                                                                                          \
    } while (0)
#define ICM_BUS_BAD(bus, need_wr)                                                                  \
    ((bus) == NULL || (bus)->write == NULL || ((need_wr) && (bus)->write_read == NULL))
#endif

/* --- driver ------------------------------------------------------------------ */

enum icm_err {
    ICM_E_ARG = -1,        /* NULL pointer or value out of range */
    ICM_E_ABSENT = -2,     /* the ICM-20948 did not acknowledge its address */
    ICM_E_WHOAMI = -3,     /* something answered, but WHO_AM_I is not 0xEA */
    ICM_E_NACK = -4,       /* a data byte was refused mid-transfer */
    ICM_E_TIMEOUT = -5,    /* the bus timed out (recovery was attempted) */
    ICM_E_BUS = -6,        /* bus error (recovery was attempted) */
    ICM_E_MAG_ABSENT = -7, /* the AK09916 never answered through SLV4, after retries */
    ICM_E_MAG_ID = -8,     /* the AK09916 answered WIA1 != 0x48 or WIA2 != 0x09, after retries */
    ICM_E_STALE = -9,      /* no new sample for longer than the stale limit */
    ICM_E_STATE = -10,     /* call not valid in this state (e.g. read before init) */
    ICM_E_MUX = -11        /* the multiplexer channel could not be selected */
};

#define ICM_BUSY 1 /* positive: in progress */

/* Sample flags. */
#define ICM_SAMPLE_NEW      0x01u /* a sample the driver had not returned before */
#define ICM_SAMPLE_OVERFLOW 0x02u /* ST2.HOFL: the magnetometer saturated, values invalid */
#define ICM_SAMPLE_OVERRUN  0x04u /* ST1.DOR: the AK09916 skipped a sample */

#define ICM_ADDR_DEFAULT 0x69u /* breakout default (AD0 high) */
#define ICM_NO_MUX       0xFFu

#define ICM_STALE_US_DEFAULT 50000u /* five AK09916 periods */
/* After PWR_MGMT_1 DEVICE_RESET: DS-000189 section 3 (A.C. electrical
 * characteristics), "Start-up time for register read/write": 11 ms typical,
 * 100 ms maximum; the maximum is waited. Sensors are initialised side by
 * side (icm_set.h), so the wait is paid once per boot. */
#define ICM_RESET_WAIT_US    100000u
#define ICM_WAKE_WAIT_US     1000u /* after wake, after an I2C master reset */
#define ICM_AK_RESET_WAIT_US 1000u /* after the AK09916 soft reset */
#define ICM_SLV4_TIMEOUT_US  5000u /* SLV4_DONE deadline */
#define ICM_MAG_TRIES        5u    /* WIA2 attempts before ICM_E_MAG_* */

/* One magnetometer sample: raw AK09916 counts (0.15 uT per LSB). */
typedef struct {
    int16_t raw[3]; /* X, Y, Z, decoded from little-endian HXL..HZH */
    uint8_t flags;  /* ICM_SAMPLE_* */
    uint8_t st1;    /* ST1 as read (DRDY, DOR) */
    uint8_t st2;    /* ST2 as read (HOFL) */
    uint32_t t_us;  /* caller time of the fetch (icm_set: when it was measured, icm_clock.h) */
} icm_sample_t;

struct tca;

/* One ICM-20948. Caller-owned; set up with icm_setup(), then only touched
 * through these functions. */
typedef struct {
#if !ICM_BUS_FIXED
    const icm_bus_t *bus;
#endif
    struct tca *mux;     /* NULL when wired directly */
    uint8_t channel;     /* mux channel 0..7, or ICM_NO_MUX */
    uint8_t addr;        /* 7-bit: 0x68 or 0x69 */
    uint8_t bank;        /* cached REG_BANK_SEL bank, 0xFF = unknown */
    uint8_t state;       /* internal: ICM_ST_* in icm20948.c */
    uint8_t step;        /* internal: init step */
    uint8_t tries;       /* WIA2 attempts so far */
    int8_t mag_fail;     /* why the last WIA2 attempt failed */
    uint8_t who_am_i;    /* last WHO_AM_I read (0 before any) */
    uint8_t mag_id;      /* last WIA2 read via SLV4 (0 before any) */
    uint8_t mag_company; /* last WIA1 read via SLV4 (0 before any) */
    uint8_t have;        /* a sample has been fetched since init */
    int8_t err;          /* last error returned, 0 if none */
    uint8_t last[9];     /* last new ST1..ST2 block */
    uint8_t prev_st1;    /* ST1 of the previous fetch, new or not */
    uint32_t wait_from_us;
    uint32_t wait_us;
    uint32_t stale_us;
    uint32_t last_new_us;
#if ICM_STATS
    uint32_t new_count;     /* new samples since init */
    uint16_t overrun_count; /* new samples with DOR */
#endif
    uint16_t overflow_count; /* new samples with HOFL */
    uint16_t error_count;    /* failed transfers and stale fetches */
} icm_dev_t;

/* Prepares dev for the ICM at addr, on bus, behind mux channel `channel`
 * (mux NULL and channel ICM_NO_MUX when wired directly). No bus traffic.
 * Returns 0, or ICM_E_ARG (NULL bus, addr not 0x68/0x69, channel > 7 with a
 * mux, or a channel given without a mux). */
int8_t icm_setup(icm_dev_t *dev, const icm_bus_t *bus, struct tca *mux, uint8_t channel,
                 uint8_t addr);

/* Sets the stale limit: a fetch with no new sample for longer than stale_us
 * returns ICM_E_STALE. Returns 0, or ICM_E_ARG for NULL or 0. */
int8_t icm_set_stale_us(icm_dev_t *dev, uint32_t stale_us);

/* Begins (or restarts) initialisation; counters are kept, the WHO_AM_I and
 * WIA2 values read are forgotten. Returns 0, or ICM_E_ARG. */
int8_t icm_init_start(icm_dev_t *dev, uint32_t now_us);

/* Advances initialisation by one step: bank 0, WHO_AM_I (no ACK ->
 * ICM_E_ABSENT, not 0xEA -> ICM_E_WHOAMI), device reset and its start-up
 * time, wake, gyro and accelerometer off, I2C master clock, rate (about
 * 137 Hz) and DELAY_ES_SHADOW set before the master is enabled and reset,
 * AK09916 soft reset and WIA1/WIA2 check through SLV4 (up to ICM_MAG_TRIES
 * attempts with a master reset between them, then ICM_E_MAG_ABSENT or
 * ICM_E_MAG_ID), continuous 100 Hz mode, SLV0 reading ST1..ST2. Returns ICM_BUSY while in progress,
 * 0 when the sensor runs, or a negative ICM_E_* (bus errors map to ICM_E_NACK/TIMEOUT/BUS/MUX,
 * ICM_E_STATE without icm_init_start). After an error, icm_init_start() again. */
int8_t icm_init_poll(icm_dev_t *dev, uint32_t now_us);

/* Nonzero when initialisation has completed and no error has occurred since. */
uint8_t icm_ready(const icm_dev_t *dev);

/* First half of a read: selects the mux channel (cached) and register bank 0
 * (cached). Returns 0, ICM_E_STATE when not ready, ICM_E_MUX, or a bus error
 * code (ICM_E_ABSENT, ICM_E_NACK, ICM_E_TIMEOUT, ICM_E_BUS) with the same
 * effect on icm_ready() as in icm_read_fetch(). */
int8_t icm_read_start(icm_dev_t *dev, uint32_t now_us);

/* Second half: reads ST1..ST2 from EXT_SLV_SENS_DATA and decodes it into
 * *out. A sample is new when its data differ from the last one (all zero
 * before the first sample, the register contents after init), or DRDY is
 * set and was clear in the previous fetch (the I2C master, at about 137 Hz,
 * brought a new sample of unchanged value); otherwise it is a repeat (flags
 * without ICM_SAMPLE_NEW). Fetches must come at least once per master period
 * (7.27 ms) for the second rule to catch every unchanged sample. Returns 0 with *out filled,
 * ICM_E_STALE with *out filled (a repeat older than the stale limit),
 * ICM_E_STATE when not ready, or a bus error code. Bus errors leave *out
 * alone. ICM_E_ABSENT (the sensor has disappeared) clears icm_ready() until
 * the next successful init; after the other errors the device stays ready
 * and the caller decides when to re-initialise. */
int8_t icm_read_fetch(icm_dev_t *dev, uint32_t now_us, icm_sample_t *out);

/* Maps a bus result to an ICM_E_* code (0 stays 0). */
int8_t icm_bus_error(int8_t bus_rc);

#endif /* HALLHOME_ICM20948_H */
