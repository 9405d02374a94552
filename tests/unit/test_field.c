/*
 * field: conversions, baseline, filters, |B - B0| and the absolute mode,
 * against values worked out by hand (in the comments).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "devices/icm20948_model.h"
#include "field/field.h"
#include "icm20948/icm20948.h"
#include "icm_fake_bus.h"

static void test_raw_to_cuT(void **state)
{
    int16_t raw[3] = {-301, 32752, 1};
    int32_t v[3];
    (void)state;
    assert_int_equal(fld_raw_to_cuT(0), 0);
    assert_int_equal(fld_raw_to_cuT(1), 15);         /* 0.15 uT */
    assert_int_equal(fld_raw_to_cuT(-301), -4515);   /* -45.15 uT */
    assert_int_equal(fld_raw_to_cuT(32752), 491280); /* 4912.80 uT */
    assert_int_equal(fld_raw_to_cuT(-32768), -491520);
    fld_vec_cuT(raw, v);
    assert_int_equal(v[0], -4515);
    assert_int_equal(v[1], 491280);
    assert_int_equal(v[2], 15);
}

static void test_isqrt_and_norm(void **state)
{
    int32_t v[3];
    (void)state;
    assert_int_equal(fld_isqrt64(0), 0);
    assert_int_equal(fld_isqrt64(1), 1);
    assert_int_equal(fld_isqrt64(15), 3);
    assert_int_equal(fld_isqrt64(16), 4);
    assert_int_equal(fld_isqrt64(1000000000000ull), 1000000);
    assert_int_equal(fld_isqrt64(UINT64_MAX), 4294967295u);
    /* (300, -400, 0) -> 500 */
    v[0] = 300, v[1] = -400, v[2] = 0;
    assert_int_equal(fld_norm_cuT(v), 500);
    /* 15 * sqrt(3) = 25.98 -> 26; 15 * sqrt(2) = 21.21 -> 21 */
    v[0] = 15, v[1] = 15, v[2] = 15;
    assert_int_equal(fld_norm_cuT(v), 26);
    v[2] = 0;
    assert_int_equal(fld_norm_cuT(v), 21);
    /* the largest AK09916 vector: 491280 * sqrt(3) = 850921.92 -> 850922 */
    v[0] = v[1] = v[2] = -491280;
    assert_int_equal(fld_norm_cuT(v), 850922);
}

/* floor(sqrt(v)) is the r with r^2 <= v < (r + 1)^2. */
static void check_isqrt(uint64_t v)
{
    uint64_t r = fld_isqrt64(v);
    assert_true(r * r <= v);
    if (r < 0xFFFFFFFFull) {
        assert_true((r + 1u) * (r + 1u) > v);
    }
}

static void test_isqrt_property(void **state)
{
    uint64_t x = 88172645463325252ull;
    uint32_t n;
    unsigned k;
    (void)state;
    for (k = 0; k < 64u; k++) {
        uint64_t p = (uint64_t)1 << k;
        check_isqrt(p);
        check_isqrt(p - 1u);
        check_isqrt(p + 1u);
    }
    for (n = 1; n < 2000000u; n = n * 3u + 1u) {
        uint64_t sq = (uint64_t)n * n;
        check_isqrt(sq - 1u);
        check_isqrt(sq);
        check_isqrt(sq + 1u);
    }
    check_isqrt(UINT64_MAX);
    check_isqrt((uint64_t)0xFFFFFFFFu * 0xFFFFFFFFu);
    for (n = 0; n < 200000u; n++) {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        check_isqrt(x >> (n % 64u));
    }
}

static void test_baseline_by_hand(void **state)
{
    fld_base_t b;
    const int16_t s[4][3] = {{10, 0, 0}, {12, 0, 0}, {10, 0, 0}, {12, 0, 4}};
    int i;
    (void)state;
    assert_int_equal(fld_base_start(&b, 1), FLD_E_ARG);
    assert_int_equal(fld_base_start(&b, FLD_BASE_MAX_N + 1u), FLD_E_ARG);
    assert_int_equal(fld_base_start(&b, 4), 0);
    for (i = 0; i < 3; i++) {
        assert_int_equal(fld_base_push(&b, s[i], 0), FLD_BUSY);
        assert_false(fld_base_done(&b));
    }
    assert_int_equal(fld_base_push(&b, s[3], 0), 0);
    assert_true(fld_base_done(&b));
    /* x: mean 11 counts = 165 cuT; sample variance 4/3 counts^2 = 300 cuT^2,
     * sd 17.3 -> 17. z: mean 1 = 15 cuT; variance 12/3 = 4 counts^2 = 900
     * cuT^2, sd 30. Vector noise sqrt(300 + 0 + 900) = 34.6 -> 35. */
    assert_int_equal(b.b0_cuT[0], 165);
    assert_int_equal(b.b0_cuT[1], 0);
    assert_int_equal(b.b0_cuT[2], 15);
    assert_int_equal(b.sd_cuT[0], 17);
    assert_int_equal(b.sd_cuT[1], 0);
    assert_int_equal(b.sd_cuT[2], 30);
    assert_int_equal(b.noise_cuT, 35);
    /* complete: further samples change nothing */
    assert_int_equal(fld_base_push(&b, s[0], 0), 0);
    assert_int_equal(b.b0_cuT[0], 165);
}

