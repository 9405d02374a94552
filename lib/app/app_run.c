/*
 * app_run: the run room. Homing runs (cal, rehome, single, dry) from the
 * request to the stored result, the app's own moves (home, release) and
 * aborts, the releases owed after a reset or a servo's hardware error, and
 * the releases that the engagement windows bound (app_win.c; docs/app.md,
 * "Recovery").
 */
#include <stddef.h>
#include <string.h>

#include "app/app_priv.h"
#include "dxl/dxl_xl430_reg.h"

/* A run finished: keep its homes (calibration frame = this power cycle's
 * frame, so the offsets become 0), count it and queue the records. */
static void run_done(app_t *a)
{
    uint32_t t = app_now_ms(a);
    uint8_t cal = (uint8_t)(a->run.mode != APP_MODE_SURVEY);
    a->run.done_out = 1; /* the robot stands at its homes: noted once <done> is out */
    a->run.amb_ok |= hom_amb_captured(&a->u.hom); /* read before u.idle reuses the storage */
    if (cal) {
        app_rec_take_homes(a, a->run.mask, a->run.tension);
    }
    /* The run's baseline is the learn baseline until the next release. From
     * here on the homing's storage is reused (u.idle overlaps its first
     * bytes only: the homes above were read first). A held pull's b0 is its
     * reference, taken with the robot bent: never kept. */
    if (cal || a->run.hold == 0u) {
        app_learn_keep_baseline(a);
    }
    if (cal) {
        app_rec_save_run(a);
        app_boot_homes_new(a);
    }
    app_rep_begin(a, app_w_done);
    app_rep_word(a, app_w_mode, app_w_mode_words, a->run.mode);
    app_rep_word(a, app_w_target, app_w_target_words, a->run.abs);
    app_rep_int(a, app_w_time_ms, (int32_t)(t - a->run.t_start));
    app_rep_u16(a, app_w_tension_mN, a->run.tension);
    app_rep_int(a, app_w_count, (int32_t)a->rec.homes.cal_count);
    app_rep_end(a);
    app_panel_set(a, APP_LED_DONE);
    a->state = APP_ST_IDLE;
}

APP_NOINLINE int8_t app_run_check(app_t *a)
{
    if (a->state == APP_ST_BOOT) {
        return CON_E_BUSY;
    }
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    return app_rep_missing(a);
}

void app_run_ambient_reset(app_t *a)
{
    a->run.amb_ok = 0;
}

/* The homing's command and configuration for a run, and its start (left to
 * the compiler to inline: as a function of its own, which keeps the 160-byte
 * command out of run_start()'s frame, it measured 26 B larger). Returns
 * hom_start()'s code. */
static int run_hom_start(app_t *a, uint8_t mode, uint8_t survey, uint16_t tension, uint8_t tendon)
{
    hom_config_t *cfg;
    hom_cmd_t cmd;
    uint8_t i;
    memset(&cmd, 0, sizeof cmd);
    a->run.abs = a->rec.set.v[STORE_SET_TARGET_MODE] != 0;
    if (a->run.abs) {
        /* the first absolute run takes A from its own straight-pose
         * baseline (a dry run stands wherever the robot is: never) */
        cmd.ambient_cuT = a->run.amb;
        cmd.ambient_capture = (uint8_t)(!a->run.amb_ok && mode != HOM_MODE_DRY);
    }
    cmd.mode = (hom_mode_t)mode;
    cmd.survey = survey != 0u;
    cmd.hold = survey ? a->run.hold : 0u;
    cmd.tension_mN = tension;
    cmd.tendon = tendon;
    for (i = 0; i < a->info.n_tendons; i++) {
        if (app_has(a->rec.home_now, i)) {
            cmd.stored_home[i] = app_rec_home(a, i);
            cmd.stored_mask |= app_bit16(i);
        }
    }
    if (APP_WIN(a) != NULL) {
        cmd.win_mask = APP_WIN(a)->mask;
        memcpy(cmd.win_lo, APP_WIN(a)->lo, sizeof cmd.win_lo);
        memcpy(cmd.win_hi, APP_WIN(a)->hi, sizeof cmd.win_hi);
    }
    app_learn_drop_baseline(a); /* its storage goes to the homing */
    cfg = hom_config_reset(&a->u.hom);
    /* filter_k is the homing's own filter: samples averaged at each fine
     * point while the servo stands still (near the target at least 4 and
     * twice as many). A moving average of the stream ahead of the homing would lag
     * during the take-up and delay the engagement it detects. */
    cfg->v_fast = (uint16_t)a->rec.set.v[STORE_SET_APPROACH_FAST];
    cfg->v_fine = (uint16_t)a->rec.set.v[STORE_SET_APPROACH_SLOW];
    cfg->avg_samples = (uint8_t)a->rec.set.v[STORE_SET_FILTER_K];
    cfg->straight = (uint8_t)a->rec.set.v[STORE_SET_HOME_POSE];
    if (survey) {
        cfg->v_moderate = APP_SURVEY_V;
    }
    cfg->servo_timeout_ms = APP_SERVO_TIMEOUT_MS;
    app_bus_goals_cleared(a);
    /* a refused start leaves the state idle: every goal read later is one
     * an app move or release set first (app_bus_goal()) */
    return hom_start(&a->u.hom, &a->htab, &cmd);
}

