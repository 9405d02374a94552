/*
 * app: the superloop that turns the modules into the product (app.h).
 */
#include "app/app.h"

#include <stddef.h>
#include <string.h>

#include "dxl/dxl_xl430_reg.h"

/* Flash is the scarce resource on the AVR: the tasks called from one place
 * stay functions of their own rather than being merged into their caller,
 * which costs more code (-0.8 KB measured). */
#if defined(__GNUC__)
#define APP_NOINLINE __attribute__((noinline))
#else
#define APP_NOINLINE
#endif

/* Report kinds, keys and words, each once in console-flash memory (program
 * memory on the AVR, where CON_FLASH is __progmem__). */
static const char s_full_quick_single_dry[] CON_FLASH = "full quick single dry";
static const char s_delta_abs[] CON_FLASH = "delta abs";
static const char s_fault_words[] CON_FLASH = HOM_FAULT_WORDS;
static const char s_target[] CON_FLASH = "target";
static const char s_boot_idle_cal_move_lea[] CON_FLASH = "boot idle cal move learn fault";
static const char s_none_sensor_servo_tend[] CON_FLASH = "none sensor servo tendon";
static const char s_preflight_release_base[] CON_FLASH =
    "- preflight release baseline tendon final";
static const char s_fault[] CON_FLASH = "fault";
static const char s_reason[] CON_FLASH = "reason";
static const char s_error[] CON_FLASH = "error";
static const char s_dev[] CON_FLASH = "dev";
static const char s_index[] CON_FLASH = "index";
static const char s_boot[] CON_FLASH = "boot";
static const char s_name[] CON_FLASH = "name";
static const char s_hallhome[] CON_FLASH = "hallhome";
static const char s_version[] CON_FLASH = "version";
static const char s_board[] CON_FLASH = "board";
static const char s_reset[] CON_FLASH = "reset";
static const char s_missing[] CON_FLASH = "missing";
static const char s_sensor[] CON_FLASH = "sensor";
static const char s_ch[] CON_FLASH = "ch";
static const char s_addr[] CON_FLASH = "addr";
static const char s_err[] CON_FLASH = "err";
static const char s_servo[] CON_FLASH = "servo";
static const char s_id[] CON_FLASH = "id";
static const char s_hw_error[] CON_FLASH = "hw_error";
static const char s_tendon[] CON_FLASH = "tendon";
static const char s_found[] CON_FLASH = "found";
static const char s_model[] CON_FLASH = "model";
static const char s_fw[] CON_FLASH = "fw";
static const char s_pos[] CON_FLASH = "pos";
static const char s_cal_pos[] CON_FLASH = "cal_pos";
static const char s_ready[] CON_FLASH = "ready";
static const char s_table[] CON_FLASH = "table";
static const char s_table_id[] CON_FLASH = "table_id";
static const char s_none[] CON_FLASH = "none";
static const char s_sensors[] CON_FLASH = "sensors";
static const char s_sensors_expected[] CON_FLASH = "sensors_expected";
static const char s_servos[] CON_FLASH = "servos";
static const char s_servos_expected[] CON_FLASH = "servos_expected";
static const char s_homes[] CON_FLASH = "homes";
static const char s_moved[] CON_FLASH = "moved";
static const char s_stored[] CON_FLASH = "stored";
static const char s_count[] CON_FLASH = "count";
static const char s_other_table[] CON_FLASH = "other_table";
static const char s_rehome[] CON_FLASH = "rehome";
static const char s_progress[] CON_FLASH = "progress";
static const char s_state[] CON_FLASH = "state";
static const char s_start[] CON_FLASH = "start";
static const char s_mode[] CON_FLASH = "mode";
static const char s_tension_mN[] CON_FLASH = "tension_mN";
static const char s_why[] CON_FLASH = "why";
static const char s_bits[] CON_FLASH = "bits";
static const char s_engaged[] CON_FLASH = "engaged";
static const char s_result[] CON_FLASH = "result";
static const char s_home[] CON_FLASH = "home";
static const char s_home_um[] CON_FLASH = "home_um";
static const char s_dB_uT[] CON_FLASH = "dB_uT";
static const char s_target_uT[] CON_FLASH = "target_uT";
static const char s_travel_um[] CON_FLASH = "travel_um";
static const char s_time_ms[] CON_FLASH = "time_ms";
static const char s_code[] CON_FLASH = "code";
static const char s_detail[] CON_FLASH = "detail";
static const char s_released[] CON_FLASH = "released";
static const char s_done[] CON_FLASH = "done";
static const char s_aborted[] CON_FLASH = "aborted";
static const char s_servo_stall[] CON_FLASH = "servo_stall";
static const char s_release[] CON_FLASH = "release";
static const char s_baseline[] CON_FLASH = "baseline";
static const char s_learned[] CON_FLASH = "learned";
static const char s_grid[] CON_FLASH = "grid";
static const char s_eeprom[] CON_FLASH = "eeprom";
static const char s_refused[] CON_FLASH = "refused";
static const char s_tendons[] CON_FLASH = "tendons";
static const char s_status[] CON_FLASH = "status";
static const char s_homes_now[] CON_FLASH = "homes_now";
static const char s_saving[] CON_FLASH = "saving";
static const char s_loop_max_us[] CON_FLASH = "loop_max_us";
static const char s_loops[] CON_FLASH = "loops";
static const char s_rest[] CON_FLASH = "rest";
static const char s_usable[] CON_FLASH = "usable";
static const char s_now[] CON_FLASH = "now";
static const char s_ok[] CON_FLASH = "ok";
static const char s_who[] CON_FLASH = "who";
static const char s_mag[] CON_FLASH = "mag";
static const char s_rate_Hz[] CON_FLASH = "rate_Hz";
static const char s_bx_uT[] CON_FLASH = "bx_uT";
static const char s_by_uT[] CON_FLASH = "by_uT";
static const char s_bz_uT[] CON_FLASH = "bz_uT";
static const char s_ovf[] CON_FLASH = "ovf";
static const char s_last_err[] CON_FLASH = "last_err";
static const char s_reinits[] CON_FLASH = "reinits";
static const char s_grid_mN[] CON_FLASH = "grid_mN";
static const char s_default_mN[] CON_FLASH = "default_mN";
static const char s_noise_cuT[] CON_FLASH = "noise_cuT";
static const char s_dir[] CON_FLASH = "dir";
static const char s_segment[] CON_FLASH = "segment";
static const char s_limit_um[] CON_FLASH = "limit_um";
static const char s_target_cuT[] CON_FLASH = "target_cuT";
static const char s_hist[] CON_FLASH = "hist";
static const char s_age[] CON_FLASH = "age";
static const char s_setting[] CON_FLASH = "setting";
static const char s_value[] CON_FLASH = "value";
static const char s_unit[] CON_FLASH = "unit";
static const char s_min[] CON_FLASH = "min";
static const char s_max[] CON_FLASH = "max";
static const char s_default[] CON_FLASH = "default";
static const char s_overrun[] CON_FLASH = "overrun";
static const char s_bytes[] CON_FLASH = "bytes";
static const char s_total[] CON_FLASH = "total";
static const char s_dropped[] CON_FLASH = "dropped";
static const char s_reports[] CON_FLASH = "reports";
static const char s_not_released[] CON_FLASH = "not_released";
static const char s_servo_error[] CON_FLASH = "servo_error";

/* Bus transactions. */
enum { TX_NONE = 0, TX_POS, TX_HWERR, TX_GOAL, TX_TORQUE, TX_REBOOT, TX_WDOG };

/* Records waiting for the EEPROM. */
enum { SAVE_HOMES = 1, SAVE_HIST = 2, SAVE_LEARNED = 4, SAVE_SETTINGS = 8 };

/* App-driven moves. */
enum { MOVE_HOME = 1, MOVE_RELEASE = 2 };

#define LEARN_BASELINE 0xFFu /* learn_tendon: capturing the straight-pose baseline */
#define GOALS_PER_TXN  6u    /* 12-byte entries of one sync write that fit DXL_TX_CAP */
#define REST_DELAY_MS  1000u
#define LEARN_WAIT_MS  1000u
#define SETTLE_MS      300u

static uint32_t now_ms(const app_t *a)
{
    return a->io->board->now_ms(a->io->board->ctx);
}

static uint32_t now_us(const app_t *a)
{
    return a->io->board->now_us(a->io->board->ctx);
}

APP_NOINLINE static uint16_t bit16(uint8_t i)
{
    return (uint16_t)(1u << i);
}

/* Bit i of m (one routine: a variable shift is a loop on the AVR). */
static uint8_t has(uint16_t m, uint8_t i)
{
    return (uint8_t)((m >> i) & 1u);
}

APP_NOINLINE static uint16_t all_mask(const app_t *a)
{
    return (uint16_t)((1u << a->info.n_tendons) - 1u);
}

/* ---- reports ------------------------------------------------------------- */

static void rep_begin(app_t *a, const char *kind)
{
    con_report_begin(&a->con, kind);
}

static void rep_int(app_t *a, const char *key, int32_t v)
{
    con_report_int(&a->con, key, v);
}

static void rep_end(app_t *a)
{
    con_report_end(&a->con);
}

/* Hex words (table_id) without a printf. */
static void rep_hex(app_t *a, const char *key, uint32_t v)
{
    char buf[11];
    uint8_t i;
    buf[0] = '0';
    buf[1] = 'x';
    for (i = 0; i < 8u; i++) {
        uint8_t d = (uint8_t)((v >> (28u - 4u * i)) & 0xFu);
        buf[2u + i] = (char)(d < 10u ? (char)('0' + d) : (char)('a' + d - 10u));
    }
    buf[10] = '\0';
    con_report_str(&a->con, key, buf);
}

/* Appends the decimal v and a separator to buf at *pos (capacity cap). */
static void list_add(char *buf, uint8_t cap, uint8_t *pos, int32_t v, char mark)
{
    char tmp[13];
    int8_t n = con_format_fixed(tmp, sizeof tmp, v, 0);
    if (n < 0 || (uint16_t)*pos + (uint16_t)n + 3u > cap) {
        return;
    }
    if (*pos > 0u) {
        buf[(*pos)++] = ',';
    }
    memcpy(&buf[*pos], tmp, (size_t)n);
    *pos = (uint8_t)(*pos + (uint8_t)n);
    if (mark != '\0') {
        buf[(*pos)++] = mark;
    }
    buf[*pos] = '\0';
}

/* Writes key=<word i of the flash list words_f> (space-separated; "?" past
 * its end): one routine instead of a table of string pointers in RAM. */
static void rep_word(app_t *a, const char *key, const char *words_f, uint8_t i)
{
    char buf[16], c;
    uint8_t n = 0;
    for (;;) {
        a->io->con_copy(&c, words_f++, 1);
        if (c == '\0' || c == ' ') {
            if (i == 0u || c == '\0') {
                break;
            }
            i--;
        } else if (i == 0u && n < sizeof buf - 1u) {
            buf[n++] = c;
        }
    }
    if (i != 0u || n == 0u) {
        buf[n++] = '?';
    }
    buf[n] = '\0';
    con_report_str(&a->con, key, buf);
}

