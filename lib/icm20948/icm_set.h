/*
 * icm_set: the set of magnetometers of one calibration frame, up to
 * ICM_SET_MAX ICM-20948s (8 mux channels x 2 addresses), polled by the main
 * loop. Part of the icm20948 module directory, prefix icm_set_.
 *
 * icm_set_poll() does at most one step per call: one init step of one
 * sensor, or the start, or the fetch of one sensor's read. Running sensors
 * are read round-robin every `period_us` (4.7 ms by default: a little more
 * than twice the AK09916's 100 Hz, so every sample is caught once, and not
 * a divisor of its 10 ms, so the reads' phase against its samples moves and
 * some reads come right after one: icm_clock.h); each read is one
 * EXT_SLV_SENS_DATA transfer plus, behind a mux, one channel write (see
 * docs/sensors.md for the timing). Sensors that disappear, go stale or fail
 * ICM_SET_MAX_ERRORS reads in a row are re-initialised; a sensor whose init
 * fails is retried every ICM_SET_RETRY_US. Times come from the caller
 * (microseconds, wrapping).
 *
 * Error convention: 0 = done, negative = ICM_E_* code (icm20948.h).
 */
#ifndef HALLHOME_ICM_SET_H
#define HALLHOME_ICM_SET_H

#include <stdint.h>

#include "icm20948/icm20948.h"
#include "icm20948/icm_clock.h"
#include "icm20948/tca9548a.h"

#define ICM_SET_MAX               16u
#define ICM_SET_PERIOD_US_DEFAULT 4700u
#define ICM_SET_RETRY_US          1000000u
#define ICM_SET_MAX_ERRORS        3u
#define ICM_SET_RATE_WINDOW_US    1000000u
#define ICM_SET_NONE              0xFFu

/* Slot states, also reported by icm_set_diag(). */
enum icm_set_state {
    ICM_SET_S_IDLE = 0, /* added, icm_set_begin() not called yet */
    ICM_SET_S_INIT = 1, /* initialising */
    ICM_SET_S_RUN = 2,  /* sampling */
    ICM_SET_S_FAIL = 3  /* init failed; retried every ICM_SET_RETRY_US */
};

typedef struct {
    /* the slot's own state first: within the first 64 bytes, which the AVR
     * reaches through the slot's pointer with one instruction a byte */
    uint8_t state;      /* ICM_SET_S_* */
    uint8_t fresh;      /* a new sample not yet taken */
    uint8_t consec_err; /* read errors in a row */
    int8_t last_err;    /* last error seen, 0 if none */
    uint32_t due_us;    /* next read (RUN) or next init attempt (FAIL) */
    uint32_t win_from_us;
    uint16_t win_new;
    uint16_t rate_dhz; /* new samples per second x10, last full window */
    uint16_t reinits;  /* inits started after the first */
    uint8_t retry;     /* icm_set_retry() asked for an attempt not finished yet */
#if ICM_STATS
    uint16_t missed; /* new samples overwritten before icm_set_take() */
#endif
    icm_dev_t dev;
    icm_sample_t last; /* last new sample; t_us: when it was measured (clk) */
    icm_clock_t clk;   /* the AK09916's sample clock */
} icm_set_slot_t;

typedef struct {
    tca_t mux;
    uint8_t has_mux;
    uint8_t n;
    uint8_t cursor; /* round-robin position */
    uint8_t active; /* slot between start and fetch, or ICM_SET_NONE */
    uint8_t begun;
    uint32_t period_us;
    uint8_t cap; /* slots available */
#if !ICM_BUS_FIXED
    const icm_bus_t *bus;
#endif
    icm_set_slot_t *slot; /* caller-owned, cap entries */
} icm_set_t;

