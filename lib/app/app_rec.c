/*
 * app_rec: the records room. The homes of this power cycle (stored homes
 * mapped into the servos' new frames), the rest positions recorded after a
 * release or a fault, and every EEPROM record (homes, history, learned
 * targets, windows, settings): queued by the rooms, written one at a time, one byte
 * per pass and only while nothing moves.
 */
#include <string.h>

#include "app/app_priv.h"

#define REST_DELAY_MS 1000u /* the servos have stopped this long after a release */

APP_NOINLINE int32_t app_rec_home(const app_t *a, uint8_t i)
{
    return a->rec.homes.t[i].home_ticks - a->rec.offset[i];
}

int32_t app_rec_goal(const app_t *a, uint8_t i)
{
    return app_rec_home(a, i) +
           (a->rec.set.v[STORE_SET_HOME_POSE] != 0 ? a->rec.homes.to_straight[i] : 0);
}

/* Maps the stored homes into this power cycle's servo frames. */
int8_t app_rec_recover(app_t *a)
{
    uint8_t i;
    int8_t worst = 0;
    a->rec.home_now = 0;
    if (a->rec.homes_rc != 0) {
        return 0;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t pos;
        int8_t rc;
        if (app_has(a->rec.homes.valid_mask, i) == 0u || app_has(a->bus.seen, i) == 0u) {
            continue;
        }
        rc = store_recover_position(&a->rec.homes.t[i], a->bus.present[i],
                                    (uint16_t)a->rec.set.v[STORE_SET_REST_TOL], &pos);
        if (rc == 0) {
            a->rec.offset[i] = pos - a->bus.present[i];
            a->rec.home_now |= app_bit16(i);
        } else if (worst == 0) {
            worst = rc;
        }
    }
    return worst;
}

/* A history or learned record waits in u.idle, or the windows record is
 * being written from it: the homing and the bring-up must not reuse that
 * storage until it is written (the windows record is built when its save
 * starts, so one only queued takes no room). */
uint8_t app_rec_busy(const app_t *a)
{
    /* save_now: one APP_SAVE_* bit, or 0 */
    return (uint8_t)(((a->rec.save_due & (APP_SAVE_HIST | APP_SAVE_LEARNED)) |
                      (a->rec.save_now & (APP_SAVE_HIST | APP_SAVE_LEARNED | APP_SAVE_WIN))) != 0u);
}

APP_NOINLINE uint8_t app_rec_saving(const app_t *a, uint8_t what)
{
    return (uint8_t)(((a->rec.save_due | a->rec.save_now) & what) != 0u); /* one bit each */
}

APP_NOINLINE void app_rec_queue(app_t *a, uint8_t what)
{
    a->rec.save_due |= what;
}

/* 0 when every tendon has a stored home usable in this power cycle, else
 * CON_E_NOT_HOMED or CON_E_MOVED (a spool turned while powered off). */
APP_NOINLINE int8_t app_rec_usable(const app_t *a)
{
    uint16_t all = app_all_mask(a);
    if (a->rec.homes_rc != 0 || a->rec.homes.valid_mask != all) {
        return CON_E_NOT_HOMED;
    }
    return a->rec.home_now != all ? CON_E_MOVED : 0;
}

/* Records the rest positions once the servos have stopped after a release or
 * a fault, so a power cycle can find the multi-turn position again. */
void app_rec_rest_poll(app_t *a)
{
    uint8_t i, changed = 0;
    if (!a->rec.rest_due || !app_idle_state(a) ||
        (uint16_t)((uint16_t)app_now_ms(a) - a->rec.t_rest) < REST_DELAY_MS ||
        app_rec_saving(a, APP_SAVE_HOMES)) {
        return;
    }
    a->rec.rest_due = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t rest, d;
        if (app_has(a->rec.home_now, i) == 0u || app_has(a->bus.seen, i) == 0u) {
            continue;
        }
        rest = a->bus.present[i] + a->rec.offset[i];
        d = rest - a->rec.homes.t[i].rest_ticks;
        if (d > 2 || d < -2) {
            store_home_set(&a->rec.homes.t[i], a->rec.homes.t[i].home_ticks, rest);
            changed = 1;
        }
    }
    if (changed) {
        app_rec_queue(a, APP_SAVE_HOMES);
    }
}