static void test_baseline_rounds_negative_mean(void **state)
{
    fld_base_t b;
    const int16_t a[3] = {-1, 0, 0};
    const int16_t c[3] = {-2, 0, 0};
    (void)state;
    assert_int_equal(fld_base_start(&b, 2), 0);
    assert_int_equal(fld_base_push(&b, a, 0), FLD_BUSY);
    assert_int_equal(fld_base_push(&b, c, 0), 0);
    /* mean -1.5 counts = -22.5 cuT -> -23 (half away from zero) */
    assert_int_equal(b.b0_cuT[0], -23);
    /* variance 0.5 counts^2 = 112.5 -> 112 cuT^2 (floor), sd 10.6 -> 11 */
    assert_int_equal(b.sd_cuT[0], 11);
}

static void test_baseline_overflow_restarts(void **state)
{
    fld_base_t b;
    const int16_t ok[3] = {1, 2, 3};
    (void)state;
    assert_int_equal(fld_base_push(NULL, ok, 0), FLD_E_ARG);
    assert_int_equal(fld_base_start(&b, 3), 0);
    assert_int_equal(fld_base_push(&b, ok, 0), FLD_BUSY);
    assert_int_equal(fld_base_push(&b, ok, 0), FLD_BUSY);
    assert_int_equal(fld_base_push(&b, ok, 1), FLD_E_OVERFLOW);
    assert_int_equal(b.n, 0);
    assert_int_equal(fld_base_push(&b, ok, 0), FLD_BUSY);
    assert_int_equal(fld_base_push(&b, ok, 0), FLD_BUSY);
    assert_int_equal(fld_base_push(&b, ok, 0), 0);
    assert_int_equal(b.b0_cuT[2], 45);
    assert_int_equal(b.noise_cuT, 0);
}

static void test_filter_mean_and_median(void **state)
{
    fld_filter_t mean, med;
    int32_t out[3];
    const int16_t s[4][3] = {{100, -100, 7}, {102, -102, 7}, {101, -101, 7}, {103, -103, 7}};
    int i;
    (void)state;
    assert_int_equal(fld_filter_init(&mean, 0, FLD_MEAN), FLD_E_ARG);
    assert_int_equal(fld_filter_init(&mean, FLD_MAX_K + 1u, FLD_MEAN), FLD_E_ARG);
    assert_int_equal(fld_filter_init(&mean, 4, 7), FLD_E_ARG);
    assert_int_equal(fld_filter_init(&mean, 4, FLD_MEAN), 0);
    assert_int_equal(fld_filter_init(&med, 4, FLD_MEDIAN), 0);
    assert_int_equal(fld_filter_cuT(&mean, out), FLD_E_EMPTY);
    for (i = 0; i < 4; i++) {
        assert_int_equal(fld_filter_push(&mean, s[i], 0), 0);
        assert_int_equal(fld_filter_push(&med, s[i], 0), 0);
    }
    /* mean 101.5 counts = 1522.5 cuT -> 1523; -1523; 7 counts = 105 */
    assert_int_equal(fld_filter_cuT(&mean, out), 0);
    assert_int_equal(out[0], 1523);
    assert_int_equal(out[1], -1523);
    assert_int_equal(out[2], 105);
    /* median of 100,101,102,103: (101 + 102) / 2 = 101.5 -> 1523 as well */
    assert_int_equal(fld_filter_cuT(&med, out), 0);
    assert_int_equal(out[0], 1523);
    assert_int_equal(out[1], -1523);
    assert_int_equal(out[2], 105);
}

