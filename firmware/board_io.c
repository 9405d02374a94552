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

uint8_t board_io_button(void)
{
    return (uint8_t)((BOARD_BTN_PIN & (1u << BOARD_BTN_BIT)) == 0u);
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
