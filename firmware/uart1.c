#include "uart1.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <stddef.h>

#include "board.h"
#include "tick.h"

static volatile uint8_t rx_buf[UART1_RX_SIZE];
static volatile uint8_t rx_head, rx_tail;
static volatile uint16_t rx_overruns, rx_errors;
/* The request being sent, in the caller's buffer (the servo master's own:
 * no ring of copies, 128 bytes of RAM less) */
static const uint8_t *volatile tx_ptr;
static volatile uint8_t tx_left;
static volatile uint8_t tx_active; /* direction is transmit until TXC after the last byte */

static void uart1_dir_tx(void)
{
    UCSR1B &= (uint8_t) ~(_BV(RXEN1) | _BV(RXCIE1));
    BOARD_DXL_DIR_PORT |= _BV(BOARD_DXL_DIR_BIT);
}

/* Always inlined: the transmit-complete interrupt calls it, and a call there
 * makes the interrupt save every call-clobbered register (measured: 46 bytes
 * less flash, and a shorter interrupt). */
__attribute__((always_inline)) static inline void uart1_dir_rx(void)
{
    BOARD_DXL_DIR_PORT &= (uint8_t)~_BV(BOARD_DXL_DIR_BIT);
    UCSR1B |= _BV(RXEN1) | _BV(RXCIE1);
}

ISR(USART1_RX_vect)
{
    uint8_t status = UCSR1A;
    uint8_t byte = UDR1;
    if (status & (_BV(FE1) | _BV(DOR1))) {
        rx_errors++;
        if (status & _BV(FE1)) {
            return; /* a broken frame; the parser's CRC would drop it anyway */
        }
    }
    uint8_t head = rx_head; /* only this interrupt moves it */
    uint8_t next = (uint8_t)(head + 1u);
    if (next == UART1_RX_SIZE) {
        next = 0; /* not a power of two: sized to the robot's servos (uart1.h) */
    }
    if (next == rx_tail) {
        rx_overruns++;
        return;
    }
    rx_buf[head] = byte;
    rx_head = next;
}

/* Data-register-empty: feed the next byte. When the ring is empty the
 * interrupt switches itself off; the transmit-complete interrupt, enabled for
 * the whole transmission, then turns the bus round. */
ISR(USART1_UDRE_vect)
{
    const uint8_t *p = tx_ptr;
    if (tx_left == 0u) {
        UCSR1B &= (uint8_t)~_BV(UDRIE1);
        return;
    }
    UCSR1A = (uint8_t)(_BV(U2X1) | _BV(TXC1)); /* clear TXC: it must mean this byte */
    UDR1 = *p;
    tx_ptr = p + 1;
    tx_left--;
}

/* TXC sets when the shift register is empty and UDR holds nothing: after the
 * last stop bit, or in a gap while bytes are still queued (then UDRE is still
 * enabled and the bus must stay in transmit). */
ISR(USART1_TX_vect)
{
    if (tx_left != 0u || (UCSR1B & _BV(UDRIE1))) {
        return;
    }
    UCSR1B &= (uint8_t)~_BV(TXCIE1);
    uart1_dir_rx();
    tx_active = 0;
}

void uart1_init(uint32_t baud)
{
    uint16_t ubrr = (uint16_t)((F_CPU / 8u + baud / 2u) / baud - 1u);
    BOARD_DXL_DIR_DDR |= _BV(BOARD_DXL_DIR_BIT);
    BOARD_DXL_DIR_PORT &= (uint8_t)~_BV(BOARD_DXL_DIR_BIT);
    UCSR1A = _BV(U2X1); /* before UBRR: a simulator may derive the rate on the UBRR write */
    UBRR1H = (uint8_t)(ubrr >> 8);
    UBRR1L = (uint8_t)ubrr;
    UCSR1C = _BV(UCSZ11) | _BV(UCSZ10);
    UCSR1B = _BV(RXEN1) | _BV(TXEN1) | _BV(RXCIE1);
    rx_head = rx_tail = 0;
    tx_left = 0;
    tx_active = 0;
}

