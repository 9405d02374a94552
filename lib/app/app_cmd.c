/*
 * app_cmd: the console room: its poll (realtime mode while anything moves,
 * lost bytes and dropped reports) and the command handlers (cmd_run()).
 * A handler validates the whole line, then asks the room that owns the work;
 * it returns 0, a CON_E_* error or CON_PENDING (answered by that room).
 */
#include <string.h>

#include "app/app_priv.h"

static int8_t cmd_run(app_t *a, uint8_t cmd);

/* The console in realtime mode while anything moves (output never waits;
 * docs/console.md), and the losses reported: console bytes lost to a full
 * receive buffer at once, report lines dropped once nothing moves. A fault
 * ends the run in the step that queues its release goals: until they are on
 * the bus the motion still counts as running, or a listing being written
 * (a burst of `help` lines) held the loop and the release with it (45 ms
 * late on chaos seed 1024). */
static void list_poll(app_t *a);

APP_NOINLINE void app_cmd_poll(app_t *a)
{
    uint8_t moving = (uint8_t)(a->state == APP_ST_CAL || a->state == APP_ST_MOVE ||
                               (a->bus.goal_due | a->bus.torque_due) != 0u);
    uint16_t n = APP_HAS_RX_LOST(a) ? APP_RX_LOST(a) : 0u;
    uint16_t lost = a->cmd.rx_lost, dropped;
    int8_t cmd;
    con_set_realtime(&a->cmd.con, moving);
    if (n != lost) {
        app_rep_begin(a, app_w_overrun);
        app_rep_u16(a, app_w_bytes, (uint16_t)(n - lost));
        app_rep_u16(a, app_w_total, n);
        app_rep_end(a);
        a->cmd.rx_lost = n;
    }
    dropped = con_dropped(&a->cmd.con);
    if (!moving && dropped != a->cmd.dropped) {
        a->cmd.dropped = dropped;
        app_rep_begin(a, app_w_dropped);
        app_rep_u16(a, app_w_reports, dropped);
        app_rep_end(a);
    }
    list_poll(a);
    (void)con_poll(&a->cmd.con, (uint16_t)app_now_ms(a));
    cmd = con_call(&a->cmd.con);
    if (cmd >= 0) {
        (void)con_called(&a->cmd.con, cmd_run(a, (uint8_t)cmd));
    }
}

static int8_t h_version(app_t *a, const con_args_t *args)
{
    (void)args;
    app_rep_begin(a, app_w_version);
    app_rep_ident(a);
    app_rep_table(a, 3); /* table_id, tendons, sensors */
    app_rep_end(a);
    return 0;
}

static const app_field_t status_fields[] CON_FLASH = {
    APP_FIELD(servos, app_t, boot.n_servos, APP_F_U),
    APP_FIELD(homes, app_t, rec.homes.valid_mask, APP_F_HEX),
    APP_FIELD(homes_now, app_t, rec.home_now, APP_F_HEX),
    APP_FIELD(rehome, app_t, boot.offer_quick, APP_F_U),
    APP_FIELD(tension_mN, app_t, rec.homes.tension_mN, APP_F_U),
    APP_FIELD(count, app_t, rec.homes.cal_count, APP_F_S),
};
static const app_field_t status_learn_fields[] CON_FLASH = {
    APP_FIELD(learned, app_t, learn.mask, APP_F_U),
    APP_FIELD(baseline, app_t, learn.have_b0, APP_F_U),
};
static const app_field_t status_loop_fields[] CON_FLASH = {
    APP_FIELD(loop_max_us, app_t, loop_max_us, APP_F_S),
    APP_FIELD(loops, app_t, loops, APP_F_S),
};
static int8_t h_status(app_t *a, const con_args_t *args)
{
    (void)args;
    app_rep_begin(a, app_w_status);
    app_rep_word(a, app_w_state, app_w_state_words, a->state);
    app_rep_table(a, 0);
    app_rep_u8(a, app_w_sensors, icm_set_ready_count(&a->sense.set));
    APP_REP_FIELDS(a, a, status_fields);
    app_rep_word(a, app_w_fault, app_w_fault_words, a->run.last_fault);
    APP_REP_FIELDS(a, a, status_learn_fields);
    app_rep_u8(a, app_w_saving, (uint8_t)(store_busy(&a->rec.store) || a->rec.save_due != 0u));
    APP_REP_FIELDS(a, a, status_loop_fields);
    if (APP_HAS_STACK_FREE(a)) {
        app_rep_int(a, app_w_stack_free, (int32_t)APP_STACK_FREE(a));
    }
    app_rep_end(a);
    return app_cmd_list(a, APP_LIST_HOMES, 0);
}

