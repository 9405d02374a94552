/*
 * uart0: the console UART (USB on the Mega), interrupt-driven with RX and TX
 * ring buffers. Nothing here blocks except uart0_write() when the TX ring is
 * full, which waits at most for the bytes ahead of it to leave (bounded by
 * the ring size at 115200 baud: about 11 ms).
 */
#ifndef HALLHOME_UART0_H
#define HALLHOME_UART0_H

#include <stdint.h>

/* Power of two. The console's streaming rule (docs/console.md): a host may
 * send a line while the lines it sent and has no final reply for, this one
 * included, hold at most UART0_RX_SIZE - 1 bytes; then no byte is ever lost.
 * Bytes that are lost anyway are counted (uart0_rx_overruns()) and the gap is
 * marked with a NUL in the stream, which the console refuses as a bad
 * character, so a line cut in two never runs as a command. */
#define UART0_RX_SIZE 128u
/* Power of two, at most 256 (uint8_t indices). 256: a calibration's burst of
 * reports fits, so writing them does not stall the main loop (a full ring
 * drains at 87 us per byte). */
#define UART0_TX_SIZE 256u

/* Realtime byte hook: called from the RX interrupt for every received byte;
 * returns nonzero when it consumed the byte (it is then not queued). */
typedef uint8_t (*uart0_rt_hook_fn)(uint8_t byte);

/* Configures UART0 at `baud` (8N1, U2X) and enables its interrupts. */
void uart0_init(uint32_t baud);

/* Installs (or with NULL removes) the realtime hook. */
void uart0_set_rt_hook(uart0_rt_hook_fn hook);

/* Next received byte (0..255), or -1 when none is waiting. */
int16_t uart0_read(void);

/* Bytes dropped because the RX ring was full, since init. */
uint16_t uart0_rx_overruns(void);

/* Bytes uart0_write() takes now without waiting. */
uint16_t uart0_tx_room(void);

/* Queues one byte for transmission. */
void uart0_write(uint8_t byte);

/* Puts n bytes at offset off behind the bytes queued, where they are not
 * sent until committed; off + n must stay within uart0_tx_room(). */
void uart0_tx_stage(uint8_t off, const uint8_t *buf, uint8_t n);

/* Queues the first n bytes staged (uart0_tx_stage()) for transmission. */
void uart0_tx_commit(uint8_t n);

/* Queues a NUL-terminated string. */
void uart0_puts(const char *s);

/* Queues a NUL-terminated string held in program memory. */
void uart0_puts_P(const char *s_P);

/* Waits until every queued byte has left the shift register (bounded by the
 * ring size). Used before a reset. */
void uart0_flush(void);

#endif /* HALLHOME_UART0_H */