/* A run or an app move starts (state APP_ST_CAL or APP_ST_MOVE): the kept
 * windows note it, the positions read before are no news. */
APP_NOINLINE static void begin_moving(app_t *a, uint8_t state)
{
    app_win_moving(a, 1);
    a->run.done_out = 0;
    app_bus_positions_stale(a);
    a->state = state;
    app_panel_set(a, APP_LED_RUN);
}

/* Starts a homing run (for run_or_defer()). Returns 0 or a CON_E_* code
 * (nothing moves then), or CON_PENDING when tendons got fresh windows that
 * go to the EEPROM first. */
static int8_t run_start(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon)
{
    int rc;
    int8_t e;
    uint8_t survey = (uint8_t)(mode & APP_RUN_SURVEY);
    mode = (uint8_t)(mode & ~APP_RUN_SURVEY);
    if (!app_idle_state(a)) {
        return CON_E_BUSY;
    }
    e = app_run_check(a);
    if (e != 0) {
        return e;
    }
    if (mode == HOM_MODE_SINGLE && tendon >= a->info.n_tendons) {
        return CON_E_BAD_TENDON;
    }
    if (survey) {
        uint16_t least = app_grid_mN(a, 0);
        tension = app_grid_mN(a, (uint8_t)(a->info.n_grid - 1u));
        tension = (uint16_t)((uint16_t)(tension * (a->run.hold != 0u ? APP_HOLD_EIGHTHS
                                                                     : APP_SURVEY_EIGHTHS)) >>
                             3);
        if (tension < least) {
            tension = least;
        }
    }
    if (tension == 0u) {
        tension = (uint16_t)a->rec.set.v[STORE_SET_CAL_TENSION];
    }
    if (!app_in_grid(a, tension)) {
        return CON_E_TENSION_RANGE;
    }
    if (mode == HOM_MODE_QUICK) {
        e = app_rec_usable(a);
        if (e != 0) {
            return e;
        }
        tension = a->rec.homes.tension_mN;
    }
    /* the EEPROM and the record storage are free: run_or_defer() waits for
     * them (a few hundred ms) */
    if (mode != HOM_MODE_DRY && app_win_before_run(a, tension)) {
        return CON_PENDING; /* started once they are saved (run_or_defer()) */
    }
    rc = run_hom_start(a, mode, survey, tension, tendon);
    if (rc == HOM_E_TENSION) {
        return CON_E_TENSION_RANGE;
    }
    if (rc == HOM_E_HOMES) {
        return CON_E_NOT_HOMED;
    }
    if (rc == HOM_E_ARG) {
        return survey && a->run.hold != 0u ? CON_E_BAD_HOLD : CON_E_BAD_TENDON;
    }
    if (rc != 0) {
        return CON_E_INTERNAL;
    }
    a->run.mode = survey ? APP_MODE_SURVEY : mode;
    a->run.survey_n = 0;
    a->run.tension = tension;
    a->run.mask = mode == HOM_MODE_SINGLE ? app_bit16(tendon) : app_all_mask(a);
    a->run.t_start = app_now_ms(a);
    begin_moving(a, APP_ST_CAL);
    app_rec_rest_at(a, 0, 0);
    return 0;
}