APP_NOINLINE void app_rec_poll(app_t *a)
{
    uint8_t idle = app_idle_state(a);
    if (store_busy(&a->rec.store)) {
        int8_t rc = store_poll(&a->rec.store, idle);
        if (rc <= 0) {
            if ((a->rec.save_now == APP_SAVE_SETTINGS ||
                 (a->rec.save_now == APP_SAVE_LEARNED &&
                  (app_learn_forgotten(a) || app_learn_installed(a)))) &&
                con_pending(&a->cmd.con)) {
                (void)con_complete(&a->cmd.con, rc == 0 ? 0 : CON_E_EEPROM);
            } else if (rc < 0) {
                app_rep_fault(a, app_w_eeprom, CON_E_EEPROM, HOM_DEV_NONE, a->rec.save_now);
            }
            a->rec.save_now = 0;
        }
        return;
    }
    if (idle && !app_rec_busy(a)) {
        app_learn_forget_next(a);
    }
    if (!idle || a->rec.save_due == 0u) {
        return;
    }
    if (a->rec.save_due & APP_SAVE_HOMES) {
        a->rec.save_now = APP_SAVE_HOMES;
        (void)store_save_homes(&a->rec.store, &a->rec.homes);
    } else if (a->rec.save_due & APP_SAVE_HIST) {
        a->rec.save_now = APP_SAVE_HIST;
        (void)store_save_hist(&a->rec.store, &a->u.idle.rec.hist);
    } else if (a->rec.save_due & APP_SAVE_LEARNED) {
        a->rec.save_now = APP_SAVE_LEARNED;
        app_learn_saving(a);
        (void)store_save_learned(&a->rec.store, &a->u.idle.rec.learned);
    } else if (a->rec.save_due & APP_SAVE_WIN) {
        /* after the history and learned records, which share its storage */
        a->rec.save_now = APP_SAVE_WIN;
        app_win_record(a, &a->u.idle.rec.win);
        (void)store_save_win(&a->rec.store, &a->u.idle.rec.win);
    } else {
        a->rec.save_now = APP_SAVE_SETTINGS;
        (void)store_save_settings(&a->rec.store, &a->rec.set);
    }
    a->rec.save_due &= (uint8_t)~a->rec.save_now;
}

void app_rec_rest_at(app_t *a, uint8_t due, uint32_t t)
{
    a->rec.rest_due = due;
    if (due) {
        a->rec.t_rest = (uint16_t)t;
    }
}

void app_rec_take_homes(app_t *a, uint16_t mask, uint16_t tension)
{
    uint8_t i;
    a->rec.homes.table_id = a->info.table_id;
    a->rec.homes.n_tendons = a->info.n_tendons;
    a->rec.homes.tension_mN = tension;
    a->rec.homes.cal_count++;
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t h;
        if (app_has(mask, i) && hom_home(&a->u.hom, i, &h) == 0) {
            store_home_set(&a->rec.homes.t[i], h, h);
            a->rec.homes.to_straight[i] = hom_to_straight(&a->u.hom, i);
            a->rec.offset[i] = 0;
            a->rec.homes.valid_mask |= app_bit16(i);
            a->rec.home_now |= app_bit16(i);
        }
    }
}

void app_rec_save_run(app_t *a)
{
    uint8_t i;
    memset(&a->u.idle.rec.hist, 0, sizeof a->u.idle.rec.hist);
    a->u.idle.rec.hist.cal_count = a->rec.homes.cal_count;
    a->u.idle.rec.hist.table_id = a->rec.homes.table_id;
    a->u.idle.rec.hist.tension_mN = a->rec.homes.tension_mN;
    a->u.idle.rec.hist.valid_mask = a->rec.homes.valid_mask;
    a->u.idle.rec.hist.n_tendons = a->rec.homes.n_tendons;
    for (i = 0; i < a->info.n_tendons; i++) {
        a->u.idle.rec.hist.home_ticks[i] = a->rec.homes.t[i].home_ticks;
    }
    a->rec.homes_rc = 0;
    app_rec_queue(a, APP_SAVE_HOMES | APP_SAVE_HIST);
}
