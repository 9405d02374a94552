/*
 * table_pack: natural units (tbl_wide_t) to the stored layout (TBL_LAYOUT),
 * written at the TBL_OFF_* offsets the accessors read.
 */
#include "table/table_pack.h"

#include <stddef.h>
#include <string.h>

static int pack_u16(uint8_t *at, uint32_t v)
{
    uint16_t x = (uint16_t)v;
    if (v > 0xFFFFu) {
        return TBL_E_RANGE;
    }
    memcpy(at, &x, sizeof x);
    return 0;
}

/* A field in cuT, rounded half away from zero to LSB, as int16. */
static int pack_field_i16(uint8_t *at, int32_t cuT)
{
    int32_t half = (int32_t)(TBL_CUT_PER_LSB / 2u);
    int32_t lsb = (cuT >= 0 ? cuT + half : cuT - half) / (int32_t)TBL_CUT_PER_LSB;
    int16_t x = (int16_t)lsb;
    if (lsb > 32767 || lsb < -32768) {
        return TBL_E_RANGE;
    }
    memcpy(at, &x, sizeof x);
    return 0;
}

static int pack_field_u16(uint8_t *at, uint32_t cuT)
{
    if (cuT > TBL_FIELD_CUT_MAX) {
        return TBL_E_RANGE;
    }
    return pack_u16(at, tbl_lsb_of_cuT(cuT));
}

int tbl_pack(const tbl_wide_t *w, tbl_buf_t *buf)
{
    uint8_t nt, ns, ng, i, g, a;
    uint8_t *b;
    int rc = 0;

    if (w == NULL || buf == NULL || w->n_tendons > TBL_MAX_TENDONS ||
        w->n_sensors > TBL_MAX_SENSORS || w->n_grid > TBL_MAX_GRID) {
        return TBL_E_ARG;
    }
    nt = w->n_tendons;
    ns = w->n_sensors;
    ng = w->n_grid;
    b = buf->bytes;
    memset(buf, 0, sizeof *buf);
    buf->head.magic = w->magic;
    buf->head.format_version = w->format_version;
    buf->head.size = (uint16_t)TBL_SIZE(nt, ns, ng);
    buf->head.table_id = w->table_id;
    memcpy(buf->head.name, w->name, TBL_NAME_LEN);
    buf->head.name[TBL_NAME_LEN - 1u] = '\0';
    buf->head.n_tendons = nt;
    buf->head.n_sensors = ns;
    buf->head.n_grid = ng;
    buf->head.mode = w->mode;
    buf->head.default_mN = w->default_mN;
    buf->head.noise_cuT = w->noise_cuT;
    memcpy(b + TBL_OFF_GRID, w->grid_mN, 2u * ng);
    for (i = 0; i < ns; i++) {
        uint8_t *s = b + TBL_OFF_SENSORS(ng) + i * sizeof(tbl_sensor_rec_t);
        s[offsetof(tbl_sensor_rec_t, mux_channel)] = w->sensors[i].mux_channel;
        s[offsetof(tbl_sensor_rec_t, i2c_addr)] = w->sensors[i].i2c_addr;
        for (a = 0; a < 3u; a++) {
            rc |= pack_field_i16(s + offsetof(tbl_sensor_rec_t, b_straight_lsb) + 2u * a,
                                 w->sensors[i].b_straight_cuT[a]);
        }
    }
    for (i = 0; i < nt; i++) {
        const tbl_tendon_t *t = &w->tendons[i];
        tbl_tendon_rec_t r;
        uint16_t base = (uint16_t)(2u * i * ng);
        r.servo_id = t->servo_id;
        r.pull_dir = t->pull_dir;
        r.segment = t->segment;
        r.sensor = t->sensor;
        r.nm_per_tick = (uint16_t)t->nm_per_tick;
        r.travel_limit_um = (uint16_t)t->travel_limit_um;
        if (t->nm_per_tick > 0xFFFFu || t->travel_limit_um > 0xFFFFu) {
            rc = TBL_E_RANGE;
        }
        memcpy(b + TBL_OFF_TENDONS(ns, ng) + i * sizeof r, &r, sizeof r);
        for (g = 0; g < ng; g++) {
            uint16_t o = (uint16_t)(base + 2u * g);
            rc |= pack_field_u16(b + TBL_OFF_ROW(nt, ns, ng, TBL_ROW_TARGET) + o, t->target_cuT[g]);
            rc |=
                pack_field_u16(b + TBL_OFF_ROW(nt, ns, ng, TBL_ROW_ABS) + o, t->abs_target_cuT[g]);
            rc |= pack_u16(b + TBL_OFF_ROW(nt, ns, ng, TBL_ROW_TRAVEL) + o, t->travel_um[g]);
            memcpy(b + TBL_OFF_ROW(nt, ns, ng, TBL_ROW_STRAIGHT) + o, &t->straight_um[g], 2u);
        }
    }
    return rc != 0 ? TBL_E_RANGE : 0;
}

int tbl_unpack(const tbl_src_t *src, tbl_wide_t *w)
{
    tbl_info_t info;
    uint8_t i;
    int rc = tbl_check(src);
    if (rc != 0 || w == NULL) {
        return rc != 0 ? rc : TBL_E_ARG;
    }
    (void)tbl_info(src, &info);
    memset(w, 0, sizeof *w);
    w->magic = TBL_MAGIC;
    w->format_version = TBL_FORMAT_VERSION;
    w->table_id = info.table_id;
    (void)tbl_name(src, w->name);
    w->n_tendons = info.n_tendons;
    w->n_sensors = info.n_sensors;
    w->n_grid = info.n_grid;
    w->mode = info.mode;
    for (i = 0; i < TBL_MAX_GRID; i++) {
        w->grid_mN[i] = tbl_grid_mN(src, i);
    }
    w->default_mN = info.default_mN;
    w->noise_cuT = info.noise_cuT;
    for (i = 0; i < info.n_sensors; i++) {
        (void)tbl_sensor(src, i, &w->sensors[i]);
    }
    for (i = 0; i < info.n_tendons; i++) {
        (void)tbl_tendon(src, i, &w->tendons[i]);
    }
    return 0;
}