#define MODE_WORDS  s_full_quick_single_dry
#define STATE_WORDS s_boot_idle_cal_move_lea
#define DEV_WORDS   s_none_sensor_servo_tend
#define PHASE_WORDS s_preflight_release_base

/* A fault the app itself detects (moves, learn, EEPROM), in the same shape
 * as the homing's: reason word, console error code, device. */
static void rep_app_fault(app_t *a, const char *reason_f, int8_t err, uint8_t dev, uint8_t index)
{
    rep_begin(a, s_fault);
    con_report_flash(&a->con, s_reason, reason_f);
    rep_int(a, s_error, -err);
    rep_word(a, s_dev, DEV_WORDS, dev);
    rep_int(a, s_index, index);
    rep_end(a);
}

/* ---- table ------------------------------------------------------------------- */

void app_table_copy(app_t *app, void *dst, const void *src, size_t n)
{
    uint8_t t;
    app->io->table_copy(dst, src, n);
    if (app->io->table == NULL || app->learned_mask == 0u) {
        return;
    }
    for (t = 0; t < TBL_MAX_TENDONS; t++) {
        uintptr_t lo, s0 = (uintptr_t)src, s1 = (uintptr_t)src + n;
        store_learned_t l;
        uint8_t g;
        if (has(app->learned_mask, t) == 0u) {
            continue;
        }
        lo = (uintptr_t)&app->io->table->tendons[t].target_cuT[0];
        if (lo >= s1 || lo + sizeof(uint32_t) * TBL_MAX_GRID <= s0) {
            continue;
        }
        if (store_learned_load(&app->store, t, app->info.table_id, &l) != 0) {
            continue;
        }
        for (g = 0; g < l.n_grid && g < TBL_MAX_GRID; g++) {
            uintptr_t w = lo + sizeof(uint32_t) * g;
            if (has(l.grid_mask, g) != 0u && w >= s0 && w + sizeof(uint32_t) <= s1) {
                memcpy((uint8_t *)dst + (w - s0), &l.target_cuT[g], sizeof(uint32_t));
            }
        }
    }
}

APP_NOINLINE static void load_table(app_t *a)
{
    uint8_t i;
    a->tab.table = a->io->table;
    a->tab.copy = a->io->table_copy;
    a->htab.table = a->io->table;
    a->htab.copy =
        a->io->table_copy_learned != NULL ? a->io->table_copy_learned : a->io->table_copy;
    a->table_ok = 0;
    memset(&a->info, 0, sizeof a->info);
    if (a->io->table == NULL || tbl_check(&a->tab) != 0 || tbl_info(&a->tab, &a->info) != 0 ||
        a->info.n_sensors > APP_MAX_SENSORS) {
        memset(&a->info, 0, sizeof a->info);
        return;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        tbl_tendon_t row;
        (void)tbl_tendon(&a->tab, i, &row);
        a->ids[i] = row.servo_id;
    }
    a->table_ok = 1;
}

/* um of tendon travel in encoder ticks at npt nm per tick (rounded; travel
 * is at most metres, so 32 bits hold um * 1000). */
static int32_t um_ticks(uint32_t npt, uint32_t um)
{
    if (npt == 0u) {
        npt = 1u;
    }
    return (int32_t)((um * 1000u + npt / 2u) / npt);
}

/* Ticks to um, split so that the products stay in 32 bits for any
 * extended-position value (+-256 turns). */
APP_NOINLINE static int32_t ticks_um(uint32_t npt, int32_t ticks)
{
    return ticks * (int32_t)(npt / 1000u) + ticks * (int32_t)(npt % 1000u) / 1000;
}

/* ---- engagement windows (app_win_t) ------------------------------------------ */

static uint16_t win_crc(const app_win_t *w)
{
    return store_crc16(0xFFFFu, w, offsetof(app_win_t, crc));
}

/* Checks the kept windows at boot: wrong magic, table or CRC clears them. */
static void win_check(app_t *a)
{
    app_win_t *w = a->io->win;
    if (w != NULL && (w->magic != APP_WIN_MAGIC || w->table_id != a->info.table_id ||
                      w->crc != win_crc(w) || !a->table_ok)) {
        memset(w, 0, sizeof *w);
        w->magic = APP_WIN_MAGIC;
        w->table_id = a->info.table_id;
        w->crc = win_crc(w);
    }
}

/* Sets tendon i's window (or forgets it with keep 0). */
APP_NOINLINE static void win_set(app_t *a, uint8_t i, int32_t lo, int32_t hi, uint8_t keep)
{
    app_win_t *w = a->io->win;
    if (w == NULL) {
        return;
    }
    w->mask = (uint16_t)(keep ? (w->mask | bit16(i)) : (w->mask & ~bit16(i)));
    w->lo[i] = lo;
    w->hi[i] = hi;
    w->crc = win_crc(w);
}

/* Notes in the kept copy whether anything moves: a watchdog or reset-pin
 * reset in the middle of a run leaves tendons taut, and the next boot
 * releases them. */
APP_NOINLINE static void win_moving(app_t *a, uint8_t on)
{
    app_win_t *w = a->io->win;
    if (w != NULL && w->moving != on) {
        w->moving = on;
        w->crc = win_crc(w);
    }
}

/* Takes the windows a run changed into the kept copy. */
APP_NOINLINE static void win_take(app_t *a)
{
    uint8_t i;
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t lo, hi;
        if (has(a->u.hom.win_changed, i) && hom_window(&a->u.hom, i, &lo, &hi) == 0) {
            win_set(a, i, lo, hi, 1);
        }
    }
    a->u.hom.win_changed = 0;
}

static int32_t home_cur(const app_t *a, uint8_t i)
{
    return a->homes.t[i].home_ticks - a->offset[i];
}

/* ---- init ---------------------------------------------------------------- */

int8_t app_init(app_t *app, const app_io_t *io)
{
    dxl_config dc;
    uint8_t t;
    if (app == NULL || io == NULL || io->board == NULL || io->board->now_ms == NULL ||
        io->board->now_us == NULL || io->board->button == NULL || io->board->led == NULL ||
        io->board->wdt_kick == NULL || io->sensor_bus == NULL || io->eeprom == NULL ||
        io->console == NULL || io->con_copy == NULL || io->store_copy == NULL || io->rt == NULL ||
        io->table_copy == NULL) {
        return APP_E_ARG;
    }
    memset(app, 0, sizeof *app);
    app->io = io;
    (void)con_init(&app->con, io->console, app_handlers, app, io->con_copy, io->rt);
    (void)store_init(&app->store, io->eeprom, io->store_copy);
    (void)store_settings_load(&app->store, &app->set);
    load_table(app);
    win_check(app);
    app->reset_release = (uint8_t)(io->win != NULL && io->win->moving && app->table_ok);
    hom_init(&app->u.hom, NULL);
    dxl_config_default(&dc, app_bus_baud(app), io->servo_bits != 0u ? io->servo_bits : 10u);
    dxl_master_init(&app->dxl, &io->servo_port, &dc);
    app->homes_rc = STORE_E_EMPTY;
    if (app->table_ok) {
        app->homes_rc = store_homes_load(&app->store, app->info.table_id, &app->homes);
        if (app->homes_rc != 0 || app->homes.n_tendons != app->info.n_tendons) {
            memset(&app->homes, 0, sizeof app->homes);
        }
        for (t = 0; t < app->info.n_tendons; t++) {
            store_learned_t l;
            if (store_learned_load(&app->store, t, app->info.table_id, &l) == 0 &&
                l.grid_mask != 0u) {
                app->learned_mask |= bit16(t);
            }
        }
    }
    app->state = APP_ST_BOOT;
    app->t_boot = now_ms(app);
    app->btn_raw = 0;
    app->led = APP_LED_BOOT;
    rep_begin(app, s_boot);
    con_report_flash(&app->con, s_name, s_hallhome);
    if (io->version_f != NULL) {
        con_report_flash(&app->con, s_version, io->version_f);
    }
    if (io->board_f != NULL) {
        con_report_flash(&app->con, s_board, io->board_f);
    }
    if (io->reset_f != NULL) {
        con_report_flash(&app->con, s_reset, io->reset_f);
    }
    rep_end(app);
    return 0;
}

uint32_t app_bus_baud(const app_t *app)
{
    return (uint32_t)app->set.v[STORE_SET_BUS_BAUD];
}

/* ---- boot preflight ------------------------------------------------------- */

APP_NOINLINE static void boot_start(app_t *a)
{
    uint8_t k;
    dxl_bringup_config bc;
    a->state = APP_ST_BOOT;
    a->boot_step = 0;
    a->t_boot = now_ms(a);
    if (!a->table_ok) {
        return;
    }
    if (a->sens.n == 0u) {
        (void)icm_set_setup(&a->sens, a->io->sensor_bus, a->io->mux_addr, a->slot, APP_MAX_SENSORS);
        for (k = 0; k < a->info.n_sensors; k++) {
            tbl_sensor_t s;
            (void)tbl_sensor(&a->tab, k, &s);
            (void)icm_set_add(&a->sens, a->io->mux_addr == ICM_NO_MUX ? ICM_NO_MUX : s.mux_channel,
                              s.i2c_addr);
        }
        (void)icm_set_begin(&a->sens, now_us(a));
    }
    memset(&bc, 0, sizeof bc);
    bc.profile_velocity = 0;
    bc.profile_acceleration = 0;
    bc.reboot_on_hw_error = 0;
    bc.reboot_wait_us = 500000u;
    dxl_abort(&a->dxl);
    a->sv_txn = TX_NONE;
    a->servo_absent = 0;
    a->torque_on = 0; /* goals of the old frames must never be sent again */
    a->have_b0 = 0;   /* the bring-up reuses the baseline's storage */
    (void)dxl_bringup_start(&a->u.bring, &a->dxl, a->ids, a->info.n_tendons, &bc);
    a->boot_step = 1;
}

/* Maps the stored homes into this power cycle's servo frames. */
APP_NOINLINE static void recover_homes(app_t *a)
{
    uint8_t i;
    a->home_now = 0;
    a->recover_rc = 0;
    if (a->homes_rc != 0) {
        return;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t pos;
        int8_t rc;
        if (has(a->homes.valid_mask, i) == 0u || has(a->servo_seen, i) == 0u) {
            continue;
        }
        rc = store_recover_position(&a->homes.t[i], a->present[i],
                                    (uint16_t)a->set.v[STORE_SET_REST_TOL], &pos);
        if (rc == 0) {
            a->offset[i] = pos - a->present[i];
            a->home_now |= bit16(i);
        } else if (a->recover_rc == 0) {
            a->recover_rc = rc;
        }
    }
}

/* One `<missing ...>` per sensor that is not sampling and per servo that is
 * absent or reports a hardware error. Returns CON_E_SENSOR_FAULT when a
 * sensor is missing, else CON_E_SERVO_FAULT when a servo is, else 0. */
