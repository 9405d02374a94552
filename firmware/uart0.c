#include "uart0.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <stddef.h>

static volatile uint8_t rx_buf[UART0_RX_SIZE];
static volatile uint8_t rx_head, rx_tail;
static volatile uint16_t rx_overruns;
static volatile uint8_t rx_gap; /* bytes were lost: mark the gap before the next byte */
static volatile uint8_t tx_buf[UART0_TX_SIZE];
static volatile uint8_t tx_head, tx_tail;
static volatile uart0_rt_hook_fn rt_hook;

ISR(USART0_RX_vect)
{
    uint8_t status = UCSR0A;
    uint8_t byte = UDR0;
    uart0_rt_hook_fn hook = rt_hook;
    if (status & _BV(FE0)) {
        return; /* framing error: a broken byte is no command */
    }
    if (hook != NULL && hook(byte)) {
        return;
    }
    uint8_t next = (uint8_t)((rx_head + 1u) & (UART0_RX_SIZE - 1u));
    if (rx_gap && next != rx_tail) {
        /* a NUL where bytes were lost: the console refuses the line the gap
         * cut (a control byte), so two halves never pass as one command */
        rx_buf[rx_head] = 0u;
        rx_head = next;
        next = (uint8_t)((rx_head + 1u) & (UART0_RX_SIZE - 1u));
        rx_gap = 0;
    }
    if (next == rx_tail) {
        rx_overruns++;
        rx_gap = 1;
        return;
    }
    rx_buf[rx_head] = byte;
    rx_head = next;
}

ISR(USART0_UDRE_vect)
{
    if (tx_head == tx_tail) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = tx_buf[tx_tail];
    tx_tail = (uint8_t)((tx_tail + 1u) & (UART0_TX_SIZE - 1u));
}

void uart0_init(uint32_t baud)
{
    uint16_t ubrr = (uint16_t)((F_CPU / 8u + baud / 2u) / baud - 1u);
    UBRR0H = (uint8_t)(ubrr >> 8);
    UBRR0L = (uint8_t)ubrr;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

void uart0_set_rt_hook(uart0_rt_hook_fn hook)
{
    uint8_t sreg = SREG;
    cli();
    rt_hook = hook;
    SREG = sreg;
}

int16_t uart0_read(void)
{
    if (rx_head == rx_tail) {
        return -1;
    }
    uint8_t byte = rx_buf[rx_tail];
    rx_tail = (uint8_t)((rx_tail + 1u) & (UART0_RX_SIZE - 1u));
    return byte;
}

uint16_t uart0_tx_room(void)
{
    return (uint16_t)((tx_tail - tx_head - 1u) & (UART0_TX_SIZE - 1u));
}

uint16_t uart0_rx_overruns(void)
{
    uint8_t sreg = SREG;
    cli();
    uint16_t n = rx_overruns;
    SREG = sreg;
    return n;
}

/* A full ring empties at one byte per 87 us, so the wait is bounded; with
 * interrupts off (never the case in hallhome's main loop) the byte is
 * pushed out by polling UDRE instead of deadlocking. */
void uart0_write(uint8_t byte)
{
    uint8_t next = (uint8_t)((tx_head + 1u) & (UART0_TX_SIZE - 1u));
    while (next == tx_tail) {
        if (!(SREG & _BV(SREG_I)) && (UCSR0A & _BV(UDRE0))) {
            UDR0 = tx_buf[tx_tail];
            tx_tail = (uint8_t)((tx_tail + 1u) & (UART0_TX_SIZE - 1u));
        }
    }
    tx_buf[tx_head] = byte;
    tx_head = next;
    UCSR0A = _BV(U2X0) | _BV(TXC0); /* writing 1 clears TXC0; U2X0 stays set */
    UCSR0B |= _BV(UDRIE0);
}

void uart0_tx_stage(uint8_t off, const uint8_t *buf, uint8_t n)
{
    uint8_t i = (uint8_t)(tx_head + off);
    while (n-- > 0u) {
        tx_buf[i & (UART0_TX_SIZE - 1u)] = *buf++;
        i++;
    }
}

void uart0_tx_commit(uint8_t n)
{
    tx_head = (uint8_t)((tx_head + n) & (UART0_TX_SIZE - 1u));
    UCSR0A = _BV(U2X0) | _BV(TXC0); /* as uart0_write() */
    UCSR0B |= _BV(UDRIE0);
}

void uart0_puts(const char *s)
{
    while (*s != '\0') {
        uart0_write((uint8_t)*s++);
    }
}

void uart0_puts_P(const char *s_P)
{
    char c;
    while ((c = (char)pgm_read_byte(s_P++)) != '\0') {
        uart0_write((uint8_t)c);
    }
}

/* TXC0 is cleared on every queued byte, so once the ring is empty it rises
 * when the last stop bit has left; the spin bound (~2 ms) covers a UART that
 * was never enabled. */
void uart0_flush(void)
{
    while (tx_head != tx_tail && (UCSR0B & _BV(UDRIE0))) {
    }
    for (uint16_t spin = 0; spin < 8000u && !(UCSR0A & _BV(TXC0)); spin++) {
    }
}
