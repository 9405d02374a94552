/*
 * app_report: the report lines of every room and the flash words they use
 * (app_priv.h). Reports are written through the console (con_report_*), which
 * drops them rather than wait while anything moves.
 */
#include <string.h>

#include "app/app_priv.h"

#define APP_W_DEF(id)        const char app_w_##id[] CON_FLASH = #id;
#define APP_WS_DEF(id, text) const char app_w_##id[] CON_FLASH = text;
APP_WORDS(APP_W_DEF, APP_WS_DEF)
#undef APP_W_DEF
#undef APP_WS_DEF

void app_rep_begin(app_t *a, const char *kind)
{
    con_report_begin(&a->cmd.con, kind);
}

void app_rep_int(app_t *a, const char *key, int32_t v)
{
    con_report_int(&a->cmd.con, key, v);
}

/* 8-bit values: no zero extension at each call */
void app_rep_u8(app_t *a, const char *key, uint8_t v)
{
    con_report_int(&a->cmd.con, key, v);
}

void app_rep_u16(app_t *a, const char *key, uint16_t v)
{
    con_report_int(&a->cmd.con, key, v);
}

void app_rep_tendon(app_t *a, uint8_t i)
{
    app_rep_u8(a, app_w_tendon, i);
    app_rep_u8(a, app_w_id, a->bus.ids[i]);
}

void app_rep_end(app_t *a)
{
    con_report_end(&a->cmd.con);
}

/* Hex words (table_id) without a printf. */
void app_rep_hex(app_t *a, const char *key, uint32_t v)
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
    con_report_str(&a->cmd.con, key, buf);
}

void app_rep_fields(app_t *a, const void *base, const app_field_t *f, uint8_t n)
{
    for (; n > 0u; n--, f++) {
        app_field_t e;
        const uint8_t *p;
        int32_t v;
        uint8_t size;
        APP_CON_COPY(a, &e, f, sizeof e);
        p = (const uint8_t *)base + e.off;
        size = (uint8_t)(e.fmt & 7u);
        if (size == 1u) {
            v = (e.fmt & APP_F_S) ? (int32_t)(int8_t)*p : (int32_t)*p;
        } else if (size == 2u) {
            uint16_t u;
            memcpy(&u, p, sizeof u);
            v = (e.fmt & APP_F_S) ? (int32_t)(int16_t)u : (int32_t)u;
        } else {
            memcpy(&v, p, sizeof v);
        }
        if (e.fmt & APP_F_HEX) {
            app_rep_hex(a, e.key, (uint32_t)v);
        } else {
            con_report_fixed(&a->cmd.con, e.key, v, (uint8_t)((e.fmt >> 4) & 3u));
        }
    }
}

/* name=hallhome version=... board=... (those the board names) */
void app_rep_ident(app_t *a)
{
    con_report_flash(&a->cmd.con, app_w_name, app_w_hallhome);
    if (a->io->version_f != NULL) {
        con_report_flash(&a->cmd.con, app_w_version, a->io->version_f);
    }
    if (a->io->board_f != NULL) {
        con_report_flash(&a->cmd.con, app_w_board, a->io->board_f);
    }
}

void app_rep_name(app_t *a, const char *key)
{
    char name[TBL_NAME_LEN];
    (void)tbl_name(&a->tab, name);
    con_report_str(&a->cmd.con, key, name);
}

/* table=<name> and the first n fields of app_info_fields, or table=none */
void app_rep_table(app_t *a, uint8_t n)
{
    if (a->table_ok) {
        app_rep_name(a, app_w_table);
        app_rep_fields(a, &a->info, app_info_fields, n);
    } else {
        con_report_flash(&a->cmd.con, app_w_table, app_w_none);
    }
}

/* A fault the app itself detects (moves, learn, EEPROM), in the same shape
 * as the homing's: reason word, console error code, device. */
void app_rep_fault(app_t *a, const char *reason_f, int8_t err, uint8_t dev, uint8_t index)
{
    app_rep_begin(a, app_w_fault);
    con_report_flash(&a->cmd.con, app_w_reason, reason_f);
    app_rep_int(a, app_w_error, -err);
    app_rep_word(a, app_w_dev, app_w_dev_words, dev);
    app_rep_u8(a, app_w_index, index);
    app_rep_end(a);
}

