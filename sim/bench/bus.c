/*
 * bus: UART1 as the half-duplex servo bus of the board (74LVC2G241-style
 * buffer, direction pin PE4 high = the MCU drives the bus).
 *
 * Every byte on the wire has a window [start, end] of 11 bit times (simavr
 * sends 11 bits per frame). An MCU byte starts when the firmware writes UDR1
 * (or when the previous frame ends) and reaches the servos at the end of its
 * stop bit; a servo byte reaches the MCU and the other servos at the time the
 * model gives for its stop bit. Two frames whose windows overlap collide and
 * both arrive corrupted. Turning the direction pin to receive while an MCU
 * frame is still being shifted out cuts it: the bits not yet sent read as
 * idle (1). Bytes for the MCU go through simavr's 63-byte RX FIFO under its
 * XON/XOFF flow control, and are lost while the buffer faces the other way
 * or the receiver is disabled. Injected noise flips one bit of a byte with a
 * given probability.
 */
#define _POSIX_C_SOURCE 200809L
#include <string.h>

#include <avr_ioport.h>
#include <avr_uart.h>
#include <sim_io.h>

#include "bench.h"
#include "simrand.h"

#define BUS_MCU_BAUD 1000000u

static uint64_t bus_rand(bench_bus_t *s)
{
    return simrand_next(&s->rng);
}

static uint8_t bus_corrupt(bench_bus_t *s, uint8_t byte)
{
    s->corrupted++;
    return (uint8_t)(byte ^ (uint8_t)(1u + bus_rand(s) % 255u));
}

static uint8_t bus_noise(bench_bus_t *s, uint8_t byte)
{
    if (s->noise_rate > 0.0 &&
        (double)(bus_rand(s) >> 11) * (1.0 / 9007199254740992.0) < s->noise_rate) {
        s->noise_hits++;
        s->corrupted++;
        return (uint8_t)(byte ^ (uint8_t)(1u << (bus_rand(s) & 7u)));
    }
    return byte;
}

static uint32_t servo_byte_us(const xl430 *m)
{
    uint32_t baud = xl430_baud(m);
    return (uint32_t)(((uint64_t)m->cfg.bits_per_byte * 1000000u + baud - 1u) / baud);
}

/* The rate UART1 runs at now (UBRR1, U2X1). */
static uint32_t mcu_baud(const bench_t *b)
{
    const uint8_t *d = b->avr->data;
    uint32_t ubrr = (uint32_t)d[BENCH_UBRR1L] | (uint32_t)(d[BENCH_UBRR1L + 1u] & 0x0Fu) << 8;
    uint32_t div = (d[BENCH_UCSR1A] & 0x02u) ? 8u : 16u;
    return BENCH_F_CPU / ((ubrr + 1u) * div);
}

/* A UART decodes a sender within about 3 % of its own rate; beyond that it
 * sees framing errors and garbage, which the bench delivers as nothing. */
static int baud_match(uint32_t a, uint32_t b)
{
    uint32_t d = a > b ? a - b : b - a;
    return (uint64_t)d * 100u < (uint64_t)b * 3u;
}

static void hist_add(bench_bus_t *s, uint64_t start, uint64_t end, int8_t src)
{
    s->hist[s->hist_pos].start_us = start;
    s->hist[s->hist_pos].end_us = end;
    s->hist[s->hist_pos].src = src;
    s->hist_pos = (uint8_t)((s->hist_pos + 1u) % BUS_HIST);
}

static uint64_t servo_due(const bench_bus_t *s, uint8_t i, uint64_t ref)
{
    uint8_t byte;
    uint32_t due;
    if (!xl430_tx_peek(&s->servo[i], &byte, &due)) {
        return 0;
    }
    uint64_t d = (ref & ~0xFFFFFFFFull) | due;
    if (d + 0x80000000ull < ref) {
        d += 0x100000000ull;
    } else if (d > ref + 0x80000000ull) {
        d -= 0x100000000ull;
    }
    return d;
}

