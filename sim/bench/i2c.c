/*
 * i2c: the TWI of the simulated MCU, with simavr 1.6's two TWI bugs worked
 * around (sim's notes: status after a write address byte, TWINT not cleared
 * by writing 1), dispatching bus conditions to byte-level slave models
 * (devices/tca9548a_model.h): the TCA9548A at 0x70 and, behind it, one
 * ICM-20948 (with its AK09916) per sensor of the plant.
 *
 * Faults: a sensor or the mux unplugged (never acknowledges), and a slave
 * holding SDA low. While SDA is held the TWI cannot complete anything: TWINT
 * never reads as set, so the firmware's deadlines expire; SDA is read low on
 * PD1. The slave lets go after the firmware, with the TWI disabled, has
 * clocked SCL (PD0, open drain through DDRD) the given number of times.
 */
#define _POSIX_C_SOURCE 200809L
#include <string.h>

#include <avr_ioport.h>
#include <avr_twi.h>
#include <sim_io.h>

#include "bench.h"

#define TW_MT_SLA_ACK   0x18u
#define TW_MT_SLA_NACK  0x20u
#define TW_MT_DATA_ACK  0x28u
#define TW_MT_DATA_NACK 0x30u
#define TWCR_TWINT      0x80u
#define SCL_BIT         0x01u /* PD0 */
#define SDA_BIT         0x02u /* PD1 */

static void twi_reply(bench_t *b, uint8_t msg, uint8_t addr, uint8_t data)
{
    avr_raise_irq(b->twi.in_irq, avr_twi_irq_msg(msg, addr, data));
}

void twi_bench_lines(bench_t *b)
{
    bench_twi_t *t = &b->twi;
    uint8_t ddr = b->avr->data[BENCH_DDRD];
    avr_ioport_external_t ext;
    /* PD2/PD3 are RXD1/TXD1: an idle UART line is high. They are also INT2
     * and INT3, which simavr 1.6 polls every cycle while they read low. */
    t->ext_d_mask = SCL_BIT | SDA_BIT | 0x0Cu;
    t->ext_d_value = (uint8_t)(SCL_BIT | 0x0Cu | (t->stuck ? 0u : SDA_BIT));
    ext.name = 'D';
    ext.mask = t->ext_d_mask;
    ext.value = t->ext_d_value;
    avr_ioctl(b->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL('D'), &ext);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 2), 1);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 3), 1);
    if (!(ddr & SCL_BIT)) {
        avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 0), 1);
    }
    if (!(ddr & SDA_BIT)) {
        avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('D'), 1), t->stuck ? 0 : 1);
    }
}

static void twi_output(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    bench_twi_t *t = &b->twi;
    avr_twi_msg_irq_t m;
    (void)irq;
    m.u.v = value;
    uint8_t msg = m.u.twi.msg;
    uint8_t addr = m.u.twi.addr;
    if (t->stuck) {
        if (msg & (TWI_COND_START | TWI_COND_WRITE | TWI_COND_READ)) {
            t->stuck_refused++;
        }
        if (msg & TWI_COND_READ) {
            twi_reply(b, TWI_COND_READ, addr, 0x00);
        }
        return;
    }
    if (msg & TWI_COND_STOP) {
        t->stops++;
        for (uint8_t i = 0; i < t->n_top; i++) {
            t->top[i].stop(t->top[i].ctx);
        }
        t->cur = -1;
        t->addr_phase = 0;
    }
    if (msg & TWI_COND_START) {
        uint8_t ack = 0;
        t->starts++;
        twi_bench_advance(b, bench_now_us(b));
        t->cur = -1;
        for (uint8_t i = 0; i < t->n_top; i++) {
            if (t->top[i].start(t->top[i].ctx, addr) && t->cur < 0) {
                t->cur = (int8_t)i;
                ack = 1;
            }
        }
        t->cur_addr = addr;
        t->addr_phase = (uint8_t) !(addr & 1u);
        if (ack) {
            t->addr_acks++;
        } else {
            t->addr_nacks++;
        }
        twi_reply(b, TWI_COND_ACK, addr, ack);
        return;
    }
    if (msg & TWI_COND_WRITE) {
        uint8_t ack = 0;
        t->writes++;
        if (t->cur >= 0) {
            ack = t->top[t->cur].write(t->top[t->cur].ctx, m.u.twi.data);
        }
        twi_reply(b, TWI_COND_ACK, addr, ack);
        return;
    }
    if (msg & TWI_COND_READ) {
        uint8_t byte = 0xFF; /* nobody drives SDA: the pull-up reads 1s */
        t->reads++;
        if (t->cur >= 0) {
            byte = t->top[t->cur].read(t->top[t->cur].ctx, (msg & TWI_COND_ACK) ? 1u : 0u);
        }
        twi_reply(b, TWI_COND_READ, addr, byte);
    }
}