/* A run or move ended in a fault: the rest positions are recorded once the
 * servos have stopped. */
APP_NOINLINE static void fault_rest(app_t *a, uint32_t t)
{
    app_win_moving(a, 0); /* the release goals are out: the servos finish them */
    a->state = APP_ST_FAULT;
    app_panel_set(a, APP_LED_FAULT);
    app_rec_rest_at(a, 1, t);
}

/* Survey: every APP_SURVEY_EVERY-th new sample of the pulled tendon's
 * sensor, one line with the tendon, its position and every sensor's newest
 * raw sample: <sv t=I p=TICKS b=x0,y0,z0,x1,...> (cuT, sensor frames). A
 * line that finds no room in the console's output is dropped and counted
 * like any report (docs/console.md); the host keeps what arrives. */
static void survey_sample(app_t *a, const hom_in_t *in)
{
    uint8_t i, k, first = 1;
    if (hom_pulling(&a->u.hom, &i) != 1u ||
        in->sensor[hom_tendon(&a->u.hom, i)->sensor].status != HOM_SENS_NEW ||
        ++a->run.survey_n < APP_SURVEY_EVERY) {
        return;
    }
    a->run.survey_n = 0;
    app_rep_begin(a, app_w_sv);
    app_rep_u8(a, app_w_t, i);
    app_rep_int(a, app_w_p, a->bus.present[i]);
    con_report_list(&a->cmd.con, app_w_b, a->info.n_sensors);
    for (k = 0; k < a->info.n_sensors; k++) {
        const int32_t *v = hom_last(&a->u.hom, k);
        uint8_t ax;
        for (ax = 0; ax < 3u; ax++) {
            con_report_item(&a->cmd.con, v[ax], '\0', first);
            first = 0;
        }
    }
    app_rep_end(a);
}

APP_NOINLINE void app_run_step(app_t *a, hom_in_t *in)
{
    hom_out_t out;
    hom_event_t ev;
    int rc;
    uint8_t reported;
    in->now_ms = app_now_ms(a);
    /* one report per pass, of an event of an earlier step: a step that
     * pushes several events (a result and the next tendon's start) would
     * otherwise format them all in the pass that did the step's work */
    /* ... and only with room for it in the console's output: a run's
     * events wait in the homing's queue rather than be dropped (seven
     * `<missing>` lines filled the ring and the run's `<fault>` and
     * `<released>` were lost: the host never saw the run end, chaos seed
     * 2053) */
    reported = (uint8_t)(con_report_fits(&a->cmd.con) && hom_event_pop(&a->u.hom, &ev));
    if (reported) {
        app_rep_event(a, &ev);
    }
    app_bus_inputs(a, in);
    rc = hom_step(&a->u.hom, in, &out);
    app_win_take(a);
    app_bus_take(a, &out);
    if (rc <= 0 && (reported || hom_event_count(&a->u.hom) != 0u)) {
        /* the end of a run waits for its reports: hom_step() repeats its
         * result, and the release goals of a fault are already queued */
        return;
    }
    if (a->run.mode == APP_MODE_SURVEY) {
        survey_sample(a, in);
    }
    if (rc == 0) {
        run_done(a);
    } else if (rc < 0) {
        uint8_t f = hom_fault_index(&a->u.hom);
        fault_rest(a, in->now_ms);
        a->run.last_fault = hom_fault(&a->u.hom);
        /* a servo that stopped answering, or did not move, may have let its
         * Bus Watchdog expire: it then refuses every goal until a bring-up
         * clears the watchdog, which the next run asks for first */
        a->run.bring_up |= (uint8_t)(a->run.last_fault == HOM_F_SERVO_TIMEOUT ||
                                     a->run.last_fault == HOM_F_SERVO_STALL);
        if (a->run.last_fault == HOM_F_SERVO_ERROR && f < a->info.n_tendons) {
            /* a servo in hardware error has its torque off and refused the
             * release: reboot it (Protocol 2.0 Reboot clears the error), then
             * release its tendon once the bus is up again */
            app_bus_reboot(a, a->bus.ids[f]);
            a->run.auto_release = a->bus.ids[f];
        }
    }
}

