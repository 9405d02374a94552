/*
 * table: accessors for the generated calibration table. Every read goes
 * through the source's copy function, so the same code reads a table in AVR
 * program memory (memcpy_P) and in host memory (memcpy). Only the few bytes a
 * caller needs are copied: a whole table does not fit the AVR's RAM. The
 * table is sized to its robot, so every address is computed from the header's
 * counts (TBL_OFF_* in table.h), and stored values are widened to the units
 * the rest of the firmware works in (cuT, um).
 */
#include "table/table.h"

#include <stddef.h>
#include <string.h>

void tbl_copy_ram(void *dst, const void *src, size_t n)
{
    memcpy(dst, src, n);
}

/* Address arithmetic on the table's own address: valid in flash too, since the
 * pointer is never dereferenced here, only handed to the copy function. */
#define TBL_AT(src, off)  ((const void *)((const uint8_t *)(const void *)(src)->table + (off)))
#define TBL_HEAD_OFF(fld) ((uint16_t)offsetof(tbl_head_t, fld))

/* n bytes at offset off of the table into dst: one call through the
 * source's copy function here instead of one at every read. */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static void
tbl_read(const tbl_src_t *src, void *dst, uint16_t off, size_t n)
{
    src->copy(dst, TBL_AT(src, off), n);
}

static int tbl_src_ok(const tbl_src_t *src)
{
    return src != NULL && src->table != NULL && src->copy != NULL;
}

/* n_tendons, n_sensors, n_grid (adjacent in the header) into c[0..2]. */
static void tbl_counts(const tbl_src_t *src, uint8_t c[3])
{
    tbl_read(src, c, TBL_HEAD_OFF(n_tendons), 3);
}

int tbl_check(const tbl_src_t *src)
{
    /* the header's first 8 bytes: every format starts with them */
    struct {
        uint32_t magic;
        uint16_t version, size;
    } h;
    tbl_info_t info;
    uint8_t i;

    if (!tbl_src_ok(src)) {
        return TBL_E_ARG;
    }
    tbl_read(src, &h, TBL_HEAD_OFF(magic), sizeof h);
    if (h.magic != TBL_MAGIC) {
        return TBL_E_MAGIC;
    }
    if (h.version != TBL_FORMAT_VERSION) {
        return TBL_E_VERSION;
    }
    (void)tbl_info(src, &info);
    if (info.n_tendons == 0u || info.n_tendons > TBL_MAX_TENDONS || info.n_sensors == 0u ||
        info.n_sensors > TBL_MAX_SENSORS || info.n_grid < 2u || info.n_grid > TBL_MAX_GRID ||
        h.size != TBL_SIZE(info.n_tendons, info.n_sensors, info.n_grid)) {
        return TBL_E_FORMAT;
    }
    for (i = 1; i < info.n_grid; i++) {
        if (tbl_grid_mN(src, i) <= tbl_grid_mN(src, (uint8_t)(i - 1u))) {
            return TBL_E_FORMAT;
        }
    }
    if (info.default_mN < tbl_grid_mN(src, 0) ||
        info.default_mN > tbl_grid_mN(src, (uint8_t)(info.n_grid - 1u))) {
        return TBL_E_FORMAT;
    }
    for (i = 0; i < info.n_tendons; i++) {
        tbl_tendon_head_t r;
        (void)tbl_tendon_head(src, i, &r); /* the counts are checked: cannot fail */
        if (r.sensor >= info.n_sensors || r.nm_per_tick == 0u) {
            return TBL_E_FORMAT;
        }
    }
    return 0;
}

int tbl_info(const tbl_src_t *src, tbl_info_t *info)
{
    if (!tbl_src_ok(src) || info == NULL) {
        return TBL_E_ARG;
    }
    tbl_read(src, &info->table_id, TBL_HEAD_OFF(table_id), sizeof info->table_id);
    /* n_tendons, n_sensors, n_grid, mode, default_mN, noise_cuT: the same
     * 8 bytes in both structs */
    tbl_read(src, &info->n_tendons, TBL_HEAD_OFF(n_tendons), 8);
    return 0;
}

int tbl_name(const tbl_src_t *src, char name[TBL_NAME_LEN])
{
    if (!tbl_src_ok(src) || name == NULL) {
        return TBL_E_ARG;
    }
    tbl_read(src, name, TBL_HEAD_OFF(name), TBL_NAME_LEN);
    name[TBL_NAME_LEN - 1u] = '\0';
    return 0;
}