static void home_line(app_t *a, uint8_t i)
{
    int32_t home = a->rec.homes.t[i].home_ticks;
    uint8_t usable = app_has(a->rec.home_now, i);
    app_rep_begin(a, app_w_home);
    app_rep_u8(a, app_w_tendon, i);
    app_rep_int(a, app_w_home, home);
    app_rep_int(a, app_w_straight, home + a->rec.homes.to_straight[i]);
    app_rep_int(a, app_w_rest, a->rec.homes.t[i].rest_ticks);
    app_rep_u8(a, app_w_usable, usable);
    if (usable) {
        app_rep_int(a, app_w_now, app_rec_home(a, i));
    }
    app_rep_end(a);
}

/* ok and mag: both 1 while the sensor samples (icm_diag_t.mag_ready is
 * state RUN) */
static const app_field_t sensor_fields[] CON_FLASH = {
    APP_FIELD(ch, icm_diag_t, channel, APP_F_U),
    APP_FIELD(addr, icm_diag_t, addr, APP_F_U),
    APP_FIELD(ok, icm_diag_t, mag_ready, APP_F_U),
    APP_FIELD(who, icm_diag_t, who_am_i, APP_F_U),
    APP_FIELD(mag, icm_diag_t, mag_ready, APP_F_U),
    APP_FIELD(rate_Hz, icm_diag_t, rate_dhz, APP_F_U | APP_F_DEC1),
    APP_FIELD(bx_uT, icm_diag_t, field_cuT[0], APP_F_S | APP_F_DEC2),
    APP_FIELD(by_uT, icm_diag_t, field_cuT[1], APP_F_S | APP_F_DEC2),
    APP_FIELD(bz_uT, icm_diag_t, field_cuT[2], APP_F_S | APP_F_DEC2),
    APP_FIELD(ovf, icm_diag_t, overflow_count, APP_F_U),
    APP_FIELD(err, icm_diag_t, error_count, APP_F_U),
    APP_FIELD(last_err, icm_diag_t, last_err, APP_F_S),
    APP_FIELD(reinits, icm_diag_t, reinits, APP_F_U),
};

static void sensor_line(app_t *a, uint8_t k)
{
    icm_diag_t d;
    (void)icm_set_diag(&a->sense.set, k, &d);
    app_rep_begin(a, app_w_sensor);
    app_rep_u8(a, app_w_index, k);
    APP_REP_FIELDS(a, &d, sensor_fields);
    app_rep_end(a);
}

static int8_t h_sensors(app_t *a, const con_args_t *args)
{
    (void)args;
    return app_cmd_list(a, APP_LIST_SENSORS, 0);
}

static int8_t h_servos(app_t *a, const con_args_t *args)
{
    /* scan|pos|err: word 0-2, 0 (scan) when not given */
    if ((uint8_t)args->v[0] != 0u) {
        return app_cmd_list(a, APP_LIST_SERVOS, 0); /* pos, err: the live cycle keeps both fresh */
    }
    if (app_rec_busy(a)) {
        return CON_E_BUSY; /* the bring-up reuses the record's storage */
    }
    app_boot_again(a);
    return CON_PENDING;
}

static int8_t h_cal(app_t *a, const con_args_t *args)
{
    uint8_t mode = HOM_MODE_FULL, t = (uint8_t)args->v[1]; /* 0-11 (synopsis) */
    if (args->given & 2u) {
        if (a->table_ok && t >= a->info.n_tendons) {
            return CON_E_BAD_TENDON;
        }
        mode = HOM_MODE_SINGLE;
    }
    /* an argument not given is 0 (con_args_t): no tension, tendon 0 */
    return app_run_request(a, mode, (uint16_t)args->v[0], t);
}

/* A tendon the table lacks is refused when the run starts (run_start), and
 * so is a hold (`survey T H`) that is T itself or not in the table
 * (hom_start(): CON_E_BAD_HOLD), before anything moves. The host picks a
 * hold of T's segment that bends the robot across T (docs/identify.md). */
