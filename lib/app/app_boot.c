/*
 * app_boot: the boot room. app_init() wires the modules, loads the settings,
 * the table, the stored homes and learned targets, and prints `<boot ...>`;
 * the bring-up then pings and sets up the servos (extended-position mode),
 * starts the sensors, waits for every device or APP_PREFLIGHT_MS, names each
 * missing one and prints `<ready ...>` with the quick re-home offer. The same
 * bring-up runs again for `servos` and after a servo reboot.
 */
#include <string.h>

#include "app/app_priv.h"

/* The table, once, into an app that app_init() has just cleared (table_ok 0,
 * info all zero until the table passes its checks). */
static void load_table(app_t *a)
{
    uint8_t i;
    a->tab.table = a->io->table;
    a->tab.copy = a->io->table_copy;
    a->htab.table = a->io->table;
    a->htab.copy =
        a->io->table_copy_learned != NULL ? a->io->table_copy_learned : a->io->table_copy;
    if (a->io->table == NULL || tbl_check(&a->tab) != 0 || tbl_info(&a->tab, &a->info) != 0 ||
        a->info.n_sensors > APP_MAX_SENSORS || a->info.n_tendons > APP_MAX_TENDONS) {
        memset(&a->info, 0, sizeof a->info);
        return;
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        tbl_tendon_head_t row;
        (void)tbl_tendon_head(&a->tab, i, &row);
        a->bus.ids[i] = row.servo_id;
    }
    a->table_ok = 1;
}

uint16_t app_grid_mN(const app_t *a, uint8_t g)
{
    return tbl_grid_mN(&a->tab, g);
}

uint8_t app_in_grid(const app_t *a, uint16_t mN)
{
    return (uint8_t)(a->info.n_grid != 0u && mN >= app_grid_mN(a, 0) &&
                     mN <= app_grid_mN(a, (uint8_t)(a->info.n_grid - 1u)));
}

/* app_init() starts in the state and LED pattern of a cleared app_t. */
typedef char app_boot_first_t[(APP_ST_BOOT == 0 && APP_LED_BOOT == 0) ? 1 : -1];

int8_t app_init(app_t *app, const app_io_t *io)
{
    dxl_config dc;
    uint8_t t;
    if (app == NULL || io == NULL ||
        (!APP_BOARD_FIXED &&
         (io->board == NULL || io->board->now_ms == NULL || io->board->now_us == NULL ||
          io->board->button == NULL || io->board->led == NULL || io->board->wdt_kick == NULL)) ||
        (io->sensor_bus == NULL && !ICM_BUS_FIXED) || (io->eeprom == NULL && !STORE_EE_FIXED) ||
        (io->console == NULL && !CON_IO_FIXED) || io->con_copy == NULL || io->store_copy == NULL ||
        io->rt == NULL || io->table_copy == NULL) {
        return APP_E_ARG;
    }
    memset(app, 0, sizeof *app);
    app->io = io;
    (void)con_init(&app->cmd.con, io->console, NULL, NULL, io->con_copy, io->rt);
    (void)store_init(&app->rec.store, io->eeprom, io->store_copy);
    (void)store_settings_load(&app->rec.store, &app->rec.set);
    load_table(app);
    app_win_check(app);
    app->run.reset_release =
        (uint8_t)(APP_WIN(app) != NULL && (APP_WIN(app)->moving || io->release_at_boot) &&
                  app->table_ok);
    hom_init(&app->u.hom, NULL);
    dxl_config_default(&dc, app_bus_baud(app), io->servo_bits != 0u ? io->servo_bits : 10u);
    dxl_master_init(&app->bus.dxl, &io->servo_port, &dc);
    app->rec.homes_rc = STORE_E_EMPTY;
    if (app->table_ok) {
        app->rec.homes_rc = store_homes_load(&app->rec.store, app->info.table_id, &app->rec.homes);
        if (app->rec.homes_rc != 0 || app->rec.homes.n_tendons != app->info.n_tendons) {
            memset(&app->rec.homes, 0, sizeof app->rec.homes);
        }
        for (t = 0; t < app->info.n_tendons; t++) {
            store_learned_t l;
            if (store_learned_load(&app->rec.store, t, app->info.table_id, &l) == 0 &&
                l.grid_mask != 0u) {
                app->learn.mask |= app_bit16(t);
            }
        }
    }
    /* state APP_ST_BOOT, LED APP_LED_BOOT: as memset() left them */
    app->boot.t_start = app_now_ms(app);
    app_rep_begin(app, app_w_boot);
    app_rep_ident(app);
    if (io->reset_f != NULL) {
        con_report_flash(&app->cmd.con, app_w_reset, io->reset_f);
    }
    app_rep_end(app);
    return 0;
}