void app_run_move(app_t *a, uint8_t kind)
{
    a->run.move_kind = kind;
    a->run.t_move = app_now_ms(a);
    begin_moving(a, APP_ST_MOVE);
}

/* Release goals computed by the app when no run is active: the slack margin
 * before each tendon's engagement window. A tendon without a window gets
 * one first: the engagement its stored home implies, or, with nothing
 * known, the homing's own assumption (anywhere up to the release that frees
 * a tendon left at the top of the grid). Never pulls, and repeated releases
 * go no further (the window stays). */
/* blind: right after a reset that cut a run, before the bring-up (which
 * takes 0.2 s or more, longer with a device missing): no position is known
 * yet, so only the tendons whose engagement window survived in .noinit get
 * a goal, the slack margin before the window (slack whatever the tendon's
 * state; the servos kept power and their own frame, which a reset of the
 * board does not change). */
static uint8_t release_goals(app_t *a, uint8_t blind)
{
    uint8_t i, moved = 0, fresh = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t g, lo, s, m, dir;
        if (app_has(a->bus.absent, i) ||
            (blind && (APP_WIN(a) == NULL || !app_has(APP_WIN(a)->mask, i)))) {
            continue;
        }
        m = app_win_margin(a, i, &s);
        dir = m < 0 ? -1 : 1;
        if (APP_WIN(a) != NULL && app_has(APP_WIN(a)->mask, i)) {
            lo = APP_WIN(a)->lo[i];
        } else if (app_has(a->rec.home_now, i)) {
            tbl_point_t pt;
            tbl_tendon_head_t row;
            uint32_t trav = 0;
            (void)tbl_tendon_head(&a->tab, i, &row);
            if (tbl_target(&a->tab, i, a->rec.homes.tension_mN, &pt) == 0) {
                trav = pt.travel_um;
            }
            lo = app_rec_home(a, i) - dir * app_um_ticks(row.nm_per_tick, trav);
            app_win_set(a, i, lo, lo, 1);
        } else {
            lo = app_win_fresh(a, i, (uint16_t)a->rec.set.v[STORE_SET_CAL_TENSION]);
            fresh = 1;
        }
        g = lo - m;
        if (!blind && dir * (g - a->bus.present[i]) > 0) {
            g = a->bus.present[i]; /* already slacker than the release point */
        }
        app_bus_goal(a, i, g, HOM_V_TOP, HOM_ACC_DEFAULT);
        moved = 1;
    }
    if (fresh) {
        app_win_persist(a); /* saved once the release is over */
    }
    return moved;
}

uint8_t app_run_release_goals(app_t *a)
{
    return release_goals(a, 0);
}

/* Releases every tendon that answered, as an app move, and reports it:
 * <released reason=...> with the ID of the servo it names (id 0: none). One
 * copy for the stop and the releases owed after a reset or a servo's error. */
APP_NOINLINE static void release_all(app_t *a, const char *reason_f, uint8_t id)
{
    (void)app_run_release_goals(a);
    app_rep_begin(a, app_w_released);
    con_report_flash(&a->cmd.con, app_w_reason, reason_f);
    if (id != 0u) {
        app_rep_u8(a, app_w_id, id);
    }
    app_rep_not_released(a, 0);
    app_rep_end(a);
    app_run_move(a, APP_MOVE_RELEASE);
}

/* The stop releases within docs/app.md's 100 ms: the release velocity and
 * goals go out before the bring-up, which waits for the tendons to get
 * there; the full release follows once the bus is up. */