static int8_t rep_missing(app_t *a)
{
    uint8_t i;
    int8_t rc = 0;
    for (i = 0; i < a->info.n_sensors; i++) {
        icm_diag_t d;
        (void)icm_set_diag(&a->sens, i, &d);
        if (d.state != ICM_SET_S_RUN) {
            rep_begin(a, s_missing);
            con_report_flash(&a->con, s_dev, s_sensor);
            rep_int(a, s_index, i);
            rep_int(a, s_ch, d.channel);
            rep_int(a, s_addr, d.addr);
            rep_int(a, s_err, d.last_err);
            rep_end(a);
            rc = CON_E_SENSOR_FAULT;
        }
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        if (has(a->servo_absent, i) || a->hw_err[i] != 0u) {
            rep_begin(a, s_missing);
            con_report_flash(&a->con, s_dev, s_servo);
            rep_int(a, s_index, i);
            rep_int(a, s_id, a->ids[i]);
            rep_int(a, s_hw_error, a->hw_err[i]);
            rep_end(a);
            if (rc == 0) {
                rc = CON_E_SERVO_FAULT;
            }
        }
    }
    return rc;
}

/* The bring-up's entry for servo id, or NULL. */
APP_NOINLINE static const dxl_servo_info *bring_info(const app_t *a, uint8_t id)
{
    uint8_t j;
    for (j = 0; j < a->u.bring.n; j++) {
        if (a->u.bring.servo[j].id == id) {
            return &a->u.bring.servo[j];
        }
    }
    return NULL;
}

APP_NOINLINE static void boot_finish(app_t *a)
{
    uint8_t i, k;
    a->n_servo_found = 0;
    a->servo_seen = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        const dxl_servo_info *s = bring_info(a, a->ids[i]);
        if (has(a->servo_absent, i) == 0u && s != NULL && s->present) {
            a->n_servo_found++;
            a->hw_err[i] = s->hw_error;
            if (a->u.bring.result == 0) {
                a->present[i] = s->position;
                a->servo_seen |= bit16(i);
            }
        } else {
            a->servo_absent |= bit16(i);
        }
    }
    a->goal_due = 0;
    a->torque_due = 0;
    a->wdog_step = (uint8_t)(2u * a->info.n_tendons);
    a->n_sens_found = icm_set_ready_count(&a->sens);
    for (k = 0; k < a->info.n_sensors; k++) {
        icm_diag_t d;
        (void)icm_set_diag(&a->sens, k, &d);
        a->sens_err[k] = (uint8_t)d.error_count;
    }
    (void)rep_missing(a);
    /* Positions not read by the bring-up (it stopped on a missing servo)
     * arrive with the first cycles; homes are recovered once they have. */
    a->boot_step = 2;
}

/* One `<servo ...>` line per tendon: what the bus knows of its servo. */
static void servo_lines(app_t *a, uint8_t with_model)
{
    uint8_t i;
    for (i = 0; i < a->info.n_tendons; i++) {
        rep_begin(a, s_servo);
        rep_int(a, s_tendon, i);
        rep_int(a, s_id, a->ids[i]);
        rep_int(a, s_found, has(a->servo_absent, i) == 0u);
        if (with_model) {
            const dxl_servo_info *s = bring_info(a, a->ids[i]);
            if (s != NULL) {
                rep_int(a, s_model, s->model);
                rep_int(a, s_fw, s->firmware);
            }
        }
        rep_int(a, s_pos, a->present[i]);
        rep_int(a, s_cal_pos, a->present[i] + a->offset[i]);
        rep_int(a, s_hw_error, a->hw_err[i]);
        rep_end(a);
    }
}

APP_NOINLINE static void boot_ready(app_t *a)
{
    recover_homes(a);
    a->offer_quick = (uint8_t)(a->table_ok && a->home_now != 0u && a->home_now == all_mask(a) &&
                               a->servo_absent == 0u);
    rep_begin(a, s_ready);
    if (a->table_ok) {
        con_report_str(&a->con, s_table, a->info.name);
        rep_hex(a, s_table_id, a->info.table_id);
    } else {
        con_report_flash(&a->con, s_table, s_none);
    }
    rep_int(a, s_sensors, a->n_sens_found);
    rep_int(a, s_sensors_expected, a->info.n_sensors);
    rep_int(a, s_servos, a->n_servo_found);
    rep_int(a, s_servos_expected, a->info.n_tendons);
    if (a->homes_rc == 0) {
        con_report_flash(&a->con, s_homes, a->recover_rc == STORE_E_MOVED ? s_moved : s_stored);
        rep_int(a, s_count, (int32_t)a->homes.cal_count);
    } else {
        con_report_flash(&a->con, s_homes,
                         a->homes_rc == STORE_E_OTHER_TABLE ? s_other_table : s_none);
    }
    rep_int(a, s_rehome, a->offer_quick);
    rep_end(a);
    a->state = APP_ST_IDLE;
    a->boot_step = 3;
    if (a->boot_con && con_pending(&a->con)) {
        servo_lines(a, 1);
        (void)con_complete(&a->con, 0);
    }
    a->boot_con = 0;
    a->reboot_id = 0;
}

APP_NOINLINE static void boot_poll(app_t *a)
{
    uint32_t t = now_ms(a);
    if (a->boot_step == 0u) {
        if (a->reboot_id != 0u && t - a->t_boot < APP_SERVO_REBOOT_MS) {
            return;
        }
        boot_start(a);
        if (!a->table_ok) {
            boot_ready(a);
        }
        return;
    }
    if (a->boot_step == 1u) {
        int8_t rc = dxl_bringup_poll(&a->u.bring);
        if (rc == -DXL_E_MISSING && a->servo_absent == 0u) {
            /* set up the servos that answered; the missing ones stay named */
            uint8_t ids[TBL_MAX_TENDONS], i, n = 0;
            for (i = 0; i < a->info.n_tendons; i++) {
                if (i < a->u.bring.n && a->u.bring.servo[i].present) {
                    ids[n++] = a->ids[i];
                } else {
                    a->servo_absent |= bit16(i);
                }
            }
            if (n > 0u && dxl_bringup_start(&a->u.bring, &a->dxl, ids, n, &a->u.bring.cfg) > 0) {
                return;
            }
        }
        if (rc > 0 && t - a->t_boot < APP_PREFLIGHT_MS) {
            return;
        }
        if (rc > 0) {
            dxl_abort(&a->dxl);
        }
        if (!icm_set_settled(&a->sens) && t - a->t_boot < APP_PREFLIGHT_MS) {
            return;
        }
        boot_finish(a);
        return;
    }
    /* step 2: every found servo's position and Bus Watchdog, then ready */
    if (((a->servo_seen | a->servo_absent) != all_mask(a) || a->wdog_step != 0u ||
         a->sv_txn == TX_WDOG) &&
        t - a->t_boot < APP_PREFLIGHT_MS) {
        return;
    }
    boot_ready(a);
}

/* ---- servo bus ------------------------------------------------------------ */

static uint8_t present_ids(const app_t *a, uint8_t *ids, uint16_t *mask)
{
    uint8_t i, n = 0;
    *mask = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        if (has(a->servo_absent, i) == 0u) {
            ids[n++] = a->ids[i];
            *mask |= bit16(i);
        }
    }
    return n;
}

APP_NOINLINE static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

APP_NOINLINE static void servo_done(app_t *a, int8_t rc)
{
    uint8_t i;
    uint16_t got = 0;
    if (a->sv_txn == TX_POS || a->sv_txn == TX_HWERR) {
        for (i = 0; i < a->info.n_tendons; i++) {
            const dxl_reply *r;
            if (has(a->txn_mask, i) == 0u) {
                continue;
            }
            r = dxl_reply_for(&a->dxl, a->ids[i]);
            if (r == NULL || (r->result != 0 && r->result != -DXL_E_ALERT)) {
                continue;
            }
            if (a->sv_txn == TX_POS && r->len >= 4u) {
                a->present[i] = dxl_reply_value(r, 4);
                got |= bit16(i);
                a->servo_fresh |= bit16(i);
                a->servo_seen |= bit16(i);
            } else if (a->sv_txn == TX_HWERR && r->len >= 1u) {
                a->hw_err[i] = r->data[0];
            }
            if (r->result == -DXL_E_ALERT && a->sv_txn == TX_POS) {
                a->hwerr_due = 1;
            }
        }
        if (a->sv_txn == TX_POS) {
            if (got == a->txn_mask) {
                a->pos_streak = 0;
            } else if (a->pos_streak < APP_POS_RETRIES) {
                a->pos_streak++;
                a->pos_force = 1;
            }
        }
    } else if (a->sv_txn == TX_REBOOT) {
        if (rc != 0 && rc != -DXL_E_ALERT) {
            if (a->auto_release) {
                a->auto_release = 0; /* named: this tendon may still be taut */
                for (i = 0; i < a->info.n_tendons; i++) {
                    if (a->ids[i] == a->reboot_id) {
                        rep_app_fault(a, s_not_released, CON_E_SERVO_FAULT, HOM_DEV_SERVO, i);
                    }
                }
            } else if (con_pending(&a->con)) {
                (void)con_complete(&a->con, CON_E_SERVO_FAULT);
            }
            a->reboot_id = 0;
        } else {
            /* the servo lost its multi-turn count: bring the bus up again
             * and recover the homes as after a power cycle; its engagement
             * window is in the old frame */
            for (i = 0; i < a->info.n_tendons; i++) {
                if (a->ids[i] == a->reboot_id) {
                    win_set(a, i, 0, 0, 0);
                }
            }
            a->t_boot = now_ms(a);
            a->boot_con = 1;
            a->boot_step = 0;
            a->state = APP_ST_BOOT;
        }
    }
    a->sv_txn = TX_NONE;
}

/* Tendons whose servo stands more than a tick from the goal last sent. A
 * sync write carries no reply: a servo that missed one to a corrupted byte
 * keeps its old goal, so these goals go out again every few cycles. A servo
 * that is really stuck stays where it is and the homing's stall check still
 * sees it; a servo on its way gets the goal it already has. */
static uint16_t off_goal(const app_t *a)
{
    uint8_t i = a->info.n_tendons;
    uint16_t m = 0;
    while (i-- > 0u) {
        m = (uint16_t)(m << 1);
        if ((uint32_t)(a->present[i] - a->u.hom.out.goal[i]) + 1u > 2u) {
            m |= 1u;
        }
    }
    return m & a->torque_on;
}

