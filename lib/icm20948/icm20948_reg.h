/*
 * icm20948_reg.h: ICM-20948 and AK09916 registers used by the icm20948 driver
 * and by the register-level model in sim/devices.
 *
 * Sources: TDK InvenSense DS-000189 "ICM-20948 Datasheet" rev. 1.3
 * (section 7 register map, 8 user bank 0 descriptions, 11 user bank 3
 * descriptions, 12 magnetometer register map, 13 magnetometer register
 * descriptions) and AKM AK09916C datasheet (register map and descriptions).
 */
#ifndef HALLHOME_ICM20948_REG_H
#define HALLHOME_ICM20948_REG_H

/* I2C addresses (DS-000189 "I2C interface": the AD0 pin is the address LSB). */
#define ICM_REG_ADDR_AD0_LOW  0x68u
#define ICM_REG_ADDR_AD0_HIGH 0x69u

/* REG_BANK_SEL, every bank, 0x7F (DS-000189 sections 8 and 11, REG_BANK_SEL): USER_BANK
 * in bits 5:4. */
#define ICM_REG_BANK_SEL   0x7Fu
#define ICM_REG_BANK_SHIFT 4u
#define ICM_REG_BANK_MASK  0x30u

/* --- User bank 0 (DS-000189 section 8) --- */
#define ICM_REG_WHO_AM_I   0x00u /* reads 0xEA */
#define ICM_REG_WHO_AM_I_V 0xEAu

#define ICM_REG_USER_CTRL        0x03u
#define ICM_REG_USER_I2C_MST_EN  0x20u /* bit 5: enable the I2C master */
#define ICM_REG_USER_I2C_IF_DIS  0x10u /* bit 4: SPI only */
#define ICM_REG_USER_I2C_MST_RST 0x02u /* bit 1: reset the I2C master, self-clearing */

#define ICM_REG_LP_CONFIG        0x05u
#define ICM_REG_LP_I2C_MST_CYCLE 0x40u /* bit 6: master runs at I2C_MST_ODR_CONFIG */

#define ICM_REG_PWR_MGMT_1      0x06u
#define ICM_REG_PWR_DEVICE_RST  0x80u /* bit 7: reset every register, self-clearing */
#define ICM_REG_PWR_SLEEP       0x40u /* bit 6: reset value is 1 (asleep) */
#define ICM_REG_PWR_CLKSEL_AUTO 0x01u /* bits 2:0 = 1: best available clock */
#define ICM_REG_PWR_RESET_VALUE 0x41u /* 7.1 reset value */

/* PWR_MGMT_2 (8.5): DISABLE_ACCEL bits 5:3, DISABLE_GYRO bits 2:0, reset 0x00
 * (both on). With both off the I2C master runs at I2C_MST_ODR_CONFIG (11.1);
 * with the gyro on it follows the gyro ODR, else the accelerometer's. */
#define ICM_REG_PWR_MGMT_2       0x07u
#define ICM_REG_PWR2_ACCEL_OFF   0x38u
#define ICM_REG_PWR2_GYRO_OFF    0x07u
#define ICM_REG_PWR2_SENSORS_OFF 0x3Fu

#define ICM_REG_INT_PIN_CFG   0x0Fu
#define ICM_REG_INT_BYPASS_EN 0x02u /* bit 1 */

#define ICM_REG_I2C_MST_STATUS   0x17u /* cleared on read */
#define ICM_REG_MST_PASS_THROUGH 0x80u
#define ICM_REG_MST_SLV4_DONE    0x40u
#define ICM_REG_MST_LOST_ARB     0x20u
#define ICM_REG_MST_SLV4_NACK    0x10u
#define ICM_REG_MST_SLV0_NACK    0x01u

#define ICM_REG_EXT_SLV_SENS_DATA_00 0x3Bu /* 24 bytes, 0x3B..0x52 */
#define ICM_REG_EXT_SLV_SENS_LEN     24u

/* --- User bank 3 (DS-000189 section 11) --- */
/* I2C_MST_ODR_CONFIG (11.1): the master polls at 1.1 kHz / 2^ODR_CONFIG[3:0]
 * when the gyro and accelerometer are off and LP_CONFIG.I2C_MST_CYCLE is set.
 * 3 gives 137.5 Hz (7.27 ms), the slowest rate above the AK09916's 100 Hz, so
 * every sample is still read once; 4 (68.75 Hz) would skip samples. */
