#include "devices/xl430_table.h"

#include <stddef.h>

#include "dxl/dxl_proto.h"
#include "dxl/dxl_xl430_reg.h"

enum { XT_RO, XT_EEPROM, XT_RAM };

/* How a field's value is judged beyond its fixed range. */
enum {
    XT_PLAIN,
    XT_SIGNED,      /* two's complement, range min..max */
    XT_ANY,         /* every value is accepted (no Range given) */
    XT_OPMODE,      /* one of the listed operating modes */
    XT_TORQUE,      /* 0..1, and 1 fails while a hardware error is set */
    XT_WATCHDOG,    /* 0 clears, 1..127 arms */
    XT_GOAL_PWM,    /* -PWM Limit(36)..PWM Limit(36) */
    XT_GOAL_VEL,    /* -Velocity Limit(44)..Velocity Limit(44) */
    XT_PROFILE_ACC, /* 0..32767, 0..32737 time-based */
    XT_PROFILE_VEL, /* 0..min(32767, Velocity Limit(44)), 0..32737 time-based */
    XT_GOAL_POS     /* position limits of the operating mode */
};

typedef struct {
    uint8_t addr;
    uint8_t size;
    uint8_t access;
    uint8_t kind;
    int32_t min;
    int32_t max;
} xl430_field;

/* e-manual XL430-W250, "Control Table of EEPROM Area" and "Control Table of
 * RAM Area": address, size, Access and Range columns, in address order. */