APP_NOINLINE static void servo_next(app_t *a)
{
    uint8_t ids[TBL_MAX_TENDONS];
    uint8_t data[GOALS_PER_TXN * 12u];
    uint8_t i, n = 0, txn, v, force;
    uint16_t mask, addr;
    if (a->reboot_req && a->goal_due == 0u && a->torque_due == 0u) {
        /* after the release goals of every other tendon are out: the
         * bring-up that follows a reboot owns the bus for a while */
        a->reboot_req = 0;
        if (dxl_reboot(&a->dxl, a->reboot_id) > 0) {
            a->sv_txn = TX_REBOOT;
        } else if (con_pending(&a->con)) {
            (void)con_complete(&a->con, CON_E_INTERNAL);
        }
        return;
    }
    if (a->wdog_step != 0u || a->torque_due != 0u) {
        if (a->wdog_step != 0u) {
            /* two writes per servo, from the last: 0 clears an expired
             * watchdog (the servo refuses goals until then), then the
             * period arms it */
            v = a->wdog_step--;
            i = (uint8_t)((v - 1u) >> 1);
            if (has(a->servo_absent, i)) {
                return;
            }
            v = (v & 1u) ? APP_BUS_WATCHDOG : 0u;
            addr = DXL_XL430_BUS_WATCHDOG_ADDR;
            txn = TX_WDOG;
        } else {
            for (i = 0; has(a->torque_due, i) == 0u; i++) {
            }
            a->torque_due &= (uint16_t)~bit16(i);
            v = has(a->torque_on, i);
            addr = DXL_XL430_TORQUE_ENABLE_ADDR;
            txn = TX_TORQUE;
        }
        if (dxl_write_value(&a->dxl, a->ids[i], addr, v, 1) > 0) {
            a->sv_txn = txn;
        }
        return;
    }
    if (a->goal_due == 0u) {
        n = present_ids(a, ids, &mask);
        if (n == 0u) {
            return;
        }
        a->txn_mask = mask;
        a->sv_cycle++;
        force = a->pos_force;
        a->pos_force = 0;
        addr = DXL_XL430_HW_ERROR_ADDR;
        v = 1;
        txn = TX_HWERR;
        if (a->hwerr_due || (!force && (a->sv_cycle % APP_HWERR_EVERY) == 0u)) {
            a->hwerr_due = 0;
        } else {
            /* even between forced position reads: a lost goal is worse
             * than a late position */
            if ((a->sv_cycle % APP_GOAL_REFRESH_EVERY) == APP_GOAL_REFRESH_EVERY / 2u) {
                a->goal_due = off_goal(a); /* this cycle refreshes goals instead */
            }
            addr = DXL_XL430_PRESENT_POSITION_ADDR;
            v = 4;
            txn = TX_POS;
        }
        if (a->goal_due == 0u) {
            if (dxl_fast_sync_read(&a->dxl, addr, v, ids, n) > 0) {
                a->sv_txn = txn;
            }
            return;
        }
        n = 0;
    }
    for (i = 0; i < a->info.n_tendons && n < GOALS_PER_TXN; i++) {
        uint8_t *p = &data[n * 12u];
        if (has(a->goal_due, i) == 0u) {
            continue;
        }
        a->goal_due &= (uint16_t)~bit16(i);
        if (has(a->servo_absent, i)) {
            continue;
        }
        ids[n++] = a->ids[i];
        put32(p, a->acc);
        put32(p + 4, a->u.hom.out.vel[i]);
        put32(p + 8, (uint32_t)a->u.hom.out.goal[i]);
    }
    if (n > 0u &&
        dxl_sync_write(&a->dxl, DXL_XL430_PROFILE_ACCELERATION_ADDR, 12u, ids, data, n) > 0) {
        a->sv_txn = TX_GOAL;
    }
}

APP_NOINLINE static void servo_poll(app_t *a)
{
    if (a->state == APP_ST_BOOT && a->boot_step != 2u) {
        return; /* the bring-up owns the bus */
    }
    if (dxl_busy(&a->dxl)) {
        int8_t rc = dxl_poll(&a->dxl);
        if (rc > 0) {
            return;
        }
        servo_done(a, rc);
    } else if (a->sv_txn != TX_NONE) {
        servo_done(a, dxl_poll(&a->dxl));
    }
    if (a->state != APP_ST_BOOT || a->boot_step == 2u) {
        servo_next(a);
    }
}

/* Queues a goal for tendon i. */
APP_NOINLINE static void set_goal(app_t *a, uint8_t i, int32_t goal, uint16_t vel, uint16_t acc)
{
    a->u.hom.out.goal[i] = goal;
    a->u.hom.out.vel[i] = vel;
    a->acc = acc;
    a->goal_due |= bit16(i);
    if (has(a->torque_on, i) == 0u) {
        a->torque_on |= bit16(i);
        a->torque_due |= bit16(i);
    }
}

/* ---- sensors -------------------------------------------------------------- */

/* Takes this pass's samples into in->sensor[] (and the learn accumulator). */
APP_NOINLINE static void sensors_take(app_t *a, hom_in_t *in)
{
    uint8_t k;
    for (k = 0; k < a->info.n_sensors && a->sens.n > 0u; k++) {
        icm_sample_t s;
        hom_sensor_in_t *o = &in->sensor[k];
        int8_t rc = icm_set_take(&a->sens, k, &s);
        icm_diag_t d;
        (void)icm_set_diag(&a->sens, k, &d);
        if (rc == 1) {
            o->status = (s.flags & ICM_SAMPLE_OVERFLOW) ? HOM_SENS_OVERFLOW : HOM_SENS_NEW;
            o->b_cuT[0] = (int32_t)s.raw[0] * 15;
            o->b_cuT[1] = (int32_t)s.raw[1] * 15;
            o->b_cuT[2] = (int32_t)s.raw[2] * 15;
        } else if (d.state == ICM_SET_S_FAIL && !d.present) {
            o->status = HOM_SENS_ABSENT;
        } else if ((uint8_t)d.error_count != a->sens_err[k]) {
            o->status = HOM_SENS_ERROR;
        } else {
            o->status = HOM_SENS_NONE;
        }
        a->sens_err[k] = (uint8_t)d.error_count;
    }
}

/* ---- runs ------------------------------------------------------------------- */

/* A history or learned record waits in u.idle: the homing and the bring-up
 * must not reuse that storage until it is written. */
static uint8_t rec_busy(const app_t *a)
{
    return (uint8_t)((a->save_due & (SAVE_HIST | SAVE_LEARNED)) != 0u || a->save_now == SAVE_HIST ||
                     a->save_now == SAVE_LEARNED);
}

static void save_queue(app_t *a, uint8_t what)
{
    a->save_due |= what;
}

APP_NOINLINE static void rep_event(app_t *a, const hom_event_t *ev)
{
    uint8_t i = ev->index;
    switch (ev->type) {
    case HOM_EV_START:
        rep_begin(a, s_progress);
        con_report_flash(&a->con, s_state, s_start);
        rep_word(a, s_mode, MODE_WORDS, ev->code);
        rep_int(a, s_tension_mN, ev->a);
        rep_end(a);
        break;
    case HOM_EV_PHASE: {
        rep_begin(a, s_progress);
        rep_word(a, s_state, PHASE_WORDS, ev->code);
        if (ev->code == HOM_PH_TENDON && i < TBL_MAX_TENDONS) {
            rep_int(a, s_tendon, i);
            rep_int(a, s_id, a->ids[i]);
        }
        rep_end(a);
        break;
    }
    case HOM_EV_MISSING:
        rep_begin(a, s_missing);
        rep_word(a, s_dev, DEV_WORDS, ev->code);
        rep_int(a, s_index, i);
        if (ev->code == HOM_DEV_SERVO && i < TBL_MAX_TENDONS) {
            rep_int(a, s_id, a->ids[i]);
        }
        rep_int(a, s_why, ev->a);
        rep_int(a, s_bits, ev->b);
        rep_end(a);
        break;
    case HOM_EV_ENGAGED:
        rep_begin(a, s_progress);
        con_report_flash(&a->con, s_state, s_engaged);
        rep_int(a, s_tendon, i);
        rep_int(a, s_pos, ev->a);
        rep_end(a);
        break;
    case HOM_EV_HOME:
        if (i < a->info.n_tendons) {
            const hom_tendon_t *t = &a->u.hom.tendon[i];
            rep_begin(a, s_result);
            rep_int(a, s_tendon, i);
            rep_int(a, s_id, a->ids[i]);
            rep_int(a, s_home, ev->a);
            rep_int(a, s_home_um, ticks_um(t->nm_per_tick, ev->a));
            con_report_fixed(&a->con, s_dB_uT, (int32_t)a->u.hom.home_dB, 2);
            con_report_fixed(&a->con, s_target_uT, (int32_t)t->target_cuT, 2);
            rep_int(a, s_travel_um, ticks_um(t->nm_per_tick, (ev->a - t->engage) * t->dir));
            rep_int(a, s_time_ms, (int32_t)a->u.hom.tendon_ms);
            rep_word(a, s_target, s_delta_abs, a->run_abs);
            rep_end(a);
        }
        break;
    case HOM_EV_DONE:
        break; /* reported by run_done() with the count */
    case HOM_EV_FAULT:
        a->last_fault = ev->code;
        rep_begin(a, s_fault);
        rep_word(a, s_reason, s_fault_words, ev->code);
        rep_int(a, s_code, ev->code);
        rep_word(a, s_dev, DEV_WORDS, (uint8_t)ev->a);
        rep_int(a, s_index, i);
        if ((ev->a == HOM_DEV_SERVO || ev->a == HOM_DEV_TENDON) && i < TBL_MAX_TENDONS) {
            rep_int(a, s_id, a->ids[i]);
        }
        rep_int(a, s_detail, ev->b);
        rep_end(a);
        break;
    case HOM_EV_RELEASED:
        rep_begin(a, s_released);
        rep_word(a, s_reason, s_fault_words, (uint8_t)ev->a);
        if ((ev->a == HOM_F_SERVO_TIMEOUT || ev->a == HOM_F_SERVO_ERROR) &&
            a->u.hom.fault_index < a->info.n_tendons) {
            /* a servo that does not answer, or has its torque off, cannot
             * take the release: named (a hardware error is rebooted next) */
            rep_int(a, s_not_released, a->ids[a->u.hom.fault_index]);
            rep_int(a, s_index, a->u.hom.fault_index);
        }
        rep_end(a);
        break;
    default:
        break;
    }
}

/* A run finished: keep its homes (calibration frame = this power cycle's
 * frame, so the offsets become 0), count it and queue the records. */
