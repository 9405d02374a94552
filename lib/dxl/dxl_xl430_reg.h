/*
 * dxl_xl430_reg: control table of the ROBOTIS DYNAMIXEL XL430-W250-T, the
 * fields hallhome uses (and the ones the servo model keeps so that reads of
 * neighbouring addresses behave).
 *
 * Source: ROBOTIS e-manual, "XL430-W250-T", section 2 "Control Table"
 * (2.1 Control Table of EEPROM Area, 2.2 Control Table of RAM Area, and the
 * per-field subsections cited beside each entry). All multi-byte fields are
 * little-endian. EEPROM fields can be written only while Torque Enable is 0
 * (e-manual 2.1, "Area (EEPROM, RAM)").
 *
 * Each field has an _ADDR and a _SIZE (bytes); the unit is in the comment.
 */
#ifndef HALLHOME_DXL_XL430_REG_H
#define HALLHOME_DXL_XL430_REG_H

/* Model Number reported by ping and at address 0 (e-manual 2.1, Model Number). */
#define DXL_XL430_MODEL_NUMBER 1060u

/* Encoder resolution: 4096 ticks per revolution (e-manual 2.4.22, Present Position). */
#define DXL_XL430_TICKS_PER_REV 4096u

/* Size of the modelled table: addresses 0..146 (Present Temperature is last). */
#define DXL_XL430_TABLE_SIZE 147u

/* --- EEPROM area (e-manual 2.1) ------------------------------------------- */
#define DXL_XL430_MODEL_NUMBER_ADDR 0u /* 2 bytes, read-only */
#define DXL_XL430_MODEL_NUMBER_SIZE 2u
#define DXL_XL430_MODEL_INFO_ADDR   2u /* 4 bytes, read-only */
#define DXL_XL430_MODEL_INFO_SIZE   4u
#define DXL_XL430_FIRMWARE_ADDR     6u /* 1 byte, read-only */
#define DXL_XL430_FIRMWARE_SIZE     1u
#define DXL_XL430_ID_ADDR           7u /* 1 byte, 0..252, default 1 (e-manual 2.3.1) */
#define DXL_XL430_ID_SIZE           1u

/* Baud Rate (e-manual 2.3.2): index, default 1. */
#define DXL_XL430_BAUD_ADDR   8u
#define DXL_XL430_BAUD_SIZE   1u
#define DXL_XL430_BAUD_9600   0u
#define DXL_XL430_BAUD_57600  1u
#define DXL_XL430_BAUD_115200 2u
#define DXL_XL430_BAUD_1M     3u
#define DXL_XL430_BAUD_2M     4u
#define DXL_XL430_BAUD_3M     5u
#define DXL_XL430_BAUD_4M     6u
#define DXL_XL430_BAUD_4M5    7u

/* Return Delay Time (e-manual 2.3.3): 2 us units, 0..254, default 250 (500 us). */
#define DXL_XL430_RETURN_DELAY_ADDR    9u
#define DXL_XL430_RETURN_DELAY_SIZE    1u
#define DXL_XL430_RETURN_DELAY_UNIT_US 2u

/* Drive Mode (e-manual 2.3.4): bit0 reverse direction, bit2 time-based profile. */
#define DXL_XL430_DRIVE_MODE_ADDR       10u
#define DXL_XL430_DRIVE_MODE_SIZE       1u
#define DXL_XL430_DRIVE_MODE_REVERSE    0x01u
#define DXL_XL430_DRIVE_MODE_TIME_BASED 0x04u

/* Operating Mode (e-manual 2.3.5); writing it resets profile and gains. */
#define DXL_XL430_OPERATING_MODE_ADDR 11u
#define DXL_XL430_OPERATING_MODE_SIZE 1u
#define DXL_XL430_MODE_VELOCITY       1u
#define DXL_XL430_MODE_POSITION       3u /* default, 0..4095 */
#define DXL_XL430_MODE_EXTENDED       4u /* +-256 rev, multi-turn lost at power-up/reboot */
#define DXL_XL430_MODE_PWM            16u

#define DXL_XL430_SECONDARY_ID_ADDR  12u /* 1 byte (e-manual 2.3.6) */
#define DXL_XL430_PROTOCOL_TYPE_ADDR 13u /* 1 byte, 2 = Protocol 2.0 (e-manual 2.3.7) */

