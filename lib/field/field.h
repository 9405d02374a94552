/*
 * field: integer-only processing of AK09916 samples into the calibration
 * quantities, in cuT (centi-microtesla, 10 nT; one AK09916 LSB = 15 cuT
 * exactly, so every conversion is exact).
 *
 *   - fld_base_t: the straight-pose baseline B0 of one sensor, the mean of N
 *     samples, with the noise standard deviation per axis and of the vector.
 *   - fld_filter_t: the last K samples of one sensor, reduced by mean or
 *     per-axis median.
 *   - fld_delta_cuT(): |B - B0| of the filtered field, the calibration target
 *     compared with the table's |B(p_T) - B(p_0)| (ambient-immune mode).
 *   - fld_abs_cuT(): |B - ambient|, the paper's absolute-magnitude mode with
 *     an ambient offset (earth field and nearby iron) removed, for comparison.
 *
 * Error convention: 0 = done, negative = FLD_E_* code, positive = FLD_BUSY
 * (baseline still collecting). No floating point; the per-sample path uses
 * 32-bit arithmetic except the 64-bit sum of squares under the square root.
 */
#ifndef HALLHOME_FIELD_H
#define HALLHOME_FIELD_H

#include <stdint.h>

#define FLD_CUT_PER_LSB 15    /* 0.15 uT per AK09916 count */
#define FLD_MAX_K       16u   /* filter window capacity */
#define FLD_BASE_MAX_N  1024u /* keeps the baseline sums inside int32/uint64 */

#define FLD_BUSY 1

enum fld_err {
    FLD_E_ARG = -1,      /* NULL pointer or value out of range */
    FLD_E_EMPTY = -2,    /* the filter holds no sample yet */
    FLD_E_OVERFLOW = -3, /* a sample in use was flagged HOFL: the value is not a field */
    FLD_E_NO_BASE = -4   /* the baseline has not been captured */
};

enum fld_mode { FLD_MEAN = 0, FLD_MEDIAN = 1 };

/* Straight-pose baseline of one sensor. */
typedef struct {
    uint16_t n_target;
    uint16_t n;
    uint8_t done;
    int32_t sum[3];     /* raw counts */
    uint64_t sumsq[3];  /* raw counts squared */
    int32_t b0_cuT[3];  /* mean, rounded to the nearest cuT */
    uint32_t sd_cuT[3]; /* sample standard deviation per axis */
    uint32_t noise_cuT; /* sqrt(sum of the axis variances): the rms of |B - B0| from noise */
} fld_base_t;

/* Moving window of the last K samples of one sensor. */
typedef struct {
    uint8_t k;     /* window length 1..FLD_MAX_K */
    uint8_t mode;  /* FLD_MEAN or FLD_MEDIAN */
    uint8_t count; /* samples held, <= k */
    uint8_t head;  /* next slot to write */
    int16_t raw[FLD_MAX_K][3];
    uint8_t ovf[FLD_MAX_K]; /* sample was flagged HOFL */
} fld_filter_t;

/* One raw count in cuT (exact). */
int32_t fld_raw_to_cuT(int16_t raw);

/* A raw vector in cuT. */
void fld_vec_cuT(const int16_t raw[3], int32_t out_cuT[3]);

/* floor(sqrt(v)) for any 64-bit v. */
uint32_t fld_isqrt64(uint64_t v);

/* |v| rounded to the nearest cuT, for components within +-2^30 cuT. */
uint32_t fld_norm_cuT(const int32_t v_cuT[3]);

/* Starts a baseline capture of n samples (2..FLD_BASE_MAX_N); forgets any
 * previous baseline. Returns 0 or FLD_E_ARG. */
int8_t fld_base_start(fld_base_t *b, uint16_t n);

/* Adds one sample. Returns FLD_BUSY while collecting, 0 when the n-th sample
 * completed the baseline (b0, sd and noise are then valid and further pushes
 * return 0 and change nothing), FLD_E_OVERFLOW for an overflowed sample
 * (the capture restarts from zero: a straight pose must not saturate),
 * FLD_E_ARG for NULL or a capture not started. */
int8_t fld_base_push(fld_base_t *b, const int16_t raw[3], uint8_t overflow);

/* Nonzero once the baseline is complete. */
uint8_t fld_base_done(const fld_base_t *b);

/* Sets up a window of k samples (1..FLD_MAX_K) reduced by mode. Returns 0 or
 * FLD_E_ARG. */
int8_t fld_filter_init(fld_filter_t *f, uint8_t k, uint8_t mode);

/* Drops every sample (e.g. when the sensor was re-initialised). */
void fld_filter_reset(fld_filter_t *f);

/* Adds one sample (the oldest leaves once k are held). Returns 0 or
 * FLD_E_ARG. */
int8_t fld_filter_push(fld_filter_t *f, const int16_t raw[3], uint8_t overflow);

/* The filtered field in cuT: per-axis mean (rounded half away from zero) or
 * per-axis median (mean of the two middle values for an even count) of the
 * samples held. Returns 0, FLD_E_EMPTY, FLD_E_OVERFLOW when any held sample
 * was overflowed (out_cuT is still written), FLD_E_ARG. */
int8_t fld_filter_cuT(const fld_filter_t *f, int32_t out_cuT[3]);

/* |filtered - B0| in cuT. Returns 0, FLD_E_NO_BASE, or the errors of
 * fld_filter_cuT() (nothing written on error). */
int8_t fld_delta_cuT(const fld_filter_t *f, const fld_base_t *b, uint32_t *out_cuT);

/* |filtered - ambient| in cuT (the absolute mode; ambient all zero gives the
 * paper's raw |B|). Returns 0 or the errors of fld_filter_cuT(). */
int8_t fld_abs_cuT(const fld_filter_t *f, const int32_t ambient_cuT[3], uint32_t *out_cuT);

/* The ambient offset from a straight-pose baseline and the magnet's
 * predicted straight-pose field (the table's b_straight_cuT): everything the
 * sensor sees that is not the magnet. Returns 0, FLD_E_NO_BASE, FLD_E_ARG. */
int8_t fld_ambient_cuT(const fld_base_t *b, const int32_t magnet_straight_cuT[3],
                       int32_t ambient_cuT[3]);

#endif /* HALLHOME_FIELD_H */