static int8_t h_survey(app_t *a, const con_args_t *args)
{
    a->run.hold = (uint8_t)((args->given & 2u) ? args->v[1] + 1 : 0);
    return app_run_request(
        a, (uint8_t)(APP_RUN_SURVEY | ((args->given & 1u) ? HOM_MODE_SINGLE : HOM_MODE_FULL)), 0,
        (uint8_t)args->v[0]);
}

static int8_t h_rehome(app_t *a, const con_args_t *args)
{
    (void)args;
    return app_run_request(a, HOM_MODE_QUICK, 0, 0);
}

static int8_t h_home(app_t *a, const con_args_t *args)
{
    uint8_t i;
    int8_t e;
    (void)args;
    e = app_run_check(a);
    if (e != 0) {
        return e;
    }
    e = app_rec_usable(a);
    if (e != 0) {
        return e;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        app_bus_goal(a, i, app_rec_goal(a, i), HOM_V_TOP, HOM_ACC_DEFAULT);
    }
    app_run_move(a, APP_MOVE_HOME);
    return 0;
}

static int8_t h_release(app_t *a, const con_args_t *args)
{
    (void)args;
    if (a->state == APP_ST_BOOT) {
        return CON_E_BUSY;
    }
    if (!app_idle_state(a)) {
        app_abort(a);
        return 0;
    }
    (void)app_run_release_goals(a);
    app_run_move(a, APP_MOVE_RELEASE);
    return 0;
}

/* The checks of `learn` after cmd_run()'s: nothing being saved, tendon
 * args->v[0] of the table, tension args->v[1] on its grid. Returns the grid
 * index, or a negative CON_E_*. */
static int8_t learn_grid(app_t *a, const con_args_t *args)
{
    uint8_t g;
    if (app_rec_busy(a) || a->learn.forget != 0u) {
        return CON_E_BUSY;
    }
    if ((uint8_t)args->v[0] >= a->info.n_tendons) {
        return CON_E_BAD_TENDON;
    }
    for (g = 0; g < a->info.n_grid && app_grid_mN(a, g) != (uint16_t)args->v[1]; g++) {
    }
    if (g >= a->info.n_grid) {
        return CON_E_TENSION_RANGE; /* learned targets sit on the table's grid */
    }
    return (int8_t)g;
}

/* `learn T N`: the field change with a weight hung (app_learn.c); `learn T
 * N DB`: DB (uT), computed on the host for an identified robot
 * (docs/identify.md), installed the same way: record, checks and report,
 * answered once written. */
static int8_t h_learn(app_t *a, const con_args_t *args)
{
    uint8_t t = (uint8_t)args->v[0];
    int8_t g = learn_grid(a, args);
    if (g < 0) {
        return g;
    }
    if (args->given & 4u) {
        return app_learn_install(a, t, (uint8_t)g, (uint32_t)args->v[2] / 10u);
    }
    if (!a->learn.have_b0) {
        return CON_E_NOT_HOMED; /* no straight-pose baseline yet: `release` first */
    }
    return app_learn_start(a, t, (uint8_t)g);
}

/* `forget T|all`: the learned targets of tendon T, or of every tendon, are
 * erased (empty records saved); the compiled table's targets apply again. */
static int8_t h_forget(app_t *a, const con_args_t *args)
{
    const char *w = args->s[0];
    uint16_t m = 0;
    if (app_rec_busy(a) || a->learn.forget != 0u) {
        return CON_E_BUSY;
    }
    if (w[0] == 'a' && w[1] == 'l' && w[2] == 'l' && w[3] == '\0') { /* no string in RAM */
        m = app_all_mask(a);
    } else {
        uint8_t t = 0;
        for (; *w != '\0'; w++) {
            if (*w < '0' || *w > '9' || t > 20u) {
                return CON_E_BAD_TENDON;
            }
            t = (uint8_t)(t * 10u + (uint8_t)(*w - '0'));
        }
        if (t >= a->info.n_tendons) {
            return CON_E_BAD_TENDON;
        }
        m = app_bit16(t);
    }
    return app_learn_forget(a, m);
}

