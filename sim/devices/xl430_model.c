#include "devices/xl430_model.h"

#include "devices/xl430_table.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

enum { XL430_WAIT_NONE, XL430_WAIT_STATUS, XL430_WAIT_FAST };

#define XL430_TICKS_PER_S_PER_VEL   (DXL_XL430_VELOCITY_UNIT_RPM * 4096.0 / 60.0)
#define XL430_TICKS_PER_S2_PER_ACC  (DXL_XL430_ACCEL_UNIT_RPM2 * 4096.0 / 3600.0)
#define XL430_MAX_STEP_US           1000u
#define XL430_FW_NO_BROADCAST_RESET 42u /* Protocol 2.0, "Factory Reset" */
#define XL430_FAST_GAP_US           1000u /* idle bus (plus 3 bytes) that ends a fast sync read chain */

static uint8_t xl430_reached(uint32_t now, uint32_t t)
{
    return (int32_t)(now - t) >= 0;
}

static void xl430_set(xl430 *m, uint16_t addr, uint32_t value, uint8_t size)
{
    dxl_put_le(&m->ct[addr], value, size);
}

uint32_t xl430_get(const xl430 *m, uint16_t addr, uint8_t size)
{
    if ((uint32_t)addr + size > DXL_XL430_TABLE_SIZE) {
        return 0;
    }
    return dxl_get_le(&m->ct[addr], size);
}

static int32_t xl430_get_s32(const xl430 *m, uint16_t addr)
{
    return (int32_t)xl430_get(m, addr, 4);
}

void xl430_config_default(xl430_config *cfg, uint8_t id)
{
    cfg->id = id;
    cfg->baud_index = DXL_XL430_BAUD_1M;
    cfg->return_delay = 250;
    cfg->bits_per_byte = 10;
    cfg->firmware = 46;
    cfg->boot_us = 300000UL;
    cfg->shaft_ticks = 0.0;
}

static void xl430_eeprom_defaults(xl430 *m, uint8_t keep_id, uint8_t keep_baud)
{
    uint8_t id = m->ct[DXL_XL430_ID_ADDR];
    uint8_t baud = m->ct[DXL_XL430_BAUD_ADDR];
    memset(m->ct, 0, 64);
    xl430_set(m, DXL_XL430_MODEL_NUMBER_ADDR, DXL_XL430_MODEL_NUMBER, 2);
    m->ct[DXL_XL430_FIRMWARE_ADDR] = m->cfg.firmware;
    m->ct[DXL_XL430_ID_ADDR] = keep_id ? id : 1u;
    m->ct[DXL_XL430_BAUD_ADDR] = keep_baud ? baud : DXL_XL430_BAUD_57600;
    m->ct[DXL_XL430_RETURN_DELAY_ADDR] = 250;
    m->ct[DXL_XL430_OPERATING_MODE_ADDR] = DXL_XL430_MODE_POSITION;
    m->ct[DXL_XL430_SECONDARY_ID_ADDR] = 255;
    m->ct[DXL_XL430_PROTOCOL_TYPE_ADDR] = 2;
    xl430_set(m, DXL_XL430_MOVING_THRESHOLD_ADDR, 10, 4);
    m->ct[DXL_XL430_TEMPERATURE_LIMIT_ADDR] = 72;
    xl430_set(m, DXL_XL430_MAX_VOLTAGE_ADDR, 140, 2);
    xl430_set(m, DXL_XL430_MIN_VOLTAGE_ADDR, 60, 2);
    xl430_set(m, DXL_XL430_PWM_LIMIT_ADDR, 885, 2);
    xl430_set(m, DXL_XL430_VELOCITY_LIMIT_ADDR, 265, 4);
    xl430_set(m, DXL_XL430_MAX_POSITION_ADDR, 4095, 4);
    xl430_set(m, DXL_XL430_MIN_POSITION_ADDR, 0, 4);
    m->ct[DXL_XL430_SHUTDOWN_ADDR] = 0x34;
}