uint16_t tbl_grid_mN(const tbl_src_t *src, uint8_t g)
{
    uint8_t ng;
    uint16_t mN = 0;
    if (!tbl_src_ok(src)) {
        return 0;
    }
    tbl_read(src, &ng, TBL_HEAD_OFF(n_grid), 1);
    if (g < ng && g < TBL_MAX_GRID) {
        tbl_read(src, &mN, (uint16_t)(TBL_OFF_GRID + 2u * g), sizeof mN);
    }
    return mN;
}

typedef char tbl_info_counts_adjacent_t
    [(offsetof(tbl_info_t, n_sensors) == offsetof(tbl_info_t, n_tendons) + 1u &&
      offsetof(tbl_info_t, mode) == offsetof(tbl_info_t, n_tendons) + 3u &&
      offsetof(tbl_head_t, mode) == offsetof(tbl_head_t, n_tendons) + 3u &&
      offsetof(tbl_info_t, default_mN) == offsetof(tbl_info_t, n_tendons) + 4u &&
      offsetof(tbl_head_t, default_mN) == offsetof(tbl_head_t, n_tendons) + 4u &&
      offsetof(tbl_info_t, noise_cuT) == offsetof(tbl_info_t, n_tendons) + 6u &&
      offsetof(tbl_head_t, noise_cuT) == offsetof(tbl_head_t, n_tendons) + 6u &&
      sizeof(tbl_info_t) == offsetof(tbl_info_t, n_tendons) + 8u &&
      offsetof(tbl_head_t, format_version) == 4u && offsetof(tbl_head_t, size) == 6u)
         ? 1
         : -1];

/* Offset of entry g of row `row` of tendon i (c: the counts). */
static uint16_t tbl_row_off(const uint8_t c[3], uint8_t row, uint8_t i, uint8_t g)
{
    return (uint16_t)(TBL_OFF_ROW(c[0], c[1], c[2], row) + 2u * ((uint16_t)i * c[2] + g));
}

/* The counts into c[] and 0 when tendon i is in the table, else TBL_E_ARG. */
static int tbl_tendon_counts(const tbl_src_t *src, uint8_t i, uint8_t c[3])
{
    if (!tbl_src_ok(src)) {
        return TBL_E_ARG;
    }
    tbl_counts(src, c);
    return i >= c[0] || i >= TBL_MAX_TENDONS || c[2] > TBL_MAX_GRID ? TBL_E_ARG : 0;
}

int tbl_tendon_head(const tbl_src_t *src, uint8_t i, tbl_tendon_head_t *out)
{
    uint8_t c[3];
    tbl_tendon_rec_t r;

    if (out == NULL || tbl_tendon_counts(src, i, c) != 0) {
        return TBL_E_ARG;
    }
    tbl_read(src, &r, (uint16_t)(TBL_OFF_TENDONS(c[1], c[2]) + i * sizeof r), sizeof r);
    out->servo_id = r.servo_id;
    out->pull_dir = r.pull_dir;
    out->segment = r.segment;
    out->sensor = r.sensor;
    out->nm_per_tick = r.nm_per_tick;
    out->travel_limit_um = r.travel_limit_um;
    return 0;
}

int tbl_entry(const tbl_src_t *src, uint8_t i, uint8_t row, uint8_t g, uint32_t *out)
{
    uint8_t c[3];
    uint16_t v;

    if (out == NULL || row >= TBL_ROW_STRAIGHT || tbl_tendon_counts(src, i, c) != 0) {
        return TBL_E_ARG;
    }
    if (g == TBL_GRID_TOP) {
        g = (uint8_t)(c[2] - 1u);
    }
    if (g >= c[2]) {
        return TBL_E_ARG;
    }
    tbl_read(src, &v, tbl_row_off(c, row, i, g), sizeof v);
    *out = row == TBL_ROW_TRAVEL ? v : (uint32_t)v * TBL_CUT_PER_LSB;
    return 0;
}

