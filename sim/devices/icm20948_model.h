/*
 * icm20948_model: register-level model of an ICM-20948 with the AK09916
 * magnetometer behind its auxiliary I2C master, seen through the byte-level
 * slave interface of tca9548a_model.h. Shared by the native unit tests and
 * the simavr virtual bench.
 *
 * Modelled: register banks (REG_BANK_SEL), auto-incrementing register
 * pointer, WHO_AM_I, DEVICE_RESET (registers to reset values, the device does
 * not acknowledge for ICMM_RESET_US), SLEEP, USER_CTRL I2C master enable and
 * reset, I2C_MST_STATUS (clear on read), SLV4 single transfers (done after
 * ICMM_SLV4_US, SLV4_NACK when the AK09916 does not answer), SLV0 block reads
 * into EXT_SLV_SENS_DATA once per master period, and the master hanging after
 * a reset until I2C_MST_RST (a reported quirk).
 *
 * Master period (DS-000189 11.1, I2C_MST_ODR_CONFIG): the gyro ODR (1.1 kHz)
 * while the gyro is on (PWR_MGMT_2), else the accelerometer ODR (1.125 kHz)
 * while it is on, else 1.1 kHz / 2^ODR_CONFIG when LP_CONFIG.I2C_MST_CYCLE is
 * set; sample-rate dividers stay at their reset value 0 (not modelled).
 * The SLV0 bytes reach EXT_SLV_SENS_DATA as they cross the auxiliary bus
 * (ICMM_AUX_BYTE_US each) unless I2C_MST_DELAY_CTRL.DELAY_ES_SHADOW is set,
 * in which case the whole block appears at once (11.3): without it a host
 * burst read that starts during the transfer sees part of the new sample and
 * part of the old one (counted in torn_reads). A host burst read sees the
 * registers as they were at its START.
 *
 * The AK09916: WIA1/WIA2, soft reset, power-down/single/continuous modes
 * (10/20/50/100 Hz of simulated time), DRDY and DOR in ST1, the data
 * registers held from the first data read until ST2 is read (a sample that
 * completes meanwhile is delivered after the ST2 read), 0.15 uT quantization,
 * saturation at +-32752 counts (+-4912 uT) with ST2.HOFL, and Gaussian noise
 * with a configurable sigma and seed.
 *
 * The true field at the sensor is set in cuT (0.01 uT) in the sensor frame.
 */
#ifndef HALLHOME_SIM_ICM20948_MODEL_H
#define HALLHOME_SIM_ICM20948_MODEL_H

#include <stdint.h>

#include "devices/tca9548a_model.h"

#define ICMM_RESET_US      2000u /* DEVICE_RESET: no ACK for this long */
#define ICMM_SLV4_US       200u  /* SLV4 transaction latency */
#define ICMM_MST_PERIOD_US 909u  /* I2C master period at 1.1 kHz (gyro ODR, divider 0) */
#define ICMM_ACC_PERIOD_US 889u  /* at 1.125 kHz (accelerometer ODR, divider 0) */
#define ICMM_AUX_BYTE_US   26u   /* one byte (9 bits) on the auxiliary bus at 345.6 kHz */
#define ICMM_SLV0_LEAD     3u    /* bytes before the first data byte: address, register, address */
#define AKM_SRST_US        100u  /* AK09916 soft reset: no ACK for this long */

typedef struct {
    uint8_t present; /* 0: never acknowledges on the auxiliary bus */
    uint8_t wia1;    /* company ID answered (0x48 for a real AK09916) */
    uint8_t wia2;    /* device ID answered (0x09 for a real AK09916) */
    uint8_t mode;    /* CNTL2 */
    uint8_t st1;
    uint8_t st2;
    uint8_t data[6]; /* HXL..HZH as read */
    uint8_t locked;  /* a data read started and ST2 has not been read */
    uint8_t pend_valid;
    uint8_t pend_data[6];
    uint8_t pend_st2;
    uint64_t next_meas_us;
    uint64_t reset_until_us;
    int32_t field_cuT[3]; /* true field, before noise and quantization */
    uint32_t noise_cuT;   /* 1-sigma noise per axis */
    uint32_t rng;         /* xorshift32 state */
    uint32_t samples;     /* measurements completed */
} akm_t;

typedef struct {
    uint8_t addr;     /* 7-bit 0x68/0x69 */
    uint8_t present;  /* 0: never acknowledges (sensor absent or unplugged) */
    uint8_t who_am_i; /* WHO_AM_I value (0xEA for a real ICM-20948) */
    uint8_t regs[4][128];
    uint8_t bank;
    /* transaction state */
    uint8_t selected; /* addressed since the last START */
    uint8_t reading;
    uint8_t have_ptr;
    uint8_t ptr;
    uint8_t nread;        /* bytes read since the last START */
    uint8_t ext_view[24]; /* EXT_SLV_SENS_DATA as of the read START */
    /* SLV0 read on its way into EXT_SLV_SENS_DATA */
    uint8_t ext_new[24];
    uint8_t ext_n;      /* bytes of ext_new not yet visible to the host */
    uint8_t ext_done;   /* bytes of ext_new already visible */
    uint64_t ext_t0_us; /* start of that SLV0 read */
    /* time */
    uint64_t now_us;
    uint64_t reset_until_us;
    uint64_t next_mst_us;
    uint8_t slv4_pending;
    uint64_t slv4_at_us;
    /* quirks */
    uint8_t mst_hang_tries; /* this many SLV4 transfers hang the master */
    uint8_t mst_hung;       /* hung until I2C_MST_RST */
    /* statistics for tests and the bench */
    uint32_t resets;
    uint32_t mst_resets;
    uint32_t slv0_reads;
    uint32_t ext_reads;            /* host reads starting at EXT_SLV_SENS_DATA_00 */
    uint32_t torn_reads;           /* host reads that saw a half-updated EXT block */
    uint32_t mst_ctrl_live_writes; /* I2C_MST_CTRL written while the master was enabled */
    akm_t ak;
} icmm_t;

/* Power-on state at simulated time 0: present, WHO_AM_I 0xEA, asleep, AK09916
 * present and powered down, zero field, no noise, rng seeded with `seed`. */
void icmm_init(icmm_t *m, uint8_t addr, uint32_t seed);

/* Sets the true field at the sensor in cuT (sensor frame). Takes effect at
 * the next AK09916 measurement. */
void icmm_set_field_cuT(icmm_t *m, int32_t x, int32_t y, int32_t z);

/* Sets the per-axis noise sigma (cuT) and reseeds the noise generator. */
void icmm_set_noise(icmm_t *m, uint32_t sigma_cuT, uint32_t seed);

/* Brings the model to now_us (monotonic): AK09916 measurements, master
 * periods and SLV4 completions in time order. */
void icmm_advance(icmm_t *m, uint64_t now_us);

/* This ICM as a slave on its bus (through a mux channel or directly). */
simi2c_slave_t icmm_slave(icmm_t *m);

/* Register value as the host would read it, without side effects. */
uint8_t icmm_peek(const icmm_t *m, uint8_t bank, uint8_t reg);

/* The raw count the AK09916 reports for a field of cuT (rounded to the
 * nearest 0.15 uT, saturated at +-32752); *sat is set when it saturated. */
int16_t akm_quantize(int32_t cuT, uint8_t *sat);

#endif /* HALLHOME_SIM_ICM20948_MODEL_H */