static int32_t xl430_reported(const xl430 *m)
{
    return (int32_t)lround(m->shaft - m->base) + xl430_get_s32(m, DXL_XL430_HOMING_OFFSET_ADDR);
}

static void xl430_publish(xl430 *m)
{
    int32_t present = xl430_reported(m);
    xl430_set(m, DXL_XL430_PRESENT_POSITION_ADDR, (uint32_t)present, 4);
    xl430_set(m, DXL_XL430_POSITION_TRAJECTORY_ADDR, (uint32_t)present, 4);
    int32_t v = (int32_t)lround(m->vel / XL430_TICKS_PER_S_PER_VEL);
    xl430_set(m, DXL_XL430_PRESENT_VELOCITY_ADDR, (uint32_t)v, 4);
    xl430_set(m, DXL_XL430_VELOCITY_TRAJECTORY_ADDR, (uint32_t)v, 4);
    uint8_t moving = (uint8_t)(m->ct[DXL_XL430_TORQUE_ENABLE_ADDR] &&
                               (m->vel != 0.0 || fabs(m->target - m->shaft) >= 0.5));
    m->ct[DXL_XL430_MOVING_ADDR] = moving;
    uint8_t status =
        moving ? (uint8_t)(DXL_XL430_MOVING_STATUS_PROFILE | DXL_XL430_MOVING_STATUS_TRAPEZOID)
               : DXL_XL430_MOVING_STATUS_IN_POSITION;
    m->ct[DXL_XL430_MOVING_STATUS_ADDR] = status;
    xl430_set(m, DXL_XL430_REALTIME_TICK_ADDR, (m->now / 1000u) % 32768u, 2);
}

/* Power-up: the encoder knows the angle within one turn only, so the
 * multi-turn origin moves to the turn the shaft is in. */
static void xl430_power_on(xl430 *m)
{
    memset(&m->ct[64], 0, DXL_XL430_TABLE_SIZE - 64u);
    m->ct[DXL_XL430_STATUS_RETURN_LEVEL_ADDR] = 2;
    xl430_set(m, DXL_XL430_VELOCITY_I_GAIN_ADDR, 1000, 2);
    xl430_set(m, DXL_XL430_VELOCITY_P_GAIN_ADDR, 100, 2);
    xl430_set(m, DXL_XL430_POSITION_P_GAIN_ADDR, 640, 2);
    xl430_set(m, DXL_XL430_GOAL_PWM_ADDR, 885, 2);
    xl430_set(m, DXL_XL430_PRESENT_VOLTAGE_ADDR, 120, 2);
    m->ct[DXL_XL430_PRESENT_TEMPERATURE_ADDR] = 30;
    m->base = floor(m->shaft / 4096.0) * 4096.0;
    m->vel = 0.0;
    m->target = m->shaft;
    m->tx_len = 0;
    m->tx_pos = 0;
    m->wait = XL430_WAIT_NONE;
    m->reg_n = 0;
    m->booting = 0;
    m->last_inst = m->now;
    dxl_parser_reset(&m->rx);
    xl430_set(m, DXL_XL430_GOAL_POSITION_ADDR, (uint32_t)xl430_reported(m), 4);
    xl430_publish(m);
}

void xl430_init(xl430 *m, const xl430_config *cfg, uint32_t t_us)
{
    memset(m, 0, sizeof(*m));
    m->cfg = *cfg;
    m->now = t_us;
    m->started = 1;
    m->shaft = cfg->shaft_ticks;
    dxl_parser_init(&m->rx, m->rx_buf, XL430_RX_CAP);
    xl430_eeprom_defaults(m, 0, 0);
    m->ct[DXL_XL430_ID_ADDR] = cfg->id;
    m->ct[DXL_XL430_BAUD_ADDR] = cfg->baud_index;
    m->ct[DXL_XL430_RETURN_DELAY_ADDR] = cfg->return_delay;
    xl430_power_on(m);
}

