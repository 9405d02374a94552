/*
 * dxl_xl430_reg: control table of the ROBOTIS DYNAMIXEL XL430-W250-T, the
 * fields hallhome uses (and the ones the servo model keeps so that reads of
 * neighbouring addresses behave).
 *
 * Source: ROBOTIS e-manual, page "XL430-W250" (emanual.robotis.com/docs/en/
 * dxl/x/xl430-w250/), section "Control Table": the tables "Control Table of
 * EEPROM Area" and "Control Table of RAM Area", and the description of each
 * field, which the page titles "<Name>(<Address>)", e.g. "Return Delay
 * Time(9)"; that title is cited beside each entry below as [Name(Address)].
 * All multi-byte fields are little-endian. EEPROM fields can be written only
 * while Torque Enable is 0 (section "Area (EEPROM, RAM)").
 *
 * Each field has an _ADDR and a _SIZE (bytes); the unit is in the comment.
 */
#ifndef HALLHOME_DXL_XL430_REG_H
#define HALLHOME_DXL_XL430_REG_H

/* Model Number reported by ping and at address 0 [Model Number(0)]. */
#define DXL_XL430_MODEL_NUMBER 1060u

/* Encoder resolution: 4096 ticks per revolution [Present Position(132)]. */
#define DXL_XL430_TICKS_PER_REV 4096u

/* Size of the modelled table: addresses 0..146 (Present Temperature is last). */
#define DXL_XL430_TABLE_SIZE 147u

/* --- EEPROM area ("Control Table of EEPROM Area") --------------------------- */
#define DXL_XL430_MODEL_NUMBER_ADDR 0u /* 2 bytes, read-only */
#define DXL_XL430_MODEL_NUMBER_SIZE 2u
#define DXL_XL430_MODEL_INFO_ADDR   2u /* 4 bytes, read-only */
#define DXL_XL430_MODEL_INFO_SIZE   4u
#define DXL_XL430_FIRMWARE_ADDR     6u /* 1 byte, read-only */
#define DXL_XL430_FIRMWARE_SIZE     1u
#define DXL_XL430_ID_ADDR           7u /* 1 byte, 0..252, default 1 [ID(7)] */
#define DXL_XL430_ID_SIZE           1u

/* [Baud Rate(8)]: index, default 1. */
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

/* [Return Delay Time(9)]: 2 us units, 0..254, default 250 (500 us). */
#define DXL_XL430_RETURN_DELAY_ADDR    9u
#define DXL_XL430_RETURN_DELAY_SIZE    1u
#define DXL_XL430_RETURN_DELAY_UNIT_US 2u

/* [Drive Mode(10)]: bit0 reverse direction, bit2 time-based profile. */
#define DXL_XL430_DRIVE_MODE_ADDR       10u
#define DXL_XL430_DRIVE_MODE_SIZE       1u
#define DXL_XL430_DRIVE_MODE_REVERSE    0x01u
#define DXL_XL430_DRIVE_MODE_TIME_BASED 0x04u

/* [Operating Mode(11)]; writing it resets profile and gains. */
#define DXL_XL430_OPERATING_MODE_ADDR 11u
#define DXL_XL430_OPERATING_MODE_SIZE 1u
#define DXL_XL430_MODE_VELOCITY       1u
#define DXL_XL430_MODE_POSITION       3u /* default, 0..4095 */
#define DXL_XL430_MODE_EXTENDED       4u /* +-256 rev, multi-turn lost at power-up/reboot */
#define DXL_XL430_MODE_PWM            16u

#define DXL_XL430_SECONDARY_ID_ADDR  12u /* 1 byte [Secondary(Shadow) ID(12)] */
#define DXL_XL430_PROTOCOL_TYPE_ADDR 13u /* 1 byte, 2 = Protocol 2.0 [Protocol Type(13)] */

/* [Homing Offset(20)]: 4 bytes signed, ticks, added to Present Position. */
#define DXL_XL430_HOMING_OFFSET_ADDR 20u
#define DXL_XL430_HOMING_OFFSET_SIZE 4u

/* [Moving Threshold(24)]: 4 bytes, 0.229 rpm, default 10. */
#define DXL_XL430_MOVING_THRESHOLD_ADDR 24u
#define DXL_XL430_MOVING_THRESHOLD_SIZE 4u

#define DXL_XL430_TEMPERATURE_LIMIT_ADDR                                                           \
    31u /* 1 byte, degC, default 72 [Temperature Limit(31)]                                        \
         */