/* Homing Offset (e-manual 2.3.8): 4 bytes signed, ticks, added to Present Position. */
#define DXL_XL430_HOMING_OFFSET_ADDR 20u
#define DXL_XL430_HOMING_OFFSET_SIZE 4u

/* Moving Threshold (e-manual 2.3.9): 4 bytes, 0.229 rpm, default 10. */
#define DXL_XL430_MOVING_THRESHOLD_ADDR 24u
#define DXL_XL430_MOVING_THRESHOLD_SIZE 4u

#define DXL_XL430_TEMPERATURE_LIMIT_ADDR 31u /* 1 byte, degC, default 72 (e-manual 2.3.10) */
#define DXL_XL430_MAX_VOLTAGE_ADDR       32u /* 2 bytes, 0.1 V, default 140 (e-manual 2.3.11) */
#define DXL_XL430_MIN_VOLTAGE_ADDR       34u /* 2 bytes, 0.1 V, default 60 */
#define DXL_XL430_PWM_LIMIT_ADDR         36u /* 2 bytes, 0.113 %, default 885 (e-manual 2.3.12) */
#define DXL_XL430_VELOCITY_LIMIT_ADDR    44u /* 4 bytes, 0.229 rpm, default 265 (e-manual 2.3.13) */
#define DXL_XL430_MAX_POSITION_ADDR      48u /* 4 bytes, ticks, default 4095 (e-manual 2.3.14) */
#define DXL_XL430_MIN_POSITION_ADDR      52u /* 4 bytes, ticks, default 0 */

/* Shutdown (e-manual 2.3.15): hardware error bits that switch torque off; default 0x34. */
#define DXL_XL430_SHUTDOWN_ADDR 63u
#define DXL_XL430_SHUTDOWN_SIZE 1u

/* --- RAM area (e-manual 2.2) ---------------------------------------------- */
/* Torque Enable (e-manual 2.4.1): 0 off, 1 on. */
#define DXL_XL430_TORQUE_ENABLE_ADDR 64u
#define DXL_XL430_TORQUE_ENABLE_SIZE 1u
#define DXL_XL430_LED_ADDR           65u /* 1 byte (e-manual 2.4.2) */

/* Status Return Level (e-manual 2.4.3): 0 ping only, 1 ping+read, 2 all (default). */
#define DXL_XL430_STATUS_RETURN_LEVEL_ADDR 68u
#define DXL_XL430_STATUS_RETURN_LEVEL_SIZE 1u
#define DXL_XL430_REGISTERED_ADDR          69u /* 1 byte, read-only (e-manual 2.4.4) */

/* Hardware Error Status (e-manual 2.4.5): read-only; any set bit raises the
 * alert bit (0x80) of every status packet's error byte; only a reboot clears it. */
#define DXL_XL430_HW_ERROR_ADDR      70u
#define DXL_XL430_HW_ERROR_SIZE      1u
#define DXL_XL430_HW_ERR_VOLTAGE     0x01u /* bit0 input voltage */
#define DXL_XL430_HW_ERR_OVERHEATING 0x04u /* bit2 */
#define DXL_XL430_HW_ERR_ENCODER     0x08u /* bit3 motor encoder */
#define DXL_XL430_HW_ERR_ELECTRICAL  0x10u /* bit4 electrical shock */
#define DXL_XL430_HW_ERR_OVERLOAD    0x20u /* bit5 */

#define DXL_XL430_VELOCITY_I_GAIN_ADDR 76u /* 2 bytes (e-manual 2.4.6) */
#define DXL_XL430_VELOCITY_P_GAIN_ADDR 78u /* 2 bytes */
#define DXL_XL430_POSITION_D_GAIN_ADDR 80u /* 2 bytes (e-manual 2.4.7) */
#define DXL_XL430_POSITION_I_GAIN_ADDR 82u /* 2 bytes */
#define DXL_XL430_POSITION_P_GAIN_ADDR 84u /* 2 bytes, default 640 */
#define DXL_XL430_FEEDFORWARD_2_ADDR   88u /* 2 bytes (e-manual 2.4.8) */
#define DXL_XL430_FEEDFORWARD_1_ADDR   90u /* 2 bytes */

/* Bus Watchdog (e-manual 2.4.9): 20 ms units, 0 disables; after it expires
 * the servo stops, the field reads 0xFF (-1) and goal writes are refused
 * with Data Range Error until 0 is written. */