/* Console diagnostics of one sensor. */
typedef struct {
    uint8_t state;        /* ICM_SET_S_* */
    uint8_t channel;      /* mux channel or ICM_NO_MUX */
    uint8_t addr;         /* 7-bit */
    uint8_t present;      /* WHO_AM_I read back as 0xEA at the last init */
    uint8_t who_am_i;     /* last WHO_AM_I value (0 if never read) */
    uint8_t mag_ready;    /* AK09916 identified and sampling (state RUN) */
    uint8_t mag_id;       /* last WIA2 value */
    int8_t last_err;      /* last ICM_E_* seen, 0 if none */
    uint16_t rate_dhz;    /* achieved sample rate, 0.1 Hz units */
    int32_t field_cuT[3]; /* last field, cuT (uT = cuT / 100) */
    uint32_t samples;     /* new samples since the last init */
    uint16_t overflow_count;
    uint16_t overrun_count;
    uint16_t error_count; /* failed transfers, stale reads and failed inits */
    uint16_t reinits;
} icm_diag_t;

/* Prepares an empty set on bus with room for cap sensors in the caller's
 * slots array (85 bytes each on the AVR, 77 with ICM_STATS=0, so a 3-sensor
 * frame does not pay for 16); mux_addr is the TCA9548A address (0x70..0x77) or ICM_NO_MUX for
 * sensors wired directly. Returns 0 or ICM_E_ARG (NULL, cap 0 or above
 * ICM_SET_MAX, bad mux address). */
int8_t icm_set_setup(icm_set_t *set, const icm_bus_t *bus, uint8_t mux_addr, icm_set_slot_t *slots,
                     uint8_t cap);

/* Adds a sensor at (channel, addr); channel must be ICM_NO_MUX without a
 * mux, 0..7 with one. Returns the sensor's index (0..cap-1), or ICM_E_ARG
 * (set full, duplicate, bad channel or address, or called after begin). */
int8_t icm_set_add(icm_set_t *set, uint8_t channel, uint8_t addr);

/* Read period per sensor (1000..100000 us). Returns 0 or ICM_E_ARG. */
int8_t icm_set_period_us(icm_set_t *set, uint32_t period_us);

/* Stale limit for every sensor (see icm_set_stale_us()). Returns 0 or
 * ICM_E_ARG. */
int8_t icm_set_stale_limit_us(icm_set_t *set, uint32_t stale_us);

/* Starts initialising every sensor. Returns 0 or ICM_E_ARG (empty set). */
int8_t icm_set_begin(icm_set_t *set, uint32_t now_us);

/* Makes every sensor whose init failed due for its next attempt now, as a
 * bring-up wants: one plugged back since its last attempt must not wait for
 * its retry period (up to ICM_SET_RETRY_US). icm_set_settled() waits for
 * these attempts, and for an init already under way. No-op before
 * icm_set_begin(). */
void icm_set_retry(icm_set_t *set, uint32_t now_us);

/* Does the next due step. Returns 0, or ICM_E_ARG / ICM_E_STATE (before
 * icm_set_begin). Sensor errors are not returned here: see icm_set_diag(). */
int8_t icm_set_poll(icm_set_t *set, uint32_t now_us);

/* Number of sensors sampling, and whether every sensor has finished its
 * first init attempt and the one icm_set_retry() asked for (running or
 * failed). */
uint8_t icm_set_ready_count(const icm_set_t *set);
uint8_t icm_set_settled(const icm_set_t *set);

/* Takes the newest unread sample of sensor idx. Returns 1 with *out filled
 * (a new sample, consumed), 0 when none arrived since the last take, the
 * sensor's last error when it is not running (ICM_E_STATE while its first
 * init is still under way), or ICM_E_ARG. Samples overwritten before being
 * taken are counted in the slot's `missed`. */
int8_t icm_set_take(icm_set_t *set, uint8_t idx, icm_sample_t *out);

/* Fills *d for sensor idx. Returns 0 or ICM_E_ARG. */
int8_t icm_set_diag(const icm_set_t *set, uint8_t idx, icm_diag_t *d);

/* Formats *d as "ch=2 addr=0x69 state=run who=0xEA mag=1 rate=100.0
 * bx=30.00 by=-45.15 bz=0.15 ovf=0 dor=0 err=0 last=0" (uT with two
 * decimals). Returns the length written (NUL excluded), or ICM_E_ARG when
 * buf is NULL or cap is too small for the longest line (ICM_DIAG_LINE_MAX). */
#define ICM_DIAG_LINE_MAX 128u
int16_t icm_diag_format(const icm_diag_t *d, char *buf, uint16_t cap);

#endif /* HALLHOME_ICM_SET_H */
