/*
 * app_win: the windows room. Each tendon's engagement window (where its
 * engagement lies, hom_window()) bounds every release: the slack margin
 * before the window, never further (docs/app.md, "Recovery"). The windows
 * are kept in RAM the C start-up leaves alone (app_win_t: a watchdog or
 * reset-pin reset keeps them) and, for a power cycle, in an EEPROM record
 * relative to each servo's single-turn position (store_win_t): a power cut
 * between a run's release and its take-up then no longer costs the next
 * run a release more (chaos seeds 3049, 4093, 5038: three cuts left 13 mm
 * of slack, more than the search covers).
 */
#include <stddef.h>
#include <string.h>

#include "app/app_priv.h"

APP_NOINLINE int32_t app_um_ticks(uint32_t npt, uint32_t um)
{
    /* travel is at most metres, so 32 bits hold um * 1000 */
    if (npt == 0u) {
        npt = 1u;
    }
    return (int32_t)((um * 1000u + npt / 2u) / npt);
}

static uint16_t win_crc(const app_win_t *w)
{
    return store_crc16(0xFFFFu, w, offsetof(app_win_t, crc));
}

/* Checks the kept windows at boot: wrong magic, table or CRC clears them. */
void app_win_check(app_t *a)
{
    app_win_t *w = APP_WIN(a);
    if (w != NULL && (w->magic != APP_WIN_MAGIC || w->table_id != a->info.table_id ||
                      w->crc != win_crc(w) || !a->table_ok)) {
        uint8_t moving = w->moving; /* outside the CRC: kept */
        memset(w, 0, sizeof *w);
        w->moving = moving;
        w->magic = APP_WIN_MAGIC;
        w->table_id = a->info.table_id;
        w->crc = win_crc(w);
    }
}

/* Sets tendon i's window (or forgets it with keep 0); crc 0 leaves the CRC
 * to the caller, which sets several windows and seals them once. */
APP_NOINLINE static void win_put(app_t *a, uint8_t i, int32_t lo, int32_t hi, uint8_t keep,
                                 uint8_t crc)
{
    app_win_t *w = APP_WIN(a);
    if (w == NULL) {
        return;
    }
    w->mask = (uint16_t)(keep ? (w->mask | app_bit16(i)) : (w->mask & ~app_bit16(i)));
    w->lo[i] = lo;
    w->hi[i] = hi;
    if (crc) {
        w->crc = win_crc(w);
    }
}

void app_win_set(app_t *a, uint8_t i, int32_t lo, int32_t hi, uint8_t keep)
{
    win_put(a, i, lo, hi, keep, 1);
}

/* Notes in the kept copy whether anything moves: a watchdog or reset-pin
 * reset in the middle of a run leaves tendons taut, and the next boot
 * releases them. */
void app_win_moving(app_t *a, uint8_t on)
{
    app_win_t *w = APP_WIN(a);
    if (w != NULL) {
        w->moving = on;
    }
}

void app_win_take(app_t *a)
{
    uint8_t i;
    uint16_t m = hom_win_take_changed(&a->u.hom);
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t lo, hi;
        if (app_has(m, i) && hom_window(&a->u.hom, i, &lo, &hi) == 0) {
            win_put(a, i, lo, hi, 1, 0);
        }
    }
    if (m != 0u && APP_WIN(a) != NULL) {
        APP_WIN(a)->crc = win_crc(APP_WIN(a));
    }
}

APP_NOINLINE int32_t app_win_margin(const app_t *a, uint8_t i, int32_t *span)
{
    tbl_tendon_head_t row;
    uint32_t top = 0;
    int32_t dir;
    (void)tbl_tendon_head(&a->tab, i, &row);
    (void)tbl_entry(&a->tab, i, TBL_ROW_TRAVEL, TBL_GRID_TOP, &top);
    dir = row.pull_dir < 0 ? -1 : 1;
    *span = dir * app_um_ticks(row.nm_per_tick, top * 3u / 2u);
    return dir * app_um_ticks(row.nm_per_tick, HOM_SLACK_MARGIN_UM);
}