int tbl_row(const tbl_src_t *src, uint8_t i, uint8_t row, uint32_t out[TBL_MAX_GRID])
{
    uint8_t c[3], g;
    uint16_t v[TBL_MAX_GRID];

    if (out == NULL || row >= TBL_ROW_STRAIGHT || tbl_tendon_counts(src, i, c) != 0) {
        return TBL_E_ARG;
    }
    tbl_read(src, v, tbl_row_off(c, row, i, 0), 2u * c[2]);
    for (g = 0; g < c[2]; g++) {
        out[g] = row == TBL_ROW_TRAVEL ? v[g] : (uint32_t)v[g] * TBL_CUT_PER_LSB;
    }
    return c[2];
}

/* tbl_tendon() copies the head into the row as bytes: the same layout. */
typedef char tbl_tendon_head_ok_t[(offsetof(tbl_tendon_t, travel_limit_um) ==
                                       offsetof(tbl_tendon_head_t, travel_limit_um) &&
                                   sizeof(tbl_tendon_head_t) <= offsetof(tbl_tendon_t, target_cuT))
                                      ? 1
                                      : -1];

int tbl_tendon(const tbl_src_t *src, uint8_t i, tbl_tendon_t *out)
{
    uint8_t c[3];
    tbl_tendon_head_t h;

    if (out == NULL || tbl_tendon_head(src, i, &h) != 0) {
        return TBL_E_ARG;
    }
    tbl_counts(src, c);
    memset(out, 0, sizeof *out);
    memcpy(out, &h, sizeof h); /* the same initial fields (TBL_TENDON_HEAD_FIELDS) */
    (void)tbl_row(src, i, TBL_ROW_TARGET, out->target_cuT);
    (void)tbl_row(src, i, TBL_ROW_ABS, out->abs_target_cuT);
    (void)tbl_row(src, i, TBL_ROW_TRAVEL, out->travel_um);
    tbl_read(src, out->straight_um, tbl_row_off(c, TBL_ROW_STRAIGHT, i, 0), 2u * c[2]);
    return 0;
}

int tbl_sensor(const tbl_src_t *src, uint8_t i, tbl_sensor_t *out)
{
    uint8_t c[3], a;
    tbl_sensor_rec_t r;
    if (!tbl_src_ok(src) || out == NULL) {
        return TBL_E_ARG;
    }
    tbl_counts(src, c);
    if (i >= c[1] || i >= TBL_MAX_SENSORS) {
        return TBL_E_ARG;
    }
    tbl_read(src, &r, (uint16_t)(TBL_OFF_SENSORS(c[2]) + i * sizeof r), sizeof r);
    out->mux_channel = r.mux_channel;
    out->i2c_addr = r.i2c_addr;
    for (a = 0; a < 3u; a++) {
        out->b_straight_cuT[a] = (int32_t)r.b_straight_lsb[a] * (int32_t)TBL_CUT_PER_LSB;
    }
    return 0;
}

const void *tbl_target_row(const tbl_table_t *table, const tbl_info_t *info, uint8_t tendon)
{
    uint8_t c[3];
    if (table == NULL || info == NULL || tendon >= info->n_tendons) {
        return NULL;
    }
    c[0] = info->n_tendons;
    c[1] = info->n_sensors;
    c[2] = info->n_grid;
    return (const uint8_t *)(const void *)table + tbl_row_off(c, TBL_ROW_TARGET, tendon, 0);
}

uint16_t tbl_lsb_of_cuT(uint32_t cuT)
{
    return (uint16_t)((cuT + TBL_CUT_PER_LSB / 2u) / TBL_CUT_PER_LSB);
}

typedef char tbl_point_rows_adjacent_t
    [(TBL_ROW_TARGET == 0u && TBL_ROW_ABS == 1u && TBL_ROW_TRAVEL == 2u &&
      offsetof(tbl_point_t, abs_target_cuT) == offsetof(tbl_point_t, target_cuT) + 4u &&
      offsetof(tbl_point_t, travel_um) == offsetof(tbl_point_t, target_cuT) + 8u)
         ? 1
         : -1];

/* Locates x in the grid: returns the index k with grid[k] <= x <= grid[k+1],
 * or -1 outside. */
static int tbl_bracket(const uint16_t *grid, uint8_t n, uint16_t x)
{
    uint8_t k;
    if (n < 2u || x < grid[0] || x > grid[n - 1u]) {
        return -1;
    }
    for (k = 0; k + 2u < n; k++) {
        if (x <= grid[k + 1u]) {
            break;
        }
    }
    return (int)k;
}