uint16_t uart1_write(const uint8_t *data, uint16_t n)
{
    if (n == 0u || n > UART1_TX_MAX || tx_left != 0u) {
        return 0;
    }
    uint8_t sreg = SREG;
    cli();
    tx_ptr = data;
    tx_left = (uint8_t)n;
    if (!tx_active) {
        tx_active = 1;
        uart1_dir_tx();
    }
    UCSR1B |= _BV(UDRIE1) | _BV(TXCIE1);
    SREG = sreg;
    return n;
}

/* Only this function moves rx_tail: it keeps a copy, stored at each byte
 * taken (the receive interrupt sees the room as soon as it is made). */
uint16_t uart1_read(uint8_t *out, uint16_t cap)
{
    uint16_t n = 0;
    uint8_t tail = rx_tail;
    while (n < cap && tail != rx_head) {
        out[n++] = rx_buf[tail];
        tail = (uint8_t)(tail + 1u == UART1_RX_SIZE ? 0u : tail + 1u);
        rx_tail = tail;
    }
    return n;
}

void uart1_set_dir(uint8_t dir)
{
    uint8_t sreg = SREG;
    cli();
    if (dir == DXL_DIR_TX) {
        tx_active = 1;
        uart1_dir_tx();
    } else if (tx_left == 0u && !(UCSR1B & (_BV(UDRIE1) | _BV(TXCIE1)))) {
        tx_active = 0;
        uart1_dir_rx();
    }
    SREG = sreg;
}

uint8_t uart1_tx_done(void)
{
    if (tx_active || tx_left != 0u) {
        return 0;
    }
    return 1;
}

uint16_t uart1_rx_overruns(void)
{
    uint8_t sreg = SREG;
    cli();
    uint16_t n = rx_overruns;
    SREG = sreg;
    return n;
}

uint16_t uart1_rx_errors(void)
{
    uint8_t sreg = SREG;
    cli();
    uint16_t n = rx_errors;
    SREG = sreg;
    return n;
}

#if DXL_PORT_FIXED
/* The master's one port (lib/dxl/dxl.h, DXL_PORT_FIXED). */
uint16_t dxl_port_write(const uint8_t *data, uint16_t n)
{
    return uart1_write(data, n);
}

uint16_t dxl_port_read(uint8_t *out, uint16_t cap)
{
    return uart1_read(out, cap);
}

void dxl_port_set_dir(uint8_t dir)
{
    uart1_set_dir(dir);
}

uint8_t dxl_port_tx_done(void)
{
    return uart1_tx_done();
}

uint32_t dxl_port_now_us(void)
{
    return tick_us();
}
#else
static uint16_t uart1_port_write(void *ctx, const uint8_t *data, uint16_t n)
{
    (void)ctx;
    return uart1_write(data, n);
}

static uint16_t uart1_port_read(void *ctx, uint8_t *out, uint16_t cap)
{
    (void)ctx;
    return uart1_read(out, cap);
}

static void uart1_port_set_dir(void *ctx, uint8_t dir)
{
    (void)ctx;
    uart1_set_dir(dir);
}

static uint8_t uart1_port_tx_done(void *ctx)
{
    (void)ctx;
    return uart1_tx_done();
}

static uint32_t uart1_port_now(void *ctx)
{
    (void)ctx;
    return tick_us();
}

/* Member by member: an initialised local is copied from a template the AVR
 * keeps in RAM. */
dxl_port uart1_port(void)
{
    dxl_port p;
    p.ctx = NULL;
    p.write = uart1_port_write;
    p.read = uart1_port_read;
    p.set_dir = uart1_port_set_dir;
    p.tx_done = uart1_port_tx_done;
    p.now_us = uart1_port_now;
    return p;
}
#endif
