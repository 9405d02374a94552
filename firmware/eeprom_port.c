#include "eeprom_port.h"

#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>

uint8_t store_ee_read_byte(uint16_t addr)
{
    return eeprom_read_byte((const uint8_t *)(uintptr_t)addr);
}

void store_ee_read_block(void *dst, uint16_t addr, uint16_t n)
{
    eeprom_read_block(dst, (const void *)(uintptr_t)addr, n);
}

uint8_t store_ee_ready(void)
{
    return eeprom_is_ready() ? 1u : 0u;
}

/* Starts one erase-and-write cycle and returns at once (avr-libc's
 * eeprom_write_byte would do the same, but first busy-waits for the previous
 * write; the store only calls here once store_ee_ready() said so). EEMPE must
 * be followed by EEPE within four cycles, hence interrupts off around it. */
void store_ee_write_byte(uint16_t addr, uint8_t value)
{
    uint8_t sreg;
    EEAR = addr;
    EEDR = value;
    EECR = 0; /* EEPM = 00: atomic erase and write */
    sreg = SREG;
    cli();
    EECR |= _BV(EEMPE);
    EECR |= _BV(EEPE);
    SREG = sreg;
}

#if !STORE_EE_FIXED
static uint8_t port_read_byte(void *ctx, uint16_t addr)
{
    (void)ctx;
    return store_ee_read_byte(addr);
}

static void port_read_block(void *ctx, void *dst, uint16_t addr, uint16_t n)
{
    (void)ctx;
    store_ee_read_block(dst, addr, n);
}

static uint8_t port_ready(void *ctx)
{
    (void)ctx;
    return store_ee_ready();
}

static void port_write_byte(void *ctx, uint16_t addr, uint8_t value)
{
    (void)ctx;
    store_ee_write_byte(addr, value);
}

const store_eeprom_t eeprom_port = {
    NULL, port_read_byte, port_read_block, port_ready, port_write_byte,
};
#endif