/* Rounded linear interpolation between (x0, y0) and (x1, y1), half away from
 * zero, in 32 bits: a field span times a tension span would overflow, so
 * the span is split into whole multiples of dx and a remainder below dx
 * (remainder * t < 2^32 for dx, t <= 65535); the result equals the exact
 * 64-bit rounding. One copy (not inlined): tbl_interp() and tbl_target()
 * both call it. */
#if defined(__GNUC__)
__attribute__((noinline))
#endif
static uint32_t
tbl_lerp(uint16_t x0, uint16_t x1, uint32_t y0, uint32_t y1, uint16_t x)
{
    uint32_t dx = (uint32_t)x1 - x0;
    uint32_t t = (uint32_t)x - x0;
    uint32_t a = y1 >= y0 ? y1 - y0 : y0 - y1;
    uint32_t q = 0;
    /* a span below 2^16 (every row of the tables built so far) times t
     * fits 32 bits: one division, the same result (a = Q dx + R gives
     * Q t + (R t + dx/2) / dx either way), a third of the time */
    if (a > 0xFFFFu) {
        q = (a / dx) * t;
        a %= dx;
    }
    q += (a * t + dx / 2u) / dx;
    return y1 >= y0 ? y0 + q : y0 - q;
}

int tbl_interp(const uint16_t *grid, const uint32_t *y, uint8_t n, uint16_t x, uint32_t *y_out)
{
    int k;
    if (grid == NULL || y == NULL || y_out == NULL || n < 2u) {
        return TBL_E_ARG;
    }
    k = tbl_bracket(grid, n, x);
    if (k < 0) {
        return TBL_E_RANGE;
    }
    *y_out = tbl_lerp(grid[k], grid[k + 1], y[k], y[k + 1], x);
    return 0;
}

/* The stored pair around the tension is widened first (fields to cuT, the
 * signed shift offset into the unsigned range), so the interpolation is the
 * exact rounding of the stored values in the returned unit. */
int tbl_target(const tbl_src_t *src, uint8_t tendon, uint16_t tension_mN, tbl_point_t *out)
{
    /* the counts and the grid only (not tbl_info()'s 52 bytes): the AVR
     * reaches the first 64 bytes of a frame with one instruction a byte */
    uint16_t y[2];
    uint8_t c[3];
    uint32_t v[TBL_ROWS];
    uint16_t grid[TBL_MAX_GRID];
    uint8_t row;
    int k;

    if (out == NULL || !tbl_src_ok(src)) {
        return TBL_E_ARG;
    }
    tbl_counts(src, c);
    if (tendon >= c[0] || tendon >= TBL_MAX_TENDONS) {
        return TBL_E_ARG;
    }
    if (c[2] > TBL_MAX_GRID) {
        return TBL_E_RANGE;
    }
    tbl_read(src, grid, TBL_OFF_GRID, 2u * c[2]);
    k = tbl_bracket(grid, c[2], tension_mN);
    if (k < 0) {
        return TBL_E_RANGE;
    }
    for (row = 0; row < TBL_ROWS; row++) {
        uint32_t y0, y1;
        tbl_read(src, y, (uint16_t)(tbl_row_off(c, row, tendon, (uint8_t)k)), sizeof y);
        if (row == TBL_ROW_STRAIGHT) {
            /* int16 + 32768: the sign bit flipped */
            y0 = (uint16_t)(y[0] ^ 0x8000u);
            y1 = (uint16_t)(y[1] ^ 0x8000u);
        } else if (row == TBL_ROW_TRAVEL) {
            y0 = y[0];
            y1 = y[1];
        } else {
            y0 = (uint32_t)y[0] * TBL_CUT_PER_LSB;
            y1 = (uint32_t)y[1] * TBL_CUT_PER_LSB;
        }
        v[row] = tbl_lerp(grid[k], grid[k + 1], y0, y1, tension_mN);
    }
    out->tension_mN = tension_mN;
    /* target_cuT, abs_target_cuT, travel_um: rows 0..2, adjacent */
    memcpy(&out->target_cuT, v, 3u * sizeof v[0]);
    out->straight_um = (int16_t)(uint16_t)(v[TBL_ROW_STRAIGHT] ^ 0x8000u);
    return 0;
}