#define ICM_REG_I2C_MST_ODR_CONFIG 0x00u
#define ICM_REG_MST_ODR_BASE_HZ    1100u
#define ICM_REG_MST_ODR_137HZ      3u
#define ICM_REG_I2C_MST_CTRL       0x01u /* 11.2 */
#define ICM_REG_MST_P_NSR          0x10u /* bit 4: stop between slave reads */
#define ICM_REG_MST_CLK_345KHZ     0x07u /* bits 3:0 = 7: 345.6 kHz, the recommended setting */
/* I2C_MST_DELAY_CTRL (11.3) bit 7 DELAY_ES_SHADOW: the EXT_SLV_SENS_DATA
 * copy is updated only once every byte of the slave read has arrived, so a
 * host read never sees half of one sample and half of the next. */
#define ICM_REG_I2C_MST_DELAY_CTRL 0x02u
#define ICM_REG_DELAY_ES_SHADOW    0x80u

#define ICM_REG_I2C_SLV0_ADDR 0x03u /* bit 7 = read */
#define ICM_REG_I2C_SLV0_REG  0x04u
#define ICM_REG_I2C_SLV0_CTRL 0x05u
#define ICM_REG_I2C_SLV0_DO   0x06u

#define ICM_REG_I2C_SLV4_ADDR 0x13u
#define ICM_REG_I2C_SLV4_REG  0x14u
#define ICM_REG_I2C_SLV4_CTRL 0x15u /* bit 7 EN (cleared when done), 4:0 DLY */
#define ICM_REG_I2C_SLV4_DO   0x16u
#define ICM_REG_I2C_SLV4_DI   0x17u

#define ICM_REG_SLV_ADDR_READ 0x80u /* SLVx_ADDR bit 7: I2C_SLVx_RNW */
#define ICM_REG_SLV_CTRL_EN   0x80u /* SLVx_CTRL bit 7: I2C_SLVx_EN */
#define ICM_REG_SLV_CTRL_LENG 0x0Fu /* SLV0..3_CTRL bits 3:0: bytes to read */

/* --- AK09916 behind the auxiliary bus (DS-000189 sections 12 and 13) --- */
#define AK_REG_ADDR            0x0Cu /* 7-bit address, fixed */
#define AK_REG_WIA1            0x00u /* 13.1: company ID, 0x48 */
#define AK_REG_WIA1_V          0x48u
#define AK_REG_WIA2            0x01u /* 13.1: device ID, 0x09 */
#define AK_REG_WIA2_V          0x09u
#define AK_REG_ST1             0x10u /* 13.2 */
#define AK_REG_ST1_DRDY        0x01u /* data ready; cleared by reading HXL..TMPS or ST2 */
#define AK_REG_ST1_DOR         0x02u /* a sample was skipped; cleared like DRDY */
#define AK_REG_HXL             0x11u /* 13.3: HXL..HZH little-endian two's complement */
#define AK_REG_TMPS            0x17u /* dummy */
#define AK_REG_ST2             0x18u /* reading ST2 ends the read cycle */
#define AK_REG_ST2_HOFL        0x08u /* bit 3: magnetic sensor overflow */
#define AK_REG_CNTL2           0x31u /* MODE[4:0] */
#define AK_REG_MODE_POWER_DOWN 0x00u
#define AK_REG_MODE_SINGLE     0x01u
#define AK_REG_MODE_CONT_10HZ  0x02u
#define AK_REG_MODE_CONT_20HZ  0x04u
#define AK_REG_MODE_CONT_50HZ  0x06u
#define AK_REG_MODE_CONT_100HZ 0x08u
#define AK_REG_MODE_SELF_TEST  0x10u
#define AK_REG_CNTL3           0x32u
#define AK_REG_CNTL3_SRST      0x01u /* soft reset, self-clearing */

/* ST1..ST2 read as one block by SLV0 (0x10..0x18). */
#define AK_REG_BLOCK_LEN 9u

/* Data format (13.3): 0.15 uT per LSB, each axis -32752..32752 (+-4912 uT). */
#define AK_REG_LSB_CUT         15 /* 0.15 uT = 15 cuT */
#define AK_REG_RAW_MAX         32752
#define AK_REG_PERIOD_100HZ_US 10000u

#endif /* HALLHOME_ICM20948_REG_H */
