#include "board_io.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>

#include "board.h"

void board_io_init(void)
{
    BOARD_BTN_DDR &= (uint8_t) ~(1u << BOARD_BTN_BIT);
    BOARD_BTN_PORT |= (uint8_t)(1u << BOARD_BTN_BIT);
    BOARD_LED_PORT &= (uint8_t) ~(1u << BOARD_LED_BIT);
    BOARD_LED_DDR |= (uint8_t)(1u << BOARD_LED_BIT);
}

static uint8_t btn_hist;             /* the last 8 samples, 1 bits released */
static volatile uint8_t btn_presses; /* bit 0: settled down; bits 1-7: releases */

void board_io_sample(void)
{
    uint8_t h = (uint8_t)(btn_hist << 1);
    uint8_t p = btn_presses;
    if (BOARD_BTN_PIN & (1u << BOARD_BTN_BIT)) {
        h |= 1u;
    }
    btn_hist = h;
    if (h == 0u) {
        p |= 1u; /* down for 8 samples */
    } else if (h == 0xFFu && (p & 1u)) {
        p = (uint8_t)(p + 1u); /* up for 8 samples after a settled press: counted */
    }
    btn_presses = p;
}

uint8_t board_io_button(void)
{
    uint8_t pin = (uint8_t)((BOARD_BTN_PIN & (1u << BOARD_BTN_BIT)) == 0u);
    return (uint8_t)((btn_presses & 0xFEu) | pin); /* one byte: read atomically */
}

void board_io_led(uint8_t on)
{
    if (on) {
        BOARD_LED_PORT |= (uint8_t)(1u << BOARD_LED_BIT);
    } else {
        BOARD_LED_PORT &= (uint8_t) ~(1u << BOARD_LED_BIT);
    }
}

void board_io_wdt_start(void)
{
    wdt_enable(WDTO_500MS);
}

void board_io_wdt_kick(void)
{
    wdt_reset();
}

/* The reset must be a real one (registers, servo UART, TWI back to reset
 * state), so the watchdog does it rather than a jump to 0. */
void board_io_reboot(void)
{
    cli();
    wdt_enable(WDTO_15MS);
    for (;;) {
    }
}
