/*
 * probe: a test fixture for the virtual bench, NOT hallhome firmware.
 *
 * A tiny console program on the real board-support drivers (tick, uart0,
 * uart1, twi, reset) that lets the bench tests drive each simulated
 * peripheral by hand before the application uses it. One command per line:
 *
 *   p ID        ping a servo; prints the reply bytes
 *   c ID US     ping, then after US microseconds send a second ping into the
 *               servo's reply (a collision); prints what came back
 *   t ID        ping with the direction pin turned round right after UDR1 is
 *               written (a truncated last byte)
 *   w CH ADDR   select mux channel CH, read WHO_AM_I of ADDR (hex) on it
 *   l           LED: three 100 ms pulses
 *   b           button level (1 = released)
 *   d           enable the watchdog (15 ms) and hang
 *   e ADDR VAL  EEPROM write; r ADDR: EEPROM read
 *   n           console bytes received so far
 *   h           cli + sleep: the simulation ends
 */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <stdlib.h>

#include "board.h"
#include "reset.h"
#include "tick.h"
#include "twi.h"
#include "uart0.h"
#include "uart1.h"

static uint16_t rx_count;

static void put_hex(uint8_t v)
{
    static const char digits[] = "0123456789ABCDEF";
    uart0_write((uint8_t)digits[v >> 4]);
    uart0_write((uint8_t)digits[v & 15u]);
}

static void put_u(uint32_t v)
{
    char buf[11];
    uint8_t n = 0;
    do {
        buf[n++] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v);
    while (n) {
        uart0_write((uint8_t)buf[--n]);
    }
}

