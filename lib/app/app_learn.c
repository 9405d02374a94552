/*
 * app_learn: the learn room. The straight-pose baseline captured after a
 * release, `learn T N` (the field change of a tendon's sensor with a weight
 * hung, checked for plausibility and stored as that grid point's target),
 * `forget`, and the table copy that applies the learned targets
 * (docs/app.md, "Learn").
 */
#include <string.h>

#include "app/app_priv.h"

#define LEARN_WAIT_MS 1000u /* longest wait for the samples of a capture, after SETTLE_MS */
#define SETTLE_MS     300u /* a baseline capture averages from this long after the release arrived */

void app_table_copy(app_t *app, void *dst, const void *src, size_t n)
{
    uint8_t t;
    APP_TABLE_COPY(app, dst, src, n);
    if (app->io->table == NULL || app->learn.mask == 0u) {
        return;
    }
    for (t = 0; t < TBL_MAX_TENDONS; t++) {
        uintptr_t lo, s0 = (uintptr_t)src, s1 = (uintptr_t)src + n;
        store_learned_t l;
        uint8_t g;
        if (app_has(app->learn.mask, t) == 0u) {
            continue;
        }
        lo = (uintptr_t)tbl_target_row(app->io->table, &app->info, t);
        if (lo == 0u || lo >= s1 || lo + sizeof(uint16_t) * app->info.n_grid <= s0) {
            continue;
        }
        if (store_learned_load(&app->rec.store, t, app->info.table_id, &l) != 0) {
            continue;
        }
        for (g = 0; g < l.n_grid && g < TBL_MAX_GRID; g++) {
            uintptr_t w = lo + sizeof(uint16_t) * g;
            if (app_has(l.grid_mask, g) != 0u && w >= s0 && w + sizeof(uint16_t) <= s1) {
                memcpy((uint8_t *)dst + (w - s0), &l.target_lsb[g], sizeof(uint16_t));
            }
        }
    }
}

void app_learn_begin(app_t *a, uint8_t tendon)
{
    a->learn.tendon = tendon;
    a->learn.n = 0;
    memset(a->u.idle.acc, 0, sizeof a->u.idle.acc);
    memset(a->u.idle.cnt, 0, sizeof a->u.idle.cnt);
    a->learn.t_start = app_now_ms(a);
    a->state = APP_ST_LEARN;
}

/* A learned target must stand well above the sensing noise (the table's
 * rule: ten times it) and rise with tension against the entries already
 * learned for the tendon by more than twice the noise; a reading taken with
 * no weight hung, or with the
 * weights swapped, would make every later calibration fault. */
static int8_t learn_plausible(const app_t *a, const store_learned_t *l, uint32_t v)
{
    uint8_t g;
    uint32_t m = 2u * (uint32_t)a->info.noise_cuT; /* a rise must exceed the noise */
    /* above TBL_FIELD_CUT_MAX (9830 uT) the table's unit cannot hold it */
    if (v < 10u * (uint32_t)a->info.noise_cuT || v == 0u || v > TBL_FIELD_CUT_MAX) {
        return CON_E_IMPLAUSIBLE;
    }
    for (g = 0; g < a->info.n_grid; g++) {
        uint32_t have = (uint32_t)l->target_lsb[g] * TBL_CUT_PER_LSB;
        if (app_has(l->grid_mask, g) &&
            ((g < a->learn.grid && have + m >= v) || (g > a->learn.grid && have <= v + m))) {
            return CON_E_IMPLAUSIBLE;
        }
    }
    return 0;
}

/* Tendon t's learned record (u.idle.rec.learned): the stored one, or empty. */
static store_learned_t *learned_of(app_t *a, uint8_t t)
{
    store_learned_t *l = &a->u.idle.rec.learned;
    if (store_learned_load(&a->rec.store, t, a->info.table_id, l) != 0) {
        memset(l, 0, sizeof *l);
    }
    return l;
}

/* v becomes tendon t's target at learn.grid, rounded to the table's LSB:
 * the record is queued for the EEPROM and reported. */
static void learned_store(app_t *a, uint8_t t, uint32_t v)
{
    store_learned_t *l = &a->u.idle.rec.learned;
    l->table_id = a->info.table_id;
    l->tendon = t;
    l->n_grid = a->info.n_grid;
    l->target_lsb[a->learn.grid] = tbl_lsb_of_cuT(v);
    l->grid_mask |= app_bit16(a->learn.grid);
    app_rec_queue(a, APP_SAVE_LEARNED);
    app_rep_begin(a, app_w_learned);
    app_rep_u8(a, app_w_tendon, t);
    app_rep_u16(a, app_w_tension_mN, app_grid_mN(a, a->learn.grid));
    app_rep_u8(a, app_w_grid, a->learn.grid);
    app_rep_u8(a, app_w_sensor, a->learn.sensor);
    /* the stored value (whole LSB), the one `table` shows */
    con_report_fixed(&a->cmd.con, app_w_dB_uT,
                     (int32_t)((uint32_t)l->target_lsb[a->learn.grid] * TBL_CUT_PER_LSB), 2);
    app_rep_end(a);
}

int8_t app_learn_install(app_t *a, uint8_t tendon, uint8_t grid, uint32_t v)
{
    tbl_tendon_head_t row;
    int8_t rc;
    (void)tbl_tendon_head(&a->tab, tendon, &row);
    a->learn.sensor = row.sensor;
    a->learn.grid = grid;
    rc = learn_plausible(a, learned_of(a, tendon), v);
    if (rc != 0) {
        return rc;
    }
    learned_store(a, tendon, v);
    a->learn.installing = 1;
    return CON_PENDING;
}