APP_NOINLINE static void run_done(app_t *a)
{
    win_moving(a, 0);
    uint8_t i, k;
    uint32_t t = now_ms(a);
    a->amb_ok |= a->u.hom.amb_capture; /* read before u.idle reuses the storage */
    a->homes.table_id = a->info.table_id;
    a->homes.n_tendons = a->info.n_tendons;
    a->homes.tension_mN = a->run_tension;
    a->homes.cal_count++;
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t h;
        if (has(a->run_mask, i) && hom_home(&a->u.hom, i, &h) == 0) {
            store_home_set(&a->homes.t[i], h, h);
            a->offset[i] = 0;
            a->homes.valid_mask |= bit16(i);
            a->home_now |= bit16(i);
        }
    }
    /* The run's baseline is the learn baseline until the next release. From
     * here on the homing's storage is reused (u.idle overlaps its first
     * bytes only: the homes and baselines above were read first). */
    for (k = 0; k < a->info.n_sensors; k++) {
        memcpy(a->u.idle.b0[k], a->u.hom.sensor[k].b0, sizeof a->u.idle.b0[k]);
    }
    a->have_b0 = 1;
    memset(&a->u.idle.rec.hist, 0, sizeof a->u.idle.rec.hist);
    a->u.idle.rec.hist.cal_count = a->homes.cal_count;
    a->u.idle.rec.hist.table_id = a->homes.table_id;
    a->u.idle.rec.hist.tension_mN = a->homes.tension_mN;
    a->u.idle.rec.hist.valid_mask = a->homes.valid_mask;
    a->u.idle.rec.hist.n_tendons = a->homes.n_tendons;
    for (i = 0; i < a->info.n_tendons; i++) {
        a->u.idle.rec.hist.home_ticks[i] = a->homes.t[i].home_ticks;
    }
    a->homes_rc = 0;
    a->recover_rc = 0;
    save_queue(a, SAVE_HOMES | SAVE_HIST);
    a->offer_quick = 0;
    rep_begin(a, s_done);
    rep_word(a, s_mode, MODE_WORDS, a->run_mode);
    rep_word(a, s_target, s_delta_abs, a->run_abs);
    rep_int(a, s_time_ms, (int32_t)(t - a->t_run));
    rep_int(a, s_tension_mN, a->run_tension);
    rep_int(a, s_count, (int32_t)a->homes.cal_count);
    rep_end(a);
    a->led = APP_LED_DONE;
    a->state = APP_ST_IDLE;
}

APP_NOINLINE static int8_t check_devices(app_t *a)
{
    if (a->state == APP_ST_BOOT) {
        return CON_E_BUSY;
    }
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    return rep_missing(a);
}

static uint8_t idle_state(const app_t *a)
{
    return (uint8_t)(a->state == APP_ST_IDLE || a->state == APP_ST_FAULT);
}

/* 0 when every tendon has a stored home usable in this power cycle, else
 * CON_E_NOT_HOMED or CON_E_MOVED (a spool turned while powered off). */
APP_NOINLINE static int8_t homes_usable(const app_t *a)
{
    if (a->homes_rc != 0 || a->homes.valid_mask != all_mask(a)) {
        return CON_E_NOT_HOMED;
    }
    return a->home_now != all_mask(a) ? CON_E_MOVED : 0;
}

/* Starts a homing run. Returns 0 or a CON_E_* code (nothing moves then). */
static int8_t run_start(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon)
{
    hom_config_t cfg;
    hom_cmd_t cmd;
    int rc;
    uint8_t i;
    int8_t e;
    if (!idle_state(a)) {
        return CON_E_BUSY;
    }
    e = check_devices(a);
    if (e != 0) {
        return e;
    }
    if (mode == HOM_MODE_SINGLE && tendon >= a->info.n_tendons) {
        return CON_E_BAD_TENDON;
    }
    if (tension == 0u) {
        tension = (uint16_t)a->set.v[STORE_SET_CAL_TENSION];
    }
    if (tension < a->info.grid_mN[0] || tension > a->info.grid_mN[a->info.n_grid - 1u]) {
        return CON_E_TENSION_RANGE;
    }
    if (mode == HOM_MODE_QUICK) {
        e = homes_usable(a);
        if (e != 0) {
            return e;
        }
        tension = a->homes.tension_mN;
    }
    if (store_busy(&a->store) || rec_busy(a)) {
        return CON_E_BUSY; /* finishes within a few hundred ms */
    }
    memset(&cmd, 0, sizeof cmd);
    a->run_abs = a->set.v[STORE_SET_TARGET_MODE] != 0;
    if (a->run_abs) {
        /* the first absolute run takes A from its own straight-pose
         * baseline (a dry run stands wherever the robot is: never) */
        cmd.ambient_cuT = a->amb;
        cmd.ambient_capture = (uint8_t)(!a->amb_ok && mode != HOM_MODE_DRY);
    }
    cmd.mode = (hom_mode_t)mode;
    cmd.tension_mN = tension;
    cmd.tendon = tendon;
    for (i = 0; i < a->info.n_tendons; i++) {
        if (has(a->home_now, i)) {
            cmd.stored_home[i] = home_cur(a, i);
            cmd.stored_mask |= bit16(i);
        }
    }
    if (a->io->win != NULL) {
        cmd.win_mask = a->io->win->mask;
        memcpy(cmd.win_lo, a->io->win->lo, sizeof cmd.win_lo);
        memcpy(cmd.win_hi, a->io->win->hi, sizeof cmd.win_hi);
    }
    hom_config_default(&cfg);
    /* filter_k is the homing's own filter: samples averaged at each fine
     * point while the servo stands still (near the target at least twice as
     * many). A moving average of the stream ahead of the homing would lag
     * during the take-up and delay the engagement it detects. */
    cfg.v_fast = (uint16_t)a->set.v[STORE_SET_APPROACH_FAST];
    cfg.v_fine = (uint16_t)a->set.v[STORE_SET_APPROACH_SLOW];
    cfg.avg_samples = (uint8_t)a->set.v[STORE_SET_FILTER_K];
    cfg.servo_timeout_ms = APP_SERVO_TIMEOUT_MS;
    a->have_b0 = 0; /* its storage goes to the homing */
    hom_init(&a->u.hom, &cfg);
    a->torque_on = 0; /* the goals were cleared: nothing to refresh until set */
    rc = hom_start(&a->u.hom, &a->htab, &cmd);
    if (rc == HOM_E_TENSION) {
        return CON_E_TENSION_RANGE;
    }
    if (rc == HOM_E_HOMES) {
        return CON_E_NOT_HOMED;
    }
    if (rc != 0) {
        return CON_E_INTERNAL;
    }
    a->run_mode = mode;
    a->run_tension = tension;
    a->run_mask = mode == HOM_MODE_SINGLE ? bit16(tendon) : all_mask(a);
    a->t_run = now_ms(a);
    a->servo_fresh = 0;
    a->state = APP_ST_CAL;
    win_moving(a, 1);
    a->led = APP_LED_RUN;
    a->rest_due = 0;
    return 0;
}

/* A run or move ended in a fault: the rest positions are recorded once the
 * servos have stopped. */
APP_NOINLINE static void fault_rest(app_t *a, uint32_t t)
{
    win_moving(a, 0); /* the release goals are out: the servos finish them */
    a->state = APP_ST_FAULT;
    a->led = APP_LED_FAULT;
    a->rest_due = 1;
    a->t_rest = (uint16_t)t;
}

APP_NOINLINE static void cal_step(app_t *a, hom_in_t *in)
{
    hom_out_t out;
    hom_event_t ev;
    uint8_t i;
    int rc;
    in->now_ms = now_ms(a);
    for (i = 0; i < a->info.n_tendons; i++) {
        hom_servo_in_t *s = &in->servo[i];
        if (has(a->servo_absent, i)) {
            s->status = HOM_SERVO_ABSENT;
        } else {
            s->status = has(a->servo_fresh, i) ? HOM_SERVO_OK : HOM_SERVO_NOREPLY;
        }
        s->hw_error = a->hw_err[i];
        s->pos = a->present[i];
    }
    a->servo_fresh = 0;
    if (a->u.hom.t_phase == 0u && (in->now_ms & 1u) == 0u) {
        /* The homing's preflight starts its clock at now | 1 and checks it
         * in the same step: an even start time would read as a wrapped,
         * expired wait. Its first step is given an odd time (1 ms early). */
        in->now_ms--;
    }
    rc = hom_step(&a->u.hom, in, &out);
    if (a->u.hom.win_changed != 0u) {
        win_take(a);
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        if (has(out.changed, i)) {
            a->acc = out.acc[i]; /* one profile acceleration for every move */
            a->goal_due |= bit16(i);
            if ((out.torque[i] != 0u) != (has(a->torque_on, i) != 0u)) {
                a->torque_on ^= bit16(i);
                a->torque_due |= bit16(i);
            }
        }
    }
    while (hom_event_pop(&a->u.hom, &ev)) {
        rep_event(a, &ev);
    }
    if (rc == 0) {
        run_done(a);
    } else if (rc < 0) {
        fault_rest(a, in->now_ms);
        if (a->u.hom.fault == HOM_F_SERVO_ERROR && a->u.hom.fault_index < a->info.n_tendons) {
            /* a servo in hardware error has its torque off and refused the
             * release: reboot it (Protocol 2.0 Reboot clears the error), then
             * release its tendon once the bus is up again */
            a->reboot_id = a->ids[a->u.hom.fault_index];
            a->reboot_req = 1;
            a->auto_release = a->reboot_id;
        }
    }
}

/* ---- app moves: home, release, baseline, learn ------------------------------ */

static void move_start(app_t *a, uint8_t kind)
{
    win_moving(a, 1);
    a->move_kind = kind;
    a->t_move = now_ms(a);
    a->servo_fresh = 0;
    a->state = APP_ST_MOVE;
    a->led = APP_LED_RUN;
}

/* Release goals computed by the app when no run is active: the slack margin
 * before each tendon's engagement window. A tendon without a window gets
 * one first: the engagement its stored home implies, or, with nothing
 * known, the homing's own assumption (anywhere up to the release that frees
 * a tendon left at the top of the grid). Never pulls, and repeated releases
 * go no further (the window stays). */
static uint8_t release_goals(app_t *a)
{
    hom_config_t cfg;
    uint8_t i, moved = 0;
    hom_config_default(&cfg);
    for (i = 0; i < a->info.n_tendons; i++) {
        tbl_point_t pt;
        tbl_tendon_t row;
        int32_t g, dir, lo, hi;
        if (has(a->servo_absent, i)) {
            continue;
        }
        (void)tbl_tendon(&a->tab, i, &row);
        dir = row.pull_dir < 0 ? -1 : 1;
        if (a->io->win != NULL && has(a->io->win->mask, i)) {
            lo = a->io->win->lo[i];
        } else {
            if (has(a->home_now, i)) {
                uint32_t trav = 0;
                if (tbl_target(&a->tab, i, a->homes.tension_mN, &pt) == 0) {
                    trav = pt.travel_um;
                }
                hi = home_cur(a, i) - dir * um_ticks(row.nm_per_tick, trav);
                lo = hi;
            } else {
                hi = a->present[i];
                lo = hi -
                     dir * um_ticks(row.nm_per_tick, row.travel_um[a->info.n_grid - 1u] * 3u / 2u);
            }
            win_set(a, i, lo, hi, 1);
        }
        g = lo - dir * um_ticks(row.nm_per_tick, cfg.slack_margin_um);
        if (dir * (g - a->present[i]) > 0) {
            g = a->present[i]; /* already slacker than the release point */
        }
        set_goal(a, i, g, cfg.v_release, cfg.acc);
        moved = 1;
    }
    return moved;
}