/* Nonzero when a frame of another source overlaps [start, end]. */
static int overlaps(const bench_bus_t *s, uint64_t start, uint64_t end, int8_t src)
{
    for (unsigned i = 0; i < BUS_HIST; i++) {
        const bus_window_t *w = &s->hist[i];
        if (w->end_us == 0 || w->src == src) {
            continue;
        }
        if (w->start_us < end && start < w->end_us) {
            return 1;
        }
    }
    if (src >= 0) {
        for (uint8_t q = s->mcu_tail; q != s->mcu_head; q++) {
            uint64_t ms = s->mcu_start[q];
            if (ms < end && start < ms + s->byte_us) {
                return 1;
            }
        }
    }
    for (uint8_t i = 0; i < s->n_servos; i++) {
        if ((int8_t)i == src || s->silent[i]) {
            continue;
        }
        uint64_t se = servo_due(s, i, end);
        if (se == 0) {
            continue;
        }
        uint64_t ss = se - servo_byte_us(&s->servo[i]);
        if (ss < end && start < se) {
            return 1;
        }
    }
    return 0;
}

static void rx_push(bench_t *b, uint8_t byte)
{
    bench_bus_t *s = &b->bus;
    uint8_t ucsrb = b->avr->data[BENCH_UCSR1B];
    if (s->dir_tx || !(ucsrb & 0x10u)) { /* RXEN1 */
        s->lost_rx_disabled++;
        return;
    }
    if (!s->xoff && s->rx_head == s->rx_tail) {
        s->delivered_rx++;
        avr_raise_irq(s->rx_irq, byte);
        return;
    }
    if ((uint8_t)(s->rx_head + 1u) == s->rx_tail) {
        s->lost_rx_disabled++;
        return;
    }
    s->rx_q[s->rx_head++] = byte;
}

static void bus_xon(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    bench_bus_t *s = &b->bus;
    (void)irq;
    (void)value;
    s->xoff = 0;
    while (!s->xoff && s->rx_tail != s->rx_head) {
        s->delivered_rx++;
        avr_raise_irq(s->rx_irq, s->rx_q[s->rx_tail++]);
    }
}

static void bus_xoff(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    (void)irq;
    (void)value;
    if (!b->bus.xoff) {
        b->bus.xoff_events++;
    }
    b->bus.xoff = 1;
}

static void bus_mcu_byte(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    bench_bus_t *s = &b->bus;
    uint64_t now = bench_now_us(b);
    uint64_t start = now > s->mcu_busy_until ? now : s->mcu_busy_until;
    (void)irq;
    s->mcu_baud = mcu_baud(b);
    s->byte_us = (uint32_t)((11u * 1000000u + s->mcu_baud - 1u) / s->mcu_baud);
    if (s->trace) {
        fprintf(stderr, "bus %10llu us mcu %02X start %llu dir %u\n", (unsigned long long)now,
                (unsigned)value & 0xFFu, (unsigned long long)start, s->dir_tx);
    }
    s->mcu_busy_until = start + s->byte_us;
    if (!s->dir_tx) {
        s->mcu_bytes_no_dir++;
        return;
    }
    if ((uint8_t)(s->mcu_head + 1u) == s->mcu_tail) {
        s->mcu_bytes_no_dir++; /* cannot happen at 1 Mbps; counted, not crashed */
        return;
    }
    s->mcu_bytes++;
    truth_bus_byte(b, now);
    s->mcu_q[s->mcu_head] = (uint8_t)value;
    s->mcu_start[s->mcu_head] = start;
    s->mcu_out[s->mcu_head] = now;
    s->mcu_head++;
    bench_rearm(b);
}

/* PE4 is also INT4. simavr 1.6 polls a level-triggered external interrupt
 * every cycle while its pin bit reads low, enabled or not (EICRB = 0 is
 * level mode), which slows the simulation fifty-fold whenever the bus is in
 * receive. The pin is an output, so the firmware reads PORTE there and never
 * this bit: keeping the input bit high stops the polling at its first look. */