void xl430_power_cycle(xl430 *m, uint32_t t_us)
{
    xl430_step(m, t_us);
    xl430_power_on(m);
}

uint32_t xl430_baud(const xl430 *m)
{
    static const uint32_t rates[8] = {9600,    57600,   115200,  1000000,
                                      2000000, 3000000, 4000000, 4500000};
    uint8_t i = m->ct[DXL_XL430_BAUD_ADDR];
    return rates[i < 8u ? i : 1u];
}

static double xl430_vmax(const xl430 *m)
{
    uint32_t v = xl430_get(m, DXL_XL430_PROFILE_VELOCITY_ADDR, 4);
    if (v == 0) {
        v = xl430_get(m, DXL_XL430_VELOCITY_LIMIT_ADDR, 4);
    }
    return (double)v * XL430_TICKS_PER_S_PER_VEL;
}

static double xl430_amax(const xl430 *m)
{
    return (double)xl430_get(m, DXL_XL430_PROFILE_ACCELERATION_ADDR, 4) *
           XL430_TICKS_PER_S2_PER_ACC;
}

/* Trapezoid: accelerate towards the target, brake when the stopping distance
 * reaches the remaining distance, snap on arrival. Acceleration 0 means an
 * instant change of speed, as on the servo. */
static void xl430_motion(xl430 *m, double dt)
{
    if (!m->ct[DXL_XL430_TORQUE_ENABLE_ADDR]) {
        m->vel = 0.0;
        return;
    }
    double d = m->target - m->shaft;
    if (fabs(d) < 0.5 && m->vel == 0.0) {
        m->shaft = m->target;
        return;
    }
    double dir = d > 0 ? 1.0 : -1.0;
    double vmax = xl430_vmax(m);
    double a = xl430_amax(m);
    double v = m->vel;
    if (a <= 0.0) {
        v = dir * vmax;
    } else {
        double stop = v * v / (2.0 * a);
        if (v * dir > 0 && fabs(d) <= stop) {
            v -= dir * a * dt;
            if (v * dir <= 0) {
                v = dir * 1e-3;
            }
        } else {
            v += dir * a * dt;
            if (fabs(v) > vmax) {
                v = dir * vmax;
            }
        }
    }
    double next = m->shaft + v * dt;
    if ((m->target - next) * dir <= 0.0) {
        m->shaft = m->target;
        m->vel = 0.0;
        return;
    }
    m->shaft = next;
    m->vel = v;
}

static void xl430_watchdog(xl430 *m)
{
    uint8_t wd = m->ct[DXL_XL430_BUS_WATCHDOG_ADDR];
    if (wd == 0 || wd == DXL_XL430_BUS_WATCHDOG_EXPIRED || !m->ct[DXL_XL430_TORQUE_ENABLE_ADDR]) {
        return;
    }
    if (m->now - m->last_inst > (uint32_t)wd * DXL_XL430_BUS_WATCHDOG_UNIT_US) {
        /* [Bus Watchdog(98)] example, step 4: the servo stops and applies
         * Profile Acceleration and Profile Velocity as 0 */
        m->ct[DXL_XL430_BUS_WATCHDOG_ADDR] = DXL_XL430_BUS_WATCHDOG_EXPIRED;
        xl430_set(m, DXL_XL430_PROFILE_ACCELERATION_ADDR, 0, 4);
        xl430_set(m, DXL_XL430_PROFILE_VELOCITY_ADDR, 0, 4);
        m->target = m->shaft;
        m->vel = 0.0;
    }
}

void xl430_step(xl430 *m, uint32_t t_us)
{
    while (!xl430_reached(m->now, t_us)) {
        uint32_t dt = t_us - m->now;
        if (dt > XL430_MAX_STEP_US) {
            dt = XL430_MAX_STEP_US;
        }
        m->now += dt;
        xl430_motion(m, (double)dt * 1e-6);
        xl430_watchdog(m);
    }
    if (m->booting && xl430_reached(m->now, m->boot_until)) {
        xl430_power_on(m);
    }
    xl430_publish(m);
}