void app_abort(app_t *app)
{
    if (app == NULL || app->state == APP_ST_BOOT) {
        return;
    }
    if (app->req_start && app->req_con && con_pending(&app->con)) {
        (void)con_complete(&app->con, CON_E_ABORTED);
    }
    app->req_start = 0;
    if (app->state == APP_ST_CAL) {
        hom_abort(&app->u.hom);
        return;
    }
    if (app->state == APP_ST_LEARN && app->learn_tendon != LEARN_BASELINE &&
        con_pending(&app->con)) {
        (void)con_complete(&app->con, CON_E_ABORTED);
    }
    if (!app->table_ok) {
        return;
    }
    (void)release_goals(app);
    rep_begin(app, s_released);
    con_report_flash(&app->con, s_reason, s_aborted);
    rep_end(app);
    move_start(app, MOVE_RELEASE);
}

static void learn_begin(app_t *a, uint8_t tendon)
{
    a->learn_tendon = tendon;
    a->learn_n = 0;
    memset(a->u.idle.acc, 0, sizeof a->u.idle.acc);
    memset(a->u.idle.cnt, 0, sizeof a->u.idle.cnt);
    a->t_move = now_ms(a);
    a->state = APP_ST_LEARN;
}

APP_NOINLINE static void move_step(app_t *a)
{
    uint8_t i, arrived = 1;
    uint32_t t = now_ms(a);
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t d = a->present[i] - a->u.hom.out.goal[i];
        if (has(a->servo_absent, i)) {
            continue;
        }
        if (has(a->servo_fresh, i) == 0u || a->goal_due != 0u || d > APP_MOVE_TOL_TICKS ||
            d < -APP_MOVE_TOL_TICKS) {
            arrived = 0;
        }
    }
    if (!arrived) {
        if (t - a->t_move > APP_MOVE_TIMEOUT_MS) {
            rep_app_fault(a, s_servo_stall, CON_E_TIMEOUT, HOM_DEV_SERVO, 0);
            fault_rest(a, t);
            if (a->move_kind == MOVE_HOME) {
                (void)release_goals(a);
            }
        }
        return;
    }
    a->rest_due = 1;
    a->t_rest = (uint16_t)t;
    win_moving(a, 0);
    if (a->move_kind == MOVE_RELEASE) {
        learn_begin(a, LEARN_BASELINE); /* the robot stands straight: capture B0 */
        return;
    }
    rep_begin(a, s_done);
    con_report_flash(&a->con, s_mode, s_home);
    rep_int(a, s_time_ms, (int32_t)(t - a->t_move));
    rep_end(a);
    a->state = APP_ST_IDLE;
    a->led = APP_LED_IDLE;
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
    if (v < 10u * (uint32_t)a->info.noise_cuT || v == 0u) {
        return CON_E_IMPLAUSIBLE;
    }
    for (g = 0; g < a->info.n_grid; g++) {
        if (has(l->grid_mask, g) && ((g < a->learn_grid && l->target_cuT[g] + m >= v) ||
                                     (g > a->learn_grid && l->target_cuT[g] <= v + m))) {
            return CON_E_IMPLAUSIBLE;
        }
    }
    return 0;
}

APP_NOINLINE static void learn_step(app_t *a, const hom_in_t *in)
{
    uint8_t k, first, last, tdn = a->learn_tendon;
    uint32_t v = 0;
    uint32_t t = now_ms(a);
    int8_t rc = 0;
    if (a->learn_tendon == LEARN_BASELINE) {
        first = 0;
        last = a->info.n_sensors;
        if (t - a->t_move < SETTLE_MS) {
            return;
        }
    } else {
        first = a->learn_sensor;
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
                a->u.idle.acc[k][0] += in->sensor[k].b_cuT[0];
                a->u.idle.acc[k][1] += in->sensor[k].b_cuT[1];
                a->u.idle.acc[k][2] += in->sensor[k].b_cuT[2];
                a->u.idle.cnt[k]++;
            }
            if (a->u.idle.cnt[k] < least) {
                least = a->u.idle.cnt[k];
            }
        }
        a->learn_n = least;
        if (least < APP_LEARN_SAMPLES && t - a->t_move > LEARN_WAIT_MS + SETTLE_MS) {
            rc = CON_E_TIMEOUT;
        }
    }
    if (rc == 0 && a->learn_n < APP_LEARN_SAMPLES) {
        return;
    }
    if (rc == 0) {
        int32_t *sum = &a->u.idle.acc[0][0];
        for (k = 0; k < 3u * APP_MAX_SENSORS; k++) {
            sum[k] /= (int32_t)APP_LEARN_SAMPLES; /* sums become averages */
        }
    }
    if (a->learn_tendon == LEARN_BASELINE) {
        if (rc == 0) {
            memcpy(a->u.idle.b0, a->u.idle.acc, sizeof a->u.idle.b0);
            a->have_b0 = 1;
        }
        rep_begin(a, s_done);
        con_report_flash(&a->con, s_mode, s_release);
        rep_int(a, s_time_ms, (int32_t)(t - a->t_move));
        rep_int(a, s_baseline, rc == 0);
        rep_end(a);
        a->state = APP_ST_IDLE;
        a->led = APP_LED_IDLE;
        return;
    }
    if (rc == 0) {
        int32_t d[3];
        for (k = 0; k < 3u; k++) {
            d[k] = a->u.idle.acc[first][k] - a->u.idle.b0[first][k];
        }
        v = hom_norm3(d);
        if (store_learned_load(&a->store, tdn, a->info.table_id, &a->u.idle.rec.learned) != 0) {
            memset(&a->u.idle.rec.learned, 0, sizeof a->u.idle.rec.learned);
        }
        rc = learn_plausible(a, &a->u.idle.rec.learned, v);
    }
    if (rc == 0) {
        a->u.idle.rec.learned.table_id = a->info.table_id;
        a->u.idle.rec.learned.tendon = tdn;
        a->u.idle.rec.learned.n_grid = a->info.n_grid;
        a->u.idle.rec.learned.target_cuT[a->learn_grid] = v;
        a->u.idle.rec.learned.grid_mask |= bit16(a->learn_grid);
        save_queue(a, SAVE_LEARNED);
        rep_begin(a, s_learned);
        rep_int(a, s_tendon, tdn);
        rep_int(a, s_tension_mN, a->info.grid_mN[a->learn_grid]);
        rep_int(a, s_grid, a->learn_grid);
        rep_int(a, s_sensor, first);
        con_report_fixed(&a->con, s_dB_uT, (int32_t)v, 2);
        rep_end(a);
    }
    if (con_pending(&a->con)) {
        (void)con_complete(&a->con, rc);
    }
    a->state = APP_ST_IDLE;
}

/* ---- store ------------------------------------------------------------------- */

/* Records the rest positions once the servos have stopped after a release or
 * a fault, so a power cycle can find the multi-turn position again. */
APP_NOINLINE static void rest_poll(app_t *a)
{
    uint8_t i, changed = 0;
    if (!a->rest_due || !idle_state(a) ||
        (uint16_t)((uint16_t)now_ms(a) - a->t_rest) < REST_DELAY_MS || (a->save_due & SAVE_HOMES) ||
        a->save_now == SAVE_HOMES) {
        return;
    }
    a->rest_due = 0;
    for (i = 0; i < a->info.n_tendons; i++) {
        int32_t rest, d;
        if (has(a->home_now, i) == 0u || has(a->servo_seen, i) == 0u) {
            continue;
        }
        rest = a->present[i] + a->offset[i];
        d = rest - a->homes.t[i].rest_ticks;
        if (d > 2 || d < -2) {
            store_home_set(&a->homes.t[i], a->homes.t[i].home_ticks, rest);
            changed = 1;
        }
    }
    if (changed) {
        save_queue(a, SAVE_HOMES);
    }
}

APP_NOINLINE static void store_task(app_t *a)
{
    uint8_t idle = idle_state(a);
    if (store_busy(&a->store)) {
        int8_t rc = store_poll(&a->store, idle);
        if (rc <= 0) {
            if ((a->save_now == SAVE_SETTINGS ||
                 (a->save_now == SAVE_LEARNED && a->forgetting && a->forget_mask == 0u)) &&
                con_pending(&a->con)) {
                a->forgetting = 0;
                (void)con_complete(&a->con, rc == 0 ? 0 : CON_E_EEPROM);
            } else if (rc < 0) {
                rep_app_fault(a, s_eeprom, CON_E_EEPROM, HOM_DEV_NONE, a->save_now);
            }
            a->save_now = 0;
        }
        return;
    }
    if (idle && a->forget_mask != 0u && !rec_busy(a)) {
        /* `forget`: an empty learned record per tendon, one at a time */
        uint8_t t = 0;
        while (has(a->forget_mask, t) == 0u) {
            t++;
        }
        memset(&a->u.idle.rec.learned, 0, sizeof a->u.idle.rec.learned);
        a->u.idle.rec.learned.table_id = a->info.table_id;
        a->u.idle.rec.learned.tendon = t;
        a->u.idle.rec.learned.n_grid = a->info.n_grid;
        a->forget_mask &= (uint16_t)~bit16(t);
        a->learned_mask &= (uint16_t)~bit16(t);
        save_queue(a, SAVE_LEARNED);
    }
    if (!idle || a->save_due == 0u) {
        return;
    }
    if (a->save_due & SAVE_HOMES) {
        a->save_now = SAVE_HOMES;
        (void)store_save_homes(&a->store, &a->homes);
    } else if (a->save_due & SAVE_HIST) {
        a->save_now = SAVE_HIST;
        (void)store_save_hist(&a->store, &a->u.idle.rec.hist);
    } else if (a->save_due & SAVE_LEARNED) {
        a->save_now = SAVE_LEARNED;
        if (a->u.idle.rec.learned.grid_mask != 0u) {
            a->learned_mask |= bit16(a->u.idle.rec.learned.tendon);
        }
        (void)store_save_learned(&a->store, &a->u.idle.rec.learned);
    } else {
        a->save_now = SAVE_SETTINGS;
        (void)store_save_settings(&a->store, &a->set);
    }
    a->save_due &= (uint8_t)~a->save_now;
}

/* ---- button and LED ----------------------------------------------------------- */

static void short_press(app_t *a)
{
    int8_t rc;
    if (a->state == APP_ST_BOOT) {
        /* pressed before <ready>: the run starts once the bring-up is done,
         * quick or full as it then offers */
        a->req_start = 1;
        a->req_con = 0;
        a->req_btn = 1;
        return;
    }
    if (!idle_state(a)) {
        return; /* a long press aborts */
    }
    a->led = APP_LED_IDLE;
    if (store_busy(&a->store) || rec_busy(a)) {
        a->req_start = 1; /* starts once the EEPROM write in flight is done */
        a->req_con = 0;
        a->req_mode = a->offer_quick ? HOM_MODE_QUICK : HOM_MODE_FULL;
        a->req_tension = 0;
        a->req_tendon = 0;
        return;
    }
    rc = run_start(a, a->offer_quick ? HOM_MODE_QUICK : HOM_MODE_FULL, 0, 0);
    if (rc != 0) {
        rep_app_fault(a, s_refused, rc, HOM_DEV_NONE, 0);
        a->led = APP_LED_FAULT;
    }
}

