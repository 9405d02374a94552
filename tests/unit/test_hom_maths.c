/* Tests of the homing module's 32-bit multiply-divide (hom_priv.h), which
 * replaced a 64-bit expression on the AVR: it must give exactly what the
 * 64-bit a * b / c gives (truncated towards zero, saturated to int32) over
 * the edge cases of every sign and magnitude and many random triples. The
 * host has 64-bit arithmetic, so the reference is the expression itself. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "homing/hom_priv.h"

static int32_t reference(int32_t a, int32_t b, int32_t c)
{
    int64_t q = (int64_t)a * (int64_t)b / (int64_t)c;
    if (q > INT32_MAX) {
        return INT32_MAX;
    }
    return q < INT32_MIN ? INT32_MIN : (int32_t)q;
}

static void test_muldiv_edges(void **state)
{
    static const int32_t v[] = {0,
                                1,
                                -1,
                                2,
                                -2,
                                3,
                                7,
                                255,
                                256,
                                1000,
                                -1000,
                                46340,
                                46341,
                                65535,
                                65536,
                                -65536,
                                1 << 20,
                                INT32_MAX,
                                INT32_MIN,
                                INT32_MIN + 1,
                                INT32_MAX - 1,
                                1 << 30,
                                -(1 << 30),
                                123456789,
                                -987654321};
    size_t n = sizeof v / sizeof v[0];
    size_t i, j, k;
    (void)state;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            for (k = 0; k < n; k++) {
                if (v[k] == 0) {
                    continue;
                }
                if (hom_muldiv(v[i], v[j], v[k]) != reference(v[i], v[j], v[k])) {
                    fail_msg("hom_muldiv(%ld, %ld, %ld) = %ld, want %ld", (long)v[i], (long)v[j],
                             (long)v[k], (long)hom_muldiv(v[i], v[j], v[k]),
                             (long)reference(v[i], v[j], v[k]));
                }
            }
        }
    }
    /* the saturation boundary itself: exactly 2^31 - 1 and 2^31 */
    assert_int_equal(hom_muldiv(INT32_MAX, 1, 1), INT32_MAX);
    assert_int_equal(hom_muldiv(65536, 32768, 1), INT32_MAX);
    assert_int_equal(hom_muldiv(-65536, 32768, 1), INT32_MIN);
    assert_int_equal(hom_muldiv(65536, 32768, -1), INT32_MIN);
    assert_int_equal(hom_muldiv(-7, 3, 2), -10); /* -10.5 towards zero */
    assert_int_equal(hom_muldiv(7, 3, -2), -10);
}

/* xorshift32: a fixed sequence, so a failure repeats */
static uint32_t next(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *s = x;
    return x;
}

/* A random value of random magnitude (shifted down 0..31 bits) and sign. */
static int32_t rnd(uint32_t *s)
{
    uint32_t m = next(s) >> (next(s) & 31u);
    return (next(s) & 1u) ? -(int32_t)(m >> 1) : (int32_t)(m >> 1);
}

static void test_muldiv_random(void **state)
{
    uint32_t s = 0x12345678u;
    long n;
    (void)state;
    for (n = 0; n < 2000000L; n++) {
        int32_t a = rnd(&s);
        int32_t b = rnd(&s);
        int32_t c = rnd(&s);
        if (c == 0) {
            continue;
        }
        if (hom_muldiv(a, b, c) != reference(a, b, c)) {
            fail_msg("hom_muldiv(%ld, %ld, %ld) = %ld, want %ld", (long)a, (long)b, (long)c,
                     (long)hom_muldiv(a, b, c), (long)reference(a, b, c));
        }
    }
}

/* The calls homing makes: um to ticks, slopes in 1/256 tick, remaining
 * travel in 1/65536. */
static void test_muldiv_homing_calls(void **state)
{
    (void)state;
    assert_int_equal(hom_muldiv(2500, 1000, 6136), 407);
    assert_int_equal(hom_muldiv(110982 - 89858, 65536, 750 * 256), 7210);
    assert_int_equal(hom_muldiv(490000, 65536, 1), INT32_MAX);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_muldiv_edges),
        cmocka_unit_test(test_muldiv_random),
        cmocka_unit_test(test_muldiv_homing_calls),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
