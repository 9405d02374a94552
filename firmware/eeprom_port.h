/*
 * eeprom_port: the ATmega2560's EEPROM behind lib/store: the store_ee_*()
 * functions of store.h, called directly with STORE_EE_FIXED, else through
 * the store_eeprom_t eeprom_port.
 *
 * Non-blocking: store_ee_write_byte() only starts a byte write (EEMPE /
 * EEPE, about 3.4 ms); store_ee_ready() reports when the next access may
 * start, and lib/store calls write and read only then. Reads are immediate.
 */
#ifndef HALLHOME_EEPROM_PORT_H
#define HALLHOME_EEPROM_PORT_H

#include "store/store.h"

#if !STORE_EE_FIXED
/* The interface to hand to store_init(); ctx is unused (one EEPROM). */
extern const store_eeprom_t eeprom_port;
#endif

#endif /* HALLHOME_EEPROM_PORT_H */