#define DXL_XL430_MAX_VOLTAGE_ADDR                                                                 \
    32u /* 2 bytes, 0.1 V, default 140 [Max/Min Voltage Limit(32, 34)] */
#define DXL_XL430_MIN_VOLTAGE_ADDR 34u /* 2 bytes, 0.1 V, default 60 */
#define DXL_XL430_PWM_LIMIT_ADDR   36u /* 2 bytes, 0.113 %, default 885 [PWM Limit(36)] */
#define DXL_XL430_VELOCITY_LIMIT_ADDR                                                              \
    44u /* 4 bytes, 0.229 rpm, default 265 [Velocity Limit(44)]                                    \
         */
#define DXL_XL430_MAX_POSITION_ADDR                                                                \
    48u /* 4 bytes, ticks, default 4095 [Max/Min Position Limit(48, 52)] */
#define DXL_XL430_MIN_POSITION_ADDR 52u /* 4 bytes, ticks, default 0 */

/* [Velocity Limit(44)] default since firmware 42; the field also caps Goal
 * Velocity(104) and Profile Velocity(112): a servo answers Data Range Error
 * to a Profile Velocity above it (velocity-based profile). */
#define DXL_XL430_VELOCITY_LIMIT_DEFAULT 265u

/* [Startup Configuration(60)]: 1 byte, 0..3. */
#define DXL_XL430_STARTUP_CONFIG_ADDR 60u

/* [Shutdown(63)]: hardware error bits that switch torque off; default 0x34. */
#define DXL_XL430_SHUTDOWN_ADDR 63u
#define DXL_XL430_SHUTDOWN_SIZE 1u

/* --- RAM area ("Control Table of RAM Area") ---------------------------------- */
/* [Torque Enable(64)]: 0 off, 1 on. */
#define DXL_XL430_TORQUE_ENABLE_ADDR 64u
#define DXL_XL430_TORQUE_ENABLE_SIZE 1u
#define DXL_XL430_LED_ADDR           65u /* 1 byte [LED(65)] */

/* [Status Return Level(68)]: 0 ping only, 1 ping+read, 2 all (default). */
#define DXL_XL430_STATUS_RETURN_LEVEL_ADDR 68u
#define DXL_XL430_STATUS_RETURN_LEVEL_SIZE 1u
#define DXL_XL430_REGISTERED_ADDR          69u /* 1 byte, read-only [Registered Instruction(69)] */

/* [Hardware Error Status(70)]: read-only; any set bit raises the
 * alert bit (0x80) of every status packet's error byte; only a reboot clears it. */
#define DXL_XL430_HW_ERROR_ADDR      70u
#define DXL_XL430_HW_ERROR_SIZE      1u
#define DXL_XL430_HW_ERR_VOLTAGE     0x01u /* bit0 input voltage */
#define DXL_XL430_HW_ERR_OVERHEATING 0x04u /* bit2 */
#define DXL_XL430_HW_ERR_ENCODER     0x08u /* bit3 motor encoder */
#define DXL_XL430_HW_ERR_ELECTRICAL  0x10u /* bit4 electrical shock */
#define DXL_XL430_HW_ERR_OVERLOAD    0x20u /* bit5 */

#define DXL_XL430_VELOCITY_I_GAIN_ADDR 76u /* 2 bytes [Velocity PI Gain(76, 78)] */
#define DXL_XL430_VELOCITY_P_GAIN_ADDR 78u /* 2 bytes */
#define DXL_XL430_POSITION_D_GAIN_ADDR 80u /* 2 bytes [Position PID Gain(80, 82, 84)] */
#define DXL_XL430_POSITION_I_GAIN_ADDR 82u /* 2 bytes */
#define DXL_XL430_POSITION_P_GAIN_ADDR 84u /* 2 bytes, default 640 */
#define DXL_XL430_FEEDFORWARD_2_ADDR   88u /* 2 bytes [Feedforward Gain(88, 90)] */
#define DXL_XL430_FEEDFORWARD_1_ADDR   90u /* 2 bytes */

/* [Bus Watchdog(98)]: 20 ms units, 0 disables; after it expires
 * the servo stops, the field reads 0xFF (-1) and goal writes are refused
 * with Data Range Error until 0 is written. */
#define DXL_XL430_BUS_WATCHDOG_ADDR    98u
#define DXL_XL430_BUS_WATCHDOG_SIZE    1u
#define DXL_XL430_BUS_WATCHDOG_UNIT_US 20000u
#define DXL_XL430_BUS_WATCHDOG_EXPIRED 0xFFu
#define DXL_XL430_BUS_WATCHDOG_MAX     127u /* Range 1..127 (0 disables) */

