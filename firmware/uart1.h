/*
 * uart1: the servo bus, UART1 (TX1 PD3, RX1 PD2) through a half-duplex
 * buffer whose direction pin is BOARD_DXL_DIR_* (high = transmit).
 *
 * Interrupt-driven in both directions. Writing queues bytes and turns the bus
 * to transmit; the direction goes back to receive in the transmit-complete
 * interrupt, i.e. only after the last stop bit has left the shift register
 * (switching on the data-register-empty interrupt would cut the last byte).
 * The receiver is off while transmitting, so an echo of our own bytes is
 * never read back. Nothing here blocks.
 *
 * uart1_port() gives the dxl_port (lib/dxl/dxl.h) the servo master uses, or
 * with DXL_PORT_FIXED uart1.c defines the master's port functions.
 */
#ifndef HALLHOME_UART1_H
#define HALLHOME_UART1_H

#include <stdint.h>

#include "dxl/dxl.h"

/* The longest reply burst must fit while a main-loop pass runs. Every group
 * read is a fast sync read (the bring-up's too, dxl_bringup.c), one packet
 * of 8 + 8 bytes a servo for Present Position (104 bytes for 12 servos;
 * every other reply is a single servo's, and the scan pings one at a time),
 * and the ring holds one byte less than its size: 9 + 8 bytes a servo,
 * rounded up to 8 (96 for 10 servos, 64 for 6). At most 256 (uint8_t
 * indices). (Plain sync reads' replies, 15 bytes a servo back to back,
 * needed 256 beyond 6 servos.) */
#define UART1_RX_SIZE ((9u + 8u * DXL_MAX_IDS + 7u) / 8u * 8u)
#if UART1_RX_SIZE > 256u
#error "a fast sync read of Present Position from DXL_MAX_IDS servos overflows UART1_RX_SIZE"
#endif
#define UART1_TX_MAX 255u /* longest request uart1_write() sends (uint8_t count) */

/* Configures UART1 at `baud` (8N1, U2X: 1 Mbps and 2 Mbps are exact at
 * 16 MHz, 57600 is -0.8 %), the direction pin as an output in receive, and
 * enables the receive interrupt. Interrupts must be enabled by the caller. */
void uart1_init(uint32_t baud);

/* Starts sending data[0..n) straight from the caller's buffer, which must
 * stay unchanged until uart1_tx_done() (the servo master's request buffer
 * does: it is rebuilt only for the next transaction). Returns n, or 0 while
 * an earlier request is still being sent (or n is 0 or over UART1_TX_MAX):
 * the caller tries again later. */
uint16_t uart1_write(const uint8_t *data, uint16_t n);

/* Copies up to cap received bytes into out; returns how many. */
uint16_t uart1_read(uint8_t *out, uint16_t cap);

/* Drives the direction pin. Transmit also disables the receiver; receive is
 * refused (ignored) while bytes are still being sent, so a caller can never
 * cut a frame. */
void uart1_set_dir(uint8_t dir);

/* Nonzero when nothing is queued or being shifted out and the bus is in receive. */
uint8_t uart1_tx_done(void);

/* Bytes dropped because the receive ring was full, and frames received with
 * a framing or data-overrun error, since init. */
uint16_t uart1_rx_overruns(void);
uint16_t uart1_rx_errors(void);

#if !DXL_PORT_FIXED
/* The dxl_port on UART1 and tick_us(); the returned struct may be copied. */
dxl_port uart1_port(void);
#endif

#endif /* HALLHOME_UART1_H */