uint8_t app_learn_installed(app_t *a)
{
    uint8_t was = a->learn.installing;
    a->learn.installing = 0;
    return was;
}

int8_t app_learn_start(app_t *a, uint8_t tendon, uint8_t grid)
{
    icm_diag_t d;
    tbl_tendon_head_t row;
    (void)tbl_tendon_head(&a->tab, tendon, &row);
    a->learn.sensor = row.sensor;
    (void)icm_set_diag(&a->sense.set, row.sensor, &d);
    if (d.state != ICM_SET_S_RUN) {
        return CON_E_SENSOR_FAULT;
    }
    a->learn.grid = grid;
    app_learn_begin(a, tendon);
    return CON_PENDING;
}

int8_t app_learn_forget(app_t *a, uint16_t mask)
{
    a->learn.forget = mask & a->learn.mask;
    a->learn.forgetting = (uint8_t)(a->learn.forget != 0u);
    return a->learn.forgetting ? CON_PENDING : 0;
}

void app_learn_forget_next(app_t *a)
{
    uint8_t t = 0;
    if (a->learn.forget == 0u) {
        return;
    }
    while (app_has(a->learn.forget, t) == 0u) {
        t++;
    }
    memset(&a->u.idle.rec.learned, 0, sizeof a->u.idle.rec.learned);
    a->u.idle.rec.learned.table_id = a->info.table_id;
    a->u.idle.rec.learned.tendon = t;
    a->u.idle.rec.learned.n_grid = a->info.n_grid;
    a->learn.forget &= (uint16_t)~app_bit16(t);
    a->learn.mask &= (uint16_t)~app_bit16(t);
    app_rec_queue(a, APP_SAVE_LEARNED);
}

uint8_t app_learn_forgotten(app_t *a)
{
    if (!a->learn.forgetting || a->learn.forget != 0u) {
        return 0;
    }
    a->learn.forgetting = 0;
    return 1;
}

APP_NOINLINE void app_learn_step(app_t *a, const hom_in_t *in)
{
    uint8_t k, first, last, tdn = a->learn.tendon;
    uint32_t v = 0;
    uint32_t el = app_now_ms(a) - a->learn.t_start;
    int8_t rc = 0;
    if (tdn == APP_LEARN_BASELINE) {
        first = 0;
        last = a->info.n_sensors;
        if (el < SETTLE_MS) {
            return;
        }
    } else {
        first = a->learn.sensor;
        last = (uint8_t)(first + 1u);
    }
    for (k = first; k < last; k++) {
        if (in->sensor[k].status == HOM_SENS_OVERFLOW) {
            rc = CON_E_SENSOR_FAULT;
        }
    }
    if (rc == 0) {
        uint8_t least = APP_LEARN_SAMPLES;
        for (k = first; k < last; k++) {
            if (in->sensor[k].status == HOM_SENS_NEW && a->u.idle.cnt[k] < APP_LEARN_SAMPLES) {
                uint8_t ax;
                for (ax = 0; ax < 3u; ax++) {
                    a->u.idle.acc[k][ax] += in->sensor[k].b_cuT[ax];
                }
                a->u.idle.cnt[k]++;
            }
            if (a->u.idle.cnt[k] < least) {
                least = a->u.idle.cnt[k];
            }
        }
        a->learn.n = least;
        if (least < APP_LEARN_SAMPLES && el > LEARN_WAIT_MS + SETTLE_MS) {
            rc = CON_E_TIMEOUT;
        }
    }
    if (rc == 0 && a->learn.n < APP_LEARN_SAMPLES) {
        return;
    }
    if (rc == 0) {
        int32_t *sum = &a->u.idle.acc[0][0];
        for (k = 0; k < 3u * APP_MAX_SENSORS; k++) {
            sum[k] /= (int32_t)APP_LEARN_SAMPLES; /* sums become averages */
        }
    }
    if (tdn == APP_LEARN_BASELINE) {
        if (rc == 0) {
            memcpy(a->u.idle.b0, a->u.idle.acc, sizeof a->u.idle.b0);
            a->learn.have_b0 = 1;
        }
        app_rep_begin(a, app_w_done);
        con_report_flash(&a->cmd.con, app_w_mode, app_w_release);
        app_rep_int(a, app_w_time_ms, (int32_t)el);
        app_rep_u8(a, app_w_baseline, (uint8_t)(rc == 0));
        app_rep_end(a);
        a->state = APP_ST_IDLE;
        app_panel_set(a, APP_LED_IDLE);
        return;
    }
    if (rc == 0) {
        int32_t d[3];
        for (k = 0; k < 3u; k++) {
            d[k] = a->u.idle.acc[first][k] - a->u.idle.b0[first][k];
        }
        v = hom_norm3(d);
        rc = learn_plausible(a, learned_of(a, tdn), v);
    }
    if (rc == 0) {
        learned_store(a, tdn, v);
    }
    (void)con_complete(&a->cmd.con, rc); /* nothing when no `learn` waits */
    a->state = APP_ST_IDLE;
}

void app_learn_drop_baseline(app_t *a)
{
    a->learn.have_b0 = 0;
}

void app_learn_saving(app_t *a)
{
    if (a->u.idle.rec.learned.grid_mask != 0u) {
        a->learn.mask |= app_bit16(a->u.idle.rec.learned.tendon);
    }
}

void app_learn_keep_baseline(app_t *a)
{
    uint8_t k;
    for (k = 0; k < a->info.n_sensors; k++) {
        memcpy(a->u.idle.b0[k], hom_baseline(&a->u.hom, k), sizeof a->u.idle.b0[k]);
    }
    a->learn.have_b0 = 1;
}
