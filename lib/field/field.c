#include "field/field.h"

#include <stddef.h>
#include <string.h>

int32_t fld_raw_to_cuT(int16_t raw)
{
    return (int32_t)raw * FLD_CUT_PER_LSB;
}

void fld_vec_cuT(const int16_t raw[3], int32_t out_cuT[3])
{
    uint8_t i;
    for (i = 0; i < 3u; i++) {
        out_cuT[i] = fld_raw_to_cuT(raw[i]);
    }
}

/* Bit-by-bit square root in 32 bits: 16 iterations of shifts and adds. */
static uint32_t fld_isqrt32(uint32_t v)
{
    uint32_t rem = v;
    uint32_t root = 0;
    uint32_t bit = (uint32_t)1 << 30;
    while (bit > rem) {
        bit >>= 2;
    }
    while (bit != 0u) {
        if (rem >= root + bit) {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    return root;
}

/* 64-bit arithmetic is slow on the AVR (library loops for every shift and
 * compare), so the root is found in 32 bits from v scaled down by 4^k and
 * only its k low bits are settled against v, with one widening multiply
 * each: k <= 5 for any sum of squares of AK09916 fields. */
uint32_t fld_isqrt64(uint64_t v)
{
    uint32_t hi = (uint32_t)(v >> 32);
    uint32_t r;
    uint32_t bit;
    uint8_t k = 0;
    if (hi == 0u) {
        return fld_isqrt32((uint32_t)v);
    }
    while (hi != 0u) {
        hi >>= 1;
        k++;
    }
    k = (uint8_t)((k + 1u) / 2u);
    r = fld_isqrt32((uint32_t)(v >> (2u * k))) << k;
    for (bit = (uint32_t)1 << (k - 1u); bit != 0u; bit >>= 1) {
        uint32_t c = r | bit;
        if ((uint64_t)c * c <= v) {
            r = c;
        }
    }
    return r;
}

/* Rounds to nearest: r = floor(sqrt(s)) rounds up when s > r^2 + r, i.e.
 * when sqrt(s) >= r + 0.5. */
static uint32_t fld_sqrt_round(uint64_t s)
{
    uint32_t r = fld_isqrt64(s);
    if (s > (uint64_t)r * r + r) {
        r++;
    }
    return r;
}

uint32_t fld_norm_cuT(const int32_t v_cuT[3])
{
    uint64_t s = 0;
    uint8_t i;
    for (i = 0; i < 3u; i++) {
        uint32_t a = v_cuT[i] < 0 ? (uint32_t)0 - (uint32_t)v_cuT[i] : (uint32_t)v_cuT[i];
        s += (uint64_t)a * a;
    }
    return fld_sqrt_round(s);
}

/* Rounds num/den half away from zero (den > 0). */
static int32_t fld_div_round(int64_t num, int64_t den)
{
    if (num >= 0) {
        return (int32_t)((num + den / 2) / den);
    }
    return (int32_t) - ((-num + den / 2) / den);
}

/* The same in 32 bits for the per-sample path, where the AVR's 64-bit
 * division would cost a large library routine. */
static int32_t fld_div_round32(int32_t num, int32_t den)
{
    if (num >= 0) {
        return (num + den / 2) / den;
    }
    return -((-num + den / 2) / den);
}

int8_t fld_base_start(fld_base_t *b, uint16_t n)
{
    if (b == NULL || n < 2u || n > FLD_BASE_MAX_N) {
        return FLD_E_ARG;
    }
    memset(b, 0, sizeof(*b));
    b->n_target = n;
    return 0;
}

/* Sample variance in counts^2 times 225 (cuT^2): (n*sumsq - sum^2) /
 * (n*(n-1)). With n <= 1024 and |raw| <= 32768 every term fits in 64 bits. */
static void fld_base_finish(fld_base_t *b)
{
    uint64_t var_total = 0;
    uint64_t n = b->n;
    uint8_t i;
    for (i = 0; i < 3u; i++) {
        int64_t sum = b->sum[i];
        uint64_t num = n * b->sumsq[i] - (uint64_t)(sum * sum);
        uint64_t var_cuT2 = (num * 225u) / (n * (n - 1u));
        b->b0_cuT[i] = fld_div_round(sum * FLD_CUT_PER_LSB, (int64_t)n);
        b->sd_cuT[i] = fld_sqrt_round(var_cuT2);
        var_total += var_cuT2;
    }
    b->noise_cuT = fld_sqrt_round(var_total);
    b->done = 1;
}

int8_t fld_base_push(fld_base_t *b, const int16_t raw[3], uint8_t overflow)
{
    uint8_t i;
    if (b == NULL || raw == NULL || b->n_target == 0u) {
        return FLD_E_ARG;
    }
    if (b->done) {
        return 0;
    }
    if (overflow) {
        uint16_t n = b->n_target;
        (void)fld_base_start(b, n);
        return FLD_E_OVERFLOW;
    }
    for (i = 0; i < 3u; i++) {
        int32_t r = raw[i];
        b->sum[i] += r;
        b->sumsq[i] += (uint64_t)((int64_t)r * r);
    }
    b->n++;
    if (b->n < b->n_target) {
        return FLD_BUSY;
    }
    fld_base_finish(b);
    return 0;
}

uint8_t fld_base_done(const fld_base_t *b)
{
    return (uint8_t)(b != NULL && b->done);
}

int8_t fld_filter_init(fld_filter_t *f, uint8_t k, uint8_t mode)
{
    if (f == NULL || k == 0u || k > FLD_MAX_K || (mode != FLD_MEAN && mode != FLD_MEDIAN)) {
        return FLD_E_ARG;
    }
    memset(f, 0, sizeof(*f));
    f->k = k;
    f->mode = mode;
    return 0;
}

void fld_filter_reset(fld_filter_t *f)
{
    if (f != NULL) {
        f->count = 0;
        f->head = 0;
    }
}

int8_t fld_filter_push(fld_filter_t *f, const int16_t raw[3], uint8_t overflow)
{
    if (f == NULL || raw == NULL || f->k == 0u) {
        return FLD_E_ARG;
    }
    memcpy(f->raw[f->head], raw, sizeof(f->raw[0]));
    f->ovf[f->head] = (uint8_t)(overflow != 0u);
    f->head = (uint8_t)((f->head + 1u) % f->k);
    if (f->count < f->k) {
        f->count++;
    }
    return 0;
}

/* Insertion sort of at most FLD_MAX_K values: bounded and small. */
static int32_t fld_median_axis(const fld_filter_t *f, uint8_t axis)
{
    int16_t v[FLD_MAX_K] = {0};
    uint8_t i, j;
    for (i = 0; i < f->count; i++) {
        int16_t x = f->raw[i][axis];
        for (j = i; j > 0u && v[j - 1u] > x; j--) {
            v[j] = v[j - 1u];
        }
        v[j] = x;
    }
    if (f->count & 1u) {
        return (int32_t)v[f->count / 2u] * FLD_CUT_PER_LSB;
    }
    return fld_div_round32(((int32_t)v[f->count / 2u - 1u] + v[f->count / 2u]) * FLD_CUT_PER_LSB,
                           2);
}

int8_t fld_filter_cuT(const fld_filter_t *f, int32_t out_cuT[3])
{
    uint8_t i, axis;
    uint8_t ovf = 0;
    if (f == NULL || out_cuT == NULL) {
        return FLD_E_ARG;
    }
    if (f->count == 0u) {
        return FLD_E_EMPTY;
    }
    for (i = 0; i < f->count; i++) {
        ovf |= f->ovf[i];
    }
    for (axis = 0; axis < 3u; axis++) {
        if (f->mode == FLD_MEDIAN) {
            out_cuT[axis] = fld_median_axis(f, axis);
        } else {
            int32_t sum = 0;
            for (i = 0; i < f->count; i++) {
                sum += f->raw[i][axis];
            }
            out_cuT[axis] = fld_div_round32(sum * FLD_CUT_PER_LSB, f->count);
        }
    }
    return ovf ? FLD_E_OVERFLOW : 0;
}

int8_t fld_abs_cuT(const fld_filter_t *f, const int32_t ambient_cuT[3], uint32_t *out_cuT)
{
    int32_t v[3];
    uint8_t i;
    int8_t rc;
    if (ambient_cuT == NULL || out_cuT == NULL) {
        return FLD_E_ARG;
    }
    rc = fld_filter_cuT(f, v);
    if (rc != 0) {
        return rc;
    }
    for (i = 0; i < 3u; i++) {
        v[i] -= ambient_cuT[i];
    }
    *out_cuT = fld_norm_cuT(v);
    return 0;
}

int8_t fld_delta_cuT(const fld_filter_t *f, const fld_base_t *b, uint32_t *out_cuT)
{
    if (b == NULL) {
        return FLD_E_ARG;
    }
    if (!b->done) {
        return FLD_E_NO_BASE;
    }
    return fld_abs_cuT(f, b->b0_cuT, out_cuT);
}

int8_t fld_ambient_cuT(const fld_base_t *b, const int32_t magnet_straight_cuT[3],
                       int32_t ambient_cuT[3])
{
    uint8_t i;
    if (b == NULL || magnet_straight_cuT == NULL || ambient_cuT == NULL) {
        return FLD_E_ARG;
    }
    if (!b->done) {
        return FLD_E_NO_BASE;
    }
    for (i = 0; i < 3u; i++) {
        ambient_cuT[i] = b->b0_cuT[i] - magnet_straight_cuT[i];
    }
    return 0;
}