/* Bug 1: after a write address byte simavr reports the data-byte codes. */
static void twi_status(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    bench_twi_t *t = &b->twi;
    (void)irq;
    if (!t->addr_phase || value == 0x08u || value == 0x10u) {
        return;
    }
    t->addr_phase = 0;
    uint8_t fixed = (uint8_t)value;
    if (value == TW_MT_DATA_ACK) {
        fixed = TW_MT_SLA_ACK;
    } else if (value == TW_MT_DATA_NACK) {
        fixed = TW_MT_SLA_NACK;
    }
    if (fixed != value) {
        t->status_fixes++;
        b->avr->data[BENCH_TWSR] = (uint8_t)((b->avr->data[BENCH_TWSR] & 0x07u) | fixed);
    }
}

/* Bug 2: writing 1 to TWINT must clear it. */
static void twcr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)param;
    if (v & TWCR_TWINT) {
        avr->data[addr] &= (uint8_t)~TWCR_TWINT;
    }
}

static uint8_t twcr_read(avr_t *avr, avr_io_addr_t addr, void *param)
{
    bench_t *b = param;
    uint8_t v = avr->data[addr];
    if (b->twi.stuck) {
        v &= (uint8_t)~TWCR_TWINT;
    }
    return v;
}

/* SCL and SDA as open-drain GPIO during bus recovery. */
static void ddrd_write(avr_irq_t *irq, uint32_t v, void *param)
{
    bench_t *b = param;
    bench_twi_t *t = &b->twi;
    uint8_t low = (uint8_t)(v & SCL_BIT);
    (void)irq;
    if (t->scl_low && !low) {
        t->scl_clocks++;
        if (t->stuck && --t->stuck_clocks <= 0) {
            t->stuck = 0;
            t->recoveries++;
        }
    }
    t->scl_low = low;
    twi_bench_lines(b);
}

void twi_bench_init(bench_t *b, uint32_t seed)
{
    bench_twi_t *t = &b->twi;
    (void)seed;
    t->cur = -1;
    tcam_init(&t->mux, 0x70);
    t->top[0] = tcam_slave(&t->mux);
    t->top_addr[0] = 0x70;
    t->n_top = 1;
}

void twi_bench_attach(bench_t *b)
{
    avr_t *avr = b->avr;
    b->twi.in_irq = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_OUTPUT), twi_output,
                            b);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(0), TWI_IRQ_STATUS), twi_status,
                            b);
    avr_register_io_write(avr, BENCH_TWCR, twcr_write, b);
    avr_register_io_read(avr, BENCH_TWCR, twcr_read, b);
    /* DDRD changes come as an IRQ: simavr 1.6 allows only four shared
     * register write hooks and the bench needs them elsewhere. */
    avr_irq_register_notify(
        avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('D'), IOPORT_IRQ_DIRECTION_ALL), ddrd_write, b);
    twi_bench_lines(b);
}

void twi_bench_advance(bench_t *b, uint64_t now_us)
{
    bench_twi_t *t = &b->twi;
    for (uint8_t i = 0; i < t->n_top; i++) {
        if (t->top[i].advance != NULL) {
            t->top[i].advance(t->top[i].ctx, now_us);
        }
    }
}

/* Power-on of every I2C part: mux channels off, sensors reset (fields and
 * noise are set again by the next world tick). */
void twi_bench_power_cycle(bench_t *b)
{
    bench_twi_t *t = &b->twi;
    t->mux.ctrl = 0;
    t->mux.target = 0;
    for (uint8_t k = 0; k < t->n_icm; k++) {
        icmm_t *m = &t->icm[k];
        uint32_t noise = m->ak.noise_cuT;
        uint8_t present = m->present;
        int32_t f[3] = {m->ak.field_cuT[0], m->ak.field_cuT[1], m->ak.field_cuT[2]};
        icmm_init(m, m->addr, b->seed + 101u * k);
        m->present = present;
        icmm_set_noise(m, noise, b->seed + 7u * k + 1u);
        icmm_set_field_cuT(m, f[0], f[1], f[2]);
        icmm_advance(m, bench_now_us(b));
    }
    t->stuck = 0;
    t->cur = -1;
    t->addr_phase = 0;
    twi_bench_lines(b);
}

void twi_bench_stick(bench_t *b, int32_t clocks)
{
    bench_twi_t *t = &b->twi;
    t->stuck = 1;
    t->stuck_clocks = clocks > 0 ? clocks : 1;
    t->stuck_events++;
    twi_bench_lines(b);
}