#define DXL_XL430_BUS_WATCHDOG_ADDR    98u
#define DXL_XL430_BUS_WATCHDOG_SIZE    1u
#define DXL_XL430_BUS_WATCHDOG_UNIT_US 20000u
#define DXL_XL430_BUS_WATCHDOG_EXPIRED 0xFFu

#define DXL_XL430_GOAL_PWM_ADDR      100u /* 2 bytes, 0.113 % (e-manual 2.4.10) */
#define DXL_XL430_GOAL_VELOCITY_ADDR 104u /* 4 bytes, 0.229 rpm (e-manual 2.4.11) */

/* Profile Acceleration (e-manual 2.4.12): 4 bytes, 214.577 rev/min^2, 0 = infinite. */
#define DXL_XL430_PROFILE_ACCELERATION_ADDR 108u
#define DXL_XL430_PROFILE_ACCELERATION_SIZE 4u
/* Profile Velocity (e-manual 2.4.13): 4 bytes, 0.229 rpm, 0 = infinite. */
#define DXL_XL430_PROFILE_VELOCITY_ADDR 112u
#define DXL_XL430_PROFILE_VELOCITY_SIZE 4u
/* The two profile units above as floating-point constants, for host-side models only. */
#define DXL_XL430_VELOCITY_UNIT_RPM 0.229
#define DXL_XL430_ACCEL_UNIT_RPM2   214.577

/* Goal Position (e-manual 2.4.14): 4 bytes signed, ticks; extended mode
 * range -1048575..1048575. */
#define DXL_XL430_GOAL_POSITION_ADDR 116u
#define DXL_XL430_GOAL_POSITION_SIZE 4u
#define DXL_XL430_EXTENDED_LIMIT     1048575L

#define DXL_XL430_REALTIME_TICK_ADDR 120u /* 2 bytes, ms, read-only (e-manual 2.4.15) */

/* Moving (e-manual 2.4.16): 1 while the profile runs or the error exceeds the threshold. */
#define DXL_XL430_MOVING_ADDR 122u
#define DXL_XL430_MOVING_SIZE 1u

/* Moving Status (e-manual 2.4.17): bit0 in-position, bit1 profile ongoing,
 * bit3 following error, bits 5:4 profile type (3 trapezoidal). */
#define DXL_XL430_MOVING_STATUS_ADDR        123u
#define DXL_XL430_MOVING_STATUS_SIZE        1u
#define DXL_XL430_MOVING_STATUS_IN_POSITION 0x01u
#define DXL_XL430_MOVING_STATUS_PROFILE     0x02u
#define DXL_XL430_MOVING_STATUS_TRAPEZOID   0x30u

#define DXL_XL430_PRESENT_PWM_ADDR 124u /* 2 bytes, read-only (e-manual 2.4.18) */

/* Present Load (e-manual 2.4.19): 2 bytes signed, 0.1 % of max torque;
 * estimated from PWM, the XL430 has no current sensor. */
#define DXL_XL430_PRESENT_LOAD_ADDR 126u
#define DXL_XL430_PRESENT_LOAD_SIZE 2u

#define DXL_XL430_PRESENT_VELOCITY_ADDR 128u /* 4 bytes signed, 0.229 rpm (e-manual 2.4.20) */

/* Present Position (e-manual 2.4.22): 4 bytes signed, ticks (plus Homing Offset). */
#define DXL_XL430_PRESENT_POSITION_ADDR 132u
#define DXL_XL430_PRESENT_POSITION_SIZE 4u

#define DXL_XL430_VELOCITY_TRAJECTORY_ADDR 136u /* 4 bytes (e-manual 2.4.23) */
#define DXL_XL430_POSITION_TRAJECTORY_ADDR 140u /* 4 bytes (e-manual 2.4.24) */

/* Present Input Voltage (e-manual 2.4.25): 2 bytes, 0.1 V. */
#define DXL_XL430_PRESENT_VOLTAGE_ADDR 144u
#define DXL_XL430_PRESENT_VOLTAGE_SIZE 2u

/* Present Temperature (e-manual 2.4.26): 1 byte, degC. */
#define DXL_XL430_PRESENT_TEMPERATURE_ADDR 146u
#define DXL_XL430_PRESENT_TEMPERATURE_SIZE 1u

#endif /* HALLHOME_DXL_XL430_REG_H */