static uint32_t xl430_due(const xl430 *m, uint16_t i)
{
    uint64_t bits = (uint64_t)(i + 1u) * m->cfg.bits_per_byte * 1000000ULL;
    return m->tx_t0 + (uint32_t)((bits + m->tx_baud - 1u) / m->tx_baud);
}

uint8_t xl430_tx_peek(const xl430 *m, uint8_t *byte, uint32_t *due_us)
{
    if (m->wait != XL430_WAIT_NONE || m->tx_pos >= m->tx_len) {
        return 0;
    }
    *byte = m->tx[m->tx_pos];
    *due_us = xl430_due(m, m->tx_pos);
    return 1;
}

void xl430_tx_pop(xl430 *m)
{
    if (m->wait == XL430_WAIT_NONE && m->tx_pos < m->tx_len) {
        m->tx_pos++;
    }
}

uint8_t xl430_transmitting(const xl430 *m, uint32_t t_us)
{
    if (m->wait != XL430_WAIT_NONE || m->tx_pos >= m->tx_len) {
        return 0;
    }
    return xl430_reached(t_us, m->tx_t0);
}

void xl430_inject_hw_error(xl430 *m, uint8_t bits)
{
    m->ct[DXL_XL430_HW_ERROR_ADDR] |= bits;
    m->ct[DXL_XL430_TORQUE_ENABLE_ADDR] = 0;
    m->vel = 0.0;
    m->target = m->shaft;
    xl430_publish(m);
}

int32_t xl430_present_position(const xl430 *m)
{
    return xl430_reported(m);
}

double xl430_shaft_ticks(const xl430 *m)
{
    return m->shaft;
}

void xl430_set_sensed(xl430 *m, int16_t load, uint16_t voltage, uint8_t temperature)
{
    xl430_set(m, DXL_XL430_PRESENT_LOAD_ADDR, (uint16_t)load, 2);
    xl430_set(m, DXL_XL430_PRESENT_VOLTAGE_ADDR, voltage, 2);
    m->ct[DXL_XL430_PRESENT_TEMPERATURE_ADDR] = temperature;
}

/* --- replies ------------------------------------------------------------------------ */

static uint8_t xl430_err(const xl430 *m, uint8_t number)
{
    return (uint8_t)(number | (m->ct[DXL_XL430_HW_ERROR_ADDR] ? DXL_ERR_ALERT : 0u));
}

static void xl430_arm(xl430 *m, uint32_t t0)
{
    m->tx_t0 = t0;
    m->tx_pos = 0;
    m->tx_baud = xl430_baud(m);
    m->wait = XL430_WAIT_NONE;
    m->replies++;
}

static uint32_t xl430_delay_us(const xl430 *m)
{
    return (uint32_t)m->ct[DXL_XL430_RETURN_DELAY_ADDR] * DXL_XL430_RETURN_DELAY_UNIT_US;
}

static void xl430_reply(xl430 *m, uint8_t number, const uint8_t *params, uint16_t n, uint32_t t)
{
    uint16_t len;
    if (dxl_build_status(m->tx, XL430_TX_CAP, m->ct[DXL_XL430_ID_ADDR], xl430_err(m, number),
                         params, n, &len) != 0) {
        return;
    }
    m->tx_len = len;
    xl430_arm(m, t + xl430_delay_us(m));
}

static uint8_t xl430_range_ok(uint16_t addr, uint16_t n)
{
    return n > 0 && (uint32_t)addr + n <= DXL_XL430_TABLE_SIZE;
}