uint8_t app_run_early_release(app_t *a, uint8_t step)
{
    if (step == 1u && !release_goals(a, 1)) {
        return 0;
    }
    return app_bus_goals_now(a, (uint8_t)((step - 1u) & 1u));
}

void app_abort(app_t *app)
{
    if (app == NULL) {
        return;
    }
    if (app->state == APP_ST_BOOT) {
        if (app->boot.con_wait && app->table_ok) {
            /* a bring-up again (`servos`, a servo's reboot) holds the bus
             * for 0.1-0.3 s with the robot as it rests: a stop in it
             * releases at once, as after a reset (the early release, then
             * the bring-up from its start; chaos seed 2090: a `!` during
             * `servos` was dropped and the robot stayed taut 1.7 s) */
            dxl_abort(&app->bus.dxl);
            /* torque on first, broadcast: a servo the bring-up had
             * switched off to check its EEPROM area takes no goal, and
             * the tendon stayed taut until the bring-up's end (seed 2090:
             * 243 ms at 778 mN). Nothing else switches torque off. */
            (void)dxl_write_value(&app->bus.dxl, DXL_BROADCAST_ID, DXL_XL430_TORQUE_ENABLE_ADDR, 1u,
                                  1u);
            app->run.reset_release = 1;
            app_boot_again(app);
        }
        return;
    }
    /* con_complete() answers a command only while one waits */
    if (app->run.req_start && app->run.req_con) {
        (void)con_complete(&app->cmd.con, CON_E_ABORTED);
    }
    app->run.req_start = 0;
    if (app->state == APP_ST_CAL) {
        /* a run that has ended but not yet reported it (its done waits for
         * its last reports) releases once it has: a `!` 10 ms before the
         * <done> left the robot at its homes 1.5 s (chaos seed 4135) */
        app->run.abort_owed = (uint8_t)!hom_abort(&app->u.hom);
        return;
    }
    if (app->state == APP_ST_LEARN && app->learn.tendon != APP_LEARN_BASELINE) {
        (void)con_complete(&app->cmd.con, CON_E_ABORTED);
    }
    if (!app->table_ok) {
        return;
    }
    release_all(app, app_w_aborted, 0);
}

APP_NOINLINE void app_run_move_step(app_t *a)
{
    uint8_t i, arrived = 1;
    uint32_t t = app_now_ms(a);
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t d = a->bus.present[i] - hom_goal(&a->u.hom, i);
        if (app_has(a->bus.absent, i)) {
            continue;
        }
        if (app_has(a->bus.fresh, i) == 0u || a->bus.goal_due != 0u || d > APP_MOVE_TOL_TICKS ||
            d < -APP_MOVE_TOL_TICKS) {
            arrived = 0;
        }
    }
    if (!arrived) {
        if (t - a->run.t_move > APP_MOVE_TIMEOUT_MS) {
            app_rep_fault(a, app_w_servo_stall, CON_E_TIMEOUT, HOM_DEV_SERVO, 0);
            fault_rest(a, t);
            if (a->run.move_kind == APP_MOVE_HOME) {
                (void)app_run_release_goals(a);
            }
        }
        return;
    }
    app_rec_rest_at(a, 1, t);
    a->run.done_out = 1;
    if (a->run.move_kind == APP_MOVE_RELEASE) {
        app_learn_begin(a, APP_LEARN_BASELINE); /* the robot stands straight: capture B0 */
        return;
    }
    app_rep_begin(a, app_w_done);
    con_report_flash(&a->cmd.con, app_w_mode, app_w_home);
    app_rep_int(a, app_w_time_ms, (int32_t)(t - a->run.t_move));
    app_rep_end(a);
    a->state = APP_ST_IDLE;
    app_panel_set(a, APP_LED_IDLE);
}

/* Keeps a run request for app_run_poll() to start once it can. */
APP_NOINLINE static void keep_request(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon,
                                      uint8_t from_con)
{
    a->run.req_start = 1;
    a->run.req_con = from_con; /* 0: a press, whose run is chosen when it starts */
    a->run.req_mode = mode;
    a->run.req_tension = tension;
    a->run.req_tendon = tendon;
}

