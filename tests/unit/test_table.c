/* Unit tests of the table accessors and the RAM packer: validation of every
 * header field, the robot-sized layout (offsets, size), row copies widened to
 * cuT / um, integer interpolation and its range errors, refusal of values the
 * stored types cannot hold, and that every read goes through the source's
 * copy function (as memcpy_P does on the AVR). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "table/table.h"
#include "table/table_pack.h"

/* The default robot's generated table (lookup_tables/generated/paper_2seg.c,
 * linked into every test through hh_lib). */
extern const tbl_table_t tbl_table_paper_2seg;

static tbl_wide_t g_tab; /* natural units; packed into g_buf by src_of() */
static tbl_buf_t g_buf;
static unsigned g_copies;

static void counting_copy(void *dst, const void *src, size_t n)
{
    g_copies++;
    memcpy(dst, src, n);
}

/* Field values are whole LSB (multiples of TBL_CUT_PER_LSB = 15 cuT), so
 * packing keeps them exactly. */
static void make_table(tbl_wide_t *t)
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
    t->sensors[2].b_straight_cuT[2] = -97005;
    for (unsigned i = 0; i < 2; i++) {
        t->tendons[i].servo_id = (uint8_t)(i + 1);
        t->tendons[i].pull_dir = 1;
        t->tendons[i].segment = 1;
        t->tendons[i].sensor = (uint8_t)i;
        t->tendons[i].nm_per_tick = 6136;
        t->tendons[i].travel_limit_um = 2000;
        t->tendons[i].target_cuT[0] = 1500;
        t->tendons[i].target_cuT[1] = 4500;
        t->tendons[i].target_cuT[2] = 7500 + 1500 * i;
        t->tendons[i].abs_target_cuT[0] = 99000;
        t->tendons[i].abs_target_cuT[1] = 90000;
        t->tendons[i].abs_target_cuT[2] = 81000;
        t->tendons[i].travel_um[0] = 100;
        t->tendons[i].travel_um[1] = 301;
        t->tendons[i].travel_um[2] = 500;
        t->tendons[i].straight_um[0] = -40;
        t->tendons[i].straight_um[1] = 10;
        t->tendons[i].straight_um[2] = (int16_t)(300 + i);
    }
}

/* Packs t (as it is now) into g_buf and returns a source reading it. */
static tbl_src_t src_of(const tbl_wide_t *t)
{
    tbl_src_t s;
    s.table = NULL;
    if (t != NULL) {
        assert_int_equal(tbl_pack(t, &g_buf), 0);
        s.table = tbl_buf_table(&g_buf);
    }
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
    s = src_of(&g_tab);
    s.copy = NULL;
    assert_int_equal(tbl_check(&s), TBL_E_ARG);
}

/* A table of another format version (e.g. an old build's uint32 layout,
 * version 2) is refused, never read. */
static void test_check_magic_and_version(void **state)
{
    tbl_src_t s;
    (void)state;
    g_tab.magic = 0x12345678u;
    s = src_of(&g_tab);
    assert_int_equal(tbl_check(&s), TBL_E_MAGIC);
    g_tab.magic = TBL_MAGIC;
    g_tab.format_version = TBL_FORMAT_VERSION + 1u;
    s = src_of(&g_tab);
    assert_int_equal(tbl_check(&s), TBL_E_VERSION);
    g_tab.format_version = 2u;
    s = src_of(&g_tab);
    assert_int_equal(tbl_check(&s), TBL_E_VERSION);
}

static int check_of(const tbl_wide_t *t)
{
    tbl_src_t s = src_of(t);
    return tbl_check(&s);
}

static void test_check_format_errors(void **state)
{
    tbl_src_t s;
    (void)state;
    g_tab.n_tendons = 0;
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.n_sensors = 0;
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.n_grid = 1;
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.grid_mN[2] = 600; /* not strictly increasing */
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.default_mN = 1001;
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.tendons[1].sensor = 3;
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    make_table(&g_tab);
    g_tab.tendons[0].nm_per_tick = 0;
    assert_int_equal(check_of(&g_tab), TBL_E_FORMAT);
    /* counts beyond the maxima, or a size that is not the layout's */
    make_table(&g_tab);
    s = src_of(&g_tab);
    g_buf.head.n_tendons = TBL_MAX_TENDONS + 1u;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    s = src_of(&g_tab);
    g_buf.head.n_sensors = TBL_MAX_SENSORS + 1u;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    s = src_of(&g_tab);
    g_buf.head.n_grid = TBL_MAX_GRID + 1u;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    s = src_of(&g_tab);
    g_buf.head.size++;
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
    s = src_of(&g_tab);
    g_buf.head.n_tendons = 1; /* counts that do not match the size */
    assert_int_equal(tbl_check(&s), TBL_E_FORMAT);
}