int32_t app_win_fresh(app_t *a, uint8_t i, uint16_t tension_mN)
{
    /* the homing's own (hom_fresh_window()): a stop that cost the window (a
     * servo's reboot, a power-up) may have come after a release that tendon
     * had not engaged since, so the search covers one release ahead (chaos
     * seed 2017: a servo rebooted in the run's slack check, its tendon
     * released again and searched short of it) */
    int32_t lo, hi;
    if (hom_fresh_window(&a->htab, i, tension_mN, a->bus.present[i], &lo, &hi) != 0) {
        lo = a->bus.present[i];
        hi = lo;
    }
    app_win_set(a, i, lo, hi, 1);
    return lo;
}

APP_NOINLINE uint8_t app_win_before_run(app_t *a, uint16_t tension_mN)
{
    uint8_t i;
    if (APP_WIN(a) == NULL || !a->table_ok) {
        return 0;
    }
    /* one tendon a pass: the table work takes 1-2 ms each (a press and the
     * request it leaves both come here in the pass of the press) */
    if (a->rec.win_fresh && a->rec.win_loop == (uint8_t)a->loops) {
        return 1;
    }
    a->rec.win_loop = (uint8_t)a->loops;
    for (i = 0; i < a->info.n_tendons; i++) {
        if (!app_has(a->bus.absent, i) && app_has(a->bus.seen, i) &&
            !app_has(APP_WIN(a)->mask, i) && !app_has(a->rec.home_now, i)) {
            (void)app_win_fresh(a, i, tension_mN);
            a->rec.win_fresh = 1;
            return 1;
        }
    }
    if (a->rec.win_fresh) {
        /* every fresh window is set: their record goes to the EEPROM */
        a->rec.win_fresh = 0;
        app_win_persist(a);
        return 1;
    }
    return app_rec_saving(a, APP_SAVE_WIN);
}

void app_win_persist(app_t *a)
{
    app_rec_queue(a, APP_SAVE_WIN);
}

/* The record of the kept windows, relative to where each servo stands now
 * (built when its save starts: app_rec_poll()). */
void app_win_record(app_t *a, store_win_t *r)
{
    uint8_t i;
    const app_win_t *w = APP_WIN(a);
    memset(r, 0, sizeof *r);
    r->table_id = a->info.table_id;
    r->n_tendons = a->info.n_tendons;
    for (i = 0; w != NULL && i < a->info.n_tendons; i++) {
        int32_t p = a->bus.present[i];
        int32_t lo = w->lo[i] - p, hi = w->hi[i] - p;
        if (app_has(w->mask, i) && app_has(a->bus.seen, i) && lo >= -32768 && lo <= 32767 &&
            hi >= -32768 && hi <= 32767) {
            r->t[i].at_turn = (uint16_t)((uint32_t)p & 4095u);
            r->t[i].lo = (int16_t)lo;
            r->t[i].hi = (int16_t)hi;
            r->mask |= app_bit16(i);
        }
    }
}

void app_win_recover(app_t *a)
{
    store_win_t r;
    uint8_t i;
    uint16_t tol = (uint16_t)a->rec.set.v[STORE_SET_REST_TOL];
    if (APP_WIN(a) == NULL || !a->table_ok ||
        store_win_load(&a->rec.store, a->info.table_id, &r) != 0) {
        return;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t s, m, lo, hi;
        /* a stored home, recovered or found moved (a spool turned while
         * powered off: its rest-position check is the tighter one), says
         * more than a window */
        if (!app_has(r.mask, i) || !app_has(a->bus.seen, i) || app_has(APP_WIN(a)->mask, i) ||
            (a->rec.homes_rc == 0 && app_has(a->rec.homes.valid_mask, i))) {
            continue;
        }
        /* since the save the spool stood at most a release (the margin
         * before the window) on its slack side and a pull (the top travel)
         * past it, give or take rest_tol; in ticks, both signed by the pull
         * direction */
        m = app_win_margin(a, i, &s);
        lo = (m < 0 ? -s : m) + (int32_t)tol; /* below the window, in ticks */
        hi = (m < 0 ? -m : s) + (int32_t)tol; /* above it */
        if (store_win_recover(&r.t[i], a->bus.present[i], (uint16_t)lo, (uint16_t)hi, &lo, &hi) ==
            0) {
            app_win_set(a, i, lo, hi, 1);
        }
    }
}
