/*
 * table: accessors for the generated calibration table. Every read goes
 * through the source's copy function, so the same code reads a table in AVR
 * program memory (memcpy_P) and in host memory (memcpy). Only the few bytes a
 * caller needs are copied: a whole table does not fit the AVR's RAM.
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
#define TBL_FIELD_ADDR(src, field) ((const void *)&((src)->table->field))

static int tbl_src_ok(const tbl_src_t *src)
{
    return src != NULL && src->table != NULL && src->copy != NULL;
}

int tbl_check(const tbl_src_t *src)
{
    uint32_t magic;
    uint16_t version;
    tbl_info_t info;
    uint8_t i;

    if (!tbl_src_ok(src)) {
        return TBL_E_ARG;
    }
    src->copy(&magic, TBL_FIELD_ADDR(src, magic), sizeof magic);
    if (magic != TBL_MAGIC) {
        return TBL_E_MAGIC;
    }
    src->copy(&version, TBL_FIELD_ADDR(src, format_version), sizeof version);
    if (version != TBL_FORMAT_VERSION) {
        return TBL_E_VERSION;
    }
    (void)tbl_info(src, &info);
    if (info.n_tendons == 0u || info.n_tendons > TBL_MAX_TENDONS || info.n_sensors == 0u ||
        info.n_sensors > TBL_MAX_SENSORS || info.n_grid < 2u || info.n_grid > TBL_MAX_GRID) {
        return TBL_E_FORMAT;
    }
    for (i = 1; i < info.n_grid; i++) {
        if (info.grid_mN[i] <= info.grid_mN[i - 1u]) {
            return TBL_E_FORMAT;
        }
    }
    if (info.default_mN < info.grid_mN[0] || info.default_mN > info.grid_mN[info.n_grid - 1u]) {
        return TBL_E_FORMAT;
    }
    for (i = 0; i < info.n_tendons; i++) {
        uint8_t sensor;
        uint32_t nm;
        src->copy(&sensor, TBL_FIELD_ADDR(src, tendons[i].sensor), sizeof sensor);
        src->copy(&nm, TBL_FIELD_ADDR(src, tendons[i].nm_per_tick), sizeof nm);
        if (sensor >= info.n_sensors || nm == 0u) {
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
    src->copy(&info->table_id, TBL_FIELD_ADDR(src, table_id), sizeof info->table_id);
    src->copy(info->name, TBL_FIELD_ADDR(src, name), sizeof info->name);
    info->name[TBL_NAME_LEN - 1u] = '\0';
    src->copy(&info->n_tendons, TBL_FIELD_ADDR(src, n_tendons), 1);
    src->copy(&info->n_sensors, TBL_FIELD_ADDR(src, n_sensors), 1);
    src->copy(&info->n_grid, TBL_FIELD_ADDR(src, n_grid), 1);
    src->copy(&info->mode, TBL_FIELD_ADDR(src, mode), 1);
    src->copy(info->grid_mN, TBL_FIELD_ADDR(src, grid_mN), sizeof info->grid_mN);
    src->copy(&info->default_mN, TBL_FIELD_ADDR(src, default_mN), sizeof info->default_mN);
    src->copy(&info->noise_cuT, TBL_FIELD_ADDR(src, noise_cuT), sizeof info->noise_cuT);
    return 0;
}

static uint8_t tbl_count(const tbl_src_t *src, int tendons)
{
    uint8_t n;
    if (tendons) {
        src->copy(&n, TBL_FIELD_ADDR(src, n_tendons), 1);
    } else {
        src->copy(&n, TBL_FIELD_ADDR(src, n_sensors), 1);
    }
    return n;
}

int tbl_tendon(const tbl_src_t *src, uint8_t i, tbl_tendon_t *out)
{
    if (!tbl_src_ok(src) || out == NULL || i >= tbl_count(src, 1) || i >= TBL_MAX_TENDONS) {
        return TBL_E_ARG;
    }
    src->copy(out, TBL_FIELD_ADDR(src, tendons[i]), sizeof *out);
    return 0;
}

int tbl_sensor(const tbl_src_t *src, uint8_t i, tbl_sensor_t *out)
{
    if (!tbl_src_ok(src) || out == NULL || i >= tbl_count(src, 0) || i >= TBL_MAX_SENSORS) {
        return TBL_E_ARG;
    }
    src->copy(out, TBL_FIELD_ADDR(src, sensors[i]), sizeof *out);
    return 0;
}

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
    uint32_t q = (a / dx) * t + ((a % dx) * t + dx / 2u) / dx;
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

/* The three per-grid arrays of a tendon lie back to back (checked below), so
 * one loop interpolates them all. */
typedef char tbl_rows_adjacent_t[(offsetof(tbl_tendon_t, abs_target_cuT) ==
                                      offsetof(tbl_tendon_t, target_cuT) + TBL_MAX_GRID * 4u &&
                                  offsetof(tbl_tendon_t, travel_um) ==
                                      offsetof(tbl_tendon_t, abs_target_cuT) + TBL_MAX_GRID * 4u)
                                     ? 1
                                     : -1];

int tbl_target(const tbl_src_t *src, uint8_t tendon, uint16_t tension_mN, tbl_point_t *out)
{
    tbl_info_t info;
    uint32_t v[3];
    uint32_t y[2];
    const uint32_t *row;
    uint8_t a;
    int k;

    if (out == NULL || tbl_info(src, &info) != 0 || tendon >= info.n_tendons ||
        tendon >= TBL_MAX_TENDONS) {
        return TBL_E_ARG;
    }
    if (info.n_grid > TBL_MAX_GRID) {
        return TBL_E_RANGE;
    }
    k = tbl_bracket(info.grid_mN, info.n_grid, tension_mN);
    if (k < 0) {
        return TBL_E_RANGE;
    }
    row = &src->table->tendons[tendon].target_cuT[k]; /* address only, never dereferenced */
    for (a = 0; a < 3u; a++) {
        src->copy(y, row + a * TBL_MAX_GRID, sizeof y);
        v[a] = tbl_lerp(info.grid_mN[k], info.grid_mN[k + 1], y[0], y[1], tension_mN);
    }
    /* the signed shifts, offset into the unsigned range of tbl_lerp */
    {
        int16_t sh[2];
        src->copy(sh, &src->table->tendons[tendon].straight_um[k], sizeof sh);
        out->straight_um =
            (int16_t)((int32_t)tbl_lerp(info.grid_mN[k], info.grid_mN[k + 1],
                                        (uint32_t)((int32_t)sh[0] + 32768),
                                        (uint32_t)((int32_t)sh[1] + 32768), tension_mN) -
                      32768);
    }
    out->tension_mN = tension_mN;
    out->target_cuT = v[0];
    out->abs_target_cuT = v[1];
    out->travel_um = v[2];
    return 0;
}