/* The table is sized to its counts: header, grid, sensors, tendons, then
 * the four per-grid rows, nothing else. */
static void test_layout_is_robot_sized(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    uint16_t v;
    (void)state;
    assert_int_equal(sizeof(tbl_head_t), 36);
    assert_int_equal(g_buf.head.size, 36 + 2 * 3 + 3 * 8 + 2 * 8 + 4 * 2 * 2 * 3);
    assert_int_equal(TBL_SIZE(6, 3, 12), 708); /* paper_2seg: 2332 bytes in format 2 */
    assert_true(TBL_SIZE_MAX <= sizeof g_buf);
    /* the straight-pose shift of tendon 1 at grid 2 is the table's last entry */
    memcpy(&v, g_buf.bytes + g_buf.head.size - 2u, 2);
    assert_int_equal((int16_t)v, 301);
    assert_int_equal(tbl_check(&s), 0);
}

static void test_info_and_rows(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_info_t info;
    tbl_tendon_t t;
    tbl_sensor_t se;
    (void)state;
    char name[TBL_NAME_LEN];
    assert_int_equal(tbl_info(&s, &info), 0);
    assert_int_equal(tbl_name(&s, name), 0);
    assert_string_equal(name, "unit");
    assert_int_equal(tbl_name(NULL, name), TBL_E_ARG);
    assert_int_equal(info.n_tendons, 2);
    assert_int_equal(info.n_sensors, 3);
    assert_int_equal(info.default_mN, 800);
    assert_int_equal(info.table_id, 0xA5A55A5Au);
    assert_int_equal(tbl_grid_mN(&s, 2), 1000);
    assert_int_equal(tbl_grid_mN(&s, 3), 0); /* beyond n_grid */
    assert_int_equal(tbl_grid_mN(&s, 255), 0);
    assert_int_equal(tbl_grid_mN(NULL, 0), 0);
    assert_int_equal(tbl_tendon(&s, 1, &t), 0);
    assert_int_equal(t.servo_id, 2);
    assert_int_equal(t.nm_per_tick, 6136);
    assert_int_equal(t.travel_limit_um, 2000);
    assert_int_equal(t.target_cuT[2], 9000);
    assert_int_equal(t.abs_target_cuT[0], 99000);
    assert_int_equal(t.travel_um[1], 301);
    assert_int_equal(t.straight_um[0], -40);
    assert_int_equal(t.target_cuT[3], 0);
    assert_int_equal(tbl_tendon(&s, 2, &t), TBL_E_ARG);
    assert_int_equal(tbl_sensor(&s, 2, &se), 0);
    assert_int_equal(se.mux_channel, 2);
    assert_int_equal(se.i2c_addr, 0x69);
    assert_int_equal(se.b_straight_cuT[2], -97005);
    assert_int_equal(tbl_sensor(&s, 3, &se), TBL_E_ARG);
    assert_int_equal(tbl_info(&s, NULL), TBL_E_ARG);
}