static const app_field_t table_fields[] CON_FLASH = {
    APP_FIELD(default_mN, tbl_info_t, default_mN, APP_F_U),
    APP_FIELD(noise_cuT, tbl_info_t, noise_cuT, APP_F_U),
};
static const app_field_t tendon_fields[] CON_FLASH = {
    APP_FIELD(id, tbl_tendon_head_t, servo_id, APP_F_U),
    APP_FIELD(dir, tbl_tendon_head_t, pull_dir, APP_F_S),
    APP_FIELD(segment, tbl_tendon_head_t, segment, APP_F_U),
    APP_FIELD(sensor, tbl_tendon_head_t, sensor, APP_F_U),
    APP_FIELD(limit_um, tbl_tendon_head_t, travel_limit_um, APP_F_S),
};

static int8_t h_table(app_t *a, const con_args_t *args)
{
    uint8_t g, n = a->info.n_grid;
    (void)args;
    app_rep_begin(a, app_w_table);
    app_rep_name(a, app_w_name);
    APP_REP_FIELDS(a, &a->info, app_info_fields);
    con_report_list(&a->cmd.con, app_w_grid_mN, n);
    for (g = 0; g < n; g++) {
        con_report_item(&a->cmd.con, app_grid_mN(a, g), '\0', g == 0u);
    }
    APP_REP_FIELDS(a, &a->info, table_fields);
    app_rep_end(a);
    return app_cmd_list(a, APP_LIST_TENDONS, 0);
}

static void tendon_line(app_t *a, uint8_t i)
{
    /* one local, the small fields first: the AVR reaches the first 64
     * bytes of a frame with one instruction a byte */
    struct {
        uint32_t v;
        tbl_tendon_head_t row;
        uint32_t eff[TBL_MAX_GRID];
    } l;
    uint8_t g, n = a->info.n_grid;
    (void)tbl_tendon_head(&a->tab, i, &l.row);
    /* its learned targets (one look at the record) */
    (void)tbl_row(app_has(a->learn.mask, i) ? &a->htab : &a->tab, i, TBL_ROW_TARGET, l.eff);
    app_rep_begin(a, app_w_tendon);
    app_rep_u8(a, app_w_tendon, i);
    APP_REP_FIELDS(a, &l.row, tendon_fields);
    con_report_list(&a->cmd.con, app_w_target_cuT, n);
    for (g = 0; g < n; g++) {
        l.v = 0;
        (void)tbl_entry(&a->tab, i, TBL_ROW_TARGET, g, &l.v);
        con_report_item(&a->cmd.con, (int32_t)l.eff[g], l.eff[g] != l.v ? '*' : '\0', g == 0u);
    }
    app_rep_end(a);
}

static const app_field_t hist_fields[] CON_FLASH = {
    APP_FIELD(count, store_hist_t, cal_count, APP_F_S),
    APP_FIELD(table_id, store_hist_t, table_id, APP_F_HEX),
    APP_FIELD(tension_mN, store_hist_t, tension_mN, APP_F_U),
};

static int8_t h_history(app_t *a, const con_args_t *args)
{
    (void)args;
    return app_cmd_list(a, APP_LIST_HISTORY, store_hist_count(&a->rec.store));
}

/* The history entry `age` calibrations back: 0 when written, else it is lost. */
static int8_t hist_line(app_t *a, uint8_t age)
{
    store_hist_t e;
    uint8_t i;
    if (store_hist_get(&a->rec.store, age, &e) != 0) {
        return -1;
    }
    app_rep_begin(a, app_w_hist);
    app_rep_u8(a, app_w_age, age);
    APP_REP_FIELDS(a, &e, hist_fields);
    con_report_list(&a->cmd.con, app_w_homes, e.n_tendons);
    for (i = 0; i < e.n_tendons && i < TBL_MAX_TENDONS; i++) {
        con_report_item(&a->cmd.con, e.home_ticks[i], app_has(e.valid_mask, i) ? 0 : '?', i == 0u);
    }
    app_rep_end(a);
    return 0;
}

static const app_field_t setting_fields[] CON_FLASH = {
    APP_FIELD(min, store_setting_info_t, min, APP_F_S),
    APP_FIELD(max, store_setting_info_t, max, APP_F_S),
    APP_FIELD(default, store_setting_info_t, def, APP_F_S),
};

