/*
 * store_fixture: the EEPROM and the store the lib/store tests share (g_ee,
 * g_st), power-ups, and the records they save, filled from a few numbers so
 * a test can rebuild the record it expects from what it reads back.
 */
#ifndef HALLHOME_STORE_FIXTURE_H
#define HALLHOME_STORE_FIXTURE_H

#include <stdint.h>

#include "store/store.h"
#include "store_fake.h"

#define STORE_FIX_TABLE_ID 0xC0FFEE01UL /* the table every record is saved for */
#define STORE_FIX_POLLS    100000u      /* polls a complete save takes at most */

extern store_fake_t g_ee;
extern store_t g_st;

/* Power comes back: the store starts again on what the EEPROM holds. */
void store_fix_boot(void);

/* A chip filled with `fill` (0xFF: erased), then store_fix_boot(). */
void store_fix_fresh(uint8_t fill);

/* Fills *h: 6 tendons at 800 mN, calibration count cal, homes around base. */
void store_fix_homes(store_homes_t *h, uint32_t cal, int32_t base);

/* Fills *e: history entry of calibration cal, 4 tendons. */
void store_fix_hist(store_hist_t *e, uint32_t cal);

/* Fills *l: learned targets of `tendon`, target_lsb[g] = v + g. */
void store_fix_learned(store_learned_t *l, uint8_t tendon, uint32_t v);

/* Saves *h and polls until the save is done; fails the test otherwise. */
void store_fix_save_homes(const store_homes_t *h);

#endif /* HALLHOME_STORE_FIXTURE_H */