#define DXL_XL430_GOAL_PWM_ADDR      100u /* 2 bytes, 0.113 % [Goal PWM(100)] */
#define DXL_XL430_GOAL_VELOCITY_ADDR 104u /* 4 bytes, 0.229 rpm [Goal Velocity(104)] */

/* [Profile Acceleration(108)]: 4 bytes, 214.577 rev/min^2, 0 = infinite. */
#define DXL_XL430_PROFILE_ACCELERATION_ADDR 108u
#define DXL_XL430_PROFILE_ACCELERATION_SIZE 4u
/* [Profile Velocity(112)]: 4 bytes, 0.229 rpm, 0 = infinite. */
#define DXL_XL430_PROFILE_VELOCITY_ADDR 112u
#define DXL_XL430_PROFILE_VELOCITY_SIZE 4u
/* Range of both profile fields [Profile Acceleration(108)], [Profile
 * Velocity(112)]: 0..32767 with the velocity-based profile, 0..32737 with the
 * time-based one; Profile Velocity is further capped by Velocity Limit(44). */
#define DXL_XL430_PROFILE_MAX            32767L
#define DXL_XL430_PROFILE_MAX_TIME_BASED 32737L
/* The two profile units above as floating-point constants, for host-side models only. */
#define DXL_XL430_VELOCITY_UNIT_RPM 0.229
#define DXL_XL430_ACCEL_UNIT_RPM2   214.577

/* [Goal Position(116)]: 4 bytes signed, ticks; extended mode
 * range -1048575..1048575. */
#define DXL_XL430_GOAL_POSITION_ADDR 116u
#define DXL_XL430_GOAL_POSITION_SIZE 4u
#define DXL_XL430_EXTENDED_LIMIT     1048575L

#define DXL_XL430_REALTIME_TICK_ADDR 120u /* 2 bytes, ms, read-only [Realtime Tick(120)] */

/* [Moving(122)]: 1 while the profile runs or the error exceeds the threshold. */
#define DXL_XL430_MOVING_ADDR 122u
#define DXL_XL430_MOVING_SIZE 1u

/* [Moving Status(123)]: bit0 in-position, bit1 profile ongoing,
 * bit3 following error, bits 5:4 profile type (3 trapezoidal). */
#define DXL_XL430_MOVING_STATUS_ADDR        123u
#define DXL_XL430_MOVING_STATUS_SIZE        1u
#define DXL_XL430_MOVING_STATUS_IN_POSITION 0x01u
#define DXL_XL430_MOVING_STATUS_PROFILE     0x02u
#define DXL_XL430_MOVING_STATUS_TRAPEZOID   0x30u

#define DXL_XL430_PRESENT_PWM_ADDR 124u /* 2 bytes, read-only [Present PWM(124)] */

/* [Present Load(126)]: 2 bytes signed, 0.1 % of max torque;
 * estimated from PWM, the XL430 has no current sensor. */
#define DXL_XL430_PRESENT_LOAD_ADDR 126u
#define DXL_XL430_PRESENT_LOAD_SIZE 2u

#define DXL_XL430_PRESENT_VELOCITY_ADDR                                                            \
    128u /* 4 bytes signed, 0.229 rpm [Present Velocity(128)]                                      \
          */

/* [Present Position(132)]: 4 bytes signed, ticks (plus Homing Offset). */
#define DXL_XL430_PRESENT_POSITION_ADDR 132u
#define DXL_XL430_PRESENT_POSITION_SIZE 4u

#define DXL_XL430_VELOCITY_TRAJECTORY_ADDR 136u /* 4 bytes [Velocity Trajectory(136)] */
#define DXL_XL430_POSITION_TRAJECTORY_ADDR 140u /* 4 bytes [Position Trajectory(140)] */

/* [Present Input Voltage(144)]: 2 bytes, 0.1 V. */
#define DXL_XL430_PRESENT_VOLTAGE_ADDR 144u
#define DXL_XL430_PRESENT_VOLTAGE_SIZE 2u

/* [Present Temperature(146)]: 1 byte, degC. */
#define DXL_XL430_PRESENT_TEMPERATURE_ADDR 146u
#define DXL_XL430_PRESENT_TEMPERATURE_SIZE 1u

#endif /* HALLHOME_DXL_XL430_REG_H */