static void xl430_read_reply(xl430 *m, uint16_t addr, uint16_t n, uint32_t t)
{
    if (!xl430_range_ok(addr, n)) {
        xl430_reply(m, DXL_ERR_ACCESS, NULL, 0, t);
        return;
    }
    xl430_reply(m, 0, &m->ct[addr], n, t);
}

/* Fast sync read chunk: ERR ID DATA and the CRC of everything so far. The
 * first servo also sends the header, with LEN for the whole packet. */
static void xl430_fast_chunk(xl430 *m, uint16_t crc, uint8_t first, uint8_t count, uint32_t t0)
{
    uint16_t n = m->wait_n;
    uint16_t pos = 0;
    if (first) {
        uint16_t field = (uint16_t)(1u + count * (n + 4u));
        const uint8_t hdr[8] = {0xFF,
                                0xFF,
                                0xFD,
                                0x00,
                                DXL_BROADCAST_ID,
                                (uint8_t)field,
                                (uint8_t)(field >> 8),
                                DXL_INST_STATUS};
        memcpy(m->tx, hdr, 8);
        pos = 8;
        crc = dxl_crc16(0, hdr, 8);
    }
    uint8_t ok = xl430_range_ok(m->wait_addr, n);
    m->tx[pos++] = xl430_err(m, ok ? 0u : DXL_ERR_ACCESS);
    m->tx[pos++] = m->ct[DXL_XL430_ID_ADDR];
    for (uint16_t i = 0; i < n; i++) {
        m->tx[pos++] = ok ? m->ct[m->wait_addr + i] : 0u;
    }
    crc = dxl_crc16(crc, m->tx + (first ? 8u : 0u), (uint16_t)(pos - (first ? 8u : 0u)));
    m->tx[pos++] = (uint8_t)crc;
    m->tx[pos++] = (uint8_t)(crc >> 8);
    m->tx_len = pos;
    xl430_arm(m, t0);
}

/* --- writes ------------------------------------------------------------------------- */

static uint8_t xl430_covers(uint16_t addr, uint16_t n, uint16_t field, uint16_t size)
{
    return addr < field + size && field < addr + n;
}

static void xl430_goal_to_target(xl430 *m)
{
    int32_t goal = xl430_get_s32(m, DXL_XL430_GOAL_POSITION_ADDR);
    m->target = m->base + (double)(goal - xl430_get_s32(m, DXL_XL430_HOMING_OFFSET_ADDR));
}

static void xl430_write_apply(xl430 *m, uint16_t addr, const uint8_t *data, uint16_t n)
{
    uint8_t torque_was = m->ct[DXL_XL430_TORQUE_ENABLE_ADDR];
    uint8_t mode_was = m->ct[DXL_XL430_OPERATING_MODE_ADDR];
    memcpy(&m->ct[addr], data, n);
    if (xl430_covers(addr, n, DXL_XL430_OPERATING_MODE_ADDR, 1) &&
        m->ct[DXL_XL430_OPERATING_MODE_ADDR] != mode_was) {
        xl430_set(m, DXL_XL430_PROFILE_ACCELERATION_ADDR, 0, 4);
        xl430_set(m, DXL_XL430_PROFILE_VELOCITY_ADDR, 0, 4);
        if (m->ct[DXL_XL430_OPERATING_MODE_ADDR] == DXL_XL430_MODE_POSITION) {
            m->base = floor(m->shaft / 4096.0) * 4096.0;
        }
    }
    if (xl430_covers(addr, n, DXL_XL430_TORQUE_ENABLE_ADDR, 1)) {
        if (m->ct[DXL_XL430_TORQUE_ENABLE_ADDR] && !torque_was) {
            m->target = m->shaft; /* hold where it is until a goal arrives */
            xl430_set(m, DXL_XL430_GOAL_POSITION_ADDR, (uint32_t)xl430_reported(m), 4);
        }
    }
    if (xl430_covers(addr, n, DXL_XL430_GOAL_POSITION_ADDR, 4) &&
        m->ct[DXL_XL430_TORQUE_ENABLE_ADDR]) {
        xl430_goal_to_target(m);
    }
    xl430_publish(m);
}

