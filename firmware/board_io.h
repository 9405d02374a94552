/*
 * board_io: the button, the status LED and the watchdog of the Mega, as the
 * application's board interface needs them (pins in board.h).
 */
#ifndef HALLHOME_BOARD_IO_H
#define HALLHOME_BOARD_IO_H

#include <stdint.h>

#define BOARD_IO_WDT_MS 500u /* watchdog period: well above the longest loop pass */

/* Button as an input with pull-up, LED as an output (off). */
void board_io_init(void);

/* Bit 0: the button is pressed now (the pin reads low). Bits 1-7: presses
 * counted by board_io_sample() (modulo 128), so a press that comes and
 * goes within one long main-loop pass is not lost (app.h, button). */
uint8_t board_io_button(void);

/* Samples the button; called by the tick interrupt every 4 ms, so a press
 * counts once it has held 32 ms and let go for 32 ms (the debounce time of
 * lib/app, APP_DEBOUNCE_MS, about the same). */
void board_io_sample(void);

/* Drives the LED. */
void board_io_led(uint8_t on);

/* Starts the watchdog (BOARD_IO_WDT_MS); board_io_wdt_kick() restarts its count. */
void board_io_wdt_start(void);
void board_io_wdt_kick(void);

/* Resets the board through the watchdog (15 ms); does not return. */
void board_io_reboot(void);

#endif /* HALLHOME_BOARD_IO_H */