APP_NOINLINE static void button_poll(app_t *a, uint16_t t)
{
    uint8_t raw = a->io->board->button(a->io->board->ctx) ? 1u : 0u;
    if (raw != a->btn_raw) {
        a->btn_raw = raw;
        a->t_btn_change = t;
    }
    if ((uint16_t)(t - a->t_btn_change) >= APP_DEBOUNCE_MS && a->btn_state != a->btn_raw) {
        a->btn_state = a->btn_raw;
        if (a->btn_state) {
            a->t_btn_down = t;
            a->btn_long_done = 0;
        } else if (!a->btn_long_done) {
            short_press(a);
        }
    }
    if (a->btn_state && !a->btn_long_done && (uint16_t)(t - a->t_btn_down) >= APP_LONG_PRESS_MS) {
        a->btn_long_done = 1;
        app_abort(a);
    }
}

uint8_t app_led_pattern(const app_t *app)
{
    switch (app->state) {
    case APP_ST_BOOT:
        return APP_LED_BOOT;
    case APP_ST_CAL:
    case APP_ST_MOVE:
    case APP_ST_LEARN:
        return APP_LED_RUN;
    case APP_ST_FAULT:
        return APP_LED_FAULT;
    default:
        return app->led == APP_LED_DONE || app->led == APP_LED_FAULT ? app->led : APP_LED_IDLE;
    }
}

APP_NOINLINE static void led_poll(app_t *a, uint32_t t)
{
    uint8_t on;
    uint32_t p;
    switch (app_led_pattern(a)) {
    case APP_LED_BOOT:
        on = (uint8_t)((t / 100u) & 1u);
        break;
    case APP_LED_RUN:
        on = (uint8_t)((t / 125u) & 1u);
        break;
    case APP_LED_DONE:
        on = 1;
        break;
    case APP_LED_FAULT:
        p = t % 1000u;
        on = (uint8_t)(p < 300u && ((p / 50u) & 1u) == 0u);
        break;
    default:
        p = t % 2000u;
        on = (uint8_t)(p < 50u || (a->offer_quick && p >= 200u && p < 250u));
        break;
    }
    if (on != a->led_on || a->loops == 0u) {
        a->led_on = on;
        a->io->board->led(a->io->board->ctx, on);
    }
}

/* ---- superloop ------------------------------------------------------------------ */

/* The console in realtime mode while anything moves (output never waits;
 * docs/console.md), and the losses reported: console bytes lost to a full
 * receive buffer at once, report lines dropped once nothing moves. */
APP_NOINLINE static void console_poll(app_t *a)
{
    uint8_t moving = (uint8_t)(a->state == APP_ST_CAL || a->state == APP_ST_MOVE);
    uint16_t n = a->io->board->rx_lost != NULL ? a->io->board->rx_lost(a->io->board->ctx) : 0u;
    con_set_realtime(&a->con, moving);
    if (n != a->rx_lost) {
        rep_begin(a, s_overrun);
        rep_int(a, s_bytes, (uint16_t)(n - a->rx_lost));
        rep_int(a, s_total, n);
        rep_end(a);
        a->rx_lost = n;
    }
    if (!moving && con_dropped(&a->con) != a->rep_dropped) {
        a->rep_dropped = con_dropped(&a->con);
        rep_begin(a, s_dropped);
        rep_int(a, s_reports, a->rep_dropped);
        rep_end(a);
    }
    (void)con_poll(&a->con, (uint16_t)now_ms(a));
}

int8_t app_poll(app_t *app)
{
    app_t *a = app;
    hom_in_t in;
    uint32_t t0 = now_us(a), t = now_ms(a), dt;
    a->io->board->wdt_kick(a->io->board->ctx);
    if (con_rt_take(a->io->rt)) {
        app_abort(a);
    }
    button_poll(a, (uint16_t)t);
    memset(&in, 0, sizeof in);
    if (a->sens.n > 0u) {
        (void)icm_set_poll(&a->sens, t0);
        sensors_take(a, &in);
    }
    if (a->state == APP_ST_BOOT) {
        boot_poll(a);
    }
    servo_poll(a);
    if (a->req_start && a->state != APP_ST_BOOT && store_busy(&a->store) == 0u && !rec_busy(a)) {
        int8_t rc;
        a->req_start = 0;
        if (a->req_btn) {
            a->req_btn = 0;
            a->req_mode = a->offer_quick ? HOM_MODE_QUICK : HOM_MODE_FULL;
            a->req_tension = 0;
            a->req_tendon = 0;
        }
        rc = run_start(a, a->req_mode, a->req_tension, a->req_tendon);
        if (a->req_con && con_pending(&a->con)) {
            (void)con_complete(&a->con, rc);
        } else if (rc != 0) {
            rep_app_fault(a, s_refused, rc, HOM_DEV_NONE, 0);
        }
    }
    if (a->reset_release && a->state == APP_ST_IDLE) {
        a->reset_release = 0;
        (void)release_goals(a);
        rep_begin(a, s_released);
        con_report_flash(&a->con, s_reason, s_reset);
        rep_end(a);
        move_start(a, MOVE_RELEASE);
    }
    if (a->auto_release && a->state == APP_ST_IDLE && a->table_ok) {
        (void)release_goals(a);
        rep_begin(a, s_released);
        con_report_flash(&a->con, s_reason, s_servo_error);
        rep_int(a, s_id, a->auto_release);
        rep_end(a);
        a->auto_release = 0;
        move_start(a, MOVE_RELEASE);
    }
    switch (a->state) {
    case APP_ST_CAL:
        cal_step(a, &in);
        break;
    case APP_ST_MOVE:
        move_step(a);
        break;
    case APP_ST_LEARN:
        learn_step(a, &in);
        break;
    default:
        break;
    }
    console_poll(a);
    rest_poll(a);
    store_task(a);
    led_poll(a, t);
    a->loops++;
    dt = now_us(a) - t0;
    if (dt > a->loop_max_us) {
        a->loop_max_us = dt;
    }
    return (int8_t)a->state;
}

/* ---- console handlers ------------------------------------------------------------ */

/* Console output waits for the UART0 ring (128 bytes, 11 ms per ring at
 * 115200): listings of several lines would hold the loop for tens of ms,
 * longer than the homing's servo deadline, so they wait until nothing moves. */
static int8_t quiet_needed(const app_t *a)
{
    return (a->state == APP_ST_IDLE || a->state == APP_ST_FAULT) ? 0 : CON_E_BUSY;
}

static int8_t h_version(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    (void)con;
    (void)args;
    rep_begin(a, s_version);
    con_report_flash(&a->con, s_name, s_hallhome);
    if (a->io->version_f != NULL) {
        con_report_flash(&a->con, s_version, a->io->version_f);
    }
    if (a->io->board_f != NULL) {
        con_report_flash(&a->con, s_board, a->io->board_f);
    }
    if (a->table_ok) {
        con_report_str(&a->con, s_table, a->info.name);
        rep_hex(a, s_table_id, a->info.table_id);
        rep_int(a, s_tendons, a->info.n_tendons);
        rep_int(a, s_sensors, a->info.n_sensors);
    } else {
        con_report_flash(&a->con, s_table, s_none);
    }
    rep_end(a);
    return 0;
}

static int8_t h_status(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    uint8_t i;
    (void)con;
    (void)args;
    rep_begin(a, s_status);
    rep_word(a, s_state, STATE_WORDS, a->state);
    if (a->table_ok) {
        con_report_str(&a->con, s_table, a->info.name);
    } else {
        con_report_flash(&a->con, s_table, s_none);
    }
    rep_int(a, s_sensors, icm_set_ready_count(&a->sens));
    rep_int(a, s_servos, a->n_servo_found);
    rep_hex(a, s_homes, a->homes.valid_mask);
    rep_hex(a, s_homes_now, a->home_now);
    rep_int(a, s_rehome, a->offer_quick);
    rep_int(a, s_tension_mN, a->homes.tension_mN);
    rep_int(a, s_count, (int32_t)a->homes.cal_count);
    rep_word(a, s_fault, s_fault_words, a->last_fault);
    rep_int(a, s_learned, a->learned_mask);
    rep_int(a, s_baseline, a->have_b0);
    rep_int(a, s_saving, store_busy(&a->store) || a->save_due != 0u);
    rep_int(a, s_loop_max_us, (int32_t)a->loop_max_us);
    rep_int(a, s_loops, (int32_t)a->loops);
    rep_end(a);
    for (i = 0; i < a->info.n_tendons; i++) {
        if (has(a->homes.valid_mask, i) == 0u) {
            continue;
        }
        rep_begin(a, s_home);
        rep_int(a, s_tendon, i);
        rep_int(a, s_home, a->homes.t[i].home_ticks);
        rep_int(a, s_rest, a->homes.t[i].rest_ticks);
        rep_int(a, s_usable, has(a->home_now, i));
        if (has(a->home_now, i)) {
            rep_int(a, s_now, home_cur(a, i));
        }
        rep_end(a);
    }
    return 0;
}

static int8_t h_sensors(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    if (quiet_needed(a) != 0) {
        return CON_E_BUSY;
    }
    uint8_t k;
    (void)con;
    (void)args;
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    for (k = 0; k < a->info.n_sensors; k++) {
        icm_diag_t d;
        (void)icm_set_diag(&a->sens, k, &d);
        rep_begin(a, s_sensor);
        rep_int(a, s_index, k);
        rep_int(a, s_ch, d.channel);
        rep_int(a, s_addr, d.addr);
        rep_int(a, s_ok, d.state == ICM_SET_S_RUN);
        rep_int(a, s_who, d.who_am_i);
        rep_int(a, s_mag, d.mag_ready);
        con_report_fixed(&a->con, s_rate_Hz, d.rate_dhz, 1);
        con_report_fixed(&a->con, s_bx_uT, d.field_cuT[0], 2);
        con_report_fixed(&a->con, s_by_uT, d.field_cuT[1], 2);
        con_report_fixed(&a->con, s_bz_uT, d.field_cuT[2], 2);
        rep_int(a, s_ovf, d.overflow_count);
        rep_int(a, s_err, d.error_count);
        rep_int(a, s_last_err, d.last_err);
        rep_int(a, s_reinits, d.reinits);
        rep_end(a);
    }
    return 0;
}

static int8_t h_servos(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    (void)con;
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    if (quiet_needed(a) != 0) {
        return CON_E_BUSY;
    }
    if ((args->given & 1u) && args->v[0] != 0) {
        servo_lines(a, 0); /* pos, err: the live cycle keeps both fresh */
        return 0;
    }
    if (!idle_state(a) || rec_busy(a)) {
        return CON_E_BUSY; /* the bring-up reuses the record's storage */
    }
    a->boot_con = 1;
    a->boot_step = 0;
    a->state = APP_ST_BOOT;
    return CON_PENDING;
}