static const app_field_t missing_fields[] CON_FLASH = {
    APP_FIELD(ch, icm_diag_t, channel, APP_F_U),
    APP_FIELD(addr, icm_diag_t, addr, APP_F_U),
    APP_FIELD(err, icm_diag_t, last_err, APP_F_S),
};

/* table_id, tendons, sensors of the table in use (tbl_info_t) */
const app_field_t app_info_fields[3] CON_FLASH = {
    APP_FIELD(table_id, tbl_info_t, table_id, APP_F_HEX),
    APP_FIELD(tendons, tbl_info_t, n_tendons, APP_F_U),
    APP_FIELD(sensors, tbl_info_t, n_sensors, APP_F_U),
};

/* One `<missing ...>` per sensor that is not sampling and per servo that is
 * absent or reports a hardware error. Returns CON_E_SENSOR_FAULT when a
 * sensor is missing, else CON_E_SERVO_FAULT when a servo is, else 0. */
int8_t app_rep_missing(app_t *a)
{
    uint8_t i;
    int8_t rc = 0;
    for (i = 0; i < a->info.n_sensors; i++) {
        icm_diag_t d;
        (void)icm_set_diag(&a->sense.set, i, &d);
        if (d.state != ICM_SET_S_RUN) {
            app_rep_begin(a, app_w_missing);
            con_report_flash(&a->cmd.con, app_w_dev, app_w_sensor);
            app_rep_u8(a, app_w_index, i);
            APP_REP_FIELDS(a, &d, missing_fields);
            app_rep_end(a);
            rc = CON_E_SENSOR_FAULT;
        }
    }
    for (i = 0; i < a->info.n_tendons; i++) {
        uint8_t hw = a->bus.hw_err[i];
        if (app_has(a->bus.absent, i) || hw != 0u) {
            app_rep_begin(a, app_w_missing);
            con_report_flash(&a->cmd.con, app_w_dev, app_w_servo);
            app_rep_u8(a, app_w_index, i);
            app_rep_u8(a, app_w_id, a->bus.ids[i]);
            app_rep_u8(a, app_w_hw_error, hw);
            app_rep_end(a);
            if (rc == 0) {
                rc = CON_E_SERVO_FAULT;
            }
        }
    }
    return rc;
}

void app_rep_servo(app_t *a, uint8_t i, uint8_t with_model)
{
    int32_t pos;
    app_rep_begin(a, app_w_servo);
    app_rep_tendon(a, i);
    app_rep_u8(a, app_w_found, (uint8_t)(app_has(a->bus.absent, i) == 0u));
    if (with_model) {
        const dxl_servo_info *s = app_boot_servo_info(a, a->bus.ids[i]);
        if (s != NULL) {
            app_rep_u16(a, app_w_model, s->model);
            app_rep_u8(a, app_w_fw, s->firmware);
        }
    }
    pos = a->bus.present[i];
    app_rep_int(a, app_w_pos, pos);
    app_rep_int(a, app_w_cal_pos, pos + a->rec.offset[i]);
    app_rep_u8(a, app_w_hw_error, a->bus.hw_err[i]);
    app_rep_end(a);
}

/* Ticks to um, split so that the products stay in 32 bits for any
 * extended-position value (+-256 turns). */
APP_NOINLINE static int32_t ticks_um(uint32_t npt, int32_t ticks)
{
    return ticks * (int32_t)(npt / 1000u) + ticks * (int32_t)(npt % 1000u) / 1000;
}