static void setting_line(app_t *a, uint8_t id)
{
    char buf[24];
    store_setting_info_t inf;
    (void)store_setting_info(&a->rec.store, id, &inf);
    app_rep_begin(a, app_w_setting);
    (void)store_setting_text(&a->rec.store, id, 0, buf, sizeof buf);
    con_report_str(&a->cmd.con, app_w_name, buf);
    app_rep_int(a, app_w_value, a->rec.set.v[id]);
    (void)store_setting_text(&a->rec.store, id, 1, buf, sizeof buf);
    con_report_str(&a->cmd.con, app_w_unit, buf);
    APP_REP_FIELDS(a, &inf, setting_fields);
    app_rep_end(a);
}

static int8_t find_setting(app_t *a, const con_args_t *args)
{
    const char *n = args->s[0];
    return store_setting_find(&a->rec.store, n, (uint8_t)strlen(n));
}

static int8_t h_get(app_t *a, const con_args_t *args)
{
    if (args->given & 1u) {
        int8_t f = find_setting(a, args);
        if (f < 0) {
            return CON_E_UNKNOWN_SETTING;
        }
        setting_line(a, (uint8_t)f);
        return 0;
    }
    return app_cmd_list(a, APP_LIST_SETTINGS, 0);
}

static int8_t h_set(app_t *a, const con_args_t *args)
{
    int32_t v = args->v[1];
    int8_t f, rc;
    f = find_setting(a, args);
    if (f < 0) {
        return CON_E_UNKNOWN_SETTING;
    }
    if (app_rec_saving(a, APP_SAVE_SETTINGS)) {
        return CON_E_BUSY; /* the record is being written */
    }
    if (f == STORE_SET_CAL_TENSION && a->table_ok &&
        (v < 0 || v > 0xFFFF || !app_in_grid(a, (uint16_t)v))) {
        return CON_E_TENSION_RANGE; /* every press would be refused */
    }
    rc = store_setting_set(&a->rec.store, &a->rec.set, (uint8_t)f, v);
    if (rc != 0) {
        return CON_E_SETTING_RANGE;
    }
    if (f == STORE_SET_TARGET_MODE) {
        app_run_ambient_reset(a);
    }
    app_boot_offer(a); /* cal_tension decides the press's run */
    return 0;
}

static int8_t h_save(app_t *a, const con_args_t *args)
{
    (void)args;
    if (app_rec_saving(a, APP_SAVE_SETTINGS)) {
        return CON_E_BUSY;
    }
    app_rec_queue(a, APP_SAVE_SETTINGS);
    return CON_PENDING;
}

static int8_t h_reboot(app_t *a, const con_args_t *args)
{
    if (app_rec_busy(a) || a->bus.reboot_id != 0u) {
        return CON_E_BUSY;
    }
    app_bus_reboot(a, (uint8_t)args->v[0]);
    return CON_PENDING;
}

/* Items of the listing under way. */
static uint8_t list_len(const app_t *a)
{
    switch (a->cmd.list) {
    case APP_LIST_SENSORS:
        return a->info.n_sensors;
    case APP_LIST_HISTORY:
        return a->cmd.list_arg;
    case APP_LIST_SETTINGS:
        return STORE_SETTING_COUNT;
    case APP_LIST_NONE:
        return 0;
    default:
        return a->info.n_tendons; /* homes, servos, tendons */
    }
}

/* The next line of the listing under way: 1 when one was written (or an
 * item skipped), 0 at its end. */
static uint8_t list_line(app_t *a)
{
    uint8_t i = a->cmd.list_i++;
    if (i >= list_len(a)) {
        return 0;
    }
    switch (a->cmd.list) {
    case APP_LIST_HOMES:
        if (app_has(a->rec.homes.valid_mask, i)) {
            home_line(a, i);
        }
        return 1;
    case APP_LIST_SENSORS:
        sensor_line(a, i);
        return 1;
    case APP_LIST_SERVOS:
        app_rep_servo(a, i, a->cmd.list_arg);
        return 1;
    case APP_LIST_TENDONS:
        tendon_line(a, i);
        return 1;
    case APP_LIST_HISTORY:
        return (uint8_t)(hist_line(a, i) == 0); /* a lost entry ends it */
    default:
        setting_line(a, i);
        return 1;
    }
}

int8_t app_cmd_list(app_t *a, uint8_t list, uint8_t arg)
{
    a->cmd.list = list;
    a->cmd.list_i = 0;
    a->cmd.list_arg = arg;
    return CON_PENDING;
}