static int8_t start_or_defer(app_t *a, uint8_t mode, uint16_t tension, uint8_t tendon)
{
    if (idle_state(a) && (store_busy(&a->store) || rec_busy(a))) {
        a->req_start = 1;
        a->req_con = 1;
        a->req_mode = mode;
        a->req_tension = tension;
        a->req_tendon = tendon;
        return CON_PENDING;
    }
    return run_start(a, mode, tension, tendon);
}

static int8_t h_cal(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    uint16_t tension = (args->given & 1u) ? (uint16_t)args->v[0] : 0u;
    (void)con;
    if (args->given & 2u) {
        if (a->table_ok && args->v[1] >= a->info.n_tendons) {
            return CON_E_BAD_TENDON;
        }
        return start_or_defer(a, HOM_MODE_SINGLE, tension, (uint8_t)args->v[1]);
    }
    return start_or_defer(a, HOM_MODE_FULL, tension, 0);
}

static int8_t h_rehome(con_t *con, const con_args_t *args, void *ctx)
{
    (void)con;
    (void)args;
    return start_or_defer(ctx, HOM_MODE_QUICK, 0, 0);
}

static int8_t h_home(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    hom_config_t cfg;
    uint8_t i;
    int8_t e;
    (void)con;
    (void)args;
    if (!idle_state(a)) {
        return CON_E_BUSY;
    }
    e = check_devices(a);
    if (e != 0) {
        return e;
    }
    e = homes_usable(a);
    if (e != 0) {
        return e;
    }
    hom_config_default(&cfg);
    for (i = 0; i < a->info.n_tendons; i++) {
        set_goal(a, i, home_cur(a, i), cfg.v_final, cfg.acc);
    }
    move_start(a, MOVE_HOME);
    return 0;
}

static int8_t h_release(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    (void)con;
    (void)args;
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    if (a->state == APP_ST_BOOT) {
        return CON_E_BUSY;
    }
    if (!idle_state(a)) {
        app_abort(a);
        return 0;
    }
    (void)release_goals(a);
    move_start(a, MOVE_RELEASE);
    return 0;
}

static int8_t h_learn(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    uint8_t g, t = (uint8_t)args->v[0];
    (void)con;
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    if (!idle_state(a) || (a->save_due & (SAVE_HIST | SAVE_LEARNED)) != 0u ||
        a->save_now == SAVE_HIST || a->save_now == SAVE_LEARNED) {
        return CON_E_BUSY;
    }
    if (t >= a->info.n_tendons) {
        return CON_E_BAD_TENDON;
    }
    for (g = 0; g < a->info.n_grid && a->info.grid_mN[g] != (uint16_t)args->v[1]; g++) {
    }
    if (g >= a->info.n_grid) {
        return CON_E_TENSION_RANGE; /* learned targets sit on the table's grid */
    }
    if (!a->have_b0) {
        return CON_E_NOT_HOMED; /* no straight-pose baseline yet: `release` first */
    }
    {
        icm_diag_t d;
        tbl_tendon_t row;
        (void)tbl_tendon(&a->tab, t, &row);
        a->learn_sensor = row.sensor;
        (void)icm_set_diag(&a->sens, row.sensor, &d);
        if (d.state != ICM_SET_S_RUN) {
            return CON_E_SENSOR_FAULT;
        }
    }
    a->learn_grid = g;
    learn_begin(a, t);
    return CON_PENDING;
}

/* `forget T|all`: the learned targets of tendon T, or of every tendon, are
 * erased (empty records saved); the compiled table's targets apply again. */
static int8_t h_forget(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    const char *w = args->s[0];
    uint16_t m = 0;
    (void)con;
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    if (!idle_state(a) || rec_busy(a) || a->forget_mask != 0u) {
        return CON_E_BUSY;
    }
    if (strcmp(w, "all") == 0) {
        m = all_mask(a);
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
        m = bit16(t);
    }
    a->forget_mask = m & a->learned_mask;
    a->forgetting = (uint8_t)(a->forget_mask != 0u);
    return a->forgetting ? CON_PENDING : 0;
}

static int8_t h_table(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    if (quiet_needed(a) != 0) {
        return CON_E_BUSY;
    }
    char buf[TBL_MAX_GRID * 12u + 1u];
    uint8_t i, g, pos;
    (void)con;
    (void)args;
    if (!a->table_ok) {
        return CON_E_NO_TABLE;
    }
    rep_begin(a, s_table);
    con_report_str(&a->con, s_name, a->info.name);
    rep_hex(a, s_table_id, a->info.table_id);
    rep_int(a, s_tendons, a->info.n_tendons);
    rep_int(a, s_sensors, a->info.n_sensors);
    pos = 0;
    buf[0] = '\0';
    for (g = 0; g < a->info.n_grid; g++) {
        list_add(buf, sizeof buf, &pos, a->info.grid_mN[g], '\0');
    }
    con_report_str(&a->con, s_grid_mN, buf);
    rep_int(a, s_default_mN, a->info.default_mN);
    rep_int(a, s_noise_cuT, a->info.noise_cuT);
    rep_end(a);
    for (i = 0; i < a->info.n_tendons; i++) {
        tbl_tendon_t row, eff;
        (void)tbl_tendon(&a->tab, i, &row);
        (void)tbl_tendon(&a->htab, i, &eff);
        rep_begin(a, s_tendon);
        rep_int(a, s_tendon, i);
        rep_int(a, s_id, row.servo_id);
        rep_int(a, s_dir, row.pull_dir);
        rep_int(a, s_segment, row.segment);
        rep_int(a, s_sensor, row.sensor);
        rep_int(a, s_limit_um, (int32_t)row.travel_limit_um);
        pos = 0;
        buf[0] = '\0';
        for (g = 0; g < a->info.n_grid; g++) {
            list_add(buf, sizeof buf, &pos, (int32_t)eff.target_cuT[g],
                     eff.target_cuT[g] != row.target_cuT[g] ? '*' : '\0');
        }
        con_report_str(&a->con, s_target_cuT, buf);
        rep_end(a);
    }
    return 0;
}

static int8_t h_history(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    if (quiet_needed(a) != 0) {
        return CON_E_BUSY;
    }
    uint8_t n, age, i, pos;
    char buf[TBL_MAX_TENDONS * 12u + 1u];
    store_hist_t e;
    (void)con;
    (void)args;
    n = store_hist_count(&a->store);
    for (age = 0; age < n; age++) {
        if (store_hist_get(&a->store, age, &e) != 0) {
            break;
        }
        rep_begin(a, s_hist);
        rep_int(a, s_age, age);
        rep_int(a, s_count, (int32_t)e.cal_count);
        rep_hex(a, s_table_id, e.table_id);
        rep_int(a, s_tension_mN, e.tension_mN);
        pos = 0;
        buf[0] = '\0';
        for (i = 0; i < e.n_tendons && i < TBL_MAX_TENDONS; i++) {
            list_add(buf, sizeof buf, &pos, e.home_ticks[i], has(e.valid_mask, i) ? 0 : '?');
        }
        con_report_str(&a->con, s_homes, buf);
        rep_end(a);
    }
    return 0;
}

static void setting_line(app_t *a, uint8_t id)
{
    char buf[24];
    store_setting_info_t inf;
    (void)store_setting_info(&a->store, id, &inf);
    rep_begin(a, s_setting);
    (void)store_setting_text(&a->store, id, 0, buf, sizeof buf);
    con_report_str(&a->con, s_name, buf);
    rep_int(a, s_value, a->set.v[id]);
    (void)store_setting_text(&a->store, id, 1, buf, sizeof buf);
    con_report_str(&a->con, s_unit, buf);
    rep_int(a, s_min, inf.min);
    rep_int(a, s_max, inf.max);
    rep_int(a, s_default, inf.def);
    rep_end(a);
}

static int8_t find_setting(app_t *a, const con_args_t *args)
{
    const char *n = args->s[0];
    return store_setting_find(&a->store, n, (uint8_t)strlen(n));
}

static int8_t h_get(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    if (quiet_needed(a) != 0) {
        return CON_E_BUSY;
    }
    uint8_t id;
    (void)con;
    if (args->given & 1u) {
        int8_t f = find_setting(a, args);
        if (f < 0) {
            return CON_E_UNKNOWN_SETTING;
        }
        setting_line(a, (uint8_t)f);
        return 0;
    }
    for (id = 0; id < STORE_SETTING_COUNT; id++) {
        setting_line(a, id);
    }
    return 0;
}

static int8_t h_set(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    int8_t f, rc;
    (void)con;
    f = find_setting(a, args);
    if (f < 0) {
        return CON_E_UNKNOWN_SETTING;
    }
    if ((a->save_due & SAVE_SETTINGS) || a->save_now == SAVE_SETTINGS) {
        return CON_E_BUSY; /* the record is being written */
    }
    if (f == STORE_SET_CAL_TENSION && a->table_ok &&
        (args->v[1] < a->info.grid_mN[0] || args->v[1] > a->info.grid_mN[a->info.n_grid - 1u])) {
        return CON_E_TENSION_RANGE; /* every press would be refused */
    }
    rc = store_setting_set(&a->store, &a->set, (uint8_t)f, args->v[1]);
    if (rc != 0) {
        return CON_E_SETTING_RANGE;
    }
    if (f == STORE_SET_TARGET_MODE) {
        a->amb_ok = 0; /* the next absolute calibration captures the ambient again */
    }
    return 0;
}

static int8_t h_save(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    (void)con;
    (void)args;
    if (!idle_state(a) || (a->save_due & SAVE_SETTINGS) || a->save_now == SAVE_SETTINGS) {
        return CON_E_BUSY; /* EEPROM writes happen only while nothing moves */
    }
    save_queue(a, SAVE_SETTINGS);
    return CON_PENDING;
}

static int8_t h_reboot(con_t *con, const con_args_t *args, void *ctx)
{
    app_t *a = ctx;
    (void)con;
    if (!idle_state(a) || rec_busy(a)) {
        return CON_E_BUSY;
    }
    a->reboot_id = (uint8_t)args->v[0];
    a->reboot_req = 1;
    return CON_PENDING;
}

const con_handler_fn app_handlers[CON_CMD_COUNT] CON_FLASH = {
    [CON_CMD_HELP] = NULL, /* built into the console */
    [CON_CMD_VERSION] = h_version, [CON_CMD_STATUS] = h_status,   [CON_CMD_SENSORS] = h_sensors,
    [CON_CMD_SERVOS] = h_servos,   [CON_CMD_CAL] = h_cal,         [CON_CMD_REHOME] = h_rehome,
    [CON_CMD_HOME] = h_home,       [CON_CMD_RELEASE] = h_release, [CON_CMD_LEARN] = h_learn,
    [CON_CMD_TABLE] = h_table,     [CON_CMD_HISTORY] = h_history, [CON_CMD_GET] = h_get,
    [CON_CMD_SET] = h_set,         [CON_CMD_SAVE] = h_save,       [CON_CMD_REBOOT] = h_reboot,
    [CON_CMD_FORGET] = h_forget,
};