/* The parts of a row: the same values as tbl_tendon()'s. */
static void test_row_parts(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_tendon_t t;
    tbl_tendon_head_t h;
    uint32_t r[TBL_MAX_GRID], v;
    uint8_t i, g, row;
    (void)state;
    for (i = 0; i < 2u; i++) {
        assert_int_equal(tbl_tendon(&s, i, &t), 0);
        assert_int_equal(tbl_tendon_head(&s, i, &h), 0);
        assert_int_equal(h.servo_id, t.servo_id);
        assert_int_equal(h.pull_dir, t.pull_dir);
        assert_int_equal(h.segment, t.segment);
        assert_int_equal(h.sensor, t.sensor);
        assert_int_equal(h.nm_per_tick, t.nm_per_tick);
        assert_int_equal(h.travel_limit_um, t.travel_limit_um);
        for (row = 0; row < TBL_ROW_STRAIGHT; row++) {
            const uint32_t *want = row == TBL_ROW_TARGET ? t.target_cuT
                                   : row == TBL_ROW_ABS  ? t.abs_target_cuT
                                                         : t.travel_um;
            memset(r, 0x5A, sizeof r);
            assert_int_equal(tbl_row(&s, i, row, r), 3);
            assert_memory_equal(r, want, 3u * sizeof r[0]);
            assert_int_equal(r[3], 0x5A5A5A5Au); /* beyond n_grid: untouched */
            for (g = 0; g < 3u; g++) {
                assert_int_equal(tbl_entry(&s, i, row, g, &v), 0);
                assert_int_equal(v, want[g]);
            }
            assert_int_equal(tbl_entry(&s, i, row, TBL_GRID_TOP, &v), 0);
            assert_int_equal(v, want[2]);
            assert_int_equal(tbl_entry(&s, i, row, 3, &v), TBL_E_ARG);
        }
    }
    assert_int_equal(tbl_tendon_head(&s, 2, &h), TBL_E_ARG);
    assert_int_equal(tbl_tendon_head(&s, 0, NULL), TBL_E_ARG);
    assert_int_equal(tbl_tendon_head(NULL, 0, &h), TBL_E_ARG);
    assert_int_equal(tbl_row(&s, 2, TBL_ROW_TARGET, r), TBL_E_ARG);
    assert_int_equal(tbl_row(&s, 0, TBL_ROW_STRAIGHT, r), TBL_E_ARG);
    assert_int_equal(tbl_row(&s, 0, TBL_ROW_TARGET, NULL), TBL_E_ARG);
    assert_int_equal(tbl_entry(&s, 2, TBL_ROW_TARGET, 0, &v), TBL_E_ARG);
    assert_int_equal(tbl_entry(&s, 0, TBL_ROW_STRAIGHT, 0, &v), TBL_E_ARG);
    assert_int_equal(tbl_entry(&s, 0, TBL_ROW_TARGET, 0, NULL), TBL_E_ARG);
}

static void test_target_interpolates(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_point_t p;
    (void)state;
    /* on grid points: exact */
    assert_int_equal(tbl_target(&s, 0, 200, &p), 0);
    assert_int_equal(p.target_cuT, 1500);
    assert_int_equal(p.travel_um, 100);
    assert_int_equal(p.straight_um, -40);
    assert_int_equal(tbl_target(&s, 1, 1000, &p), 0);
    assert_int_equal(p.target_cuT, 9000);
    /* between: 800 mN is half-way from 600 to 1000 */
    assert_int_equal(tbl_target(&s, 1, 800, &p), 0);
    assert_int_equal(p.tension_mN, 800);
    assert_int_equal(p.target_cuT, 6750);
    assert_int_equal(p.abs_target_cuT, 85500); /* decreasing values too */
    assert_int_equal(p.travel_um, 401);        /* 301 + 199/2 = 400.5, rounded */
    assert_int_equal(p.straight_um, 156);      /* 10 + 291/2 = 155.5, rounded */
    assert_int_equal(tbl_target(&s, 0, 300, &p), 0);
    assert_int_equal(p.target_cuT, 2250);
    assert_int_equal(p.straight_um, -27); /* -40 + 50/4 = -27.5: the shift rounds half up */
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

/* Fields round to the nearest LSB when packed; a value the stored type
 * cannot hold is refused, never clipped. */
static void test_pack_rounds_and_refuses(void **state)
{
    tbl_src_t s;
    tbl_tendon_t t;
    (void)state;
    assert_int_equal(tbl_lsb_of_cuT(0), 0);
    assert_int_equal(tbl_lsb_of_cuT(7), 0);
    assert_int_equal(tbl_lsb_of_cuT(8), 1);
    assert_int_equal(tbl_lsb_of_cuT(22), 1);
    assert_int_equal(tbl_lsb_of_cuT(23), 2);
    assert_int_equal(tbl_lsb_of_cuT(TBL_FIELD_CUT_MAX), 0xFFFF);
    g_tab.tendons[0].target_cuT[1] = 4507; /* 300.47 LSB */
    s = src_of(&g_tab);
    assert_int_equal(tbl_tendon(&s, 0, &t), 0);
    assert_int_equal(t.target_cuT[1], 4500);
    g_tab.tendons[0].target_cuT[2] = TBL_FIELD_CUT_MAX;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), 0);
    g_tab.tendons[0].target_cuT[2] = TBL_FIELD_CUT_MAX + 1u;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_RANGE);
    make_table(&g_tab);
    g_tab.tendons[1].abs_target_cuT[0] = TBL_FIELD_CUT_MAX + 1u;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_RANGE);
    make_table(&g_tab);
    g_tab.tendons[1].travel_um[2] = 65536u;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_RANGE);
    make_table(&g_tab);
    g_tab.tendons[1].travel_limit_um = 70000u;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_RANGE);
    make_table(&g_tab);
    g_tab.tendons[0].nm_per_tick = 65536u;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_RANGE);
    make_table(&g_tab);
    g_tab.sensors[1].b_straight_cuT[0] = -32768 * 15 - 8; /* -32768.5 LSB */
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_RANGE);
    g_tab.sensors[1].b_straight_cuT[0] = -32768 * 15;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), 0);
    make_table(&g_tab);
    g_tab.n_tendons = TBL_MAX_TENDONS + 1u;
    assert_int_equal(tbl_pack(&g_tab, &g_buf), TBL_E_ARG);
    assert_int_equal(tbl_pack(NULL, &g_buf), TBL_E_ARG);
}