/* Step 0 of the bring-up (state APP_ST_BOOT) ends: the devices' bring-up
 * starts (step 1). */
static void boot_start(app_t *a)
{
    dxl_bringup_config bc;
    a->boot.t_start = app_now_ms(a);
    if (!a->table_ok) {
        return;
    }
    app_sense_start(a);
    memset(&bc, 0, sizeof bc);
    bc.profile_velocity = 0;
    bc.profile_acceleration = 0;
    bc.reboot_on_hw_error = 0;
    bc.reboot_wait_us = 500000u;
    app_bus_stop(a);
    app_learn_drop_baseline(a); /* the bring-up reuses the baseline's storage */
    (void)dxl_bringup_start(&a->u.bring, &a->bus.dxl, a->bus.ids, a->info.n_tendons, &bc);
    a->boot.step = 1;
}

/* The bring-up's entry for servo id, or NULL. */
APP_NOINLINE const dxl_servo_info *app_boot_servo_info(const app_t *a, uint8_t id)
{
    uint8_t j;
    for (j = 0; j < a->u.bring.n; j++) {
        if (a->u.bring.servo[j].id == id) {
            return &a->u.bring.servo[j];
        }
    }
    return NULL;
}

static void boot_finish(app_t *a)
{
    a->boot.n_servos = app_bus_found(a);
    a->boot.n_sensors = app_sense_settled(a);
    (void)app_rep_missing(a);
    /* Positions not read by the bring-up (it stopped on a missing servo)
     * arrive with the first cycles; homes are recovered once they have. */
    a->boot.step = 2;
}

static const app_field_t ready_fields[] CON_FLASH = {
    APP_FIELD(sensors, app_t, boot.n_sensors, APP_F_U),
    APP_FIELD(sensors_expected, app_t, info.n_sensors, APP_F_U),
    APP_FIELD(servos, app_t, boot.n_servos, APP_F_U),
    APP_FIELD(servos_expected, app_t, info.n_tendons, APP_F_U),
};

APP_NOINLINE static void boot_ready(app_t *a)
{
    int8_t rc;
    a->boot.recover_rc = app_rec_recover(a);
    app_win_recover(a); /* after the homes, which come first */
    a->boot.recovered = (uint8_t)(a->table_ok && a->rec.home_now != 0u &&
                                  a->rec.home_now == app_all_mask(a) && a->bus.absent == 0u);
    app_boot_offer(a);
    app_rep_begin(a, app_w_ready);
    app_rep_table(a, 1); /* table_id */
    APP_REP_FIELDS(a, a, ready_fields);
    if (a->rec.homes_rc == 0) {
        con_report_flash(&a->cmd.con, app_w_homes,
                         a->boot.recover_rc == STORE_E_MOVED ? app_w_moved : app_w_stored);
        app_rep_int(a, app_w_count, (int32_t)a->rec.homes.cal_count);
    } else {
        con_report_flash(&a->cmd.con, app_w_homes,
                         a->rec.homes_rc == STORE_E_OTHER_TABLE ? app_w_other_table : app_w_none);
    }
    app_rep_u8(a, app_w_rehome, a->boot.offer_quick);
    app_rep_end(a);
    a->state = APP_ST_IDLE;
    a->boot.step = 3;
    rc = app_run_rebooted(a); /* 0 when no servo was rebooted */
    if (rc != CON_PENDING && a->boot.con_wait && con_pending(&a->cmd.con) &&
        !(a->run.req_start && a->run.req_con)) {
        if (rc == 0) {
            (void)app_cmd_list(a, APP_LIST_SERVOS, 1); /* answered after its lines */
        } else {
            (void)con_complete(&a->cmd.con, rc);
        }
    }
    if (rc != CON_PENDING) {
        a->boot.con_wait = 0;
    }
}

