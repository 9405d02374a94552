/*
 * The servo bring-up of the master: every servo pinged, a servo's hardware
 * error read (and cleared by a reboot when allowed), each servo configured
 * (its EEPROM fields written only when they differ), the positions read; one
 * transaction at a time (dxl_priv.h lists the files).
 */
#include <stddef.h>

#include "dxl/dxl.h"
#include "dxl/dxl_priv.h"
#include "dxl/dxl_xl430_reg.h"

/* --- bring-up ------------------------------------------------------------------------ */

/* 1 once the microsecond clock `now` has reached `t` (wraps); dxl.c has the
 * same function: dxl_priv.h says why. */
static uint8_t dxl_time_reached(uint32_t now, uint32_t t)
{
    return (int32_t)(now - t) >= 0;
}

enum {
    DXL_BU_PING,
    DXL_BU_HW_READ,
    DXL_BU_REBOOT,
    DXL_BU_REBOOT_WAIT,
    DXL_BU_REPING,
    DXL_BU_CONFIG,
    DXL_BU_POSITIONS,
    DXL_BU_DONE
};

/* Per-servo configuration, in order. The EEPROM-area fields (Return Delay
 * Time, Operating Mode) are read first and written only when they differ:
 * the servo's EEPROM wears with every write, and a bring-up runs at every
 * boot. Torque goes off first because the EEPROM area refuses writes while it
 * is on (e-manual XL430-W250, "Control Table Description"). */
enum {
    DXL_BU_C_READ,       /* Return Delay Time(9), Drive Mode(10), Operating Mode(11) */
    DXL_BU_C_TORQUE_OFF, /* Torque Enable(64) = 0 */
    DXL_BU_C_DELAY,      /* Return Delay Time = DXL_BU_RETURN_DELAY, when it differs */
    DXL_BU_C_MODE,       /* Operating Mode = extended position, when it differs */
    DXL_BU_C_ACC,        /* Profile Acceleration(108) */
    DXL_BU_C_VEL,        /* Profile Velocity(112) */
    DXL_BU_C_TORQUE_ON,  /* Torque Enable(64) = 1 */
    DXL_BU_C_STEPS
};

#define DXL_BU_RETURN_DELAY 0u /* answer at once: the master's timeouts assume it */
#define DXL_BU_READ_LEN     3u /* addresses 9..11 */

