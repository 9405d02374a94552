/*
 * store_fake: a RAM EEPROM behind store_eeprom_t for the unit tests. It
 * models the AVR's write timing (ready() is busy for a set number of polls
 * after every write), counts protocol violations (a write or read while
 * busy), and can cut the power at any byte write: the torn byte keeps its
 * old value, takes the new one or becomes garbage, and every later write is
 * lost.
 */
#ifndef HALLHOME_STORE_FAKE_H
#define HALLHOME_STORE_FAKE_H

#include <stdint.h>

#include "store/store.h"

#define STORE_FAKE_TORN_OLD     0u /* the cut byte keeps its old value */
#define STORE_FAKE_TORN_NEW     1u /* the cut byte was written completely */
#define STORE_FAKE_TORN_GARBAGE 2u /* the cut byte is erased (0xFF) or half written */

typedef struct {
    uint8_t mem[STORE_EEPROM_SIZE];
    store_eeprom_t ee;
    uint32_t writes;    /* byte writes started (also those lost after a cut) */
    int32_t cut_at;     /* index of the write the power dies in, or -1 */
    uint8_t torn;       /* STORE_FAKE_TORN_* */
    uint8_t dead;       /* power is off: writes are lost */
    uint8_t busy_polls; /* ready() answers 0 this many times after each write */
    uint8_t busy_left;
    int32_t stuck_addr;  /* a worn cell that ignores writes, or -1 */
    uint32_t violations; /* reads or writes while a write was in progress */
} store_fake_t;

/* Fills the EEPROM with `fill` (0xFF: erased chip) and binds the interface. */
void store_fake_init(store_fake_t *f, uint8_t fill);

/* Power comes back: clears the cut and busy state, keeps the contents. */
void store_fake_power_on(store_fake_t *f);

/* memcpy with the store_copy_fn signature. */
void store_fake_copy(void *dst, const void *src, size_t n);

/* Runs store_poll() until it returns <= 0 or `limit` polls passed; returns
 * the last result. */
int8_t store_fake_run(store_t *st, uint32_t limit);

#endif /* HALLHOME_STORE_FAKE_H */