void app_rep_event(app_t *a, const hom_event_t *ev)
{
    uint8_t i = ev->index;
    uint8_t a8 = (uint8_t)ev->a; /* a of a fault (HOM_DEV_*) or a release (the fault): 8 bits */
    switch (ev->type) {
    case HOM_EV_START:
        app_rep_begin(a, app_w_progress);
        con_report_flash(&a->cmd.con, app_w_state, app_w_start);
        app_rep_word(a, app_w_mode, app_w_mode_words, ev->code);
        app_rep_int(a, app_w_tension_mN, ev->a);
        app_rep_end(a);
        break;
    case HOM_EV_PHASE: {
        app_rep_begin(a, app_w_progress);
        app_rep_word(a, app_w_state, app_w_phase_words, ev->code);
        if ((ev->code == HOM_PH_TENDON || ev->code == HOM_PH_HOLD) && i < APP_MAX_TENDONS) {
            app_rep_tendon(a, i);
        }
        if (ev->code == HOM_PH_HOLD) {
            app_rep_int(a, app_w_pos, ev->a); /* where the held tendon stands */
        }
        app_rep_end(a);
        break;
    }
    case HOM_EV_MISSING:
        app_rep_begin(a, app_w_missing);
        app_rep_word(a, app_w_dev, app_w_dev_words, ev->code);
        app_rep_u8(a, app_w_index, i);
        if (ev->code == HOM_DEV_SERVO && i < APP_MAX_TENDONS) {
            app_rep_u8(a, app_w_id, a->bus.ids[i]);
        }
        app_rep_int(a, app_w_why, ev->a);
        app_rep_int(a, app_w_bits, ev->b);
        app_rep_end(a);
        break;
    case HOM_EV_ENGAGED:
        app_rep_begin(a, app_w_progress);
        con_report_flash(&a->cmd.con, app_w_state, app_w_engaged);
        app_rep_u8(a, app_w_tendon, i);
        app_rep_int(a, app_w_pos, ev->a);
        app_rep_end(a);
        break;
    case HOM_EV_HOME:
        if (i < a->info.n_tendons) {
            const hom_tendon_t *t = hom_tendon(&a->u.hom, i);
            app_rep_begin(a, app_w_result);
            app_rep_tendon(a, i);
            app_rep_int(a, app_w_home, ev->a);
            app_rep_int(a, app_w_straight, ev->a + hom_to_straight(&a->u.hom, i));
            app_rep_int(a, app_w_home_um, ticks_um(t->nm_per_tick, ev->a));
            con_report_fixed(&a->cmd.con, app_w_dB_uT, (int32_t)hom_home_dB(&a->u.hom), 2);
            con_report_fixed(&a->cmd.con, app_w_target_uT, (int32_t)t->target_cuT, 2);
            app_rep_int(a, app_w_travel_um, ticks_um(t->nm_per_tick, (ev->a - t->engage) * t->dir));
            app_rep_int(a, app_w_time_ms, (int32_t)hom_tendon_ms(&a->u.hom));
            app_rep_word(a, app_w_target, app_w_target_words, a->run.abs);
            app_rep_end(a);
        }
        break;
    case HOM_EV_DONE:
        break; /* reported by run_done() with the count */
    case HOM_EV_FAULT:
        app_rep_begin(a, app_w_fault);
        app_rep_word(a, app_w_reason, app_w_fault_words, ev->code);
        app_rep_u8(a, app_w_code, ev->code);
        app_rep_word(a, app_w_dev, app_w_dev_words, a8);
        app_rep_u8(a, app_w_index, i);
        if ((a8 == HOM_DEV_SERVO || a8 == HOM_DEV_TENDON) && i < APP_MAX_TENDONS) {
            app_rep_u8(a, app_w_id, a->bus.ids[i]);
        }
        app_rep_int(a, app_w_detail, ev->b);
        app_rep_end(a);
        break;
    case HOM_EV_RELEASED:
        app_rep_begin(a, app_w_released);
        app_rep_word(a, app_w_reason, app_w_fault_words, a8);
        i = 0; /* the silent servo, if any */
        if ((a8 == HOM_F_SERVO_TIMEOUT || a8 == HOM_F_SERVO_ERROR) &&
            hom_fault_index(&a->u.hom) < a->info.n_tendons) {
            /* a servo that does not answer, or has its torque off, cannot
             * take the release: named (a hardware error is rebooted next) */
            i = (uint8_t)(hom_fault_index(&a->u.hom) + 1u);
        }
        app_rep_not_released(a, i);
        app_rep_end(a);
        break;
    default:
        break;
    }
}

void app_rep_not_released(app_t *a, uint8_t i)
{
    if (i == 0u) {
        i = app_bus_silent(a);
    }
    if (i != 0u) {
        app_rep_u8(a, app_w_not_released, a->bus.ids[i - 1u]);
        app_rep_u8(a, app_w_index, (uint8_t)(i - 1u));
    }
}
