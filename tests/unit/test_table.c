/* Unit tests of the table accessors: validation of every header field, row
 * copies, integer interpolation and its range errors, and that every read goes
 * through the source's copy function (as memcpy_P does on the AVR). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "table/table.h"

/* The default robot's generated table (lookup_tables/generated/paper_2seg.c,
 * linked into every test through hh_lib). */
extern const tbl_table_t tbl_table_paper_2seg;

static tbl_table_t g_tab;
static unsigned g_copies;

static void counting_copy(void *dst, const void *src, size_t n)
{
    g_copies++;
    memcpy(dst, src, n);
}

static void make_table(tbl_table_t *t)
{
    memset(t, 0, sizeof *t);
    t->magic = TBL_MAGIC;
    t->format_version = TBL_FORMAT_VERSION;
    t->table_id = 0xA5A55A5Au;
    strcpy(t->name, "unit");
    t->n_tendons = 2;
    t->n_sensors = 3;
    t->n_grid = 3;
    t->grid_mN[0] = 200;
    t->grid_mN[1] = 600;
    t->grid_mN[2] = 1000;
    t->default_mN = 800;
    t->noise_cuT = 40;
    t->sensors[2].mux_channel = 2;
    t->sensors[2].i2c_addr = 0x69;
    t->sensors[2].b_straight_cuT[2] = -97000;
    for (unsigned i = 0; i < 2; i++) {
        t->tendons[i].servo_id = (uint8_t)(i + 1);
        t->tendons[i].pull_dir = 1;
        t->tendons[i].segment = 1;
        t->tendons[i].sensor = (uint8_t)i;
        t->tendons[i].nm_per_tick = 6136;
        t->tendons[i].travel_limit_um = 2000;
        t->tendons[i].target_cuT[0] = 1000;
        t->tendons[i].target_cuT[1] = 5000;
        t->tendons[i].target_cuT[2] = 7000 + 1000 * i;
        t->tendons[i].abs_target_cuT[0] = 100000;
        t->tendons[i].abs_target_cuT[1] = 90000;
        t->tendons[i].abs_target_cuT[2] = 80000;
        t->tendons[i].travel_um[0] = 100;
        t->tendons[i].travel_um[1] = 301;
        t->tendons[i].travel_um[2] = 500;
    }
}

static tbl_src_t src_of(const tbl_table_t *t)
{
    tbl_src_t s;
    s.table = t;
    s.copy = counting_copy;
    return s;
}

static int setup(void **state)
{
    (void)state;
    make_table(&g_tab);
    g_copies = 0;
    return 0;
}

static void test_check_accepts_valid(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    (void)state;
    assert_int_equal(tbl_check(&s), 0);
    assert_true(g_copies > 0u);
}

static void test_check_rejects_null(void **state)
{
    tbl_src_t s = src_of(NULL);
    (void)state;
    assert_int_equal(tbl_check(NULL), TBL_E_ARG);
    assert_int_equal(tbl_check(&s), TBL_E_ARG);
    s.table = &g_tab;
    s.copy = NULL;
    assert_int_equal(tbl_check(&s), TBL_E_ARG);
}

static void test_check_magic_and_version(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    (void)state;
    g_tab.magic = 0x12345678u;
    assert_int_equal(tbl_check(&s), TBL_E_MAGIC);
    g_tab.magic = TBL_MAGIC;
    g_tab.format_version = TBL_FORMAT_VERSION + 1u;
    assert_int_equal(tbl_check(&s), TBL_E_VERSION);
}

static void test_check_format_errors(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    (void)state;
    g_tab.n_tendons = TBL_MAX_TENDONS + 1u;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.n_tendons = 0;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.n_sensors = TBL_MAX_SENSORS + 1u;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.n_grid = 1;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.grid_mN[2] = 600; /* not strictly increasing */
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.default_mN = 1001;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.tendons[1].sensor = 3;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.tendons[0].nm_per_tick = 0;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
}

static void test_info_and_rows(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_info_t info;
    tbl_tendon_t t;
    tbl_sensor_t se;
    (void)state;
    assert_int_equal(tbl_info(&s, &info), 0);
    assert_string_equal(info.name, "unit");
    assert_int_equal(info.n_tendons, 2);
    assert_int_equal(info.n_sensors, 3);
    assert_int_equal(info.default_mN, 800);
    assert_int_equal(info.table_id, 0xA5A55A5Au);
    assert_int_equal(info.grid_mN[2], 1000);
    assert_int_equal(tbl_tendon(&s, 1, &t), 0);
    assert_int_equal(t.servo_id, 2);
    assert_int_equal(t.target_cuT[2], 8000);
    assert_int_equal(tbl_tendon(&s, 2, &t), TBL_E_ARG);
    assert_int_equal(tbl_sensor(&s, 2, &se), 0);
    assert_int_equal(se.b_straight_cuT[2], -97000);
    assert_int_equal(tbl_sensor(&s, 3, &se), TBL_E_ARG);
    assert_int_equal(tbl_info(&s, NULL), TBL_E_ARG);
}

