/*
 * twi: the ATmega2560's TWI as a polled I2C master at BOARD_TWI_HZ (400 kHz),
 * exposed to the portable sensor driver as an icm_bus_t.
 *
 * Every wait for the hardware has a deadline (TWI_BYTE_DEADLINE_US per bus
 * phase, checked against tick_us(), plus an iteration cap so a stopped clock
 * cannot hang it). A transfer of n bytes therefore returns within about
 * (n + 3) ms in the worst case and in (9 n + 3) / 400 kHz plus a few
 * microseconds per byte normally. On a timeout or bus error the TWI is reset
 * and the bus recovered (twi_recover) before returning.
 *
 * Return codes are the icm_bus_err values of icm20948/icm20948.h: 0 done,
 * ICM_BUS_E_ADDR_NACK, ICM_BUS_E_DATA_NACK, ICM_BUS_E_TIMEOUT, ICM_BUS_E_BUS.
 */
#ifndef HALLHOME_TWI_H
#define HALLHOME_TWI_H

#include <stdint.h>

#include "icm20948/icm20948.h"

#define TWI_BYTE_DEADLINE_US 1000u /* one byte takes 22.5 us; the rest is clock stretching */

/* Configures the TWI for BOARD_TWI_HZ (prescaler 1, TWBR = (F_CPU / hz - 16) / 2)
 * and enables it. The tick timer must be running. */
void twi_init(void);

/* START, addr+W, len bytes, STOP. Returns 0 or an ICM_BUS_E_* code. */
int8_t twi_write(uint8_t addr, const uint8_t *data, uint8_t len);

/* START, addr+W, wlen bytes, repeated START, addr+R, rlen bytes (ACK all but
 * the last), STOP. Returns 0 or an ICM_BUS_E_* code. */
int8_t twi_write_read(uint8_t addr, const uint8_t *wdata, uint8_t wlen, uint8_t *rdata,
                      uint8_t rlen);

/* Bus recovery: with the TWI off, clocks SCL (open drain, 100 kHz) up to 9
 * times until a slave holding SDA low releases it, then sends STOP and
 * re-enables the TWI. Returns 0 when SDA and SCL are both high afterwards,
 * ICM_BUS_E_BUS otherwise. Takes at most about 9 * (10 us + clock stretch
 * deadline). */
int8_t twi_recover(void);

/* Recoveries performed since twi_init (diagnostics). */
uint16_t twi_recoveries(void);

/* The bus interface for icm_setup() / icm_set_setup(). */
#if !ICM_BUS_FIXED
const icm_bus_t *twi_bus(void);
#endif

#endif /* HALLHOME_TWI_H */
