/*
 * reset: why the board last reset, read from MCUSR before anything else runs
 * (and the watchdog disabled there, so a watchdog reset cannot loop).
 */
#ifndef HALLHOME_RESET_H
#define HALLHOME_RESET_H

#include <stdint.h>

#define RESET_POWER    0x01u /* PORF */
#define RESET_EXTERNAL 0x02u /* EXTRF: reset pin, e.g. the USB serial DTR pulse */
#define RESET_BROWNOUT 0x04u /* BORF */
#define RESET_WATCHDOG 0x08u /* WDRF */
#define RESET_JTAG     0x10u /* JTRF */

/* MCUSR as it was at this boot (RESET_* bits; 0 = a jump to 0, e.g. a
 * bootloader exit without a hardware reset). */
uint8_t reset_flags(void);

/* Short name of the most significant cause: "power", "external",
 * "brown-out", "watchdog", "jtag" or "software". Points to program memory. */
const char *reset_cause_P(void);

#endif /* HALLHOME_RESET_H */