static void test_median_rejects_outlier_window_slides(void **state)
{
    fld_filter_t mean, med;
    int32_t out[3];
    const int16_t s[6][3] = {{100, 0, 0}, {100, 0, 0}, {5000, 0, 0},
                             {101, 0, 0}, {99, 0, 0},  {300, 0, 0}};
    int i;
    (void)state;
    assert_int_equal(fld_filter_init(&mean, 5, FLD_MEAN), 0);
    assert_int_equal(fld_filter_init(&med, 5, FLD_MEDIAN), 0);
    for (i = 0; i < 5; i++) {
        fld_filter_push(&mean, s[i], 0);
        fld_filter_push(&med, s[i], 0);
    }
    /* median of 99,100,100,101,5000 = 100 -> 1500; mean 5400/5 = 1080 -> 16200 */
    assert_int_equal(fld_filter_cuT(&med, out), 0);
    assert_int_equal(out[0], 1500);
    assert_int_equal(fld_filter_cuT(&mean, out), 0);
    assert_int_equal(out[0], 16200);
    /* one more: the first 100 leaves; window 100,5000,101,99,300 */
    fld_filter_push(&mean, s[5], 0);
    fld_filter_push(&med, s[5], 0);
    assert_int_equal(fld_filter_cuT(&med, out), 0);
    assert_int_equal(out[0], 1515); /* 101 */
    assert_int_equal(fld_filter_cuT(&mean, out), 0);
    assert_int_equal(out[0], 16800); /* 5600 / 5 = 1120 */
    fld_filter_reset(&med);
    assert_int_equal(fld_filter_cuT(&med, out), FLD_E_EMPTY);
}

static void test_filter_overflow_until_it_leaves(void **state)
{
    fld_filter_t f;
    int32_t out[3];
    const int16_t s[3] = {32752, 0, 0};
    const int16_t ok[3] = {1, 0, 0};
    (void)state;
    assert_int_equal(fld_filter_init(&f, 2, FLD_MEAN), 0);
    fld_filter_push(&f, s, 1);
    assert_int_equal(fld_filter_cuT(&f, out), FLD_E_OVERFLOW);
    fld_filter_push(&f, ok, 0);
    assert_int_equal(fld_filter_cuT(&f, out), FLD_E_OVERFLOW);
    fld_filter_push(&f, ok, 0);
    assert_int_equal(fld_filter_cuT(&f, out), 0);
    assert_int_equal(out[0], 15);
}

static void test_delta_by_hand(void **state)
{
    fld_base_t b;
    fld_filter_t f;
    uint32_t d = 0;
    const int16_t b0[3] = {100, -200, 30};
    const int16_t now[3] = {112, -184, 30};
    const int16_t one[3] = {101, -199, 31};
    (void)state;
    assert_int_equal(fld_filter_init(&f, 1, FLD_MEAN), 0);
    assert_int_equal(fld_base_start(&b, 2), 0);
    fld_filter_push(&f, now, 0);
    assert_int_equal(fld_delta_cuT(&f, &b, &d), FLD_E_NO_BASE);
    fld_base_push(&b, b0, 0);
    fld_base_push(&b, b0, 0);
    /* difference (12, 16, 0) counts = (180, 240, 0) cuT -> 300 cuT = 3 uT */
    assert_int_equal(fld_delta_cuT(&f, &b, &d), 0);
    assert_int_equal(d, 300);
    /* difference of one count per axis: 15 sqrt(3) = 25.98 -> 26 */
    fld_filter_push(&f, one, 0);
    assert_int_equal(fld_delta_cuT(&f, &b, &d), 0);
    assert_int_equal(d, 26);
    /* at the baseline itself */
    fld_filter_push(&f, b0, 0);
    assert_int_equal(fld_delta_cuT(&f, &b, &d), 0);
    assert_int_equal(d, 0);
    assert_int_equal(fld_delta_cuT(&f, NULL, &d), FLD_E_ARG);
}

static void test_absolute_mode_with_ambient(void **state)
{
    fld_base_t b;
    fld_filter_t f;
    uint32_t d = 0;
    int32_t ambient[3] = {2000, -3000, 4000}; /* 20, -30, 40 uT */
    int32_t zero[3] = {0, 0, 0};
    const int16_t now[3] = {112, -184, 30};       /* 1680, -2760, 450 cuT */
    const int16_t straight[3] = {200, -300, 300}; /* 3000, -4500, 4500 cuT */
    const int32_t magnet_straight[3] = {1000, -1500, 500};
    int32_t amb[3];
    (void)state;
    assert_int_equal(fld_filter_init(&f, 1, FLD_MEDIAN), 0);
    fld_filter_push(&f, now, 0);
    /* (1680 - 2000, -2760 + 3000, 450 - 4000) = (-320, 240, -3550):
     * sqrt(12762500) = 3572.46 -> 3572 */
    assert_int_equal(fld_abs_cuT(&f, ambient, &d), 0);
    assert_int_equal(d, 3572);
    /* no ambient: the paper's |B| = sqrt(1680^2 + 2760^2 + 450^2) = 3262.2 */
    assert_int_equal(fld_abs_cuT(&f, zero, &d), 0);
    assert_int_equal(d, 3262);
    /* ambient from a straight-pose baseline minus the predicted magnet field */
    assert_int_equal(fld_ambient_cuT(NULL, magnet_straight, amb), FLD_E_ARG);
    assert_int_equal(fld_base_start(&b, 2), 0);
    assert_int_equal(fld_ambient_cuT(&b, magnet_straight, amb), FLD_E_NO_BASE);
    fld_base_push(&b, straight, 0);
    fld_base_push(&b, straight, 0);
    assert_int_equal(fld_ambient_cuT(&b, magnet_straight, amb), 0);
    assert_int_equal(amb[0], 2000);
    assert_int_equal(amb[1], -3000);
    assert_int_equal(amb[2], 4000);
}