void bus_pin_high(bench_t *b)
{
    b->avr->data[BENCH_PINE] |= 0x10u;
}

static void porte_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)avr;
    (void)addr;
    (void)v;
    bus_pin_high(param);
}

/* Direction pin. Receive while a frame is still being shifted out cuts it;
 * frames not yet started never reach the bus. */
static void bus_dir(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    bench_bus_t *s = &b->bus;
    uint64_t now = bench_now_us(b);
    (void)irq;
    if (s->trace) {
        fprintf(stderr, "bus %10llu us dir %u\n", (unsigned long long)now, (unsigned)value);
    }
    bus_pin_high(b);
    if (value && !s->dir_tx) {
        s->dir_tx = 1;
        return;
    }
    if (value || !s->dir_tx) {
        return;
    }
    s->dir_tx = 0;
    uint8_t keep = s->mcu_tail;
    for (uint8_t q = s->mcu_tail; q != s->mcu_head; q++) {
        uint64_t st = s->mcu_start[q];
        /* Cut or not is judged on simavr's own frame clock, the one its
         * TXC follows: a UDR1 write that an interrupt delayed past a frame
         * time goes out at once, but simavr's next UDRE (and TXC) keeps its
         * period, so the wire here (one frame after another) lags it by a
         * few microseconds. A firmware that turns the bus round at TXC, as
         * a real USART's TXC allows, was then seen to cut its last byte
         * (chaos seed 2090: the early release after a watchdog reset lost
         * its goals to a CRC error). Turning round before TXC still cuts. */
        uint64_t out = s->mcu_out[q];
        if (out >= now) {
            s->mcu_bytes_no_dir++;
            continue;
        }
        if (out + s->byte_us > now) {
            uint64_t bits = (now - out) * s->mcu_baud / 1000000u; /* start bit first */
            unsigned sent = bits > 1u ? (unsigned)(bits - 1u) : 0u;
            if (sent < 8u) {
                s->mcu_q[q] |= (uint8_t)(0xFFu << sent);
            }
            s->truncated++;
            s->corrupted++;
        }
        s->mcu_q[keep] = s->mcu_q[q];
        s->mcu_start[keep] = st;
        keep++;
    }
    s->mcu_head = keep;
    if (s->mcu_busy_until > now) {
        s->mcu_busy_until = now;
    }
}

/* simavr sets TXC1 for every byte as soon as UDR1 is written; clearing it here
 * makes TXC1 mean "the last frame has left" (its own timer sets it again). */
static void bus_udr1_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)addr;
    (void)v;
    (void)param;
    avr->data[BENCH_UCSR1A] &= (uint8_t)~0x40u;
}

void bus_init(bench_t *b)
{
    bench_bus_t *s = &b->bus;
    s->mcu_baud = BUS_MCU_BAUD;
    s->byte_us = 11u * 1000000u / BUS_MCU_BAUD;
    s->rng = 0x9E3779B97F4A7C15ull ^ ((uint64_t)b->seed << 17) ^ b->seed;
    if (s->rng == 0) {
        s->rng = 1;
    }
}

void bus_attach_irqs(bench_t *b)
{
    bench_bus_t *s = &b->bus;
    avr_t *avr = b->avr;
    s->rx_irq = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('1'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('1'), UART_IRQ_OUTPUT),
                            bus_mcu_byte, b);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('1'), UART_IRQ_OUT_XON),
                            bus_xon, b);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('1'), UART_IRQ_OUT_XOFF),
                            bus_xoff, b);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 4), bus_dir, b);
    avr_register_io_write(avr, BENCH_UDR1, bus_udr1_write, b);
    avr_register_io_write(avr, BENCH_PINE + 2u, porte_write, b); /* PORTE */
}