/* A listing goes out a line a pass, each when the output ring has room for
 * the longest line: written at once, the UART (11.5 bytes a millisecond at
 * 115200) held the main loop 13-73 ms at rest (`table` 73 ms, `get` and
 * `servos` 34 ms; the servos' Bus Watchdogs run meanwhile). */
static void list_poll(app_t *a)
{
    if (a->cmd.list == APP_LIST_NONE || !con_line_fits(&a->cmd.con)) {
        return;
    }
    if (!list_line(a)) {
        a->cmd.list = APP_LIST_NONE;
        if (con_pending(&a->cmd.con)) {
            (void)con_complete(&a->cmd.con, 0);
        }
    }
}

/* What a command needs before its handler runs, as masks of CON_CMD_* bits,
 * checked in this order:
 *   CMD_TABLE_FIRST  a valid table (else CON_E_NO_TABLE)
 *   CMD_QUIET        nothing moving (state idle or fault; else CON_E_BUSY):
 *                    listings, because console output waits for the UART0
 *                    ring (128 bytes, 11 ms per ring at 115200) and several
 *                    lines would hold the loop for tens of ms, longer than
 *                    the homing's servo deadline; EEPROM writes and bring-ups,
 *                    which happen only while nothing moves
 *   CMD_TABLE        a valid table, checked after CMD_QUIET
 * The handlers check the rest themselves. */
#define CMD_BIT(id)     ((uint32_t)1u << CON_CMD_##id)
#define CMD_TABLE_FIRST (CMD_BIT(SERVOS) | CMD_BIT(RELEASE) | CMD_BIT(LEARN) | CMD_BIT(FORGET))
#define CMD_QUIET                                                                                  \
    (CMD_BIT(SENSORS) | CMD_BIT(SERVOS) | CMD_BIT(HOME) | CMD_BIT(LEARN) | CMD_BIT(TABLE) |        \
     CMD_BIT(HISTORY) | CMD_BIT(GET) | CMD_BIT(SAVE) | CMD_BIT(REBOOT) | CMD_BIT(FORGET))
#define CMD_TABLE (CMD_BIT(SENSORS) | CMD_BIT(TABLE))

APP_NOINLINE static uint8_t cmd_needs(uint32_t mask, uint8_t cmd)
{
    return (uint8_t)((mask >> cmd) & 1u);
}

/* The command of a validated line (con_call()), run with this app: direct
 * calls, not a table of handlers called through a pointer, so that the
 * compiler sees the one app every command works on (measured: -2.0 KB of
 * AVR code, whose accesses to the app then take its fixed address). */
static int8_t cmd_run(app_t *a, uint8_t cmd)
{
    const con_args_t *args = &a->cmd.con.args;
    if (cmd_needs(CMD_TABLE_FIRST, cmd) && !a->table_ok) {
        return CON_E_NO_TABLE;
    }
    if (cmd_needs(CMD_QUIET, cmd) && !app_idle_state(a)) {
        return CON_E_BUSY;
    }
    if (cmd_needs(CMD_TABLE, cmd) && !a->table_ok) {
        return CON_E_NO_TABLE;
    }
    switch (cmd) {
    case CON_CMD_VERSION:
        return h_version(a, args);
    case CON_CMD_STATUS:
        return h_status(a, args);
    case CON_CMD_SENSORS:
        return h_sensors(a, args);
    case CON_CMD_SERVOS:
        return h_servos(a, args);
    case CON_CMD_CAL:
        return h_cal(a, args);
    case CON_CMD_SURVEY:
        return h_survey(a, args);
    case CON_CMD_REHOME:
        return h_rehome(a, args);
    case CON_CMD_HOME:
        return h_home(a, args);
    case CON_CMD_RELEASE:
        return h_release(a, args);
    case CON_CMD_LEARN:
        return h_learn(a, args);
    case CON_CMD_TABLE:
        return h_table(a, args);
    case CON_CMD_HISTORY:
        return h_history(a, args);
    case CON_CMD_GET:
        return h_get(a, args);
    case CON_CMD_SET:
        return h_set(a, args);
    case CON_CMD_SAVE:
        return h_save(a, args);
    case CON_CMD_REBOOT:
        return h_reboot(a, args);
    case CON_CMD_FORGET:
        return h_forget(a, args);
    default:
        return CON_E_NOT_AVAILABLE; /* help is the console's own */
    }
}