int8_t dxl_bringup_start(dxl_bringup *b, dxl_master *m, const uint8_t *ids, uint8_t count,
                         const dxl_bringup_config *cfg)
{
    if (ids == NULL || count == 0 || count > DXL_MAX_IDS) {
        return -DXL_E_ARG;
    }
    if (dxl_busy(m)) {
        return -DXL_E_BUSY;
    }
    for (uint8_t i = 0; i < count; i++) {
        if (ids[i] > DXL_MAX_ID) {
            return -DXL_E_ARG;
        }
        b->servo[i] = (dxl_servo_info){ids[i], 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    }
    b->m = m;
    b->cfg = *cfg;
    b->n = count;
    b->n_missing = 0;
    b->n_wrong_model = 0;
    b->step = DXL_BU_PING;
    b->index = 0;
    b->sub = 0;
    b->result = 1;
    return 1;
}

DXL_NOINLINE static int8_t dxl_bu_done(dxl_bringup *b, int8_t result)
{
    b->step = DXL_BU_DONE;
    b->result = result;
    return result;
}

/* Records a ping reply; returns nonzero when the servo answered. */
static uint8_t dxl_bu_pinged(dxl_bringup *b, dxl_servo_info *s)
{
    const dxl_reply *r = dxl_reply_for(b->m, s->id);
    if (r == NULL || r->len < 3u) {
        s->present = 0; /* transport errors leave no data; a servo error with data is an answer */
        return 0;
    }
    s->present = 1;
    s->alert = (uint8_t)((r->err & DXL_ERR_ALERT) != 0);
    s->model = (uint16_t)(r->data[0] | (uint16_t)r->data[1] << 8); /* little-endian */
    s->firmware = r->data[2];
    s->model_ok = (uint8_t)(s->model == DXL_XL430_MODEL_NUMBER);
    return 1;
}

/* The writes of the configuration steps after the read, in step order:
 * address, size and value (DXL_BU_V_ACC / _VEL: the profile from cfg). */
#define DXL_BU_V_ACC 0xFEu
#define DXL_BU_V_VEL 0xFFu
static const uint8_t dxl_bu_writes[DXL_BU_C_STEPS - 1][3] DXL_FLASH = {
    {DXL_XL430_TORQUE_ENABLE_ADDR, 1, 0},
    {DXL_XL430_RETURN_DELAY_ADDR, 1, DXL_BU_RETURN_DELAY},
    {DXL_XL430_OPERATING_MODE_ADDR, 1, DXL_XL430_MODE_EXTENDED},
    {DXL_XL430_PROFILE_ACCELERATION_ADDR, 4, DXL_BU_V_ACC},
    {DXL_XL430_PROFILE_VELOCITY_ADDR, 4, DXL_BU_V_VEL},
    {DXL_XL430_TORQUE_ENABLE_ADDR, 1, 1},
};

static int8_t dxl_bu_config_issue(dxl_bringup *b, uint8_t id)
{
    if (b->sub == DXL_BU_C_READ) {
        return dxl_read(b->m, id, DXL_XL430_RETURN_DELAY_ADDR, DXL_BU_READ_LEN);
    }
    const uint8_t *w = dxl_bu_writes[b->sub - 1u];
    uint8_t k = DXL_FLASH_BYTE(&w[2]);
    uint32_t v = k == DXL_BU_V_ACC   ? b->cfg.profile_acceleration
                 : k == DXL_BU_V_VEL ? b->cfg.profile_velocity
                                     : k;
    return dxl_write_value(b->m, id, DXL_FLASH_BYTE(&w[0]), v, DXL_FLASH_BYTE(&w[1]));
}

/* Next configuration step of servo s, skipping EEPROM writes that would
 * store the value already there. */
static void dxl_bu_next_sub(dxl_bringup *b, const dxl_servo_info *s)
{
    b->sub++;
    if (b->sub == DXL_BU_C_DELAY && s->return_delay == DXL_BU_RETURN_DELAY) {
        b->sub++;
    }
    if (b->sub == DXL_BU_C_MODE && s->mode == DXL_XL430_MODE_EXTENDED) {
        b->sub++;
    }
}

/* Starts the transaction the current step needs; each step's result is
 * handled in dxl_bringup_poll() when the master is idle again. */
static int8_t dxl_bu_issue(dxl_bringup *b)
{
    dxl_servo_info *s = &b->servo[b->index];
    switch (b->step) {
    case DXL_BU_PING:
    case DXL_BU_REPING:
        return dxl_ping(b->m, s->id);
    case DXL_BU_HW_READ:
        return dxl_read(b->m, s->id, DXL_XL430_HW_ERROR_ADDR, DXL_XL430_HW_ERROR_SIZE);
    case DXL_BU_REBOOT:
        return dxl_reboot(b->m, s->id);
    case DXL_BU_CONFIG:
        return dxl_bu_config_issue(b, s->id);
    case DXL_BU_POSITIONS: {
        uint8_t ids[DXL_MAX_IDS];
        for (uint8_t i = 0; i < b->n; i++) {
            ids[i] = b->servo[i].id;
        }
        /* one fast sync read, as every later position read: one packet of
         * 8 + 8 bytes a servo (104 for 12) where a plain sync read's replies
         * come back to back, 15 bytes a servo (180 for 12), and the servo
         * port's receive ring (uart1.h) holds the reply whole */
        return dxl_fast_sync_read(b->m, DXL_XL430_PRESENT_POSITION_ADDR,
                                  DXL_XL430_PRESENT_POSITION_SIZE, ids, b->n);
    }
    default:
        return 0;
    }
}

/* Moves to the next servo that needs the hardware check, or on to configuration. */
static void dxl_bu_next_alert(dxl_bringup *b, uint8_t from)
{
    for (b->index = from; b->index < b->n; b->index++) {
        if (b->servo[b->index].alert) {
            b->step = DXL_BU_HW_READ;
            return;
        }
    }
    b->index = 0;
    b->sub = 0;
    b->step = DXL_BU_CONFIG;
}

static int8_t dxl_bu_after(dxl_bringup *b, int8_t rc)
{
    dxl_servo_info *s = &b->servo[b->index];
    switch (b->step) {
    case DXL_BU_PING:
        if (!dxl_bu_pinged(b, s)) {
            b->missing[b->n_missing++] = s->id;
        } else if (!s->model_ok) {
            b->n_wrong_model++;
        }
        if (++b->index < b->n) {
            return 1;
        }
        if (b->n_missing > 0) {
            return dxl_bu_done(b, -DXL_E_MISSING);
        }
        dxl_bu_next_alert(b, 0);
        return 1;
    case DXL_BU_HW_READ: {
        const dxl_reply *r = dxl_reply_for(b->m, s->id);
        if ((rc != 0 && rc != -DXL_E_ALERT) || r == NULL || r->len < 1u) {
            return dxl_bu_done(b, rc != 0 ? rc : -DXL_E_MALFORMED);
        }
        s->hw_error = r->data[0];
        if (s->hw_error == 0) {
            s->alert = 0;
            dxl_bu_next_alert(b, (uint8_t)(b->index + 1u));
        } else if (b->cfg.reboot_on_hw_error && !s->rebooted) {
            b->step = DXL_BU_REBOOT;
        } else {
            return dxl_bu_done(b, -DXL_E_HW_ERROR);
        }
        return 1;
    }
    case DXL_BU_REBOOT:
        if (rc != 0 && rc != -DXL_E_ALERT) {
            return dxl_bu_done(b, rc);
        }
        s->rebooted = 1;
        b->wait_until = DXL_PORT_NOW_US(b->m) + b->cfg.reboot_wait_us;
        b->step = DXL_BU_REBOOT_WAIT;
        return 1;
    case DXL_BU_REPING:
        if (!dxl_bu_pinged(b, s)) {
            b->missing[b->n_missing++] = s->id;
            return dxl_bu_done(b, -DXL_E_MISSING);
        }
        if (s->alert) {
            b->step = DXL_BU_HW_READ;
        } else {
            s->hw_error = 0;
            dxl_bu_next_alert(b, (uint8_t)(b->index + 1u));
        }
        return 1;
    case DXL_BU_CONFIG:
        if (rc != 0) {
            return dxl_bu_done(b, rc);
        }
        if (b->sub == DXL_BU_C_READ) {
            const dxl_reply *r = dxl_reply_for(b->m, s->id);
            if (r == NULL || r->len < DXL_BU_READ_LEN) {
                return dxl_bu_done(b, -DXL_E_MALFORMED);
            }
            s->return_delay = r->data[0];
            s->mode = r->data[DXL_XL430_OPERATING_MODE_ADDR - DXL_XL430_RETURN_DELAY_ADDR];
        } else if (b->sub == DXL_BU_C_DELAY || b->sub == DXL_BU_C_MODE) {
            s->eeprom_writes++;
        }
        dxl_bu_next_sub(b, s);
        if (b->sub < DXL_BU_C_STEPS) {
            return 1;
        }
        b->sub = 0;
        if (++b->index >= b->n) {
            b->index = 0;
            b->step = DXL_BU_POSITIONS;
        }
        return 1;
    case DXL_BU_POSITIONS:
        if (rc != 0) {
            return dxl_bu_done(b, rc);
        }
        for (uint8_t i = 0; i < b->n; i++) {
            b->servo[i].position = dxl_reply_value(dxl_reply_for(b->m, b->servo[i].id), 4);
        }
        return dxl_bu_done(b, 0);
    default:
        return b->result;
    }
}

int8_t dxl_bringup_poll(dxl_bringup *b)
{
    if (b->step == DXL_BU_DONE) {
        return b->result;
    }
    if (b->step == DXL_BU_REBOOT_WAIT) {
        if (!dxl_time_reached(DXL_PORT_NOW_US(b->m), b->wait_until)) {
            return 1;
        }
        b->step = DXL_BU_REPING;
    }
    if (!dxl_busy(b->m)) {
        int8_t rc = dxl_bu_issue(b);
        if (rc < 0) {
            return dxl_bu_done(b, rc);
        }
    }
    int8_t rc = dxl_poll(b->m);
    if (rc > 0) {
        return 1;
    }
    return dxl_bu_after(b, rc);
}
