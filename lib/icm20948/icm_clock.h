/*
 * icm_clock: when each AK09916 sample was measured.
 *
 * The host sees a sample some time after the AK09916 measured it: the
 * ICM-20948's I2C master copies it into EXT_SLV_SENS_DATA at its own rate
 * (about 137 Hz, icm20948.h), and the host reads those registers at its own
 * (icm_set.h, 5 ms). The sample's age at the read is anywhere from 0 to the
 * sum of both periods and a main-loop pass, about 16 ms, and so is where a
 * moving servo was when the field was measured: 30 ticks at the take-up's
 * top speed (chaos seed 19346: an engagement recorded 20 ticks late).
 *
 * But the AK09916 measures on its own clock, every 10 ms in continuous
 * mode 4 (AK09916 datasheet, 9.3 "Continuous measurement mode"), and a
 * sample is never read before it was measured. So the measurement times
 * lie on a line, below every read: the estimate is that line, lowered at
 * once to a read that comes before it, and raised at the end of each window
 * of ICM_CLOCK_WINDOW samples to the lowest read of the window. The reads'
 * lags beat against the AK09916's period, so the lowest of a window comes
 * within a millisecond or two of the measurement. What the line was lowered
 * and raised in a window corrects its period, for an AK09916 whose
 * oscillator runs fast or slow. A read later than ICM_CLOCK_LAG_MAX_US, or
 * a sample the reads missed, can leave the estimate a period early until
 * the window ends, which only makes a sample look older than it is.
 */
#ifndef HALLHOME_ICM_CLOCK_H
#define HALLHOME_ICM_CLOCK_H

#include <stdint.h>

/* AK09916 continuous mode 4 (100 Hz): one sample every 10 ms. */
#define ICM_CLOCK_PERIOD_US 10000u
/* The longest a sample is taken to wait for the host: the master's period
 * (7.3 ms), the host's read period (5 ms) and a main-loop pass (4 ms). */
#define ICM_CLOCK_LAG_MAX_US 16300u
/* Samples per window of the line's correction. */
#define ICM_CLOCK_WINDOW 16u

typedef struct {
    uint32_t at_us;      /* the line at the last sample: when it was measured */
    uint16_t period_us;  /* the line's slope: the AK09916's period as estimated */
    uint16_t low_us;     /* lowest lag of a read behind the line in this window */
    uint16_t lowered_us; /* how far reads before the line lowered it in this window */
    uint8_t k;           /* samples since the window's start */
    uint8_t have;        /* bit 0: the line is set; bit 1: a window has ended, the
                            period is corrected from then (the first finds the phase) */
} icm_clock_t;

/* Forgets the phase (a sensor re-initialised: its AK09916 restarted). */
void icm_clock_reset(icm_clock_t *c);

/* A new sample seen by a read at seen_us: returns when it was measured, by
 * the estimate. The first sample after a reset is taken as measured when
 * seen. */
uint32_t icm_clock_seen(icm_clock_t *c, uint32_t seen_us);

#endif /* HALLHOME_ICM_CLOCK_H */