/* DYNAMIXEL Protocol 2.0 CRC-16 (poly 0x8005, init 0). */
static uint16_t crc16(const uint8_t *p, uint8_t n)
{
    uint16_t crc = 0;
    while (n--) {
        crc ^= (uint16_t)(*p++) << 8;
        for (uint8_t i = 0; i < 8; i++) {
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x8005u) : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

static void ping_packet(uint8_t *pkt, uint8_t id)
{
    pkt[0] = 0xFF;
    pkt[1] = 0xFF;
    pkt[2] = 0xFD;
    pkt[3] = 0x00;
    pkt[4] = id;
    pkt[5] = 3;
    pkt[6] = 0;
    pkt[7] = 0x01;
    uint16_t c = crc16(pkt, 8);
    pkt[8] = (uint8_t)c;
    pkt[9] = (uint8_t)(c >> 8);
}

static void wait_us(uint32_t us)
{
    uint32_t t0 = tick_us();
    while ((uint32_t)(tick_us() - t0) < us) {
    }
}

/* Collects reply bytes for `ms` and prints them. */
static void dump_rx(uint16_t ms)
{
    uint8_t buf[64];
    uint16_t n = 0;
    uint32_t t0 = tick_ms();
    while ((uint32_t)(tick_ms() - t0) < ms) {
        n = (uint16_t)(n + uart1_read(buf + n, (uint16_t)(sizeof buf - n)));
    }
    uart0_puts_P(PSTR("rx n="));
    put_u(n);
    for (uint16_t i = 0; i < n; i++) {
        uart0_write(' ');
        put_hex(buf[i]);
    }
    uart0_puts_P(PSTR(" errors="));
    put_u(uart1_rx_errors());
    uart0_puts_P(PSTR("\r\n"));
}

static void cmd_ping(uint8_t id, uint16_t second_us)
{
    uint8_t pkt[10];
    ping_packet(pkt, id);
    uart1_write(pkt, sizeof pkt);
    if (second_us) {
        while (!uart1_tx_done()) {
        }
        wait_us(second_us);
        uart1_write(pkt, sizeof pkt);
    }
    dump_rx(5);
}

static void cmd_truncate(uint8_t id)
{
    uint8_t pkt[10];
    ping_packet(pkt, id);
    cli();
    UCSR1B &= (uint8_t) ~(_BV(RXEN1) | _BV(RXCIE1) | _BV(UDRIE1) | _BV(TXCIE1));
    BOARD_DXL_DIR_PORT |= _BV(BOARD_DXL_DIR_BIT);
    for (uint8_t i = 0; i < sizeof pkt; i++) {
        while (!(UCSR1A & _BV(UDRE1))) {
        }
        UDR1 = pkt[i];
    }
    /* turn round at once: the last frame is still in the shift register */
    BOARD_DXL_DIR_PORT &= (uint8_t)~_BV(BOARD_DXL_DIR_BIT);
    UCSR1B |= _BV(RXEN1) | _BV(RXCIE1);
    sei();
    dump_rx(5);
}

static void cmd_twi(uint8_t ch, uint8_t addr)
{
    uint8_t mask = (uint8_t)(1u << ch);
    uint8_t reg = 0;
    uint8_t who = 0;
    int8_t rc = twi_write(BOARD_MUX_ADDR, &mask, 1);
    if (rc == 0) {
        rc = twi_write_read(addr, &reg, 1, &who, 1);
    }
    uart0_puts_P(PSTR("twi rc="));
    if (rc < 0) {
        uart0_write('-');
        rc = (int8_t)-rc;
    }
    put_u((uint8_t)rc);
    uart0_puts_P(PSTR(" who="));
    put_hex(who);
    uart0_puts_P(PSTR(" recoveries="));
    put_u(twi_recoveries());
    uart0_puts_P(PSTR("\r\n"));
}

static void run(char *line)
{
    char *end;
    char c = line[0];
    long a = strtol(line + 1, &end, 0);
    long v = strtol(end, NULL, 0);
    switch (c) {
    case 'p':
        cmd_ping((uint8_t)a, 0);
        break;
    case 'c':
        cmd_ping((uint8_t)a, (uint16_t)v);
        break;
    case 't':
        cmd_truncate((uint8_t)a);
        break;
    case 'w':
        cmd_twi((uint8_t)a, (uint8_t)strtol(end, NULL, 16));
        break;
    case 'l':
        for (uint8_t i = 0; i < 3; i++) {
            BOARD_LED_PORT |= _BV(BOARD_LED_BIT);
            wait_us(100000);
            BOARD_LED_PORT &= (uint8_t)~_BV(BOARD_LED_BIT);
            wait_us(100000);
        }
        uart0_puts_P(PSTR("led done\r\n"));
        break;
    case 'b':
        uart0_puts_P(PSTR("btn="));
        put_u((BOARD_BTN_PIN & _BV(BOARD_BTN_BIT)) ? 1u : 0u);
        uart0_puts_P(PSTR("\r\n"));
        break;
    case 'd':
        uart0_puts_P(PSTR("hang\r\n"));
        uart0_flush();
        wdt_enable(WDTO_15MS);
        for (;;) {
        }
    case 'e':
        eeprom_write_byte((uint8_t *)(uintptr_t)a, (uint8_t)v);
        uart0_puts_P(PSTR("ee ok\r\n"));
        break;
    case 'r':
        uart0_puts_P(PSTR("ee="));
        put_u(eeprom_read_byte((const uint8_t *)(uintptr_t)a));
        uart0_puts_P(PSTR("\r\n"));
        break;
    case 'n':
        uart0_puts_P(PSTR("rx_count="));
        put_u(rx_count);
        uart0_puts_P(PSTR("\r\n"));
        break;
    case 'h':
        uart0_puts_P(PSTR("halt\r\n"));
        uart0_flush();
        cli();
        sleep_cpu();
        break;
    default:
        uart0_puts_P(PSTR("?\r\n"));
        break;
    }
}

int main(void)
{
    char line[32];
    uint8_t len = 0;
    tick_init();
    uart0_init(BOARD_CONSOLE_BAUD);
    uart1_init(BOARD_DXL_BAUD);
    twi_init();
    BOARD_LED_DDR |= _BV(BOARD_LED_BIT);
    BOARD_BTN_DDR &= (uint8_t)~_BV(BOARD_BTN_BIT);
    BOARD_BTN_PORT |= _BV(BOARD_BTN_BIT);
    sei();
    uart0_puts_P(PSTR("<probe reset="));
    uart0_puts_P(reset_cause_P());
    uart0_puts_P(PSTR(">\r\n"));
    for (;;) {
        int16_t ch = uart0_read();
        if (ch < 0) {
            continue;
        }
        rx_count++;
        if (ch == '\r' || ch == '\n') {
            if (len) {
                line[len] = '\0';
                run(line);
                len = 0;
            }
        } else if (len < sizeof line - 1u) {
            line[len++] = (char)ch;
        }
    }
}
