/*
 * xl430_table: which control-table writes a DYNAMIXEL XL430-W250-T accepts,
 * for the servo model (xl430_model.h). One row per field of the e-manual's
 * "Control Table of EEPROM Area" / "Control Table of RAM Area" (page
 * "XL430-W250"), with its access and the Range column; the error numbers are
 * those of the Protocol 2.0 page, section "Status Packet" / "Error".
 *
 * A write is checked as a whole before any byte is stored: one refused field
 * refuses the whole write (for a sync or bulk write, the whole entry of that
 * servo), which is how a real servo drops the goal of a sync write whose
 * profile velocity it refuses.
 */
#ifndef HALLHOME_XL430_TABLE_H
#define HALLHOME_XL430_TABLE_H

#include <stdint.h>

/* Checks a write of data[0..n) at addr against the table ct (the servo's
 * current control table, DXL_XL430_TABLE_SIZE bytes). Returns 0 when the
 * servo stores it, else the error number it answers:
 *  - DXL_ERR_ACCESS: outside the table, an address no field defines, a
 *    read-only field, or an EEPROM field while Torque Enable is 1;
 *  - DXL_ERR_DATA_LENGTH: the write covers part of a multi-byte field;
 *  - DXL_ERR_DATA_RANGE: a value outside the field's Range column (limits
 *    that are other fields included, e.g. Profile Velocity above Velocity
 *    Limit(44)), or a goal written while the Bus Watchdog has expired;
 *  - DXL_ERR_DATA_LIMIT: Goal Position outside the position limits of the
 *    operating mode;
 *  - DXL_ERR_RESULT_FAIL: Torque Enable 1 while Hardware Error Status is set.
 */
uint8_t xl430_table_check(const uint8_t *ct, uint16_t addr, const uint8_t *data, uint16_t n);

#endif /* HALLHOME_XL430_TABLE_H */