/* Returns the error number (0 when written). */
static uint8_t xl430_write(xl430 *m, uint16_t addr, const uint8_t *data, uint16_t n)
{
    uint8_t err = xl430_table_check(m->ct, addr, data, n);
    if (err == 0) {
        xl430_write_apply(m, addr, data, n);
        if (addr < DXL_XL430_TORQUE_ENABLE_ADDR) {
            m->eeprom_writes++;
        }
    }
    return err;
}

/* --- instructions ------------------------------------------------------------------- */

static int16_t xl430_index_of(const xl430 *m, const uint8_t *list, uint16_t count, uint16_t stride)
{
    for (uint16_t i = 0; i < count; i++) {
        if (list[(uint16_t)(i * stride)] == m->ct[DXL_XL430_ID_ADDR]) {
            return (int16_t)i;
        }
    }
    return -1;
}

/* The servo goes away after its reply (if any) and powers up again after
 * its boot time: RAM back to defaults, torque off. */
static void xl430_reboot(xl430 *m, uint32_t t)
{
    m->booting = 1;
    m->boot_until = t + xl430_delay_us(m) + 200u + m->cfg.boot_us;
}

static void xl430_factory_reset(xl430 *m, uint8_t mode)
{
    xl430_eeprom_defaults(m, mode != DXL_RESET_ALL, mode == DXL_RESET_KEEP_ID_AND_BAUD);
}

