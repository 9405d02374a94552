/*
 * eeprom_port: the ATmega2560's EEPROM behind lib/store's store_eeprom_t.
 *
 * Non-blocking: eeprom_port_write_byte() only starts a byte write (EEMPE /
 * EEPE, about 3.4 ms); eeprom_port_ready() reports when the next access may
 * start, and lib/store calls write and read only then. Reads are immediate.
 */
#ifndef HALLHOME_EEPROM_PORT_H
#define HALLHOME_EEPROM_PORT_H

#include "store/store.h"

/* The interface to hand to store_init(); ctx is unused (one EEPROM). */
extern const store_eeprom_t eeprom_port;

#endif /* HALLHOME_EEPROM_PORT_H */