/* The driver and the model together: a baseline of 100 samples of a sensor
 * with 0.60 uT noise finds the field and the noise. */
static void test_baseline_from_modelled_sensor(void **state)
{
    icmm_t icm;
    icm_fake_bus_t fb;
    icm_dev_t dev;
    icm_sample_t s;
    fld_base_t b;
    fld_filter_t f;
    uint32_t d = 0;
    int8_t rc = FLD_BUSY;
    int guard = 0;
    (void)state;
    icmm_init(&icm, 0x69, 3);
    icmm_set_field_cuT(&icm, 2500, -1200, 4100);
    icmm_set_noise(&icm, 60, 99);
    icm_fake_bus_setup(&fb, icmm_slave(&icm));
    assert_int_equal(icm_setup(&dev, &fb.bus, NULL, ICM_NO_MUX, 0x69), 0);
    assert_int_equal(icm_init_start(&dev, 0), 0);
    while (icm_init_poll(&dev, icm_fake_bus_now_us(&fb)) == ICM_BUSY && guard++ < 5000) {
        icm_fake_bus_sleep_us(&fb, 100);
    }
    assert_true(icm_ready(&dev));
    assert_int_equal(fld_base_start(&b, 100), 0);
    assert_int_equal(fld_filter_init(&f, 8, FLD_MEAN), 0);
    guard = 0;
    while (rc == FLD_BUSY && guard++ < 1000) {
        icm_fake_bus_sleep_us(&fb, 5000);
        assert_int_equal(icm_read_start(&dev, icm_fake_bus_now_us(&fb)), 0);
        assert_int_equal(icm_read_fetch(&dev, icm_fake_bus_now_us(&fb), &s), 0);
        if (s.flags & ICM_SAMPLE_NEW) {
            rc = fld_base_push(&b, s.raw, s.flags & ICM_SAMPLE_OVERFLOW);
            fld_filter_push(&f, s.raw, 0);
        }
    }
    assert_int_equal(rc, 0);
    /* mean within 3 sigma/sqrt(100) = 18 cuT of the truth, plus quantization */
    assert_in_range(b.b0_cuT[0], 2500 - 26, 2500 + 26);
    assert_in_range(b.b0_cuT[1], -1200 - 26, -1200 + 26);
    assert_in_range(b.b0_cuT[2], 4100 - 26, 4100 + 26);
    /* per-axis sd of 60 cuT (quantization adds 15/sqrt(12) = 4.3 in quadrature) */
    assert_in_range(b.sd_cuT[0], 48, 74);
    assert_in_range(b.noise_cuT, 88, 120); /* sqrt(3) * 60 = 104 */
    /* the field has not moved: |B - B0| of an 8-sample mean is noise-sized */
    assert_int_equal(fld_delta_cuT(&f, &b, &d), 0);
    assert_true(d < 80u);
    /* move the magnet: |dB| follows */
    icmm_set_field_cuT(&icm, 2500 + 3000, -1200 - 4000, 4100);
    guard = 0;
    while (guard++ < 40) {
        icm_fake_bus_sleep_us(&fb, 5000);
        assert_int_equal(icm_read_start(&dev, icm_fake_bus_now_us(&fb)), 0);
        assert_int_equal(icm_read_fetch(&dev, icm_fake_bus_now_us(&fb), &s), 0);
        if (s.flags & ICM_SAMPLE_NEW) {
            fld_filter_push(&f, s.raw, 0);
        }
    }
    assert_int_equal(fld_delta_cuT(&f, &b, &d), 0);
    assert_in_range(d, 5000 - 60, 5000 + 60);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_raw_to_cuT),
        cmocka_unit_test(test_isqrt_and_norm),
        cmocka_unit_test(test_isqrt_property),
        cmocka_unit_test(test_baseline_by_hand),
        cmocka_unit_test(test_baseline_rounds_negative_mean),
        cmocka_unit_test(test_baseline_overflow_restarts),
        cmocka_unit_test(test_filter_mean_and_median),
        cmocka_unit_test(test_median_rejects_outlier_window_slides),
        cmocka_unit_test(test_filter_overflow_until_it_leaves),
        cmocka_unit_test(test_delta_by_hand),
        cmocka_unit_test(test_absolute_mode_with_ambient),
        cmocka_unit_test(test_baseline_from_modelled_sensor),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