static const xl430_field xl430_fields[] = {
    {0, 2, XT_RO, XT_ANY, 0, 0},                /* Model Number(0) */
    {2, 4, XT_RO, XT_ANY, 0, 0},                /* Model Information(2) */
    {6, 1, XT_RO, XT_ANY, 0, 0},                /* Firmware Version(6) */
    {7, 1, XT_EEPROM, XT_PLAIN, 0, DXL_MAX_ID}, /* ID(7): 0..252 */
    {8, 1, XT_EEPROM, XT_PLAIN, 0, 7},          /* Baud Rate(8): 0..7 */
    {9, 1, XT_EEPROM, XT_PLAIN, 0, 254},        /* Return Delay Time(9): 0..254 */
    {10, 1, XT_EEPROM, XT_PLAIN, 0, 13},        /* Drive Mode(10): 0..13 */
    {11, 1, XT_EEPROM, XT_OPMODE, 0, 16},       /* Operating Mode(11): modes 1, 3, 4, 16 */
    /* Secondary(Shadow) ID(12): 0..252 are IDs, above 252 switches it off
     * (its factory value is 255), so every byte is accepted. */
    {12, 1, XT_EEPROM, XT_ANY, 0, 0},
    {13, 1, XT_EEPROM, XT_PLAIN, 1, 2},                 /* Protocol Type(13): 1..2 */
    {20, 4, XT_EEPROM, XT_SIGNED, -1044479L, 1044479L}, /* Homing Offset(20) */
    {24, 4, XT_EEPROM, XT_PLAIN, 0, 1023},              /* Moving Threshold(24) */
    {31, 1, XT_EEPROM, XT_PLAIN, 0, 100},               /* Temperature Limit(31) */
    {32, 2, XT_EEPROM, XT_PLAIN, 60, 140},              /* Max Voltage Limit(32) */
    {34, 2, XT_EEPROM, XT_PLAIN, 60, 140},              /* Min Voltage Limit(34) */
    {36, 2, XT_EEPROM, XT_PLAIN, 0, 885},               /* PWM Limit(36) */
    {44, 4, XT_EEPROM, XT_PLAIN, 0, 1023},              /* Velocity Limit(44) */
    {48, 4, XT_EEPROM, XT_PLAIN, 0, 4095},              /* Max Position Limit(48) */
    {52, 4, XT_EEPROM, XT_PLAIN, 0, 4095},              /* Min Position Limit(52) */
    {60, 1, XT_EEPROM, XT_PLAIN, 0, 3},                 /* Startup Configuration(60) */
    {63, 1, XT_EEPROM, XT_ANY, 0, 0},                   /* Shutdown(63): no Range */
    {64, 1, XT_RAM, XT_TORQUE, 0, 1},                   /* Torque Enable(64): 0..1 */
    {65, 1, XT_RAM, XT_PLAIN, 0, 1},                    /* LED(65): 0..1 */
    {68, 1, XT_RAM, XT_PLAIN, 0, 2},                    /* Status Return Level(68): 0..2 */
    {69, 1, XT_RO, XT_ANY, 0, 0},                       /* Registered Instruction(69) */
    {70, 1, XT_RO, XT_ANY, 0, 0},                       /* Hardware Error Status(70) */
    {76, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Velocity I Gain(76) */
    {78, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Velocity P Gain(78) */
    {80, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Position D Gain(80) */
    {82, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Position I Gain(82) */
    {84, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Position P Gain(84) */
    {88, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Feedforward 2nd Gain(88) */
    {90, 2, XT_RAM, XT_PLAIN, 0, 16383},                /* Feedforward 1st Gain(90) */
    {98, 1, XT_RAM, XT_WATCHDOG, 0, 127},               /* Bus Watchdog(98): 0, 1..127 */
    {100, 2, XT_RAM, XT_GOAL_PWM, 0, 0},                /* Goal PWM(100) */
    {104, 4, XT_RAM, XT_GOAL_VEL, 0, 0},                /* Goal Velocity(104) */
    {108, 4, XT_RAM, XT_PROFILE_ACC, 0, 0},             /* Profile Acceleration(108) */
    {112, 4, XT_RAM, XT_PROFILE_VEL, 0, 0},             /* Profile Velocity(112) */
    {116, 4, XT_RAM, XT_GOAL_POS, 0, 0},                /* Goal Position(116) */
    {120, 2, XT_RO, XT_ANY, 0, 0},                      /* Realtime Tick(120) */
    {122, 1, XT_RO, XT_ANY, 0, 0},                      /* Moving(122) */
    {123, 1, XT_RO, XT_ANY, 0, 0},                      /* Moving Status(123) */
    {124, 2, XT_RO, XT_ANY, 0, 0},                      /* Present PWM(124) */
    {126, 2, XT_RO, XT_ANY, 0, 0},                      /* Present Load(126) */
    {128, 4, XT_RO, XT_ANY, 0, 0},                      /* Present Velocity(128) */
    {132, 4, XT_RO, XT_ANY, 0, 0},                      /* Present Position(132) */
    {136, 4, XT_RO, XT_ANY, 0, 0},                      /* Velocity Trajectory(136) */
    {140, 4, XT_RO, XT_ANY, 0, 0},                      /* Position Trajectory(140) */
    {144, 2, XT_RO, XT_ANY, 0, 0},                      /* Present Input Voltage(144) */
    {146, 1, XT_RO, XT_ANY, 0, 0},                      /* Present Temperature(146) */
};

#define XL430_FIELDS (sizeof(xl430_fields) / sizeof(xl430_fields[0]))

static const xl430_field *xl430_field_at(uint16_t addr)
{
    for (uint8_t i = 0; i < XL430_FIELDS; i++) {
        const xl430_field *f = &xl430_fields[i];
        if (addr >= f->addr && addr < f->addr + f->size) {
            return f;
        }
    }
    return NULL;
}

static int32_t xl430_signed(uint32_t v, uint8_t size)
{
    if (size == 1u) {
        return (int8_t)v;
    }
    if (size == 2u) {
        return (int16_t)v;
    }
    return (int32_t)v;
}

static uint8_t xl430_in(int32_t v, int32_t lo, int32_t hi)
{
    return v >= lo && v <= hi;
}

/* Operating Mode(11) of the XL430: 1 velocity, 3 position, 4 extended
 * position, 16 PWM; no current-based modes. */
static uint8_t xl430_mode_ok(uint32_t v)
{
    return v == DXL_XL430_MODE_VELOCITY || v == DXL_XL430_MODE_POSITION ||
           v == DXL_XL430_MODE_EXTENDED || v == DXL_XL430_MODE_PWM;
}

/* The value check of one whole field; returns 0 or the error number. */
static uint8_t xl430_value_check(const uint8_t *ct, const xl430_field *f, uint32_t raw)
{
    int32_t v = xl430_signed(raw, f->size);
    uint8_t time_based =
        (uint8_t)((ct[DXL_XL430_DRIVE_MODE_ADDR] & DXL_XL430_DRIVE_MODE_TIME_BASED) != 0);
    uint8_t expired = ct[DXL_XL430_BUS_WATCHDOG_ADDR] == DXL_XL430_BUS_WATCHDOG_EXPIRED;
    int32_t lim;
    switch (f->kind) {
    case XT_ANY:
        return 0;
    case XT_PLAIN:
        return (raw >= (uint32_t)f->min && raw <= (uint32_t)f->max) ? 0u : DXL_ERR_DATA_RANGE;
    case XT_SIGNED:
        return xl430_in(v, f->min, f->max) ? 0u : DXL_ERR_DATA_RANGE;
    case XT_OPMODE:
        return xl430_mode_ok(raw) ? 0u : DXL_ERR_DATA_RANGE;
    case XT_TORQUE:
        if (raw > 1u) {
            return DXL_ERR_DATA_RANGE;
        }
        return (raw == 1u && ct[DXL_XL430_HW_ERROR_ADDR] != 0) ? DXL_ERR_RESULT_FAIL : 0u;
    case XT_WATCHDOG:
        return raw <= DXL_XL430_BUS_WATCHDOG_MAX ? 0u : DXL_ERR_DATA_RANGE;
    case XT_GOAL_PWM:
        /* [Bus Watchdog(98)]: after expiry the goals are read-only and a
         * write gets Data Range Error until 0 is written. */
        lim = (int32_t)dxl_get_le(&ct[DXL_XL430_PWM_LIMIT_ADDR], 2);
        return (!expired && xl430_in(v, -lim, lim)) ? 0u : DXL_ERR_DATA_RANGE;
    case XT_GOAL_VEL:
        lim = (int32_t)dxl_get_le(&ct[DXL_XL430_VELOCITY_LIMIT_ADDR], 4);
        return (!expired && xl430_in(v, -lim, lim)) ? 0u : DXL_ERR_DATA_RANGE;
    case XT_PROFILE_ACC:
        lim = time_based ? DXL_XL430_PROFILE_MAX_TIME_BASED : DXL_XL430_PROFILE_MAX;
        return raw <= (uint32_t)lim ? 0u : DXL_ERR_DATA_RANGE;
    case XT_PROFILE_VEL:
        lim = time_based ? DXL_XL430_PROFILE_MAX_TIME_BASED : DXL_XL430_PROFILE_MAX;
        if (!time_based) {
            /* [Velocity Limit(44)]: the maximum of Profile Velocity(112) */
            int32_t vl = (int32_t)dxl_get_le(&ct[DXL_XL430_VELOCITY_LIMIT_ADDR], 4);
            lim = vl < lim ? vl : lim;
        }
        return raw <= (uint32_t)lim ? 0u : DXL_ERR_DATA_RANGE;
    case XT_GOAL_POS:
        if (expired) {
            return DXL_ERR_DATA_RANGE;
        }
        if (ct[DXL_XL430_OPERATING_MODE_ADDR] == DXL_XL430_MODE_EXTENDED) {
            return xl430_in(v, -DXL_XL430_EXTENDED_LIMIT, DXL_XL430_EXTENDED_LIMIT)
                       ? 0u
                       : DXL_ERR_DATA_LIMIT;
        }
        return xl430_in(v, (int32_t)dxl_get_le(&ct[DXL_XL430_MIN_POSITION_ADDR], 4),
                        (int32_t)dxl_get_le(&ct[DXL_XL430_MAX_POSITION_ADDR], 4))
                   ? 0u
                   : DXL_ERR_DATA_LIMIT;
    default:
        return DXL_ERR_ACCESS;
    }
}

uint8_t xl430_table_check(const uint8_t *ct, uint16_t addr, const uint8_t *data, uint16_t n)
{
    uint8_t torque = ct[DXL_XL430_TORQUE_ENABLE_ADDR];
    uint16_t i;
    if (n == 0 || (uint32_t)addr + n > DXL_XL430_TABLE_SIZE) {
        return DXL_ERR_ACCESS;
    }
    /* first the shape of the write: whole fields, defined and writable */
    for (i = 0; i < n;) {
        const xl430_field *f = xl430_field_at((uint16_t)(addr + i));
        if (f == NULL || f->access == XT_RO) {
            return DXL_ERR_ACCESS;
        }
        if (f->addr != addr + i || i + f->size > n) {
            return DXL_ERR_DATA_LENGTH;
        }
        if (f->access == XT_EEPROM && torque) {
            return DXL_ERR_ACCESS; /* "ROM lock" while torque is on */
        }
        i = (uint16_t)(i + f->size);
    }
    /* [Bus Watchdog(98)]: a write of 0 in the same packet clears the expiry
     * before the goals are judged */
    uint8_t view[DXL_XL430_TABLE_SIZE];
    const uint8_t *judge = ct;
    if (addr <= DXL_XL430_BUS_WATCHDOG_ADDR && addr + n > DXL_XL430_BUS_WATCHDOG_ADDR &&
        data[DXL_XL430_BUS_WATCHDOG_ADDR - addr] == 0 &&
        ct[DXL_XL430_BUS_WATCHDOG_ADDR] == DXL_XL430_BUS_WATCHDOG_EXPIRED) {
        for (i = 0; i < DXL_XL430_TABLE_SIZE; i++) {
            view[i] = ct[i];
        }
        view[DXL_XL430_BUS_WATCHDOG_ADDR] = 0;
        judge = view;
    }
    for (i = 0; i < n;) {
        const xl430_field *f = xl430_field_at((uint16_t)(addr + i));
        uint8_t err = xl430_value_check(judge, f, dxl_get_le(&data[i], f->size));
        if (err != 0) {
            return err;
        }
        i = (uint16_t)(i + f->size);
    }
    return 0;
}