static void test_target_interpolates(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_point_t p;
    (void)state;
    /* on grid points: exact */
    assert_int_equal(tbl_target(&s, 0, 200, &p), 0);
    assert_int_equal(p.target_cuT, 1000);
    assert_int_equal(p.travel_um, 100);
    assert_int_equal(tbl_target(&s, 1, 1000, &p), 0);
    assert_int_equal(p.target_cuT, 8000);
    /* between: 800 mN is half-way from 600 to 1000 */
    assert_int_equal(tbl_target(&s, 1, 800, &p), 0);
    assert_int_equal(p.tension_mN, 800);
    assert_int_equal(p.target_cuT, 6500);
    assert_int_equal(p.abs_target_cuT, 85000); /* decreasing values too */
    assert_int_equal(p.travel_um, 401);        /* 301 + 199/2 = 400.5, rounded */
    assert_int_equal(tbl_target(&s, 0, 300, &p), 0);
    assert_int_equal(p.target_cuT, 2000);
}

static void test_target_errors(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_point_t p;
    memset(&p, 0x5A, sizeof p);
    (void)state;
    assert_int_equal(tbl_target(&s, 0, 199, &p), TBL_E_RANGE);
    assert_int_equal(tbl_target(&s, 0, 1001, &p), TBL_E_RANGE);
    assert_int_equal(p.target_cuT, 0x5A5A5A5Au); /* unchanged on error */
    assert_int_equal(tbl_target(&s, 2, 500, &p), TBL_E_ARG);
    assert_int_equal(tbl_target(&s, 0, 500, NULL), TBL_E_ARG);
    assert_int_equal(tbl_target(NULL, 0, 500, &p), TBL_E_ARG);
}

static void test_interp_ram(void **state)
{
    const uint16_t grid[4] = {100, 200, 400, 800};
    const uint32_t y[4] = {0, 1000, 1000, 3000};
    uint32_t v = 0;
    (void)state;
    assert_int_equal(tbl_interp(grid, y, 4, 150, &v), 0);
    assert_int_equal(v, 500);
    assert_int_equal(tbl_interp(grid, y, 4, 300, &v), 0);
    assert_int_equal(v, 1000);
    assert_int_equal(tbl_interp(grid, y, 4, 600, &v), 0);
    assert_int_equal(v, 2000);
    assert_int_equal(tbl_interp(grid, y, 4, 800, &v), 0);
    assert_int_equal(v, 3000);
    assert_int_equal(tbl_interp(grid, y, 4, 99, &v), TBL_E_RANGE);
    assert_int_equal(tbl_interp(grid, y, 1, 100, &v), TBL_E_ARG);
    assert_int_equal(tbl_interp(NULL, y, 4, 100, &v), TBL_E_ARG);
}

/* The generated table passes the checks and interpolates its default tension
 * to a positive target for every tendon. */
static void test_generated_table(void **state)
{
    tbl_src_t s;
    tbl_info_t info;
    uint8_t i;
    (void)state;
    s.table = &tbl_table_paper_2seg;
    s.copy = tbl_copy_ram;
    assert_int_equal(tbl_check(&s), 0);
    assert_int_equal(tbl_info(&s, &info), 0);
    assert_string_equal(info.name, "paper_2seg");
    for (i = 0; i < info.n_tendons; i++) {
        tbl_point_t p;
        assert_int_equal(tbl_target(&s, i, info.default_mN, &p), 0);
        assert_true(p.target_cuT > 0u && p.travel_um > 0u);
        assert_int_equal(tbl_target(&s, i, (uint16_t)(info.grid_mN[0] - 1u), &p), TBL_E_RANGE);
    }
}

/* The 32-bit interpolation equals the exact rounded (half away from zero)
 * 64-bit result over seeded random spans, down and up, up to the extremes. */
static void test_interp_matches_64_bit(void **state)
{
    uint32_t x = 99u;
    int n;
    (void)state;
    for (n = 0; n < 200000; n++) {
        uint16_t grid[2];
        uint32_t y[2], got;
        int64_t dy, dx, num, q;
        uint16_t at;
        x = x * 1664525u + 1013904223u;
        grid[0] = (uint16_t)(x >> 20);
        x = x * 1664525u + 1013904223u;
        grid[1] = (uint16_t)(grid[0] + 1u + ((x >> 16) % (65535u - grid[0])));
        if (grid[1] <= grid[0]) {
            continue;
        }
        x = x * 1664525u + 1013904223u;
        y[0] = n % 3 == 0 ? x : x >> 8;
        x = x * 1664525u + 1013904223u;
        y[1] = n % 5 == 0 ? x : x >> 8;
        x = x * 1664525u + 1013904223u;
        at = (uint16_t)(grid[0] + x % ((uint32_t)grid[1] - grid[0] + 1u));
        assert_int_equal(tbl_interp(grid, y, 2, at, &got), 0);
        dy = (int64_t)y[1] - (int64_t)y[0];
        dx = (int64_t)grid[1] - grid[0];
        num = dy * (int64_t)(at - grid[0]);
        q = (num >= 0 ? num + dx / 2 : num - dx / 2) / dx;
        assert_int_equal(got, (uint32_t)((int64_t)y[0] + q));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_check_accepts_valid, setup),
        cmocka_unit_test_setup(test_check_rejects_null, setup),
        cmocka_unit_test_setup(test_check_magic_and_version, setup),
        cmocka_unit_test_setup(test_check_format_errors, setup),
        cmocka_unit_test_setup(test_info_and_rows, setup),
        cmocka_unit_test_setup(test_target_interpolates, setup),
        cmocka_unit_test_setup(test_target_errors, setup),
        cmocka_unit_test_setup(test_interp_ram, setup),
        cmocka_unit_test(test_generated_table),
        cmocka_unit_test(test_interp_matches_64_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