static void xl430_instruction(xl430 *m, uint8_t id, const uint8_t *body, uint16_t len, uint32_t t)
{
    uint8_t inst = body[0];
    const uint8_t *p = body + 1;
    uint16_t np = (uint16_t)(len - 1u);
    uint8_t mine = id == m->ct[DXL_XL430_ID_ADDR];
    uint8_t srl = m->ct[DXL_XL430_STATUS_RETURN_LEVEL_ADDR];
    uint8_t answer = mine && srl >= 2u;
    if (!mine && id != DXL_BROADCAST_ID) {
        return;
    }
    m->instructions++;
    m->last_inst = t;
    m->wait = XL430_WAIT_NONE;
    m->tx_len = 0;
    m->tx_pos = 0;
    switch (inst) {
    case DXL_INST_PING:
        if (np != 0) {
            break;
        }
        {
            uint8_t info[3] = {m->ct[DXL_XL430_MODEL_NUMBER_ADDR],
                               m->ct[DXL_XL430_MODEL_NUMBER_ADDR + 1u],
                               m->ct[DXL_XL430_FIRMWARE_ADDR]};
            /* broadcast ping: answers spaced by ID so that they never overlap */
            uint32_t extra = mine ? 0u : (uint32_t)m->ct[DXL_XL430_ID_ADDR] * 16u * 11u;
            xl430_reply(m, 0, info, 3, t + extra);
        }
        break;
    case DXL_INST_READ:
        if (!mine || srl < 1u) {
            break;
        }
        if (np != 4u) {
            xl430_reply(m, DXL_ERR_DATA_LENGTH, NULL, 0, t);
            break;
        }
        xl430_read_reply(m, (uint16_t)dxl_get_le(p, 2), (uint16_t)dxl_get_le(p + 2, 2), t);
        break;
    case DXL_INST_WRITE:
    case DXL_INST_REG_WRITE: {
        uint8_t err = DXL_ERR_DATA_LENGTH;
        if (np >= 3u) {
            uint16_t addr = (uint16_t)dxl_get_le(p, 2);
            uint16_t n = (uint16_t)(np - 2u);
            if (inst == DXL_INST_WRITE) {
                err = xl430_write(m, addr, p + 2, n);
            } else if (n > XL430_REG_CAP || !xl430_range_ok(addr, n)) {
                err = DXL_ERR_ACCESS;
            } else {
                err = 0;
                m->reg_addr = addr;
                m->reg_n = (uint8_t)n;
                memcpy(m->reg_data, p + 2, n);
                m->ct[DXL_XL430_REGISTERED_ADDR] = 1;
            }
        }
        if (answer) {
            xl430_reply(m, err, NULL, 0, t);
        }
        break;
    }
    case DXL_INST_ACTION: {
        /* Protocol 2.0, "Error": Instruction Error also when Action comes
         * without a Reg Write */
        uint8_t err = DXL_ERR_INSTRUCTION;
        if (m->ct[DXL_XL430_REGISTERED_ADDR]) {
            err = xl430_write(m, m->reg_addr, m->reg_data, m->reg_n);
            m->ct[DXL_XL430_REGISTERED_ADDR] = 0;
        }
        if (answer) {
            xl430_reply(m, err, NULL, 0, t);
        }
        break;
    }
    case DXL_INST_FACTORY_RESET:
        if (np != 1u || (p[0] != DXL_RESET_ALL && p[0] != DXL_RESET_KEEP_ID &&
                         p[0] != DXL_RESET_KEEP_ID_AND_BAUD)) {
            if (answer) {
                xl430_reply(m, DXL_ERR_DATA_RANGE, NULL, 0, t);
            }
            break;
        }
        /* Protocol 2.0, "Factory Reset": from X-series firmware 42 a
         * broadcast Reset All is not executed */
        if (!mine && p[0] == DXL_RESET_ALL && m->cfg.firmware >= XL430_FW_NO_BROADCAST_RESET) {
            break;
        }
        if (answer) {
            xl430_reply(m, 0, NULL, 0, t);
        }
        xl430_factory_reset(m, p[0]);
        xl430_reboot(m, t); /* the servo restarts with its factory table */
        break;
    case DXL_INST_REBOOT:
        if (answer) {
            xl430_reply(m, 0, NULL, 0, t);
        }
        m->reboots++;
        xl430_reboot(m, t);
        break;
    case DXL_INST_CLEAR: {
        static const uint8_t key[5] = {DXL_CLEAR_MULTITURN, 0x44, 0x58, 0x4C, 0x22};
        uint8_t err = 0;
        if (np != 5u || memcmp(p, key, 5) != 0) {
            err = DXL_ERR_DATA_RANGE;
        } else if (m->ct[DXL_XL430_MOVING_ADDR]) {
            err = DXL_ERR_RESULT_FAIL;
        } else {
            m->base = floor(m->shaft / 4096.0) * 4096.0;
            xl430_set(m, DXL_XL430_GOAL_POSITION_ADDR, (uint32_t)xl430_reported(m), 4);
            xl430_publish(m);
        }
        if (answer) {
            xl430_reply(m, err, NULL, 0, t);
        }
        break;
    }
    case DXL_INST_SYNC_READ:
    case DXL_INST_FAST_SYNC_READ: {
        if (mine || np < 5u || srl < 1u) {
            break;
        }
        uint16_t count = (uint16_t)(np - 4u);
        int16_t k = xl430_index_of(m, p + 4, count, 1);
        if (k < 0) {
            break;
        }
        m->wait_addr = (uint16_t)dxl_get_le(p, 2);
        m->wait_n = (uint16_t)dxl_get_le(p + 2, 2);
        if (inst == DXL_INST_FAST_SYNC_READ) {
            if ((uint32_t)8u + count * (m->wait_n + 4u) > XL430_TX_CAP) {
                break;
            }
            if (k == 0) {
                xl430_fast_chunk(m, 0, 1, (uint8_t)count, t + xl430_delay_us(m));
            } else {
                m->wait = XL430_WAIT_FAST;
                m->fast_seen = 0;
                m->fast_crc = 0;
                m->fast_need = (uint16_t)(8u + (uint16_t)k * (m->wait_n + 4u));
            }
        } else if (k == 0) {
            xl430_read_reply(m, m->wait_addr, m->wait_n, t);
        } else {
            m->wait = XL430_WAIT_STATUS;
            m->wait_id = p[4 + k - 1];
        }
        break;
    }
    case DXL_INST_BULK_READ: {
        if (mine || np < 5u || np % 5u != 0 || srl < 1u) {
            break;
        }
        int16_t k = xl430_index_of(m, p, (uint16_t)(np / 5u), 5);
        if (k < 0) {
            break;
        }
        const uint8_t *e = p + 5 * k;
        m->wait_addr = (uint16_t)dxl_get_le(e + 1, 2);
        m->wait_n = (uint16_t)dxl_get_le(e + 3, 2);
        if (k == 0) {
            xl430_read_reply(m, m->wait_addr, m->wait_n, t);
        } else {
            m->wait = XL430_WAIT_STATUS;
            m->wait_id = p[5 * (k - 1)];
        }
        break;
    }
    case DXL_INST_SYNC_WRITE: {
        if (mine || np < 5u) {
            break;
        }
        uint16_t addr = (uint16_t)dxl_get_le(p, 2);
        uint16_t n = (uint16_t)dxl_get_le(p + 2, 2);
        if (n == 0 || (np - 4u) % (n + 1u) != 0) {
            break;
        }
        int16_t k = xl430_index_of(m, p + 4, (uint16_t)((np - 4u) / (n + 1u)), (uint16_t)(n + 1u));
        if (k >= 0) {
            (void)xl430_write(m, addr, p + 4 + (uint16_t)k * (n + 1u) + 1u, n);
        }
        break;
    }
    case DXL_INST_BULK_WRITE: {
        uint16_t i = 0;
        while (!mine && i + 5u <= np) {
            uint16_t n = (uint16_t)dxl_get_le(p + i + 3, 2);
            if (i + 5u + n > np) {
                break;
            }
            if (p[i] == m->ct[DXL_XL430_ID_ADDR]) {
                (void)xl430_write(m, (uint16_t)dxl_get_le(p + i + 1, 2), p + i + 5, n);
            }
            i = (uint16_t)(i + 5u + n);
        }
        break;
    }
    default:
        if (answer) {
            xl430_reply(m, DXL_ERR_INSTRUCTION, NULL, 0, t);
        }
        break;
    }
}