/* A run asked for while a device is missing or a servo reports a hardware
 * error is not refused at once (every new request, app_run_press() and
 * app_run_request(), gets its budget of bring-ups here; it once did only
 * when no request was kept, and a press kept while the rest positions were
 * written was refused without a bring-up: chaos seed 2033): the devices are brought up again first
 * (a servo in hardware error is rebooted, Protocol 2.0 Reboot; a sensor or servo that stopped
 * answering is looked for again), and the run starts after the new <ready>. Each servo in hardware
 * error costs one bring-up, so a request gets one more than there are such servos; a device still
 * missing after them refuses the run as before. Returns 1 when a bring-up
 * was started for the request (which the caller keeps in req_*), 0 when none
 * is left. */
static uint8_t defer_for_devices(app_t *a)
{
    uint8_t i;
    uint8_t id = 0;
    if (a->run.recover_left == APP_RECOVER_NEW) {
        a->run.recover_left = 1;
        for (i = 0; i < a->info.n_tendons; i++) {
            if (a->bus.hw_err[i] != 0u) {
                a->run.recover_left++;
            }
        }
    }
    if (a->run.recover_left == 0u) {
        return 0;
    }
    a->run.recover_left--;
    for (i = 0; i < a->info.n_tendons && id == 0u; i++) {
        if (a->bus.hw_err[i] != 0u && !app_has(a->bus.absent, i)) {
            id = a->bus.ids[i];
        }
    }
    if (id != 0u) {
        app_bus_reboot(a, id); /* the bring-up follows the reboot */
    } else {
        app_boot_again(a);
    }
    return 1;
}

/* The board is busy with what follows a reset or a stop, not with what
 * someone asked for: the bring-up, a servo's reboot and the bring-up after
 * it, a release and the baseline capture after it (a servo rebooted after a
 * hardware error is released so; a `cal` then
 * was answered `error:9 busy` and a press did nothing: chaos seed 2013). A
 * run asked for meanwhile waits for the end. */
static uint8_t settling(const app_t *a)
{
    return (uint8_t)(a->state == APP_ST_BOOT || a->bus.reboot_id != 0u ||
                     (a->state == APP_ST_MOVE && a->run.move_kind == APP_MOVE_RELEASE) ||
                     (a->state == APP_ST_LEARN && a->learn.tendon == APP_LEARN_BASELINE));
}

/* Starts the run now, defers it (EEPROM write in flight, bring-up or a
 * release under way, devices to bring up again), or refuses it: 0,
 * CON_PENDING or a CON_E_*. Sets req_start: 1 (the request kept) only with
 * CON_PENDING. */
static int8_t run_or_defer(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon,
                           uint8_t from_con)
{
    int8_t rc = CON_PENDING; /* the request is kept (req_*) and started later */
    if (settling(a) || (app_idle_state(a) && (store_busy(&a->rec.store) || app_rec_busy(a)))) {
        /* once that is over */
    } else if (a->run.bring_up && app_idle_state(a)) {
        a->run.bring_up = 0;
        app_boot_again(a); /* after the bring-up */
    } else {
        /* CON_PENDING: once the fresh windows are in the EEPROM */
        rc = run_start(a, mode, tension, tendon);
        if ((rc == CON_E_SENSOR_FAULT || rc == CON_E_SERVO_FAULT) && defer_for_devices(a)) {
            rc = CON_PENDING; /* after the devices' bring-up */
        }
    }
    if (rc == CON_PENDING) {
        keep_request(a, mode, tension, tendon, from_con);
    } else {
        a->run.req_start = 0;
    }
    return rc;
}

void app_run_press(app_t *a)
{
    int8_t rc;
    a->run.recover_left = APP_RECOVER_NEW;
    if (settling(a)) {
        /* pressed before <ready> or during the release after a stop: the
         * run starts once that is done, quick or full as it then offers */
        keep_request(a, 0, 0, 0, 0);
        return;
    }
    if (!app_idle_state(a)) {
        return; /* a long press aborts */
    }
    app_panel_set(a, APP_LED_IDLE);
    rc = run_or_defer(a, a->boot.offer_quick ? HOM_MODE_QUICK : HOM_MODE_FULL, 0, 0, 0);
    if (rc != 0 && rc != CON_PENDING) {
        app_rep_fault(a, app_w_refused, rc, HOM_DEV_NONE, 0);
        app_panel_set(a, APP_LED_FAULT);
    }
}

