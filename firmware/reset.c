#include "reset.h"

#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/wdt.h>

static uint8_t reset_mcusr __attribute__((section(".noinit")));

/* Runs in .init3, before .data/.bss are set up and before main(): a watchdog
 * that fired stays enabled after reset with the shortest timeout, so it must
 * be stopped before the C runtime spends time initialising memory. */
void reset_capture(void) __attribute__((naked, used, section(".init3")));
void reset_capture(void)
{
    reset_mcusr = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

uint8_t reset_flags(void)
{
    return reset_mcusr;
}

static const char name_power[] PROGMEM = "power";
static const char name_external[] PROGMEM = "external";
static const char name_brownout[] PROGMEM = "brown-out";
static const char name_watchdog[] PROGMEM = "watchdog";
static const char name_jtag[] PROGMEM = "jtag";
static const char name_software[] PROGMEM = "software";

const char *reset_cause_P(void)
{
    uint8_t f = reset_mcusr;
    if (f & RESET_WATCHDOG) {
        return name_watchdog;
    }
    if (f & RESET_BROWNOUT) {
        return name_brownout;
    }
    if (f & RESET_POWER) {
        return name_power;
    }
    if (f & RESET_EXTERNAL) {
        return name_external;
    }
    if (f & RESET_JTAG) {
        return name_jtag;
    }
    return name_software;
}