uint64_t bus_next_us(bench_t *b)
{
    bench_bus_t *s = &b->bus;
    uint64_t now = bench_now_us(b);
    uint64_t next = 0;
    if (s->mcu_tail != s->mcu_head) {
        next = s->mcu_start[s->mcu_tail] + s->byte_us;
    }
    for (uint8_t i = 0; i < s->n_servos; i++) {
        uint64_t d = servo_due(s, i, now);
        if (d != 0 && (next == 0 || d < next)) {
            next = d;
        }
    }
    return next;
}

static void deliver_mcu_byte(bench_t *b)
{
    bench_bus_t *s = &b->bus;
    uint8_t byte = s->mcu_q[s->mcu_tail];
    uint64_t start = s->mcu_start[s->mcu_tail];
    uint64_t end = start + s->byte_us;
    s->mcu_tail++;
    if (overlaps(s, start, end, -1)) {
        s->collisions++;
        byte = bus_corrupt(s, byte);
    }
    uint8_t sent = byte;
    byte = bus_noise(s, byte);
    if (s->trace && byte != sent) {
        fprintf(stderr, "bus %10llu us noise mcu %02X->%02X\n", (unsigned long long)end, sent,
                byte);
    }
    hist_add(s, start, end, -1);
    for (uint8_t i = 0; i < s->n_servos; i++) {
        if (s->silent[i]) {
            continue;
        }
        if (!baud_match(xl430_baud(&s->servo[i]), s->mcu_baud)) {
            s->baud_mismatch++;
            continue;
        }
        xl430_rx(&s->servo[i], byte, (uint32_t)end);
    }
}

static void deliver_servo_byte(bench_t *b, uint8_t i, uint64_t due)
{
    bench_bus_t *s = &b->bus;
    uint8_t byte;
    uint32_t due32;
    xl430_tx_peek(&s->servo[i], &byte, &due32);
    xl430_tx_pop(&s->servo[i]);
    if (s->silent[i]) {
        return;
    }
    s->servo_bytes++;
    uint64_t start = due - servo_byte_us(&s->servo[i]);
    if (overlaps(s, start, due, (int8_t)i)) {
        s->collisions++;
        byte = bus_corrupt(s, byte);
    }
    byte = bus_noise(s, byte);
    hist_add(s, start, due, (int8_t)i);
    if (s->trace) {
        fprintf(stderr, "bus %10llu us servo %u %02X start %llu\n", (unsigned long long)due, i,
                byte, (unsigned long long)start);
    }
    uint32_t baud = xl430_baud(&s->servo[i]);
    for (uint8_t k = 0; k < s->n_servos; k++) {
        if (k != i && !s->silent[k] && baud_match(xl430_baud(&s->servo[k]), baud)) {
            xl430_rx(&s->servo[k], byte, due32);
        }
    }
    if (!baud_match(mcu_baud(b), baud)) {
        s->baud_mismatch++;
        return;
    }
    rx_push(b, byte);
}

void bus_service(bench_t *b, uint64_t now)
{
    bench_bus_t *s = &b->bus;
    for (;;) {
        uint64_t best = 0;
        int who = -2;
        if (s->mcu_tail != s->mcu_head) {
            best = s->mcu_start[s->mcu_tail] + s->byte_us;
            who = -1;
        }
        for (uint8_t i = 0; i < s->n_servos; i++) {
            uint64_t d = servo_due(s, i, now);
            if (d != 0 && (who == -2 || d < best)) {
                best = d;
                who = i;
            }
        }
        if (who == -2 || best > now) {
            return;
        }
        if (who == -1) {
            deliver_mcu_byte(b);
        } else {
            deliver_servo_byte(b, (uint8_t)who, best);
        }
    }
}

void bus_power_cycle(bench_t *b, uint64_t now_us)
{
    bench_bus_t *s = &b->bus;
    for (uint8_t i = 0; i < s->n_servos; i++) {
        xl430_power_cycle(&s->servo[i], (uint32_t)now_us);
    }
    s->mcu_head = s->mcu_tail = 0;
    s->rx_head = s->rx_tail = 0;
    s->mcu_busy_until = now_us;
    s->dir_tx = 0;
}