int8_t app_run_rebooted(app_t *a)
{
    uint8_t i, id = a->bus.reboot_id;
    if (id == 0u) {
        return 0;
    }
    a->bus.reboot_id = 0;
    for (i = 0; i < a->info.n_tendons && a->bus.ids[i] != id; i++) {
    }
    if (i < a->info.n_tendons && !app_has(a->bus.absent, i) && a->bus.hw_err[i] == 0u) {
        a->bus.reboot_tries = 0;
        return 0;
    }
    /* still in error, or silent: the reboot or its reply was lost (bus
     * noise), or the servo is gone */
    if (a->run.auto_release && ++a->bus.reboot_tries < APP_REBOOT_TRIES) {
        app_bus_reboot(a, id);
        return CON_PENDING;
    }
    a->bus.reboot_tries = 0;
    if (a->run.auto_release && i < a->info.n_tendons) {
        a->run.auto_release = 0; /* named: this tendon may still be taut */
        app_rep_fault(a, app_w_not_released, CON_E_SERVO_FAULT, HOM_DEV_SERVO, i);
    }
    return CON_E_SERVO_FAULT;
}

/* Between the steps: the releases owed after a reset or a servo's hardware
 * error go out once nothing else moves, then a run requested while the
 * bring-up, that release or an EEPROM write was under way starts (in this
 * order: a run started first left the owed release for its end, and it
 * released the robot from the homes the run had just found). */
void app_run_poll(app_t *a)
{
    if (a->run.done_out && con_out_drained(&a->cmd.con)) {
        /* A reset-pin reset while a run's <done> was still in the output
         * ring took the robot for at rest and left it at its homes, taut,
         * while the host had not been told the run was over (chaos seed
         * 7071: 823 mN for 1.9 s). Until the report is out, a reset counts
         * as one in the run: the boot releases. */
        a->run.done_out = 0;
        app_win_moving(a, 0);
    }
    if (a->run.abort_owed && app_idle_state(a)) {
        a->run.abort_owed = 0;
        app_abort(a);
    }
    if (a->run.reset_release && a->state == APP_ST_IDLE) {
        a->run.reset_release = 0;
        release_all(a, app_w_reset, 0);
    }
    if (a->run.auto_release && a->state == APP_ST_IDLE && a->table_ok && a->bus.reboot_id == 0u) {
        uint8_t id = a->run.auto_release;
        a->run.auto_release = 0;
        release_all(a, app_w_servo_error, id);
    }
    if (a->run.req_start && a->state != APP_ST_BOOT && store_busy(&a->rec.store) == 0u &&
        !app_rec_busy(a) && a->bus.reboot_id == 0u && !a->bus.reboot_req) {
        int8_t rc;
        if (a->run.req_con) {
            rc = run_or_defer(a, a->run.req_mode, a->run.req_tension, a->run.req_tendon, 1);
        } else {
            /* a press asks for the run the board offers when it starts: a
             * quick re-home kept while the devices came up again was
             * refused (error 22) once that bring-up found the homes moved
             * (chaos seed 7416) */
            rc = run_or_defer(a, a->boot.offer_quick ? HOM_MODE_QUICK : HOM_MODE_FULL, 0, 0, 0);
        }
        if (rc == CON_PENDING) {
            return; /* the devices are brought up again first, or the release ends */
        }
        if (a->run.req_con && con_pending(&a->cmd.con)) {
            (void)con_complete(&a->cmd.con, rc);
        } else if (rc != 0) {
            app_rep_fault(a, app_w_refused, rc, HOM_DEV_NONE, 0);
        }
    }
}

APP_NOINLINE int8_t app_run_request(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon)
{
    a->run.recover_left = APP_RECOVER_NEW;
    return run_or_defer(a, mode, tension, tendon, 1);
}
