/*
 * The board around the simulated MCU as hh_bench holds it: the LED pin, the
 * EEPROM image (loaded at start, saved at exit, writes counted) and resets
 * (the firmware's, a power cycle, the reset button): what the board's
 * hardware keeps on the pins put back after each.
 */
#include <errno.h>
#include <string.h>

#include <avr_eeprom.h>
#include <avr_ioport.h>
#include <sim_io.h>

#include "bench.h"

void bench_led_pin(avr_irq_t *irq, uint32_t value, void *param)
{
    bench_t *b = param;
    (void)irq;
    uint8_t on = value ? 1u : 0u;
    if (on == b->led_on && b->led_changes > 0) {
        return;
    }
    b->led_on = on;
    b->led_changes++;
    if (b->n_led < BENCH_LED_LOG) {
        b->led[b->n_led].t_us = bench_now_us(b);
        b->led[b->n_led].on = on;
        b->n_led++;
    }
}

void bench_eecr_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    bench_t *b = param;
    (void)avr;
    (void)addr;
    if (v & 0x02u) { /* EEPE: simavr has written the byte */
        b->ee_writes++;
        if (b->eewrite_stop != 0 && b->ee_writes >= b->eewrite_stop) {
            bench_finish(b, BENCH_EXIT_OK, "power-loss after EEPROM write");
        }
    }
}

void bench_reset_hook(avr_io_t *io)
{
    bench_t *b = ((bench_reset_io_t *)(void *)io)->b;
    b->reset_seen = 1;
}

static void ee_get(bench_t *b, uint8_t *img)
{
    avr_eeprom_desc_t d = {img, 0, BENCH_EEPROM_SIZE};
    avr_ioctl(b->avr, AVR_IOCTL_EEPROM_GET, &d); /* returns -1 even on success */
}

static void ee_set(bench_t *b, uint8_t *img)
{
    avr_eeprom_desc_t d = {img, 0, BENCH_EEPROM_SIZE};
    avr_ioctl(b->avr, AVR_IOCTL_EEPROM_SET, &d);
}

int bench_ee_load(bench_t *b)
{
    FILE *f;
    memset(b->ee_image, 0xFF, sizeof b->ee_image);
    if (b->eeprom_path == NULL) {
        return 0;
    }
    f = fopen(b->eeprom_path, "rb");
    if (f == NULL) {
        if (errno == ENOENT) {
            ee_set(b, b->ee_image); /* a new board: erased */
            return 0;
        }
        perror(b->eeprom_path);
        return -1;
    }
    size_t n = fread(b->ee_image, 1, sizeof b->ee_image, f);
    fclose(f);
    if (n != sizeof b->ee_image) {
        fprintf(stderr, "hh_bench: %s: %zu bytes, expected %u\n", b->eeprom_path, n,
                BENCH_EEPROM_SIZE);
        return -1;
    }
    ee_set(b, b->ee_image);
    return 0;
}

int bench_ee_save(bench_t *b)
{
    char tmp[4096];
    FILE *f;
    if (b->eeprom_path == NULL) {
        return 0;
    }
    ee_get(b, b->ee_image);
    snprintf(tmp, sizeof tmp, "%s.tmp", b->eeprom_path);
    f = fopen(tmp, "wb");
    if (f == NULL || fwrite(b->ee_image, 1, sizeof b->ee_image, f) != sizeof b->ee_image) {
        perror(tmp);
        if (f) {
            fclose(f);
        }
        return -1;
    }
    if (fclose(f) != 0 || rename(tmp, b->eeprom_path) != 0) {
        perror(b->eeprom_path);
        return -1;
    }
    return 0;
}

/* The reset cleared the PIN registers, but a pin IRQ keeps its last level
 * and simavr 1.6 filters a raise to the same level: raising the button's PE5
 * high again after a reset left PINE5 reading 0, a button held down from the
 * reset on (the firmware took it for a long press 2 s later), and PD2/PD3,
 * PE6/PE7 low (INT2/3/6/7 polled every cycle). Write the levels the board
 * holds on its inputs into the registers. */
static void held_levels(bench_t *b)
{
    uint8_t *pine = &b->avr->data[BENCH_PINE];
    uint8_t *pind = &b->avr->data[BENCH_PIND];
    *pine = (uint8_t)((*pine & (uint8_t)~b->ext_e_mask) | b->ext_e_value);
    *pind = (uint8_t)((*pind & (uint8_t)~b->twi.ext_d_mask) | b->twi.ext_d_value);
    bus_pin_high(b);
}

/* After any reset (ours or the firmware's watchdog): simavr dropped every
 * host timer and cleared the I/O registers; put back what the board's
 * hardware holds there. */
void bench_after_reset(bench_t *b)
{
    uint64_t now = bench_now_us(b);
    b->resets++;
    if (b->n_reset_log < BENCH_RESET_LOG) {
        b->reset_log[b->n_reset_log].t_us = now;
        b->reset_log[b->n_reset_log].mcusr = b->avr->data[BENCH_MCUSR];
        b->n_reset_log++;
    }
    if (b->avr->data[BENCH_MCUSR] & 0x08u) {
        b->wdt_resets++;
    }
    truth_reset(b, b->avr->data[BENCH_MCUSR]);
    loop_reset(b);
    b->timer_at = 0;
    b->bus.dir_tx = 0;
    b->bus.mcu_head = b->bus.mcu_tail = 0;
    b->bus.xoff = 0;
    b->con.xoff = 0;
    bench_led_pin(NULL, 0, b);
    avr_raise_irq(avr_io_getirq(b->avr, AVR_IOCTL_IOPORT_GETIRQ('E'), 4), 0);
    bus_pin_high(b);
    bench_button(b, b->button_down);
    if (b->button_down) {
        b->presses--; /* re-applied, not pressed again */
    }
    twi_bench_advance(b, now);
    b->twi.cur = -1;
    b->twi.addr_phase = 0;
    twi_bench_lines(b);
    held_levels(b);
    bench_rearm(b);
}

static uint64_t sram_rng(uint64_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    return *s;
}

void bench_do_reset(bench_t *b, uint8_t kind)
{
    uint64_t now = bench_now_us(b);
    ee_get(b, b->ee_image);
    avr_reset(b->avr);
    ee_set(b, b->ee_image);
    b->reset_seen = 0;
    if (kind == EV_POWER_CYCLE) {
        /* SRAM content is undefined after power-up: no .noinit survives */
        uint64_t s =
            0x2545F4914F6CDD1Dull ^ (b->power_cycles + 1u) * 0x9E3779B97F4A7C15ull ^ b->seed;
        for (unsigned a = BENCH_RAMSTART; a <= BENCH_RAMEND; a++) {
            b->avr->data[a] = (uint8_t)sram_rng(&s);
        }
        b->avr->data[BENCH_MCUSR] = 0x01u; /* PORF */
        b->power_cycles++;
        world_power_cycle(b, now);
    } else if (kind == EV_WDT_RESET) {
        b->avr->data[BENCH_MCUSR] = 0x08u; /* WDRF */
    } else {
        b->avr->data[BENCH_MCUSR] = 0x02u; /* EXTRF */
    }
    bench_after_reset(b);
}