void app_boot_homes_new(app_t *a)
{
    a->boot.recover_rc = 0;
    a->boot.recovered = 0;
    a->boot.offer_quick = 0;
}

APP_NOINLINE void app_boot_offer(app_t *a)
{
    a->boot.offer_quick = (uint8_t)(a->boot.recovered &&
                                    a->rec.homes.tension_mN == a->rec.set.v[STORE_SET_CAL_TENSION]);
}

void app_boot_again(app_t *a)
{
    a->boot.t_start = app_now_ms(a);
    a->boot.con_wait = 1;
    a->boot.step = 0;
    a->state = APP_ST_BOOT;
}

APP_NOINLINE void app_boot_poll(app_t *a)
{
    uint32_t t = app_now_ms(a);
    uint32_t el = t - a->boot.t_start; /* t_start changes only on the way out */
    if (a->boot.step == 0u) {
        if (a->bus.reboot_id != 0u && el < APP_SERVO_REBOOT_MS) {
            return;
        }
        if (dxl_busy(&a->bus.dxl)) {
            (void)dxl_poll(&a->bus.dxl); /* the early release still on the wire */
            return;
        }
        /* reset_release 1: owed; then velocity and goals in turn, each
         * APP_EARLY_COPIES times (a sync write has no reply); once
         * APP_EARLY_SENT, the bring-up waits APP_EARLY_RELEASE_MS for the
         * tendons to slacken (its torque cycle would stop them where they
         * stand) */
        if (a->run.reset_release >= 1u && a->run.reset_release < APP_EARLY_SENT) {
            if (app_run_early_release(a, a->run.reset_release)) {
                a->run.reset_release++;
                a->boot.t_start = t;
                return;
            }
            a->run.reset_release = APP_EARLY_DONE; /* nothing known to release early */
        }
        if (a->run.reset_release == APP_EARLY_SENT && el < APP_EARLY_RELEASE_MS) {
            return;
        }
        boot_start(a);
        if (!a->table_ok) {
            boot_ready(a);
        }
        return;
    }
    if (a->boot.step == 1u) {
        int8_t rc = dxl_bringup_poll(&a->u.bring);
        if (rc == -DXL_E_MISSING && a->bus.absent == 0u) {
            /* set up the servos that answered; the missing ones stay named */
            uint8_t ids[APP_MAX_TENDONS], i, n = 0;
            for (i = 0; i < a->info.n_tendons; i++) {
                if (i < a->u.bring.n && a->u.bring.servo[i].present) {
                    ids[n++] = a->bus.ids[i];
                } else {
                    a->bus.absent |= app_bit16(i);
                }
            }
            if (n > 0u &&
                dxl_bringup_start(&a->u.bring, &a->bus.dxl, ids, n, &a->u.bring.cfg) > 0) {
                return;
            }
        }
        if (rc > 0 && el < APP_PREFLIGHT_MS) {
            return;
        }
        if (rc > 0) {
            dxl_abort(&a->bus.dxl);
        }
        if (!icm_set_settled(&a->sense.set) && el < APP_PREFLIGHT_MS) {
            return;
        }
        boot_finish(a);
        return;
    }
    /* step 2: every found servo's position and Bus Watchdog, then ready */
    if (((a->bus.seen | a->bus.absent) != app_all_mask(a) || a->bus.wdog_step != 0u ||
         a->bus.txn == APP_TX_WDOG) &&
        el < APP_PREFLIGHT_MS) {
        return;
    }
    boot_ready(a);
}