/* pack then unpack gives the same table back (values in whole LSB). */
static void test_pack_unpack_round_trip(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    static tbl_wide_t back;
    (void)state;
    assert_int_equal(tbl_unpack(&s, &back), 0);
    assert_memory_equal(&back, &g_tab, sizeof back);
    g_buf.head.magic = 0;
    assert_int_equal(tbl_unpack(&s, &back), TBL_E_MAGIC);
}

/* The stored target row is where tbl_target_row() says: a copy function
 * that patches that address range changes what the accessors return (the
 * app's learned targets use this). */
static void test_target_row_address(void **state)
{
    tbl_src_t s = src_of(&g_tab);
    tbl_info_t info;
    const uint8_t *row;
    uint16_t v;
    (void)state;
    assert_int_equal(tbl_info(&s, &info), 0);
    row = tbl_target_row(s.table, &info, 1);
    assert_ptr_equal(row, g_buf.bytes + TBL_OFF_ROW(2u, 3u, 3u, TBL_ROW_TARGET) + 2u * 3u);
    memcpy(&v, row + 4, 2);
    assert_int_equal(v * TBL_CUT_PER_LSB, 9000);
    v = 1000; /* 15000 cuT */
    memcpy(g_buf.bytes + (row + 4 - g_buf.bytes), &v, 2);
    {
        tbl_point_t p;
        assert_int_equal(tbl_target(&s, 1, 1000, &p), 0);
        assert_int_equal(p.target_cuT, 15000);
    }
    assert_null(tbl_target_row(s.table, &info, 2));
    assert_null(tbl_target_row(NULL, &info, 0));
    assert_null(tbl_target_row(s.table, NULL, 0));
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
    char name[TBL_NAME_LEN];
    assert_int_equal(tbl_info(&s, &info), 0);
    assert_int_equal(tbl_name(&s, name), 0);
    assert_string_equal(name, "paper_2seg");
    /* sized to the robot: 6 tendons, 3 sensors, 12 grid points */
    assert_int_equal(((const tbl_head_t *)(const void *)&tbl_table_paper_2seg)->size,
                     TBL_SIZE(6u, 3u, 12u));
    for (i = 0; i < info.n_tendons; i++) {
        tbl_point_t p;
        assert_int_equal(tbl_target(&s, i, info.default_mN, &p), 0);
        assert_true(p.target_cuT > 0u && p.travel_um > 0u);
        assert_int_equal(tbl_target(&s, i, (uint16_t)(tbl_grid_mN(&s, 0) - 1u), &p), TBL_E_RANGE);
    }
}

/* The 32-bit interpolation equals the exact rounded (half away from zero)
 * 64-bit result over seeded random spans, down and up, up to the extremes;
 * every other draw a span of at most 0xFFFF (the one-division path), the
 * largest of them among them. */
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
        if (n % 2 == 1) {
            uint32_t span = n % 6 == 1 ? 0xFFFFu : (x >> 7) & 0xFFFFu;
            y[1] = (n & 2) ? (y[0] >= span ? y[0] - span : y[0] + span)
                           : (y[0] <= 0xFFFFFFFFu - span ? y[0] + span : y[0] - span);
        }
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
        cmocka_unit_test_setup(test_row_parts, setup),
        cmocka_unit_test_setup(test_target_interpolates, setup),
        cmocka_unit_test_setup(test_target_errors, setup),
        cmocka_unit_test_setup(test_layout_is_robot_sized, setup),
        cmocka_unit_test_setup(test_pack_rounds_and_refuses, setup),
        cmocka_unit_test_setup(test_pack_unpack_round_trip, setup),
        cmocka_unit_test_setup(test_target_row_address, setup),
        cmocka_unit_test_setup(test_interp_ram, setup),
        cmocka_unit_test(test_generated_table),
        cmocka_unit_test(test_interp_matches_64_bit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