void xl430_rx(xl430 *m, uint8_t byte, uint32_t t_us)
{
    xl430_step(m, t_us);
    if (m->booting) {
        return;
    }
    uint32_t gap = t_us - m->last_rx;
    m->last_rx = t_us;
    uint32_t gap_limit =
        XL430_FAST_GAP_US + (uint32_t)(3000000ULL * m->cfg.bits_per_byte / xl430_baud(m));
    if (m->wait == XL430_WAIT_FAST && gap > gap_limit) {
        m->wait = XL430_WAIT_NONE; /* the chain of chunks broke off: give up */
    }
    if (m->wait == XL430_WAIT_FAST) {
        m->fast_crc = dxl_crc16_byte(m->fast_crc, byte);
        if (++m->fast_seen == m->fast_need) {
            uint8_t count = 0; /* header LEN is only needed by the first servo */
            xl430_fast_chunk(m, m->fast_crc, 0, count, t_us);
            return;
        }
    }
    int8_t rc = dxl_parser_feed(&m->rx, byte);
    if (rc != 0 || m->rx.body_len == 0) {
        return;
    }
    if (m->rx.buf[0] == DXL_INST_STATUS) {
        if (m->wait == XL430_WAIT_STATUS && m->rx.id == m->wait_id) {
            m->wait = XL430_WAIT_NONE;
            xl430_read_reply(m, m->wait_addr, m->wait_n, t_us);
        }
        return;
    }
    m->wait = XL430_WAIT_NONE; /* any new instruction ends an unfinished group read */
    xl430_instruction(m, m->rx.id, m->rx.buf, m->rx.body_len, t_us);
}
